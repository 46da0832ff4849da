//! The X3D material of the CityGML writer: a colour as written with its surface material, and
//! the one `app:surfaceDataMember` writer that the exterior's appearance and the LOD4
//! interior's share.

use crate::color::material::Material;
use crate::color::Color;

use super::xml::Xml;

/// A colour quantised as written (4 decimals), used to merge equal materials.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) struct ColorKey {
    pub(super) rgb: [u16; 3],
    /// Transparency (1 - alpha) in 1/10000.
    pub(super) transparency: u16,
}

impl ColorKey {
    pub(super) fn of(c: Color) -> ColorKey {
        let q = |v: f32| {
            if v.is_finite() {
                (v.clamp(0.0, 1.0) * 10_000.0).round() as u16
            } else {
                0
            }
        };
        let alpha = if c.a.is_finite() { c.a } else { 1.0 };
        ColorKey {
            rgb: [q(c.r), q(c.g), q(c.b)],
            transparency: 10_000 - q(alpha),
        }
    }
}

/// Writes one `app:surfaceDataMember` holding an `app:X3DMaterial` with id `{id[0]}{id[1]}{n}`
/// (e.g. `B_way_1_m0`) of the colour and material `key`: `app:diffuseColor`, the material's
/// `app:shininess` when a material is known ([`Material::shininess`]: one minus its PBR
/// roughness, so brick is 0.15, slate 0.4, glass 0.9), `app:transparency` only when not opaque,
/// targeting each of `targets` by the polygon id `target` writes for it. Used for the
/// exterior's materials (`appearance`) and for the LOD4 interior's (`lod4::materials`).
pub(super) fn x3d_material<T>(
    x: &mut Xml,
    id: [&str; 2],
    n: usize,
    (key, material): (ColorKey, Material),
    targets: &[T],
    target: impl Fn(&mut Xml, &T),
) {
    x.s("<app:surfaceDataMember>\n<app:X3DMaterial gml:id=\"");
    x.s(id[0]);
    x.s(id[1]);
    x.uint(n as u64);
    x.s("\">\n<app:diffuseColor>");
    for (i, c) in key.rgb.iter().enumerate() {
        if i > 0 {
            x.s(" ");
        }
        x.fixed4(*c);
    }
    x.s("</app:diffuseColor>\n");
    if material != Material::Unspecified {
        x.s("<app:shininess>");
        x.fixed4((material.shininess() * 10_000.0).round() as u16);
        x.s("</app:shininess>\n");
    }
    if key.transparency > 0 {
        x.s("<app:transparency>");
        x.fixed4(key.transparency);
        x.s("</app:transparency>\n");
    }
    for t in targets {
        x.s("<app:target>#");
        target(x, t);
        x.s("</app:target>\n");
    }
    x.s("</app:X3DMaterial>\n</app:surfaceDataMember>\n");
}
