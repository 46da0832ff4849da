//! Appearance of the CityGML writer: one `app:X3DMaterial` per distinct (colour, material) of a
//! building, targeting its polygons by id. A surface's material is the part's `wall_material`
//! or `roof_material`, glass for a glazed window ([`Material::of_pane`]), none for the rest.

use crate::color::material::Material;
use crate::color::Color;
use crate::export::lod3geom::{balcony_faces, opening_face, sill_faces, sills, SILL_COLOR};
use crate::model::{Building, OpeningKind};

use super::material::{x3d_material, ColorKey};
use super::surfaces::{surfaces, written_walls, SurfaceKind};
use super::{lod4, GeometryLod, Renderer, APPEARANCE_THEME, GLASS_TRANSPARENCY};

/// A polygon an appearance targets: (part index, kind, index in the part's list).
pub(super) type Target = (usize, SurfaceKind, usize);

impl Renderer<'_> {
    /// The local appearance: one X3DMaterial per distinct (colour, material), in order of first
    /// use.
    pub(super) fn appearance(&mut self, building_id: &str, b: &Building, part_ids: &[String]) {
        // (colour, [(part index, kind, index)]) in first-use order: deterministic, and the few
        // colours of a building make a linear search cheaper than hashing.
        let mut materials: Vec<((ColorKey, Material), Vec<Target>)> = Vec::new();
        for (pi, part) in b.parts.iter().enumerate() {
            for s in surfaces(part) {
                let (color, material) = match s.kind {
                    SurfaceKind::Ground => (Color::GREY, Material::Unspecified),
                    SurfaceKind::Roof => (part.roof_color, part.roof_material),
                    // `surfaces` yields no openings or balconies.
                    SurfaceKind::Wall
                    | SurfaceKind::Opening { .. }
                    | SurfaceKind::Balcony { .. }
                    | SurfaceKind::Sill { .. } => (part.wall_color, part.wall_material),
                };
                add_target(&mut materials, color, material, (pi, s.kind, s.index));
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
                        Material::of_pane(o.kind == OpeningKind::Window && o.glazed),
                        (pi, SurfaceKind::Opening { wall: wi }, k),
                    );
                }
                for (k, bc) in wall.balconies.iter().enumerate() {
                    let Some(f) = balcony_faces(wall, bc) else {
                        continue;
                    };
                    for (i, (_, color)) in f.colored(bc).enumerate() {
                        let kind = SurfaceKind::Balcony {
                            wall: wi,
                            balcony: k,
                        };
                        add_target(&mut materials, color, Material::Unspecified, (pi, kind, i));
                    }
                }
                let faces = sills(wall)
                    .iter()
                    .filter_map(|s| sill_faces(wall, s))
                    .count()
                    * 6;
                for i in 0..faces {
                    let kind = SurfaceKind::Sill { wall: wi };
                    add_target(
                        &mut materials,
                        SILL_COLOR,
                        Material::Unspecified,
                        (pi, kind, i),
                    );
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

/// Adds `target` to the X3D material of `color` and `material`, creating it (last) on first
/// use.
pub(super) fn add_target(
    materials: &mut Vec<((ColorKey, Material), Vec<Target>)>,
    color: Color,
    material: Material,
    target: Target,
) {
    let key = (ColorKey::of(color), material);
    match materials.iter_mut().find(|(k, _)| *k == key) {
        Some((_, targets)) => targets.push(target),
        None => materials.push((key, vec![target])),
    }
}
