//! Appearance of the CityGML writer: one `app:X3DMaterial` per distinct (colour, material) of a
//! building, targeting its polygons by id. A surface's material is the part's `wall_material`
//! or `roof_material`, glass for a glazed window ([`Material::of_pane`]), none for the rest.

use crate::color::material::Material;
use crate::color::Color;
use crate::export::lod3geom::{
    balcony_faces, cornice_solids, eaves_solids, opening_face, trim_color, wall_sill_faces,
    SILL_COLOR,
};
use crate::model::{Building, OpeningKind};

use super::material::{x3d_material, ColorKey};
use super::surfaces::{ring, seated_surfaces, surfaces, written_walls, SurfaceKind};
use super::xml::written_points;
use super::{lod4, GeometryLod, Renderer, APPEARANCE_THEME, GLASS_TRANSPARENCY};
use crate::export::format::push_fixed4_i64;
use crate::export::lod3geom::seated_changes;
use crate::export::texture::{note_used, roof_map, wall_maps, Texture, Texturing};

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
                    | SurfaceKind::Sill { .. }
                    | SurfaceKind::Trim { .. } => (part.wall_color, part.wall_material),
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
                let faces = wall_sill_faces(wall).len();
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
            // The cornice and eaves (issue 49), each face in its colour.
            for eaves in [false, true] {
                let solids = if eaves {
                    eaves_solids(part)
                } else {
                    cornice_solids(part)
                };
                let faces = solids.iter().flat_map(|s| s.faces.iter().enumerate());
                for (i, (k, _)) in faces.enumerate() {
                    let (color, material) = trim_color(part, eaves, k);
                    let kind = SurfaceKind::Trim { eaves };
                    add_target(&mut materials, color, material, (pi, kind, i));
                }
            }
        }
        let textured = self.texture_targets(b);
        if materials.is_empty() && textured.is_empty() {
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
        for (n, (t, targets)) in textured.iter().enumerate() {
            x.s("<app:surfaceDataMember>\n<app:ParameterizedTexture gml:id=\"");
            x.s(building_id);
            x.s("_t");
            x.uint(n as u64);
            x.s("\">\n<app:imageURI>");
            x.escaped(&self.tex.uri(*t), false);
            x.s("</app:imageURI>\n<app:mimeType>image/png</app:mimeType>\n");
            x.s("<app:wrapMode>wrap</app:wrapMode>\n");
            for (pi, kind, index, rings) in targets {
                x.s("<app:target uri=\"#");
                x.polygon_id(&part_ids[*pi], *kind, *index);
                x.s("\">\n<app:TexCoordList>\n");
                for (k, st) in rings.iter().enumerate() {
                    x.s("<app:textureCoordinates ring=\"#");
                    x.ring_id(&part_ids[*pi], *kind, *index, k.checked_sub(1));
                    x.s("\">");
                    for (i, c) in st.iter().chain(st.first()).enumerate() {
                        if i > 0 {
                            x.s(" ");
                        }
                        push_fixed4_i64(&mut x.0, c[0]);
                        x.s(" ");
                        push_fixed4_i64(&mut x.0, c[1]);
                    }
                    x.s("</app:textureCoordinates>\n");
                }
                x.s("</app:TexCoordList>\n</app:target>\n");
            }
            x.s("</app:ParameterizedTexture>\n</app:surfaceDataMember>\n");
        }
        if !textured.is_empty() {
            note_used(&self.tex.used, textured.iter().map(|(t, _)| *t));
        }
        x.s("</app:Appearance>\n</app:appearance>\n");
    }
}

/// A textured polygon: (part index, kind, index, each written ring's coordinates in
/// [`crate::export::texture::ST_UNIT`]s, the exterior first, without the closing point).
type Textured = (usize, SurfaceKind, usize, Vec<Vec<[i64; 2]>>);

impl Renderer<'_> {
    /// The building's textured polygons (`--textures`: walls and roofs) by picture, in
    /// first-use order, each ring's coordinates those of its written points
    /// ([`written_points`]): the pictures and maps of `crate::export::texture` that the glTF
    /// writer uses, a wall wholly below the eaves with its bay picture ([`WallMaps::whole`]).
    fn texture_targets(&self, b: &Building) -> Vec<(Texture, Vec<Textured>)> {
        let mut out: Vec<(Texture, Vec<Textured>)> = Vec::new();
        if self.tex.tex == Texturing::Off {
            return out;
        }
        for (pi, part) in b.parts.iter().enumerate() {
            let seated = if self.lod >= GeometryLod::Lod3 {
                seated_changes(part)
            } else {
                Vec::new()
            };
            for s in seated_surfaces(part, &seated) {
                let (t, map) = match s.kind {
                    SurfaceKind::Wall => {
                        let Some(w) = part.walls.get(s.index) else {
                            continue;
                        };
                        let maps = wall_maps(part, w, !s.face.holes.is_empty(), self.tex.tex);
                        let (t, map) = maps.whole(s.face);
                        (t, *map)
                    }
                    SurfaceKind::Roof => roof_map(part, s.face.normal()),
                    _ => continue,
                };
                let rings: Vec<Vec<[i64; 2]>> = ring(&s.face.outer)
                    .into_iter()
                    .chain(s.face.holes.iter().filter_map(|h| ring(h)))
                    .map(|r| {
                        written_points(r, self.origin)
                            .iter()
                            .map(|p| map.st(*p))
                            .collect()
                    })
                    .collect();
                let target = (pi, s.kind, s.index, rings);
                match out.iter_mut().find(|(k, _)| *k == t) {
                    Some((_, targets)) => targets.push(target),
                    None => out.push((t, vec![target])),
                }
            }
        }
        out
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
