//! The batched primitives of a content: every building's triangles, one primitive per kind of
//! material (the surface's material, opaque or blended: [`Kind`]) with the colour per vertex (`COLOR_0`) and the
//! building's feature id per vertex (`_FEATURE_ID_0`), so a tile of thousands of buildings is
//! drawn in one draw call per material it holds.
//!
//! A building is encoded on its own (in parallel): its faces grouped and triangulated as the
//! glTF writer does, each vertex mapped to ECEF by the building's affine map, kept as an f32
//! offset from the building's anchor. The content's frame is only known at the end, when the
//! offsets are put in it ([`Primitive::positions_in`]).

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

/// A building's or a content's primitives, one per [`Kind`], in primitive order.
pub(crate) type Prims = BTreeMap<Kind, Primitive>;

/// The triangles of one kind of material, from one building or a whole content.
#[derive(Default)]
pub(crate) struct Primitive {
    /// ECEF offsets from the anchor of the vertex's building.
    offsets: Vec<[f32; 3]>,
    /// Unit ECEF normals.
    normals: Vec<[f32; 3]>,
    /// Linear RGBA, normalised u16.
    colors: Vec<[u16; 4]>,
    /// The vertex's building: its feature id (empty in a building's own primitives).
    features: Vec<u32>,
    /// Texture coordinates (a textured kind's; empty otherwise).
    uvs: Vec<[f32; 2]>,
    indices: Vec<u32>,
}

impl Primitive {
    fn vertices(&self) -> usize {
        self.offsets.len()
    }

    /// Triangles so far.
    pub(crate) fn triangles(&self) -> u64 {
        self.indices.len() as u64 / 3
    }

    /// Whether `b`'s vertices can be appended (the content stays under 2^32 vertices).
    pub(crate) fn fits(&self, b: &Primitive) -> bool {
        u32::try_from(self.vertices() + b.vertices()).is_ok()
    }

    /// Appends a building's primitive, its vertices tagged with feature id `feature`; call
    /// [`Primitive::fits`] first.
    pub(crate) fn append(&mut self, b: &Primitive, feature: u32) {
        let base = self.vertices() as u32;
        self.offsets.extend_from_slice(&b.offsets);
        self.normals.extend_from_slice(&b.normals);
        self.colors.extend_from_slice(&b.colors);
        self.uvs.extend_from_slice(&b.uvs);
        self.features
            .extend(std::iter::repeat_n(feature, b.vertices()));
        self.indices.extend(b.indices.iter().map(|i| base + i));
    }
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
    let mut prims = Prims::new();
    for g in classes.iter().flat_map(|(_, gs)| gs) {
        let (c, _, _) = finish_params(g.color, g.material);
        let m = &g.mesh;
        let texture = g.texture.filter(|_| m.uvs.len() == m.positions.len());
        let kind = Kind::of(g.material, c.a, texture);
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
        if texture.is_some() {
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
pub(crate) fn lay_out(prims: &Prims, anchors: &[DVec3], frame: &EnuFrame, bin: &mut Bin) -> Laid {
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
    for (kind, p) in prims {
        if p.indices.is_empty() {
            continue;
        }
        let mut positions: Vec<[f32; 3]> = Vec::with_capacity(p.vertices());
        for (o, &f) in p.offsets.iter().zip(&p.features) {
            let a = anchors.get(f as usize).copied().unwrap_or_default();
            let enu = a + frame.rotate_in(glam::Vec3::from(*o).as_dvec3());
            positions.push([enu.x as f32, enu.z as f32, -enu.y as f32]);
        }
        let (mut lo, mut hi) = ([f32::INFINITY; 3], [f32::NEG_INFINITY; 3]);
        for q in &positions {
            for k in 0..3 {
                lo[k] = lo[k].min(q[k]);
                hi[k] = hi[k].max(q[k]);
            }
        }
        // Back to east, north, up for the bounding volumes.
        laid.lo = laid
            .lo
            .min(DVec3::new(lo[0].into(), (-hi[2]).into(), lo[1].into()));
        laid.hi = laid
            .hi
            .max(DVec3::new(hi[0].into(), (-lo[2]).into(), hi[1].into()));
        let normals: Vec<[f32; 3]> = p
            .normals
            .iter()
            .map(|n| {
                let e = frame
                    .rotate_in(glam::Vec3::from(*n).as_dvec3())
                    .normalize_or_zero();
                [e.x as f32, e.z as f32, -e.y as f32]
            })
            .collect();
        let features: Vec<f32> = p.features.iter().map(|&f| f as f32).collect();
        let count = p.vertices();
        let mut accessor = |laid: &mut Laid, data: &[u8], target: u32, extra: Value| {
            let view = bin.view(data, Some(target));
            let mut a = json!({"bufferView": view, "count": count});
            if let (Value::Object(a), Value::Object(extra)) = (&mut a, extra) {
                a.extend(extra);
            }
            laid.accessors.push(a);
            laid.accessors.len() - 1
        };
        let bytes_f32 = |v: &[[f32; 3]]| -> Vec<u8> {
            v.iter().flatten().flat_map(|c| c.to_le_bytes()).collect()
        };
        let position = accessor(
            &mut laid,
            &bytes_f32(&positions),
            ARRAY_BUFFER,
            json!({"componentType": FLOAT, "type": "VEC3",
                   "min": lo.map(short), "max": hi.map(short)}),
        );
        let normal = accessor(
            &mut laid,
            &bytes_f32(&normals),
            ARRAY_BUFFER,
            json!({"componentType": FLOAT, "type": "VEC3"}),
        );
        let colors: Vec<u8> = p
            .colors
            .iter()
            .flatten()
            .flat_map(|c| c.to_le_bytes())
            .collect();
        let color = accessor(
            &mut laid,
            &colors,
            ARRAY_BUFFER,
            json!({"componentType": UNSIGNED_SHORT, "normalized": true, "type": "VEC4"}),
        );
        let feature_bytes: Vec<u8> = features.iter().flat_map(|c| c.to_le_bytes()).collect();
        let feature = accessor(
            &mut laid,
            &feature_bytes,
            ARRAY_BUFFER,
            json!({"componentType": FLOAT, "type": "SCALAR"}),
        );
        // 65535 is the primitive-restart value of u16 indices: never an index.
        let (index_bytes, index_type): (Vec<u8>, u32) = if count <= 65535 {
            let b = p
                .indices
                .iter()
                .flat_map(|&i| (i as u16).to_le_bytes())
                .collect();
            (b, UNSIGNED_SHORT)
        } else {
            let b = p.indices.iter().flat_map(|&i| i.to_le_bytes()).collect();
            (b, UNSIGNED_INT)
        };
        let view = bin.view(&index_bytes, Some(ELEMENT_ARRAY_BUFFER));
        laid.accessors.push(json!({
            "bufferView": view,
            "componentType": index_type,
            "count": p.indices.len(),
            "type": "SCALAR"
        }));
        let indices = laid.accessors.len() - 1;
        let mut ids: Vec<u32> = p.features.clone();
        ids.sort_unstable();
        ids.dedup();
        let mut attributes = json!({
            "POSITION": position,
            "NORMAL": normal,
            "COLOR_0": color,
            "_FEATURE_ID_0": feature
        });
        let texture = match kind.texture {
            Some(t) if p.uvs.len() == count => {
                let uvs: Vec<u8> = p
                    .uvs
                    .iter()
                    .flatten()
                    .flat_map(|c| c.to_le_bytes())
                    .collect();
                let view = bin.view(&uvs, Some(ARRAY_BUFFER));
                laid.accessors.push(json!({
                    "bufferView": view,
                    "componentType": FLOAT,
                    "count": count,
                    "type": "VEC2"
                }));
                attributes["TEXCOORD_0"] = json!(laid.accessors.len() - 1);
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
                        "featureCount": ids.len(),
                        "attribute": 0,
                        "propertyTable": 0
                    }]
                }
            }
        }));
    }
    laid
}
