//! A minimal reader of glTF 2.0 binaries (GLB), for drawing a region from its 3D Tiles
//! contents: the triangles of every mesh the default scene places, with their nodes'
//! transforms, and each primitive's base colour.
//!
//! Read: the GLB header and chunks (a JSON chunk, then a `BIN` chunk holding buffer 0); the
//! default scene (`scene`, else the first; a file without scenes: every node that is no
//! node's child) and its node trees (`matrix`, or `translation`/`rotation`/`scale`, and
//! `children`); meshes' primitives of mode 4 (triangles), 5 (strip) and 6 (fan) with a
//! `POSITION` accessor of `FLOAT` `VEC3` and indices of unsigned byte, short or int, or none;
//! the material's `pbrMetallicRoughness.baseColorFactor` (linear, to sRGB; white without one,
//! as glTF says). Points and lines are skipped; textures, normals and every extension are
//! ignored (a content's `EXT_mesh_features` ids, for one). Anything malformed or outside this
//! (an external buffer, a sparse accessor, an index out of range, an accessor past its view,
//! a node graph that is not a forest) is an error naming it; the reader never panics and caps
//! what it returns at [`MAX_VERTICES`].
//!
//! Frames: glTF is Y up; 3D Tiles turns a content's glTF into its Z-up frame before applying
//! the tile's transform. So does this reader: each point's glTF world coordinates (x, y, z)
//! become (x, -z, y) and are then given to the caller's `to_frame`, which for a 3D Tiles
//! content applies the tile transform (to ECEF) and then the common frame's, and for a GLB of
//! citygen's `--gltf` (model frame, Y up) is the identity.

use glam::{DMat4, DQuat, DVec3};
use serde_json::Value;
use thiserror::Error;

use super::raster::linear_to_srgb;
use crate::color::srgb_u8_to_linear;
use crate::export::glb::{CHUNK_BIN, CHUNK_JSON, GLB_MAGIC, GLB_VERSION};

/// The most vertices [`glb_triangles`] returns (instanced meshes counted each time): past it,
/// an error rather than memory without bound.
pub const MAX_VERTICES: usize = 1 << 25;

/// Node trees deeper than this are refused.
const MAX_DEPTH: usize = 256;

/// Why a GLB could not be read.
#[derive(Debug, Error)]
#[error("GLB: {0}")]
pub struct GlbError(String);

/// The triangles of one primitive as placed by one node.
#[derive(Clone, Debug, PartialEq)]
pub struct GlbMesh {
    /// The material's base colour, sRGB, 8 bits a channel.
    pub color: [u8; 3],
    /// The vertices in the caller's frame (`to_frame` of the Z-up point).
    pub positions: Vec<[f64; 3]>,
    /// The triangles, three indices into `positions` each.
    pub indices: Vec<u32>,
}

fn err<T>(msg: impl Into<String>) -> Result<T, GlbError> {
    Err(GlbError(msg.into()))
}

/// Reads `glb`'s triangles (see the module documentation). `to_frame` maps a point of glTF
/// world space turned Z up, (x, -z, y), to the common frame.
pub fn glb_triangles(
    glb: &[u8],
    to_frame: &dyn Fn([f64; 3]) -> [f64; 3],
) -> Result<Vec<GlbMesh>, GlbError> {
    let (json, bin) = chunks(glb)?;
    let doc: Value = serde_json::from_slice(json)
        .or_else(|e| err(format!("the JSON chunk is not JSON: {e}")))?;
    let gltf = Gltf { doc: &doc, bin };
    let mut out = Vec::new();
    let mut vertices = 0usize;
    let nodes = gltf.array("nodes")?;
    let mut visited = vec![false; nodes.len()];
    let mut stack: Vec<(usize, DMat4, usize)> = gltf
        .roots(nodes.len())?
        .into_iter()
        .rev()
        .map(|n| (n, DMat4::IDENTITY, 0))
        .collect();
    while let Some((n, parent, depth)) = stack.pop() {
        if depth > MAX_DEPTH {
            return err(format!("node trees deeper than {MAX_DEPTH}"));
        }
        let node = nodes
            .get(n)
            .ok_or_else(|| GlbError(format!("node {n} does not exist")))?;
        if std::mem::replace(&mut visited[n], true) {
            return err(format!(
                "node {n} is reached twice: the nodes are not a forest"
            ));
        }
        let world = parent * local_matrix(node, n)?;
        if let Some(m) = node.get("mesh") {
            let m = index(m, &format!("node {n}'s mesh"))?;
            for prim in gltf.primitives(m)? {
                let Some((color, vertex_colors, positions, indices)) = gltf.primitive(prim, m)?
                else {
                    continue;
                };
                vertices = vertices.saturating_add(positions.len());
                if vertices > MAX_VERTICES {
                    return err(format!("more than {MAX_VERTICES} vertices"));
                }
                let positions = positions
                    .iter()
                    .map(|p| {
                        let w = world.transform_point3(DVec3::from(*p));
                        to_frame([w.x, -w.z, w.y])
                    })
                    .collect();
                match vertex_colors {
                    None => out.push(GlbMesh {
                        color,
                        positions,
                        indices,
                    }),
                    Some(colors) => split_by_color(&positions, &indices, &colors, &mut out),
                }
            }
        }
        if let Some(children) = node.get("children") {
            let children = children
                .as_array()
                .ok_or_else(|| GlbError(format!("node {n}'s children are not an array")))?;
            for c in children.iter().rev() {
                let c = index(c, &format!("a child of node {n}"))?;
                stack.push((c, world, depth + 1));
            }
        }
    }
    Ok(out)
}

/// The JSON chunk and the BIN chunk (empty without one) of a GLB.
fn chunks(glb: &[u8]) -> Result<(&[u8], &[u8]), GlbError> {
    let u32_at = |at: usize| {
        glb.get(at..at + 4)
            .and_then(|s| s.try_into().ok())
            .map(u32::from_le_bytes)
    };
    if u32_at(0) != Some(GLB_MAGIC) {
        return err("not a GLB file (no glTF magic)");
    }
    match u32_at(4) {
        Some(GLB_VERSION) => {}
        Some(v) => return err(format!("version {v}, not 2")),
        None => return err("truncated header"),
    }
    let length = u32_at(8).ok_or_else(|| GlbError("truncated header".into()))? as usize;
    if length > glb.len() {
        return err(format!(
            "the header says {length} bytes, the file has {}",
            glb.len()
        ));
    }
    let glb = &glb[..length];
    let (mut json, mut bin) = (None, None);
    let mut at = 12usize;
    while at < glb.len() {
        let (Some(len), Some(kind)) = (u32_at(at), u32_at(at + 4)) else {
            return err(format!("truncated chunk header at byte {at}"));
        };
        let start = at + 8;
        let end = start
            .checked_add(len as usize)
            .filter(|&e| e <= glb.len())
            .ok_or_else(|| GlbError(format!("the chunk at byte {at} runs past the file")))?;
        match kind {
            CHUNK_JSON if json.is_none() && at == 12 => json = Some(&glb[start..end]),
            CHUNK_BIN if bin.is_none() && json.is_some() => bin = Some(&glb[start..end]),
            // Other chunks are skipped, as glTF asks.
            _ if at > 12 => {}
            _ => return err("the first chunk is not JSON"),
        }
        // Chunks are 4-byte aligned.
        at = end.checked_add(3).map_or(usize::MAX, |e| e & !3);
    }
    let json = json.ok_or_else(|| GlbError("no JSON chunk".into()))?;
    Ok((json, bin.unwrap_or(&[])))
}

/// A JSON value as an array index.
fn index(v: &Value, what: &str) -> Result<usize, GlbError> {
    v.as_u64()
        .and_then(|i| usize::try_from(i).ok())
        .ok_or_else(|| GlbError(format!("{what} is not an index")))
}

/// A node's own transform: `matrix` (column-major), or T * R * S.
fn local_matrix(node: &Value, n: usize) -> Result<DMat4, GlbError> {
    let numbers = |key: &str, len: usize| -> Result<Option<Vec<f64>>, GlbError> {
        let Some(v) = node.get(key) else {
            return Ok(None);
        };
        let a: Option<Vec<f64>> = v
            .as_array()
            .filter(|a| a.len() == len)
            .and_then(|a| a.iter().map(Value::as_f64).collect());
        match a {
            Some(a) if a.iter().all(|x| x.is_finite()) => Ok(Some(a)),
            _ => err(format!("node {n}'s {key} is not {len} finite numbers")),
        }
    };
    if let Some(m) = numbers("matrix", 16)? {
        let mut cols = [0.0; 16];
        cols.copy_from_slice(&m);
        return Ok(DMat4::from_cols_array(&cols));
    }
    let t = numbers("translation", 3)?.map_or(DVec3::ZERO, |v| DVec3::new(v[0], v[1], v[2]));
    let r = numbers("rotation", 4)?.map_or(DQuat::IDENTITY, |v| {
        DQuat::from_xyzw(v[0], v[1], v[2], v[3])
    });
    let s = numbers("scale", 3)?.map_or(DVec3::ONE, |v| DVec3::new(v[0], v[1], v[2]));
    let r = if r.length_squared() > 0.0 {
        r.normalize()
    } else {
        return err(format!("node {n}'s rotation is zero"));
    };
    Ok(DMat4::from_scale_rotation_translation(s, r, t))
}

/// A parsed glTF document and its binary buffer.
struct Gltf<'a> {
    doc: &'a Value,
    bin: &'a [u8],
}

/// One primitive read: its colour, positions (glTF space) and triangle indices.
/// A primitive's colour (its material's), its vertex colours (`COLOR_0`, sRGB) if any, its
/// positions and its triangles' indices.
type Primitive = ([u8; 3], Option<Vec<[u8; 3]>>, Vec<[f64; 3]>, Vec<u32>);

impl<'a> Gltf<'a> {
    /// A top-level array (empty when absent).
    fn array(&self, key: &str) -> Result<&'a [Value], GlbError> {
        match self.doc.get(key) {
            None => Ok(&[]),
            Some(Value::Array(a)) => Ok(a),
            Some(_) => err(format!("{key} is not an array")),
        }
    }

    /// The element `i` of the top-level array `key`.
    fn item(&self, key: &str, i: usize) -> Result<&'a Value, GlbError> {
        self.array(key)?
            .get(i)
            .ok_or_else(|| GlbError(format!("{key}[{i}] does not exist")))
    }

    /// The root nodes of the default scene.
    fn roots(&self, node_count: usize) -> Result<Vec<usize>, GlbError> {
        let scenes = self.array("scenes")?;
        if scenes.is_empty() {
            // No scene: every node that is nobody's child.
            let mut child = vec![false; node_count];
            for (n, node) in self.array("nodes")?.iter().enumerate() {
                for c in node
                    .get("children")
                    .and_then(Value::as_array)
                    .into_iter()
                    .flatten()
                {
                    let c = index(c, &format!("a child of node {n}"))?;
                    if let Some(f) = child.get_mut(c) {
                        *f = true;
                    }
                }
            }
            return Ok((0..node_count).filter(|&n| !child[n]).collect());
        }
        let s = match self.doc.get("scene") {
            Some(v) => index(v, "scene")?,
            None => 0,
        };
        let scene = self.item("scenes", s)?;
        match scene.get("nodes") {
            None => Ok(Vec::new()),
            Some(Value::Array(a)) => a
                .iter()
                .map(|v| index(v, &format!("a node of scene {s}")))
                .collect(),
            Some(_) => err(format!("scene {s}'s nodes are not an array")),
        }
    }

    /// The primitives of mesh `m`.
    fn primitives(&self, m: usize) -> Result<&'a [Value], GlbError> {
        match self.item("meshes", m)?.get("primitives") {
            Some(Value::Array(a)) => Ok(a),
            _ => err(format!("mesh {m} has no primitives array")),
        }
    }

    /// A primitive's colour, positions and triangles; `None` for points and lines.
    fn primitive(&self, prim: &Value, m: usize) -> Result<Option<Primitive>, GlbError> {
        let what = format!("a primitive of mesh {m}");
        let mode = match prim.get("mode") {
            Some(v) => index(v, &format!("{what}'s mode"))?,
            None => 4,
        };
        if mode < 4 {
            return Ok(None);
        }
        if mode > 6 {
            return err(format!("{what} has mode {mode}"));
        }
        let pos = prim
            .get("attributes")
            .and_then(|a| a.get("POSITION"))
            .ok_or_else(|| GlbError(format!("{what} has no POSITION")))?;
        let pos = self.accessor(index(pos, &format!("{what}'s POSITION"))?)?;
        if pos.component != FLOAT || pos.kind != "VEC3" {
            return err(format!("{what}'s POSITION is not FLOAT VEC3"));
        }
        let positions: Vec<[f64; 3]> = (0..pos.count)
            .map(|i| std::array::from_fn(|k| f64::from(pos.f32(i, k))))
            .collect();
        let order: Vec<u32> = match prim.get("indices") {
            Some(v) => {
                let acc = self.accessor(index(v, &format!("{what}'s indices"))?)?;
                if acc.kind != "SCALAR" {
                    return err(format!("{what}'s indices are not SCALAR"));
                }
                let list = (0..acc.count)
                    .map(|i| acc.uint(i))
                    .collect::<Option<Vec<u32>>>()
                    .ok_or_else(|| {
                        GlbError(format!("{what}'s indices are not unsigned integers"))
                    })?;
                if let Some(bad) = list.iter().find(|&&i| i as usize >= positions.len()) {
                    return err(format!(
                        "{what} has index {bad} for {} vertices",
                        positions.len()
                    ));
                }
                list
            }
            None => (0..u32::try_from(positions.len()).unwrap_or(u32::MAX)).collect(),
        };
        let indices = match mode {
            4 => order[..order.len() / 3 * 3].to_vec(),
            // Strip: every other triangle's first two corners swapped, to keep the winding.
            5 => order
                .windows(3)
                .enumerate()
                .flat_map(|(i, w)| {
                    if i % 2 == 0 {
                        [w[0], w[1], w[2]]
                    } else {
                        [w[1], w[0], w[2]]
                    }
                })
                .collect(),
            _ => match order.split_first() {
                Some((&first, rest)) => rest.windows(2).flat_map(|w| [first, w[0], w[1]]).collect(),
                None => Vec::new(),
            },
        };
        let color = match prim.get("material") {
            Some(v) => self.base_color(index(v, &format!("{what}'s material"))?)?,
            None => [255; 3],
        };
        let vertex_colors = match prim.get("attributes").and_then(|a| a.get("COLOR_0")) {
            None => None,
            Some(v) => {
                let acc = self.accessor(index(v, &format!("{what}'s COLOR_0"))?)?;
                if !matches!(acc.kind, "VEC3" | "VEC4") || acc.count != positions.len() {
                    return err(format!(
                        "{what}'s COLOR_0 is not one VEC3 or VEC4 per vertex"
                    ));
                }
                // Vertex colours are linear, times the material's (white here).
                let tint: [f32; 3] = std::array::from_fn(|k| srgb_u8_to_linear(color[k]));
                let cols = (0..acc.count)
                    .map(|i| {
                        let mut c = [0u8; 3];
                        for (k, out) in c.iter_mut().enumerate() {
                            let v = acc.unorm(i, k).ok_or_else(|| {
                                GlbError(format!("{what}'s COLOR_0 has an unknown component type"))
                            })?;
                            *out = linear_to_srgb(v * tint[k]);
                        }
                        Ok(c)
                    })
                    .collect::<Result<Vec<_>, GlbError>>()?;
                Some(cols)
            }
        };
        Ok(Some((color, vertex_colors, positions, indices)))
    }

    /// Material `i`'s base colour factor as 8-bit sRGB (white without one).
    fn base_color(&self, i: usize) -> Result<[u8; 3], GlbError> {
        let Some(f) = self
            .item("materials", i)?
            .get("pbrMetallicRoughness")
            .and_then(|p| p.get("baseColorFactor"))
        else {
            return Ok([255; 3]);
        };
        let f: Option<Vec<f64>> = f
            .as_array()
            .filter(|a| a.len() == 4)
            .and_then(|a| a.iter().map(Value::as_f64).collect());
        let f =
            f.ok_or_else(|| GlbError(format!("material {i}'s baseColorFactor is not 4 numbers")))?;
        Ok(std::array::from_fn(|k| linear_to_srgb(f[k] as f32)))
    }

    /// Accessor `i`, checked against its buffer view and the binary chunk.
    fn accessor(&self, i: usize) -> Result<Accessor<'a>, GlbError> {
        let what = format!("accessor {i}");
        let a = self.item("accessors", i)?;
        if a.get("sparse").is_some() {
            return err(format!("{what} is sparse (not read)"));
        }
        let uint = |key: &str, default: Option<u64>| -> Result<usize, GlbError> {
            match a.get(key) {
                Some(v) => index(v, &format!("{what}'s {key}")),
                None => default
                    .map(|d| d as usize)
                    .ok_or_else(|| GlbError(format!("{what} has no {key}"))),
            }
        };
        let view = uint("bufferView", None)?;
        let offset = uint("byteOffset", Some(0))?;
        let count = uint("count", None)?;
        let component = uint("componentType", None)?;
        let kind = a
            .get("type")
            .and_then(Value::as_str)
            .ok_or_else(|| GlbError(format!("{what} has no type")))?;
        let components = match kind {
            "SCALAR" => 1,
            "VEC2" => 2,
            "VEC3" => 3,
            "VEC4" => 4,
            "MAT2" => 4,
            "MAT3" => 9,
            "MAT4" => 16,
            _ => return err(format!("{what} has type {kind}")),
        };
        let size = match component {
            BYTE | UNSIGNED_BYTE => 1,
            SHORT | UNSIGNED_SHORT => 2,
            UNSIGNED_INT | FLOAT => 4,
            _ => return err(format!("{what} has component type {component}")),
        };
        let element = size * components;

        let v = self.item("bufferViews", view)?;
        let vwhat = format!("buffer view {view}");
        let vuint = |key: &str, default: Option<u64>| -> Result<usize, GlbError> {
            match v.get(key) {
                Some(x) => index(x, &format!("{vwhat}'s {key}")),
                None => default
                    .map(|d| d as usize)
                    .ok_or_else(|| GlbError(format!("{vwhat} has no {key}"))),
            }
        };
        let buffer = vuint("buffer", None)?;
        let buf = self.item("buffers", buffer)?;
        if buffer != 0 || buf.get("uri").is_some() {
            return err(format!(
                "{vwhat} is in buffer {buffer}, not the GLB's binary chunk"
            ));
        }
        let view_offset = vuint("byteOffset", Some(0))?;
        let view_length = vuint("byteLength", None)?;
        let stride = vuint("byteStride", Some(element as u64))?;
        if stride < element {
            return err(format!(
                "{vwhat}'s stride {stride} is less than {what}'s element ({element} bytes)"
            ));
        }
        let view_bytes = view_offset
            .checked_add(view_length)
            .and_then(|end| self.bin.get(view_offset..end))
            .ok_or_else(|| GlbError(format!("{vwhat} runs past the binary chunk")))?;
        let needed = match count {
            0 => Some(0),
            c => (c - 1)
                .checked_mul(stride)
                .and_then(|b| b.checked_add(element))
                .and_then(|b| b.checked_add(offset)),
        };
        let bytes = needed
            .and_then(|n| view_bytes.get(offset.min(n)..n))
            .ok_or_else(|| GlbError(format!("{what} runs past {vwhat}")))?;
        Ok(Accessor {
            bytes,
            count,
            stride,
            component,
            kind,
        })
    }
}

const BYTE: usize = 5120;
const UNSIGNED_BYTE: usize = 5121;
const SHORT: usize = 5122;
const UNSIGNED_SHORT: usize = 5123;
const UNSIGNED_INT: usize = 5125;
const FLOAT: usize = 5126;

/// An accessor's bytes (from its first element to the end of its last), checked in range.
struct Accessor<'a> {
    bytes: &'a [u8],
    count: usize,
    stride: usize,
    component: usize,
    kind: &'a str,
}

impl Accessor<'_> {
    /// Component `k` of element `i` of a colour: `FLOAT`, or normalized unsigned byte or short,
    /// as 0 to 1; `None` for another component type.
    fn unorm(&self, i: usize, k: usize) -> Option<f32> {
        match self.component {
            FLOAT => Some(self.f32(i, k).clamp(0.0, 1.0)),
            UNSIGNED_BYTE => {
                let at = i * self.stride + k;
                Some(self.bytes.get(at).map_or(0.0, |&b| f32::from(b) / 255.0))
            }
            UNSIGNED_SHORT => {
                let at = i * self.stride + 2 * k;
                Some(self.bytes.get(at..at + 2).map_or(0.0, |s| {
                    f32::from(u16::from_le_bytes([s[0], s[1]])) / 65535.0
                }))
            }
            _ => None,
        }
    }

    /// Component `k` of element `i` as `f32` (a `FLOAT` accessor), 0 if out of range.
    fn f32(&self, i: usize, k: usize) -> f32 {
        let at = i * self.stride + 4 * k;
        self.bytes
            .get(at..at + 4)
            .and_then(|s| s.try_into().ok())
            .map_or(0.0, f32::from_le_bytes)
    }

    /// Element `i` of an unsigned integer scalar accessor; `None` for another component type.
    fn uint(&self, i: usize) -> Option<u32> {
        let at = i * self.stride;
        match self.component {
            UNSIGNED_BYTE => self.bytes.get(at).map(|&b| u32::from(b)),
            UNSIGNED_SHORT => self
                .bytes
                .get(at..at + 2)
                .map(|s| u32::from(u16::from_le_bytes([s[0], s[1]]))),
            UNSIGNED_INT => self
                .bytes
                .get(at..at + 4)
                .and_then(|s| s.try_into().ok())
                .map(u32::from_le_bytes),
            _ => None,
        }
    }
}

/// A primitive with vertex colours as one mesh per colour (each triangle takes its first
/// vertex's), each with only the vertices it uses, in first-seen order of the colours.
fn split_by_color(
    positions: &[[f64; 3]],
    indices: &[u32],
    colors: &[[u8; 3]],
    out: &mut Vec<GlbMesh>,
) {
    let mut groups: Vec<([u8; 3], Vec<u32>)> = Vec::new();
    let mut slot: std::collections::HashMap<[u8; 3], usize> = Default::default();
    for t in indices.chunks_exact(3) {
        let c = colors.get(t[0] as usize).copied().unwrap_or([255; 3]);
        let g = *slot.entry(c).or_insert_with(|| {
            groups.push((c, Vec::new()));
            groups.len() - 1
        });
        groups[g].1.extend_from_slice(t);
    }
    for (color, idx) in groups {
        let mut remap: std::collections::HashMap<u32, u32> = Default::default();
        let mut pos = Vec::new();
        let indices = idx
            .iter()
            .map(|&i| {
                *remap.entry(i).or_insert_with(|| {
                    pos.push(positions.get(i as usize).copied().unwrap_or([0.0; 3]));
                    (pos.len() - 1) as u32
                })
            })
            .collect();
        out.push(GlbMesh {
            color,
            positions: pos,
            indices,
        });
    }
}
