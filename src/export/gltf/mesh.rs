//! Mesh building of the glTF writer: a building's faces grouped by surface class and colour,
//! triangulated (flat shaded) and laid out as vertex and index bytes.

use crate::color::Color;
use crate::export::lod3geom::{
    balcony_faces, cornice_solids, eaves_solids, opening_face, opening_frame, opening_reveals,
    sill_against_wall, sill_faces, sills, trim_color, SILL_COLOR,
};
use crate::export::{check_finite, ExportError};
use crate::model::{Building, OpeningKind, Part};

use super::contact::{self, Exposed};
use super::group::{bounds, group, group_textured, group_with, to_gltf, Group};
use super::lod4::add_interior;
use super::{
    SurfaceClass, GLASS_ALPHA, GROUND_COLOR, OPENING_SETBACK, UNSIGNED_INT, UNSIGNED_SHORT,
};
use crate::color::material::Material;
pub(crate) use crate::export::texture::Texturing;
use crate::export::texture::{edge_maps, roof_map, Texture};
use glam::DVec3;

/// Adds the panes and reveals of `part`'s openings of `kind` (see the module documentation),
/// on its walls that are `shown` (not wholly against another part). Glazed panes are glass:
/// opaque on a hollow part, transparent ([`GLASS_ALPHA`]) on a part with an interior (LOD4),
/// whose rooms are there to be seen through them.
pub(super) fn add_openings(
    groups: &mut Vec<Group>,
    part: &Part,
    shown: &Exposed<'_>,
    kind: OpeningKind,
) {
    let glass_alpha = if part.interior.is_empty() {
        1.0
    } else {
        GLASS_ALPHA
    };
    for (w, _) in part
        .walls
        .iter()
        .zip(&shown.walls)
        .filter(|(_, s)| !s.is_empty())
    {
        // Never behind the wall's inner face; no setback (and no reveals) for a wall without
        // thickness.
        let depth = if w.thickness.is_finite() && w.thickness > 0.0 {
            OPENING_SETBACK.min(w.thickness)
        } else {
            0.0
        };
        for o in w.openings.iter().filter(|o| o.kind == kind) {
            // A framed opening's frame is drawn round a smaller pane.
            let framed = opening_frame(w, o, depth);
            let Some(pane) = framed
                .as_ref()
                .map(|f| f.pane.clone())
                .or_else(|| opening_face(w, o, depth))
            else {
                continue;
            };
            if kind == OpeningKind::Window && o.glazed {
                let glass = Color {
                    a: glass_alpha,
                    ..o.color
                };
                group_with(groups, glass, Material::of_pane(true)).add_face(&pane);
            } else {
                group(groups, Color { a: 1.0, ..o.color }).add_face(&pane);
            }
            // The reveals in the wall's colour, the frame in its own; a framed opening too small
            // for its frame has its reveals in the frame's colour.
            let lining = if o.framed && framed.is_none() {
                o.frame_color
            } else {
                part.wall_color
            };
            let g = group(groups, Color { a: 1.0, ..lining });
            opening_reveals(w, o, depth)
                .iter()
                .for_each(|f| g.add_face(f));
            if let Some(f) = &framed {
                let g = group(
                    groups,
                    Color {
                        a: 1.0,
                        ..o.frame_color
                    },
                );
                f.frame.iter().for_each(|f| g.add_face(f));
            }
        }
        if kind == OpeningKind::Window {
            // The sills, less their faces in the wall's plane (hidden, they would fight it).
            for s in sills(w) {
                let Some(faces) = sill_faces(w, &s) else {
                    continue;
                };
                let g = group(groups, SILL_COLOR);
                for (i, f) in faces.iter().enumerate() {
                    if !sill_against_wall(i) {
                        g.add_face(f);
                    }
                }
            }
        }
    }
}

/// One building's binary data (vertex and index bytes) and primitive layout: all the work of a
/// write that needs no writer state, so a chunk of buildings can be encoded in parallel. The
/// writer keeps one per building of a parallel batch and reuses their buffers.
#[derive(Default)]
pub(super) struct Encoded {
    pub(super) layouts: Vec<Vec<PrimLayout>>,
    pub(super) vertex_bytes: Vec<u8>,
    pub(super) index_bytes: Vec<u8>,
    /// Texture coordinates (`--textures`): f32 pairs, in the building's third view.
    pub(super) uv_bytes: Vec<u8>,
}

impl Encoded {
    /// Frees the byte buffers that a large building grew past `SLOT_KEPT`, so that they are
    /// not kept for the next batch.
    pub(super) fn trim(&mut self) {
        use crate::export::SLOT_KEPT;
        if self.vertex_bytes.capacity() > SLOT_KEPT {
            self.vertex_bytes = Vec::new();
        }
        if self.index_bytes.capacity() > SLOT_KEPT {
            self.index_bytes = Vec::new();
        }
        if self.uv_bytes.capacity() > SLOT_KEPT {
            self.uv_bytes = Vec::new();
        }
    }
}

/// One building's faces, triangulated (flat shaded, in the model frame) and grouped by surface
/// class (in [`SurfaceClass::ALL`]'s order, the detail classes only with `detail`: LOD3 and up)
/// and within a class by colour and material (in first-seen order); faces against another part
/// of the building are left out (`contact`), and classes and groups without a triangle too.
/// What the glTF writer lays out ([`encode`]) and the 3D Tiles writer batches.
pub(crate) fn building_groups(
    b: &Building,
    detail: bool,
    tex: Texturing,
) -> Vec<(SurfaceClass, Vec<Group>)> {
    // Faces against another part of the building are inside it: not drawn.
    let exposed = contact::exposed(b);
    let mut classes: Vec<(SurfaceClass, Vec<Group>)> = Vec::new();
    for class in SurfaceClass::ALL {
        if class.is_detail() && !detail {
            continue;
        }
        let mut groups: Vec<Group> = Vec::new();
        for (part, shown) in b.parts.iter().zip(&exposed) {
            match class {
                SurfaceClass::Walls if tex != Texturing::Off => {
                    for (w, faces) in part.walls.iter().zip(&shown.walls) {
                        for f in faces {
                            add_textured_wall(&mut groups, part, w, f, tex);
                        }
                    }
                }
                SurfaceClass::Walls => {
                    let g = group_with(&mut groups, part.wall_color, part.wall_material);
                    shown.walls.iter().flatten().for_each(|f| g.add_face(f));
                }
                SurfaceClass::Roof if tex != Texturing::Off => {
                    shown
                        .roof
                        .iter()
                        .for_each(|f| add_textured_roof(&mut groups, part, f));
                }
                SurfaceClass::Roof => {
                    let g = group_with(&mut groups, part.roof_color, part.roof_material);
                    shown.roof.iter().for_each(|f| g.add_face(f));
                }
                SurfaceClass::Ground => {
                    let g = group(&mut groups, GROUND_COLOR);
                    shown.ground.iter().for_each(|f| g.add_face(f));
                }
                SurfaceClass::Windows => {
                    add_openings(&mut groups, part, shown, OpeningKind::Window)
                }
                SurfaceClass::Doors => add_openings(&mut groups, part, shown, OpeningKind::Door),
                SurfaceClass::Balconies => {
                    let walls = part.walls.iter().zip(&shown.walls);
                    for (w, _) in walls.filter(|(_, s)| !s.is_empty()) {
                        for bc in &w.balconies {
                            let Some(f) = balcony_faces(w, bc) else {
                                continue;
                            };
                            // The faces in the wall's plane are hidden and would fight it.
                            for (face, color) in f.colored(bc) {
                                if !f.against_wall(face) {
                                    group(&mut groups, color).add_face(face);
                                }
                            }
                        }
                    }
                }
                SurfaceClass::Floors
                | SurfaceClass::InteriorWalls
                | SurfaceClass::InteriorDoors
                | SurfaceClass::Stairs
                | SurfaceClass::Slabs => add_interior(&mut groups, part, class),
                SurfaceClass::Terrain => {}
            }
            // The cornice with the walls, the eaves with the roof (issue 49).
            match class {
                SurfaceClass::Walls => add_trim(&mut groups, part, false),
                SurfaceClass::Roof => add_trim(&mut groups, part, true),
                _ => {}
            }
        }
        groups.retain(|g| !g.mesh.indices.is_empty());
        if !groups.is_empty() {
            classes.push((class, groups));
        }
    }
    classes
}

/// Adds `part`'s cornice (`eaves` false) or eaves solids, less their faces against the wall,
/// each face in its colour and material (`lod3geom::trim_color`).
fn add_trim(groups: &mut Vec<Group>, part: &Part, eaves: bool) {
    let solids = if eaves {
        eaves_solids(part)
    } else {
        cornice_solids(part)
    };
    for s in &solids {
        for (i, f) in s.shown() {
            let (c, m) = trim_color(part, eaves, i);
            group_with(groups, c, m).add_face(f);
        }
    }
}

/// Adds a face `f` of wall `w` of `part` to its textured group: with [`Texturing::Facades`]
/// and a rhythm, the piece below the eaves with the bay picture (a picture a bay wide, as
/// many bays as the rules' `repeat` fits, and a storey high from the part's ground) and the
/// piece above them (a gable) with the material's pattern; else the material's pattern, in
/// metres from the wall's start and the part's ground.
fn add_textured_wall(
    groups: &mut Vec<Group>,
    part: &Part,
    w: &crate::model::Wall,
    f: &crate::model::Face,
    tex: Texturing,
) {
    add_textured_edge(groups, part, (w.start, w.end), f, tex);
}

/// Adds a roof face `f` of `part` to its textured group: the roof material's pattern, rows
/// along the eaves counted from the eaves' height (`crate::export::texture::roof_map`).
pub(crate) fn add_textured_roof(groups: &mut Vec<Group>, part: &Part, f: &crate::model::Face) {
    let (m, t) = (part.roof_material, Texture::Surface(part.roof_material));
    group_textured(groups, part.roof_color, m, Some(t))
        .add_mapped(f, &roof_map(part, f.normal()).1);
}

/// As [`add_textured_wall`], for a face `f` of a wall of `part` along `start` -> `end` (the
/// Blocks of 3D Tiles: one a footprint edge, `crate::export::texture::edge_maps`).
pub(crate) fn add_textured_edge(
    groups: &mut Vec<Group>,
    part: &Part,
    (start, end): (glam::DVec2, glam::DVec2),
    f: &crate::model::Face,
    tex: Texturing,
) {
    let (m, c) = (part.wall_material, part.wall_color);
    let maps = edge_maps(part, start, end, !f.holes.is_empty(), tex);
    let (plain_t, plain) = maps.plain;
    let Some((bay_t, map)) = maps.bay else {
        group_textured(groups, c, m, Some(plain_t)).add_mapped(f, &plain);
        return;
    };
    let (below, above) = split_at(f, maps.eave_z);
    if let Some(below) = below {
        group_textured(groups, c, m, Some(bay_t)).add_mapped(&below, &map);
    }
    if let Some(above) = above {
        group_textured(groups, c, m, Some(plain_t)).add_mapped(&above, &plain);
    }
}

/// A face without holes cut by the height `z` into its pieces below and above (each `None`
/// when empty); a face wholly on one side is given back whole.
pub(super) fn split_at(
    f: &crate::model::Face,
    z: f64,
) -> (Option<crate::model::Face>, Option<crate::model::Face>) {
    const EPS: f64 = 0.01;
    let lo = f.outer.iter().map(|p| p.z).fold(f64::INFINITY, f64::min);
    let hi = f
        .outer
        .iter()
        .map(|p| p.z)
        .fold(f64::NEG_INFINITY, f64::max);
    if hi <= z + EPS {
        return (Some(f.clone()), None);
    }
    if lo >= z - EPS {
        return (None, Some(f.clone()));
    }
    let clip = |below: bool| {
        let inside = |p: DVec3| if below { p.z <= z } else { p.z >= z };
        let n = f.outer.len();
        let mut out: Vec<DVec3> = Vec::with_capacity(n + 2);
        let mut push = |p: DVec3| {
            if out.last().is_none_or(|q: &DVec3| q.distance(p) > 1e-9) {
                out.push(p);
            }
        };
        for i in 0..n {
            let (a, b) = (f.outer[i], f.outer[(i + 1) % n]);
            if inside(a) {
                push(a);
            }
            if inside(a) != inside(b) && (b.z - a.z).abs() > 1e-12 {
                push(a.lerp(b, (z - a.z) / (b.z - a.z)));
            }
        }
        if out.len() > 1 && out[0].distance(out[out.len() - 1]) <= 1e-9 {
            out.pop();
        }
        (out.len() >= 3).then(|| crate::model::Face::new(out))
    };
    (clip(true), clip(false))
}

/// Triangulates and lays out one building (`detail`: LOD3 and up classes are written) into
/// `out`, whose buffers are reused. `checked`: the building is known finite
/// ([`crate::export::Checked`]), else it is checked here.
pub(super) fn encode(
    b: &Building,
    detail: bool,
    tex: Texturing,
    checked: bool,
    out: &mut Encoded,
) -> Result<(), ExportError> {
    out.layouts.clear();
    out.vertex_bytes.clear();
    out.index_bytes.clear();
    out.uv_bytes.clear();
    if !checked {
        check_finite("glTF writer", b)?;
    }
    let classes = building_groups(b, detail, tex);
    // The bytes are reserved at once, at their size, rather than grown by doubling, which
    // copies a tower's tens of MB and faults in fresh pages each time.
    let (vertices, index_bytes_len) =
        classes
            .iter()
            .flat_map(|(_, groups)| groups)
            .fold((0, 0), |(v, i), g| {
                let width = if g.mesh.positions.len() <= 65535 {
                    2
                } else {
                    4
                };
                (
                    v + g.mesh.positions.len(),
                    i + (g.mesh.indices.len() * width).next_multiple_of(4),
                )
            });
    out.vertex_bytes.reserve(vertices * 24);
    out.index_bytes.reserve(index_bytes_len);
    // Positions in glTF's frame, reused from primitive to primitive.
    let mut gltf_positions: Vec<[f32; 3]> = Vec::new();

    // Binary layout of one building: one vertex view (per primitive: positions, then
    // normals) and one index view (per primitive: indices padded to 4 bytes).
    let Encoded {
        layouts,
        vertex_bytes,
        index_bytes,
        uv_bytes,
    } = out;
    for (class, groups) in &classes {
        let mut prims = Vec::new();
        for g in groups {
            let m = &g.mesh;
            let too_big = || {
                ExportError::Invalid(format!(
                    "building {}: the {} mesh is too large for glTF ({} vertices)",
                    b.id,
                    class.name(),
                    m.positions.len()
                ))
            };
            let count = u32::try_from(m.positions.len()).map_err(|_| too_big())?;
            let idx_count = u32::try_from(m.indices.len()).map_err(|_| too_big())?;
            gltf_positions.clear();
            gltf_positions.extend(m.positions.iter().map(|p| to_gltf(*p)));
            let pos_offset = vertex_bytes.len() as u64;
            for p in &gltf_positions {
                p.iter()
                    .for_each(|c| vertex_bytes.extend_from_slice(&c.to_le_bytes()));
            }
            let nrm_offset = vertex_bytes.len() as u64;
            for n in &m.normals {
                to_gltf(*n)
                    .iter()
                    .for_each(|c| vertex_bytes.extend_from_slice(&c.to_le_bytes()));
            }
            // Texture coordinates, in their own view (a stride of 8), when the group has them.
            let uv_offset = (m.uvs.len() == m.positions.len() && g.texture.is_some()).then(|| {
                let at = uv_bytes.len() as u64;
                for uv in &m.uvs {
                    uv.iter()
                        .for_each(|c| uv_bytes.extend_from_slice(&c.to_le_bytes()));
                }
                at
            });
            let idx_offset = index_bytes.len() as u64;
            // 65535 is the primitive-restart value of u16 indices: never use it as an index.
            let idx_type = if count <= 65535 {
                m.indices
                    .iter()
                    .for_each(|&i| index_bytes.extend_from_slice(&(i as u16).to_le_bytes()));
                UNSIGNED_SHORT
            } else {
                m.indices
                    .iter()
                    .for_each(|&i| index_bytes.extend_from_slice(&i.to_le_bytes()));
                UNSIGNED_INT
            };
            while index_bytes.len() % 4 != 0 {
                index_bytes.push(0);
            }
            let (min, max) = bounds(&gltf_positions);
            prims.push(PrimLayout {
                class: *class,
                color: g.color,
                material: g.material,
                texture: g.texture,
                uv_offset,
                count,
                pos_offset,
                nrm_offset,
                idx_offset,
                idx_count,
                idx_type,
                min,
                max,
            });
        }
        layouts.push(prims);
    }

    Ok(())
}

/// Where one primitive's data lies in its building's vertex and index views.
pub(super) struct PrimLayout {
    pub(super) class: SurfaceClass,
    pub(super) color: Color,
    pub(super) material: Material,
    /// The picture of a textured primitive, whose coordinates are at `uv_offset` of the
    /// building's coordinate view.
    pub(super) texture: Option<Texture>,
    pub(super) uv_offset: Option<u64>,
    pub(super) count: u32,
    pub(super) pos_offset: u64,
    pub(super) nrm_offset: u64,
    pub(super) idx_offset: u64,
    pub(super) idx_count: u32,
    pub(super) idx_type: u32,
    pub(super) min: [f32; 3],
    pub(super) max: [f32; 3],
}
