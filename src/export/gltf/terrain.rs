//! The terrain of a file as its own node: a root node `terrain` with one mesh of one
//! triangle primitive in the terrain material (matte, [`TERRAIN_COLOR`]), written after the
//! buildings. Its vertices are shared between triangles and carry smooth normals (each the
//! area-weighted mean of its triangles' normals), unlike the buildings' flat faces: the ground
//! is a surface, not facets. Coordinates as the buildings': metres, Y up, local frame.

use std::io::Write;

use glam::{DVec3, Vec3};

use crate::color::material::Material;
use crate::color::Color;
use crate::export::ExportError;
use crate::model::Terrain;

use super::json::{AccessorRec, Attributes, MeshRec, NodeRec, PrimitiveRec, ViewRec};
use super::json::{ACCESSORS, MESHES, NODES, VIEWS};
use super::{
    GltfWriter, State, SurfaceClass, ARRAY_BUFFER, ELEMENT_ARRAY_BUFFER, FLOAT, UNSIGNED_INT,
    VEC3_STRIDE,
};

/// The terrain's colour: a dry grass green.
pub(crate) const TERRAIN_COLOR: Color = Color {
    r: 0.55,
    g: 0.6,
    b: 0.42,
    a: 1.0,
};

/// glTF's frame (x, y up, z south) of a model point.
fn gltf(p: DVec3) -> Vec3 {
    Vec3::new(p.x as f32, p.z as f32, -p.y as f32)
}

/// The terrain's positions, normals and indices as the binary chunk holds them.
fn encode(t: &Terrain) -> (Vec<u8>, Vec<u8>, [f32; 3], [f32; 3]) {
    let mut normals = vec![DVec3::ZERO; t.vertices.len()];
    for tri in &t.triangles {
        let p = tri.map(|k| t.vertices[k as usize]);
        // Twice the area times the unit normal: larger triangles weigh more.
        let n = (p[1] - p[0]).cross(p[2] - p[0]);
        for &k in tri {
            normals[k as usize] += n;
        }
    }
    let (mut lo, mut hi) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
    let mut bytes = Vec::with_capacity(24 * t.vertices.len());
    for p in &t.vertices {
        let g = gltf(*p);
        lo = lo.min(g);
        hi = hi.max(g);
        g.to_array()
            .iter()
            .for_each(|c| bytes.extend_from_slice(&c.to_le_bytes()));
    }
    for n in &normals {
        let n = n.try_normalize().unwrap_or(DVec3::Z);
        gltf(n)
            .to_array()
            .iter()
            .for_each(|c| bytes.extend_from_slice(&c.to_le_bytes()));
    }
    let indices: Vec<u8> = t
        .triangles
        .iter()
        .flatten()
        .flat_map(|k| k.to_le_bytes())
        .collect();
    (bytes, indices, lo.to_array(), hi.to_array())
}

impl<W: Write + Send> GltfWriter<W> {
    /// Appends the terrain: its data to the binary chunk, its records, and its root node.
    pub(super) fn add_terrain(&mut self, t: &Terrain) -> Result<(), ExportError> {
        if t.triangles.is_empty() || t.vertices.is_empty() {
            return Ok(());
        }
        let (vertex_bytes, index_bytes, min, max) = encode(t);
        let vertex_offset = self.bin_len;
        let index_offset = vertex_offset + vertex_bytes.len() as u64;
        if !self.discard {
            let scratch = self
                .scratch
                .as_mut()
                .ok_or_else(|| ExportError::Invalid("glTF writer: scratch file missing".into()))?;
            let written = scratch
                .write_all(&vertex_bytes)
                .and_then(|()| scratch.write_all(&index_bytes));
            if let Err(e) = written {
                self.state = State::Failed;
                return Err(e.into());
            }
        }
        self.bin_len = index_offset + index_bytes.len() as u64;
        if self.bin_len > self.max_bin {
            self.state = State::Failed;
            return Err(ExportError::Invalid(format!(
                "the glTF binary is over the GLB limit of 4 GiB ({} bytes with the terrain); \
                 write fewer buildings per file (--tile METRES) or a coarser terrain \
                 (--terrain-tolerance)",
                self.bin_len
            )));
        }
        let material = self.material_for(
            SurfaceClass::Terrain,
            TERRAIN_COLOR,
            Material::Unspecified,
            None,
        );
        let count = t.vertices.len() as u32;
        let mut tmp = std::mem::take(&mut self.json_scratch);
        let r = (|| -> std::io::Result<()> {
            let view = |offset, length, stride, target| ViewRec {
                buffer: 0,
                byte_offset: offset,
                byte_length: length,
                byte_stride: stride,
                target: Some(target),
            };
            let len = vertex_bytes.len() as u64;
            let vertex_view = self.spools[VIEWS].push(
                &view(vertex_offset, len, Some(VEC3_STRIDE), ARRAY_BUFFER),
                &mut tmp,
            )?;
            let len = index_bytes.len() as u64;
            let index_view = self.spools[VIEWS].push(
                &view(index_offset, len, None, ELEMENT_ARRAY_BUFFER),
                &mut tmp,
            )?;
            let acc = &mut self.spools[ACCESSORS];
            let accessor = |view, offset, kind, component, count, bounds: Option<_>| AccessorRec {
                buffer_view: view,
                byte_offset: offset,
                component_type: component,
                count,
                kind,
                min: bounds.map(|(lo, _)| lo),
                max: bounds.map(|(_, hi)| hi),
            };
            let position = acc.push(
                &accessor(vertex_view, 0, "VEC3", FLOAT, count, Some((min, max))),
                &mut tmp,
            )?;
            let normal = acc.push(
                &accessor(
                    vertex_view,
                    12 * u64::from(count),
                    "VEC3",
                    FLOAT,
                    count,
                    None,
                ),
                &mut tmp,
            )?;
            let n = 3 * t.triangles.len() as u32;
            let indices = acc.push(
                &accessor(index_view, 0, "SCALAR", UNSIGNED_INT, n, None),
                &mut tmp,
            )?;
            let mesh = self.spools[MESHES].push(
                &MeshRec {
                    name: "terrain".into(),
                    primitives: vec![PrimitiveRec {
                        attributes: Attributes {
                            position,
                            normal,
                            texcoord: None,
                        },
                        indices,
                        material,
                    }],
                },
                &mut tmp,
            )?;
            let node = self.spools[NODES].push(
                &NodeRec {
                    name: "terrain",
                    children: Vec::new(),
                    mesh: Some(mesh),
                    extras: None,
                },
                &mut tmp,
            )?;
            self.doc.roots.push(node);
            Ok(())
        })();
        self.json_scratch = tmp;
        r.map_err(|e| {
            self.state = State::Failed;
            e.into()
        })
    }
}
