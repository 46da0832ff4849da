//! The batched primitives of a content: every building's triangles, one primitive per kind of
//! material (the surface's material, opaque or blended: [`Kind`]) with the colour per vertex (`COLOR_0`) and the
//! building's feature id per vertex (`_FEATURE_ID_0`), so a tile of thousands of buildings is
//! drawn in one draw call per material it holds.
//!
//! A building is encoded on its own (in parallel): its faces grouped and triangulated as the
//! glTF writer does, each vertex mapped to ECEF by the building's affine map, kept as an f32
//! offset from the building's anchor, and kept as it is in the content's [`Batch`] of its
//! kind. The content's frame is only known at the end, when [`lay_out`] puts the offsets in it
//! and writes each batch's vertex and index data straight into the GLB's buffer.

use std::collections::BTreeMap;

use glam::DVec3;
use serde_json::{json, Value};

use crate::color::material::Material;
use crate::color::{srgb_to_linear, Color};
use crate::export::gltf::{finish_params, Group, SurfaceClass};
use crate::export::texture::Texture;

use super::frame::{BuildingMap, EnuFrame};
use super::glb::Bin;

/// glTF component types and buffer view targets.
const FLOAT: u32 = 5126;
const UNSIGNED_SHORT: u32 = 5123;
const UNSIGNED_INT: u32 = 5125;
const ARRAY_BUFFER: u32 = 34962;
const ELEMENT_ARRAY_BUFFER: u32 = 34963;

/// A kind of material of a content: the surface's [`Material`] and whether it is blended
/// (translucent). Ordered opaque first, then by material ([`Material::Unspecified`] first,
/// glass last): the contents' primitive order.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub(crate) struct Kind {
    blend: bool,
    material: Material,
    /// The picture its faces carry (`--textures`): their primitive has texture coordinates.
    texture: Option<Texture>,
}

impl Kind {
    fn of(material: Material, alpha: f32, texture: Option<Texture>) -> Kind {
        Kind {
            blend: alpha < 1.0,
            material,
            texture,
        }
    }

    /// The material: white, so the vertex colours show as they are; the material's metallic
    /// and roughness factors (`finish_params`, as the glTF writer's). Named `matte` for a
    /// surface of no known material, else the material's name, `translucent` added when
    /// blended.
    fn material(self, texture: Option<usize>) -> Value {
        let (_, metallic, roughness) = finish_params(Color::WHITE, self.material);
        let base = match self.material {
            Material::Unspecified => "matte",
            m => m.name(),
        };
        let name = if self.blend {
            format!("{base} translucent")
        } else {
            base.to_string()
        };
        let mut m = json!({
            "name": name,
            "pbrMetallicRoughness": {
                "baseColorFactor": [1.0, 1.0, 1.0, 1.0],
                "metallicFactor": short(metallic),
                "roughnessFactor": short(roughness)
            }
        });
        if self.blend {
            m["alphaMode"] = json!("BLEND");
        }
        if let (Some(t), Some(i)) = (self.texture, texture) {
            m["name"] = json!(format!("{name} textured {}", t.name()));
            m["pbrMetallicRoughness"]["baseColorTexture"] = json!({ "index": i });
        }
        m
    }
}

/// A building's primitives, one per [`Kind`], in primitive order.
pub(crate) type Prims = BTreeMap<Kind, Primitive>;

/// The triangles of one kind of material of one building.
#[derive(Default)]
pub(crate) struct Primitive {
    /// ECEF offsets from the anchor of the building.
    offsets: Vec<[f32; 3]>,
    /// Unit ECEF normals.
    normals: Vec<[f32; 3]>,
    /// Linear RGBA, normalised u16.
    colors: Vec<[u16; 4]>,
    /// Texture coordinates (a textured kind's; empty otherwise).
    uvs: Vec<[f32; 2]>,
    indices: Vec<u32>,
}

impl Primitive {
    fn vertices(&self) -> usize {
        self.offsets.len()
    }
}

/// The triangles of one kind of material of a whole content: its buildings' primitives as
/// they were encoded, each with its feature id, in feature order (laid out end to end, with
/// the indices rebased, only in [`lay_out`]).
#[derive(Default)]
pub(crate) struct Batch {
    parts: Vec<(u32, Primitive)>,
    vertices: usize,
    indices: usize,
}

impl Batch {
    /// Triangles so far.
    pub(crate) fn triangles(&self) -> u64 {
        self.indices as u64 / 3
    }

    /// Whether `b`'s vertices can be added (the content stays under 2^32 vertices).
    pub(crate) fn fits(&self, b: &Primitive) -> bool {
        u32::try_from(self.vertices + b.vertices()).is_ok()
    }

    /// Adds a building's primitive, its vertices tagged with feature id `feature` (greater
    /// than every feature id before it); call [`Batch::fits`] first.
    pub(crate) fn push(&mut self, b: Primitive, feature: u32) {
        self.vertices += b.vertices();
        self.indices += b.indices.len();
        self.parts.push((feature, b));
    }

    /// Bytes of this batch's buffer views in [`lay_out`], alignment padding included.
    fn bytes(&self) -> usize {
        let index = if self.vertices <= 65535 { 2 } else { 4 };
        let uv = if self.parts.iter().any(|(_, p)| !p.uvs.is_empty()) {
            8
        } else {
            0
        };
        self.vertices * (12 + 12 + 8 + 4 + uv) + self.indices * index + 6 * 8
    }
}

/// A content's primitives, one [`Batch`] per [`Kind`], in primitive order.
pub(crate) type Batches = BTreeMap<Kind, Batch>;

/// Bytes of the buffer views [`lay_out`] appends for `batches` (alignment padding included).
pub(crate) fn laid_bytes(batches: &Batches) -> usize {
    batches.values().map(Batch::bytes).sum()
}

/// One building's primitives (by [`Kind`]) and where its offsets start from.
pub(crate) struct EncodedBuilding {
    pub(crate) anchor_ecef: DVec3,
    /// What lifts the building's heights to ellipsoidal ones (`BuildingMap::lift`).
    pub(crate) lift: Option<f64>,
    pub(crate) prims: Prims,
}

/// Encodes the faces `classes` of a building (grouped by [`crate::export::gltf::building_groups`]
/// or Blocks) through its map `map`.
pub(crate) fn encode(classes: &[(SurfaceClass, Vec<Group>)], map: &BuildingMap) -> EncodedBuilding {
    let groups: Vec<(&Group, Kind, Color)> = classes
        .iter()
        .flat_map(|(_, gs)| gs)
        .map(|g| {
            let (c, _, _) = finish_params(g.color, g.material);
            let m = &g.mesh;
            let texture = g.texture.filter(|_| m.uvs.len() == m.positions.len());
            (g, Kind::of(g.material, c.a, texture), c)
        })
        .collect();
    // Each primitive's vertices and indices, to allocate it once.
    let mut sizes: Vec<(Kind, usize, usize)> = Vec::new();
    for (g, kind, _) in &groups {
        let (v, i) = (g.mesh.positions.len(), g.mesh.indices.len());
        match sizes.iter_mut().find(|(k, ..)| k == kind) {
            Some((_, nv, ni)) => (*nv, *ni) = (*nv + v, *ni + i),
            None => sizes.push((*kind, v, i)),
        }
    }
    let mut prims: Prims = sizes
        .into_iter()
        .map(|(kind, v, i)| {
            let p = Primitive {
                offsets: Vec::with_capacity(v),
                normals: Vec::with_capacity(v),
                colors: Vec::with_capacity(v),
                uvs: Vec::with_capacity(if kind.texture.is_some() { v } else { 0 }),
                indices: Vec::with_capacity(i),
            };
            (kind, p)
        })
        .collect();
    for (g, kind, c) in groups {
        let p = prims.entry(kind).or_default();
        let Ok(base) = u32::try_from(p.vertices()) else {
            continue;
        };
        let unit = |v: f32| (v.clamp(0.0, 1.0) * 65535.0).round() as u16;
        let color = [
            unit(srgb_to_linear(c.r)),
            unit(srgb_to_linear(c.g)),
            unit(srgb_to_linear(c.b)),
            unit(c.a),
        ];
        let m = &g.mesh;
        if kind.texture.is_some() {
            p.uvs.extend_from_slice(&m.uvs);
        }
        p.offsets.extend(
            m.positions
                .iter()
                .map(|&q| map.offset(q).as_vec3().to_array()),
        );
        p.normals.extend(
            m.normals
                .iter()
                .map(|&n| map.normal(n).as_vec3().to_array()),
        );
        p.colors
            .extend(std::iter::repeat_n(color, m.positions.len()));
        p.indices.extend(m.indices.iter().map(|i| base + i));
    }
    EncodedBuilding {
        anchor_ecef: map.anchor_ecef,
        lift: map.lift,
        prims,
    }
}

/// A glTF number for an f32: its shortest decimal, which reads back as the same f32 (rather than
/// the f64 widening's long tail).
pub(crate) fn short(v: f32) -> f64 {
    format!("{v}").parse().unwrap_or(0.0)
}

/// The batched content in its frame: per [`Kind`] the primitive, and the bounds of all
/// positions (east, north, up).
pub(crate) struct Laid {
    pub(crate) primitives: Vec<Value>,
    pub(crate) materials: Vec<Value>,
    pub(crate) accessors: Vec<Value>,
    /// The pictures the materials use, in first-use order (the content's textures).
    pub(crate) textures: Vec<Texture>,
    pub(crate) lo: DVec3,
    pub(crate) hi: DVec3,
}

/// Puts the content's primitives in `frame` (glTF's y-up axes: x east, y up, z south) and lays
/// out their data in `bin`. `anchors` are the buildings' anchors in ECEF, by feature id.
pub(crate) fn lay_out(
    batches: &Batches,
    anchors: &[DVec3],
    frame: &EnuFrame,
    bin: &mut Bin,
) -> Laid {
    let mut laid = Laid {
        primitives: Vec::new(),
        materials: Vec::new(),
        accessors: Vec::new(),
        textures: Vec::new(),
        lo: DVec3::INFINITY,
        hi: DVec3::NEG_INFINITY,
    };
    // Each anchor in the frame, once.
    let anchors: Vec<DVec3> = anchors.iter().map(|&a| frame.to_enu(a)).collect();
    for (kind, batch) in batches {
        if batch.indices == 0 {
            continue;
        }
        let count = batch.vertices;
        let (mut lo, mut hi) = ([f32::INFINITY; 3], [f32::NEG_INFINITY; 3]);
        let positions = bin.view_with(Some(ARRAY_BUFFER), |out| {
            out.reserve(count * 12);
            for (f, p) in &batch.parts {
                let a = anchors.get(*f as usize).copied().unwrap_or_default();
                for o in &p.offsets {
                    let enu = a + frame.rotate_in(glam::Vec3::from(*o).as_dvec3());
                    let q = [enu.x as f32, enu.z as f32, -enu.y as f32];
                    for k in 0..3 {
                        lo[k] = lo[k].min(q[k]);
                        hi[k] = hi[k].max(q[k]);
                        out.extend_from_slice(&q[k].to_le_bytes());
                    }
                }
            }
        });
        // Back to east, north, up for the bounding volumes.
        laid.lo = laid
            .lo
            .min(DVec3::new(lo[0].into(), (-hi[2]).into(), lo[1].into()));
        laid.hi = laid
            .hi
            .max(DVec3::new(hi[0].into(), (-lo[2]).into(), hi[1].into()));
        let normals = bin.view_with(Some(ARRAY_BUFFER), |out| {
            out.reserve(count * 12);
            for n in batch.parts.iter().flat_map(|(_, p)| &p.normals) {
                let e = frame
                    .rotate_in(glam::Vec3::from(*n).as_dvec3())
                    .normalize_or_zero();
                for c in [e.x as f32, e.z as f32, -e.y as f32] {
                    out.extend_from_slice(&c.to_le_bytes());
                }
            }
        });
        let colors = bin.view_with(Some(ARRAY_BUFFER), |out| {
            out.reserve(count * 8);
            for c in batch.parts.iter().flat_map(|(_, p)| &p.colors).flatten() {
                out.extend_from_slice(&c.to_le_bytes());
            }
        });
        let features = bin.view_with(Some(ARRAY_BUFFER), |out| {
            out.reserve(count * 4);
            for (f, p) in &batch.parts {
                let bytes = (*f as f32).to_le_bytes();
                for _ in 0..p.vertices() {
                    out.extend_from_slice(&bytes);
                }
            }
        });
        let accessor = |laid: &mut Laid, view: usize, extra: Value| {
            let mut a = json!({"bufferView": view, "count": count});
            if let (Value::Object(a), Value::Object(extra)) = (&mut a, extra) {
                a.extend(extra);
            }
            laid.accessors.push(a);
            laid.accessors.len() - 1
        };
        let position = accessor(
            &mut laid,
            positions,
            json!({"componentType": FLOAT, "type": "VEC3",
                   "min": lo.map(short), "max": hi.map(short)}),
        );
        let normal = accessor(
            &mut laid,
            normals,
            json!({"componentType": FLOAT, "type": "VEC3"}),
        );
        let color = accessor(
            &mut laid,
            colors,
            json!({"componentType": UNSIGNED_SHORT, "normalized": true, "type": "VEC4"}),
        );
        let feature = accessor(
            &mut laid,
            features,
            json!({"componentType": FLOAT, "type": "SCALAR"}),
        );
        // 65535 is the primitive-restart value of u16 indices: never an index.
        let short_indices = count <= 65535;
        let view = bin.view_with(Some(ELEMENT_ARRAY_BUFFER), |out| {
            out.reserve(batch.indices * if short_indices { 2 } else { 4 });
            let mut base = 0u32;
            for (_, p) in &batch.parts {
                if short_indices {
                    for &i in &p.indices {
                        out.extend_from_slice(&((base + i) as u16).to_le_bytes());
                    }
                } else {
                    for &i in &p.indices {
                        out.extend_from_slice(&(base + i).to_le_bytes());
                    }
                }
                // Fits: the batch's vertices are under 2^32 (`Batch::fits`).
                base += p.vertices() as u32;
            }
        });
        let index_type = if short_indices {
            UNSIGNED_SHORT
        } else {
            UNSIGNED_INT
        };
        laid.accessors.push(json!({
            "bufferView": view,
            "componentType": index_type,
            "count": batch.indices,
            "type": "SCALAR"
        }));
        let indices = laid.accessors.len() - 1;
        // The buildings that have vertices here (each is in the batch once).
        let ids = batch.parts.iter().filter(|(_, p)| p.vertices() > 0).count();
        let mut attributes = json!({
            "POSITION": position,
            "NORMAL": normal,
            "COLOR_0": color,
            "_FEATURE_ID_0": feature
        });
        let uvs = batch.parts.iter().map(|(_, p)| p.uvs.len()).sum::<usize>();
        let texture = match kind.texture {
            Some(t) if uvs == count => {
                let view = bin.view_with(Some(ARRAY_BUFFER), |out| {
                    out.reserve(count * 8);
                    for c in batch.parts.iter().flat_map(|(_, p)| &p.uvs).flatten() {
                        out.extend_from_slice(&c.to_le_bytes());
                    }
                });
                attributes["TEXCOORD_0"] = json!(accessor(
                    &mut laid,
                    view,
                    json!({"componentType": FLOAT, "type": "VEC2"}),
                ));
                Some(match laid.textures.iter().position(|u| *u == t) {
                    Some(i) => i,
                    None => {
                        laid.textures.push(t);
                        laid.textures.len() - 1
                    }
                })
            }
            _ => None,
        };
        laid.materials.push(kind.material(texture));
        laid.primitives.push(json!({
            "attributes": attributes,
            "indices": indices,
            "material": laid.materials.len() - 1,
            "mode": 4,
            "extensions": {
                "EXT_mesh_features": {
                    "featureIds": [{
                        "featureCount": ids,
                        "attribute": 0,
                        "propertyTable": 0
                    }]
                }
            }
        }));
    }
    laid
}
