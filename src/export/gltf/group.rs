//! Faces grouped by colour within one surface class of a building, as flat-shaded triangle
//! data in the model frame (f64; the glTF writer turns it to glTF's frame with [`to_gltf`] as it
//! lays it out, the 3D Tiles writer to its tile's frame): what the exterior (`mesh`) and the
//! interior (`lod4`) add faces to.

use std::cell::RefCell;

use glam::DVec3;

use crate::color::Color;
use crate::geometry::triangulate::Triangulator;
use crate::model::Face;

use super::materials::color_key;
use crate::color::material::Material;
use crate::export::texture::{Texture, UvMap};

/// Model frame (x east, y north, z up) to glTF (y up, z towards the viewer = south). A proper
/// rotation, so windings are kept. Adding 0.0 turns -0.0 into 0.0 for tidier min/max.
pub(crate) fn to_gltf(p: DVec3) -> [f32; 3] {
    [p.x as f32 + 0.0, p.z as f32 + 0.0, (-p.y) as f32 + 0.0]
}

/// Faces of one surface class, one colour and one material in one building.
pub(crate) struct Group {
    pub(crate) color: Color,
    pub(super) color_key: [u32; 4],
    pub(crate) material: Material,
    /// The picture its faces are textured with (`--textures`): its mesh has coordinates.
    pub(crate) texture: Option<Texture>,
    pub(crate) mesh: MeshData,
}

impl Group {
    /// Triangulates `face` into the group (see [`MeshData::add_face`]).
    pub(crate) fn add_face(&mut self, face: &Face) {
        self.mesh.add_face(face, None);
    }

    /// Triangulates `face` into the group with texture coordinates from `map`.
    pub(crate) fn add_mapped(&mut self, face: &Face, map: &UvMap) {
        self.mesh.add_face(face, Some(map));
    }
}

/// The matte group of `color` in `groups`, created (last) on first use.
pub(crate) fn group(groups: &mut Vec<Group>, color: Color) -> &mut Group {
    group_with(groups, color, Material::Unspecified)
}

/// The group of `color` and `material` in `groups`, created (last) on first use.
pub(super) fn group_with(groups: &mut Vec<Group>, color: Color, material: Material) -> &mut Group {
    group_textured(groups, color, material, None)
}

/// The group of `color`, `material` and `texture` in `groups`, created (last) on first use.
pub(super) fn group_textured(
    groups: &mut Vec<Group>,
    color: Color,
    material: Material,
    texture: Option<Texture>,
) -> &mut Group {
    let key = color_key(color);
    let i = match groups
        .iter()
        .position(|g| g.color_key == key && g.material == material && g.texture == texture)
    {
        Some(i) => i,
        None => {
            groups.push(Group {
                color,
                color_key: key,
                material,
                texture,
                mesh: MeshData::default(),
            });
            groups.len() - 1
        }
    };
    &mut groups[i]
}

thread_local! {
    /// Each thread's triangulation buffers, reused from face to face.
    static TRIANGULATOR: RefCell<Triangulator> = RefCell::new(Triangulator::default());
}

/// Flat-shaded triangle data of one primitive, in the model frame (x east, y north, z up,
/// metres from the run's local origin).
#[derive(Default)]
pub(crate) struct MeshData {
    pub(crate) positions: Vec<DVec3>,
    /// The unit normal of each vertex's face.
    pub(crate) normals: Vec<DVec3>,
    /// Texture coordinates of each vertex (a textured group's; empty otherwise).
    pub(crate) uvs: Vec<[f32; 2]>,
    pub(crate) indices: Vec<u32>,
}

impl MeshData {
    /// Appends a face with its own vertices and normal; degenerate faces, and faces with a
    /// vertex beyond f32 range in glTF's frame, add nothing.
    pub(super) fn add_face(&mut self, face: &Face, map: Option<&UvMap>) {
        TRIANGULATOR.with_borrow_mut(|tri| self.add_triangulated(face, tri, map));
    }

    fn add_triangulated(&mut self, face: &Face, tri: &mut Triangulator, map: Option<&UvMap>) {
        let Some(t) = tri.face(&face.outer, &face.holes) else {
            return;
        };
        let Ok(base) = u32::try_from(self.positions.len()) else {
            return;
        };
        if u32::try_from(self.positions.len() + t.vertices.len()).is_err() {
            return;
        }
        // Coordinates beyond f32 range (never in a local frame, but input is input).
        if t.vertices
            .iter()
            .any(|p| to_gltf(*p).iter().any(|c| !c.is_finite()))
        {
            return;
        }
        if let Some(map) = map {
            self.uvs.extend(t.vertices.iter().map(|p| map.uv(*p)));
        }
        self.positions.extend_from_slice(t.vertices);
        self.normals
            .extend(std::iter::repeat_n(t.normal, t.vertices.len()));
        self.indices
            .extend(t.triangles.iter().flatten().map(|i| base + i));
    }
}

/// Component-wise min and max of `positions` (as glTF requires for POSITION).
pub(crate) fn bounds(positions: &[[f32; 3]]) -> ([f32; 3], [f32; 3]) {
    let mut lo = [f32::INFINITY; 3];
    let mut hi = [f32::NEG_INFINITY; 3];
    for p in positions {
        for k in 0..3 {
            lo[k] = lo[k].min(p[k]);
            hi[k] = hi[k].max(p[k]);
        }
    }
    (lo, hi)
}
