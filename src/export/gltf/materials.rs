//! Materials of the glTF writer: one PBR metallic-roughness material per (surface class, colour,
//! material). The roughness and metalness are the material's ([`Material`], the one table of
//! `crate::color::material`): a surface of no known material is matte (roughness 0.9), glass is
//! smooth and slightly metallic, and opaque glass is the window colour darkened
//! ([`GLASS_SHADE`]), so that a pane reads as glass with a dark room behind it rather than as a
//! painted panel, without showing the hollow shell behind it.

use std::io::Write;

use crate::color::material::Material;
use crate::color::{srgb_to_linear, Color};

use super::json::{MaterialRec, Pbr, TextureRef};
use super::{GltfWriter, SurfaceClass, GLASS_SHADE};
use crate::export::texture::Texture;

impl<W: Write + Send> GltfWriter<W> {
    /// The material of `class` in `color` and `material`, created on first use.
    pub(super) fn material_for(
        &mut self,
        class: SurfaceClass,
        color: Color,
        material: Material,
        texture: Option<Texture>,
    ) -> u32 {
        let key = (class, color_key(color), material, texture);
        if let Some(&i) = self.material_index.get(&key) {
            return i;
        }
        let i = self.doc.materials.len() as u32;
        let c = sanitize(color);
        let mut name = if c.a < 1.0 {
            format!("{} {} alpha {}", class.name(), c.to_hex(), c.a)
        } else {
            format!("{} {}", class.name(), c.to_hex())
        };
        if material != Material::Unspecified {
            name.push(' ');
            name.push_str(material.name());
        }
        // The picture's index among the file's textures, in first-use order.
        let base_color_texture = texture.map(|t| {
            let at = match self.pictures.iter().position(|p| *p == t) {
                Some(at) => at,
                None => {
                    self.pictures.push(t);
                    self.pictures.len() - 1
                }
            };
            name.push_str(" textured ");
            name.push_str(&t.name());
            TextureRef { index: at as u32 }
        });
        let (c, metallic, roughness) = finish_params(color, material);
        self.doc.materials.push(MaterialRec {
            name,
            pbr: Pbr {
                base_color_factor: [
                    srgb_to_linear(c.r),
                    srgb_to_linear(c.g),
                    srgb_to_linear(c.b),
                    c.a,
                ],
                base_color_texture,
                metallic_factor: metallic,
                roughness_factor: roughness,
            },
            // No `doubleSided`: every surface is the outside of a closed (or walled-in) body.
            alpha_mode: (c.a < 1.0).then_some("BLEND"),
        });
        self.material_index.insert(key, i);
        i
    }
}

/// The colour (sRGB, sanitised: [`sanitize`]) and the metallic and roughness factors a
/// surface of `color` in `material` is drawn with: the colour as given, the material's
/// factors ([`Material::metallic`], [`Material::roughness`]); glass darker ([`GLASS_SHADE`])
/// when opaque, since transparent glass shows what is behind it.
pub(crate) fn finish_params(color: Color, material: Material) -> (Color, f32, f32) {
    let c = sanitize(color);
    match material {
        Material::Glass => {
            let shade = if c.a < 1.0 { 1.0 } else { GLASS_SHADE };
            let c = Color {
                r: c.r * shade,
                g: c.g * shade,
                b: c.b * shade,
                a: c.a,
            };
            (c, material.metallic(), material.roughness())
        }
        _ => (c, material.metallic(), material.roughness()),
    }
}

/// Colour components clamped to 0..=1, NaN as 0 (alpha NaN as opaque).
pub(super) fn sanitize(c: Color) -> Color {
    let f = |v: f32, nan: f32| if v.is_nan() { nan } else { v.clamp(0.0, 1.0) };
    Color {
        r: f(c.r, 0.0),
        g: f(c.g, 0.0),
        b: f(c.b, 0.0),
        a: f(c.a, 1.0),
    }
}

/// Bit pattern of the sanitised colour: a total, hashable key.
pub(super) fn color_key(c: Color) -> [u32; 4] {
    let c = sanitize(c);
    [c.r.to_bits(), c.g.to_bits(), c.b.to_bits(), c.a.to_bits()]
}
