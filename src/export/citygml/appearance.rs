//! Appearance of the CityGML writer: one `app:X3DMaterial` per distinct colour of a building,
//! targeting its polygons by id.

use crate::color::Color;
use crate::export::lod3geom::{balcony_faces, opening_face};
use crate::model::{Building, OpeningKind};

use super::surfaces::{surfaces, written_walls, SurfaceKind};
use super::xml::Xml;
use super::{lod4, GeometryLod, Renderer, APPEARANCE_THEME, GLASS_TRANSPARENCY};

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

/// A polygon an appearance targets: (part index, kind, index in the part's list).
pub(super) type Target = (usize, SurfaceKind, usize);

impl Renderer<'_> {
    /// The local appearance: one X3DMaterial per distinct colour, in order of first use.
    pub(super) fn appearance(&mut self, building_id: &str, b: &Building, part_ids: &[String]) {
        // (colour, [(part index, kind, index)]) in first-use order: deterministic, and the few
        // colours of a building make a linear search cheaper than hashing.
        let mut materials: Vec<(ColorKey, Vec<Target>)> = Vec::new();
        for (pi, part) in b.parts.iter().enumerate() {
            for s in surfaces(part) {
                let color = match s.kind {
                    SurfaceKind::Ground => Color::GREY,
                    SurfaceKind::Roof => part.roof_color,
                    // `surfaces` yields no openings or balconies.
                    SurfaceKind::Wall
                    | SurfaceKind::Opening { .. }
                    | SurfaceKind::Balcony { .. } => part.wall_color,
                };
                add_target(&mut materials, color, (pi, s.kind, s.index));
            }
            if self.lod < GeometryLod::Lod3 {
                continue;
            }
            for (wi, wall) in written_walls(part) {
                for (k, o) in wall.openings.iter().enumerate() {
                    if opening_face(wall, o, 0.0).is_none() {
                        continue;
                    }
                    let color = match o.kind {
                        OpeningKind::Window if o.glazed => Color {
                            a: 1.0 - GLASS_TRANSPARENCY,
                            ..o.color
                        },
                        _ => Color { a: 1.0, ..o.color },
                    };
                    add_target(
                        &mut materials,
                        color,
                        (pi, SurfaceKind::Opening { wall: wi }, k),
                    );
                }
                for (k, bc) in wall.balconies.iter().enumerate() {
                    let Some(f) = balcony_faces(wall, bc) else {
                        continue;
                    };
                    for i in 0..f.all().count() {
                        let kind = SurfaceKind::Balcony {
                            wall: wi,
                            balcony: k,
                        };
                        add_target(&mut materials, bc.color, (pi, kind, i));
                    }
                }
            }
        }
        if materials.is_empty() {
            return;
        }
        let x = &mut *self.x;
        x.s("<app:appearance>\n<app:Appearance>\n<app:theme>");
        x.s(APPEARANCE_THEME);
        x.s("</app:theme>\n");
        for (mi, (key, targets)) in materials.iter().enumerate() {
            x3d_material(
                x,
                [building_id, "_m"],
                mi,
                *key,
                targets,
                |x, &(pi, kind, index)| {
                    x.polygon_id(&part_ids[pi], kind, index);
                },
            );
        }
        if self.lod == GeometryLod::Lod4 {
            lod4::materials(x, building_id, b, part_ids);
        }
        x.s("</app:Appearance>\n</app:appearance>\n");
    }
}

/// Adds `target` to the material of `color`, creating it (last) on first use.
pub(super) fn add_target(
    materials: &mut Vec<(ColorKey, Vec<Target>)>,
    color: Color,
    target: Target,
) {
    let key = ColorKey::of(color);
    match materials.iter_mut().find(|(k, _)| *k == key) {
        Some((_, targets)) => targets.push(target),
        None => materials.push((key, vec![target])),
    }
}

/// Writes one `app:surfaceDataMember` holding an `app:X3DMaterial` with id `{id[0]}{id[1]}{n}`
/// (e.g. `B_way_1_m0`) of the colour `key` (its `app:transparency` only when not opaque),
/// targeting each of `targets` by the polygon id `target` writes for it. Used for the
/// exterior's materials and for the LOD4 interior's ([`lod4::materials`]).
pub(super) fn x3d_material<T>(
    x: &mut Xml,
    id: [&str; 2],
    n: usize,
    key: ColorKey,
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
