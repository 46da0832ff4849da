//! Mesh building of the glTF writer: a building's faces grouped by surface class and colour,
//! triangulated (flat shaded) and laid out as vertex and index bytes.

use glam::DVec3;

use crate::color::Color;
use crate::export::lod3geom::{balcony_faces, opening_face, opening_reveals};
use crate::export::{check_finite, ExportError};
use crate::geometry::triangulate::triangulate_face;
use crate::model::{Building, Face, OpeningKind, Part};

use super::lod4::add_interior;
use super::materials::color_key;
use super::{
    SurfaceClass, GLASS_ALPHA, GROUND_COLOR, OPENING_SETBACK, UNSIGNED_INT, UNSIGNED_SHORT,
};

/// Model frame (x east, y north, z up) to glTF (y up, z towards the viewer = south). A proper
/// rotation, so windings are kept. Adding 0.0 turns -0.0 into 0.0 for tidier min/max.
pub(super) fn to_gltf(p: DVec3) -> [f32; 3] {
    [p.x as f32 + 0.0, p.z as f32 + 0.0, (-p.y) as f32 + 0.0]
}

/// Faces of one surface class and one colour in one building.
pub(super) struct Group {
    pub(super) color: Color,
    pub(super) color_key: [u32; 4],
    pub(super) mesh: MeshData,
}

impl Group {
    pub(super) fn add_face(&mut self, face: &Face) {
        self.mesh.add_face(face);
    }
}

/// The group of `color` in `groups`, created (last) on first use.
pub(super) fn group(groups: &mut Vec<Group>, color: Color) -> &mut Group {
    let key = color_key(color);
    let i = match groups.iter().position(|g| g.color_key == key) {
        Some(i) => i,
        None => {
            groups.push(Group {
                color,
                color_key: key,
                mesh: MeshData::default(),
            });
            groups.len() - 1
        }
    };
    &mut groups[i]
}

/// Adds the panes and reveals of `part`'s openings of `kind` (see the module documentation).
pub(super) fn add_openings(groups: &mut Vec<Group>, part: &Part, kind: OpeningKind) {
    for w in &part.walls {
        // Never behind the wall's inner face; no setback (and no reveals) for a wall without
        // thickness.
        let depth = if w.thickness.is_finite() && w.thickness > 0.0 {
            OPENING_SETBACK.min(w.thickness)
        } else {
            0.0
        };
        for o in w.openings.iter().filter(|o| o.kind == kind) {
            let Some(pane) = opening_face(w, o, depth) else {
                continue;
            };
            let color = if kind == OpeningKind::Window && o.glazed {
                Color {
                    a: GLASS_ALPHA,
                    ..o.color
                }
            } else {
                Color { a: 1.0, ..o.color }
            };
            group(groups, color).add_face(&pane);
            let lining = if o.framed {
                o.frame_color
            } else {
                part.wall_color
            };
            let g = group(groups, Color { a: 1.0, ..lining });
            opening_reveals(w, o, depth)
                .iter()
                .for_each(|f| g.add_face(f));
        }
    }
}

/// One building's binary data (vertex and index bytes) and primitive layout: all the work of a
/// write that needs no writer state, so a chunk of buildings can be encoded in parallel.
pub(super) struct Encoded {
    pub(super) layouts: Vec<Vec<PrimLayout>>,
    pub(super) vertex_bytes: Vec<u8>,
    pub(super) index_bytes: Vec<u8>,
}

/// Triangulates and lays out one building (`detail`: LOD3 and up classes are written).
pub(super) fn encode(b: &Building, detail: bool) -> Result<Encoded, ExportError> {
    check_finite("glTF writer", b)?;
    let mut classes: Vec<(SurfaceClass, Vec<Group>)> = Vec::new();
    for class in SurfaceClass::ALL {
        if class.is_detail() && !detail {
            continue;
        }
        let mut groups: Vec<Group> = Vec::new();
        for part in &b.parts {
            match class {
                SurfaceClass::Walls => {
                    let g = group(&mut groups, part.wall_color);
                    part.walls.iter().for_each(|w| g.add_face(&w.outline));
                }
                SurfaceClass::Roof => {
                    let g = group(&mut groups, part.roof_color);
                    part.roof.iter().for_each(|f| g.add_face(f));
                }
                SurfaceClass::Ground => group(&mut groups, GROUND_COLOR).add_face(&part.ground),
                SurfaceClass::Windows => add_openings(&mut groups, part, OpeningKind::Window),
                SurfaceClass::Doors => add_openings(&mut groups, part, OpeningKind::Door),
                SurfaceClass::Balconies => {
                    for w in &part.walls {
                        for bc in &w.balconies {
                            if let Some(f) = balcony_faces(w, bc) {
                                let g = group(&mut groups, bc.color);
                                f.all().for_each(|face| g.add_face(face));
                            }
                        }
                    }
                }
                SurfaceClass::Floors
                | SurfaceClass::InteriorWalls
                | SurfaceClass::InteriorDoors
                | SurfaceClass::Stairs
                | SurfaceClass::Slabs => add_interior(&mut groups, part, class),
            }
        }
        groups.retain(|g| !g.mesh.indices.is_empty());
        if !groups.is_empty() {
            classes.push((class, groups));
        }
    }

    // Binary layout of one building: one vertex view (per primitive: positions, then
    // normals) and one index view (per primitive: indices padded to 4 bytes).
    let mut vertex_bytes: Vec<u8> = Vec::new();
    let mut index_bytes: Vec<u8> = Vec::new();
    let mut layouts: Vec<Vec<PrimLayout>> = Vec::new();
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
            let pos_offset = vertex_bytes.len() as u64;
            for p in &m.positions {
                p.iter()
                    .for_each(|c| vertex_bytes.extend_from_slice(&c.to_le_bytes()));
            }
            let nrm_offset = vertex_bytes.len() as u64;
            for n in &m.normals {
                n.iter()
                    .for_each(|c| vertex_bytes.extend_from_slice(&c.to_le_bytes()));
            }
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
            let (min, max) = m.bounds();
            prims.push(PrimLayout {
                class: *class,
                color: g.color,
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

    Ok(Encoded {
        layouts,
        vertex_bytes,
        index_bytes,
    })
}

/// Flat-shaded triangle data of one primitive.
#[derive(Default)]
pub(super) struct MeshData {
    pub(super) positions: Vec<[f32; 3]>,
    pub(super) normals: Vec<[f32; 3]>,
    pub(super) indices: Vec<u32>,
}

impl MeshData {
    /// Appends a face with its own vertices and normal; degenerate faces add nothing.
    pub(super) fn add_face(&mut self, face: &Face) {
        let Some(t) = triangulate_face(&face.outer, &face.holes) else {
            return;
        };
        let positions: Vec<[f32; 3]> = t.vertices.iter().map(|p| to_gltf(*p)).collect();
        // Coordinates beyond f32 range (never in a local frame, but input is input).
        if positions.iter().flatten().any(|c| !c.is_finite()) {
            return;
        }
        let Ok(base) = u32::try_from(self.positions.len()) else {
            return;
        };
        if u32::try_from(self.positions.len() + positions.len()).is_err() {
            return;
        }
        let n = to_gltf(t.normal);
        self.normals.extend(std::iter::repeat_n(n, positions.len()));
        self.positions.extend(positions);
        self.indices
            .extend(t.triangles.iter().flatten().map(|i| base + i));
    }

    /// Component-wise min and max of the positions (as glTF requires for POSITION).
    fn bounds(&self) -> ([f32; 3], [f32; 3]) {
        let mut lo = [f32::INFINITY; 3];
        let mut hi = [f32::NEG_INFINITY; 3];
        for p in &self.positions {
            for k in 0..3 {
                lo[k] = lo[k].min(p[k]);
                hi[k] = hi[k].max(p[k]);
            }
        }
        (lo, hi)
    }
}

/// Where one primitive's data lies in its building's vertex and index views.
pub(super) struct PrimLayout {
    pub(super) class: SurfaceClass,
    pub(super) color: Color,
    pub(super) count: u32,
    pub(super) pos_offset: u64,
    pub(super) nrm_offset: u64,
    pub(super) idx_offset: u64,
    pub(super) idx_count: u32,
    pub(super) idx_type: u32,
    pub(super) min: [f32; 3],
    pub(super) max: [f32; 3],
}
