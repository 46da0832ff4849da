//! The glTF JSON records of the glTF writer, serialised with a fixed key order.

use std::io;

use serde::Serialize;

/// Index of each growing array of the document in the writer's spools
/// ([`super::GltfWriter`]): the nodes, meshes, accessors and buffer views, in that order.
pub(super) const NODES: usize = 0;
/// The meshes' array (see [`NODES`]).
pub(super) const MESHES: usize = 1;
/// The accessors' array (see [`NODES`]).
pub(super) const ACCESSORS: usize = 2;
/// The buffer views' array (see [`NODES`]).
pub(super) const VIEWS: usize = 3;

#[derive(Default)]
pub(super) struct Document {
    pub(super) asset_extras: AssetExtras,
    /// The scene's root nodes: one per building.
    pub(super) roots: Vec<u32>,
    pub(super) materials: Vec<MaterialRec>,
    /// The textures, their images (PNG in buffer views) and the one sampler (`--textures`).
    pub(super) textures: Vec<TextureRec>,
    pub(super) images: Vec<ImageRec>,
    pub(super) buffer_length: u64,
}

/// A piece of the JSON chunk: text, or the records of a spooled array.
pub(super) enum Piece {
    Text(Vec<u8>),
    Spool(usize),
}

impl Document {
    /// The JSON chunk in document order (the key order of the glTF JSON is fixed: asset, scene,
    /// scenes, nodes, meshes, materials, accessors, bufferViews, buffers; empty arrays are left
    /// out), with the growing arrays as references to the spools; `counts` are the records in
    /// each spool (indexed by [`NODES`], [`MESHES`], [`ACCESSORS`], [`VIEWS`]).
    pub(super) fn pieces(&self, counts: [u32; 4]) -> io::Result<Vec<Piece>> {
        let head = Head {
            asset: Asset {
                version: "2.0",
                generator: concat!("citygen ", env!("CARGO_PKG_VERSION")),
                extras: &self.asset_extras,
            },
            scene: 0,
            scenes: [Scene { nodes: &self.roots }],
        };
        let mut text = serde_json::to_vec(&head).map_err(io::Error::from)?;
        text.pop(); // the closing brace, written last
        let mut pieces = Vec::new();
        let array = |pieces: &mut Vec<Piece>, text: &mut Vec<u8>, key: &str, body: Piece| {
            text.extend_from_slice(b",\"");
            text.extend_from_slice(key.as_bytes());
            text.extend_from_slice(b"\":[");
            match body {
                Piece::Text(t) => text.extend_from_slice(&t),
                Piece::Spool(i) => {
                    pieces.push(Piece::Text(std::mem::take(text)));
                    pieces.push(Piece::Spool(i));
                }
            }
            text.push(b']');
        };
        for (key, i) in [("nodes", NODES), ("meshes", MESHES)] {
            if counts[i] > 0 {
                array(&mut pieces, &mut text, key, Piece::Spool(i));
            }
        }
        if !self.materials.is_empty() {
            let mut m = serde_json::to_vec(&self.materials).map_err(io::Error::from)?;
            m.pop();
            m.remove(0);
            array(&mut pieces, &mut text, "materials", Piece::Text(m));
        }
        if !self.textures.is_empty() {
            let inner = |v: Vec<u8>| v[1..v.len().saturating_sub(1).max(1)].to_vec();
            let t = serde_json::to_vec(&self.textures).map_err(io::Error::from)?;
            array(&mut pieces, &mut text, "textures", Piece::Text(inner(t)));
            let i = serde_json::to_vec(&self.images).map_err(io::Error::from)?;
            array(&mut pieces, &mut text, "images", Piece::Text(inner(i)));
            let s = serde_json::to_vec(&[SAMPLER]).map_err(io::Error::from)?;
            array(&mut pieces, &mut text, "samplers", Piece::Text(inner(s)));
        }
        for (key, i) in [("accessors", ACCESSORS), ("bufferViews", VIEWS)] {
            if counts[i] > 0 {
                array(&mut pieces, &mut text, key, Piece::Spool(i));
            }
        }
        if self.buffer_length > 0 {
            let b = serde_json::to_vec(&Buffer {
                byte_length: self.buffer_length,
            })
            .map_err(io::Error::from)?;
            array(&mut pieces, &mut text, "buffers", Piece::Text(b));
        }
        text.push(b'}');
        pieces.push(Piece::Text(text));
        Ok(pieces)
    }
}

pub(super) fn is_empty<T>(s: &[T]) -> bool {
    s.is_empty()
}

/// The JSON chunk's first keys.
#[derive(Serialize)]
pub(super) struct Head<'a> {
    pub(super) asset: Asset<'a>,
    pub(super) scene: u32,
    pub(super) scenes: [Scene<'a>; 1],
}

#[derive(Serialize)]
pub(super) struct Asset<'a> {
    pub(super) version: &'static str,
    pub(super) generator: &'static str,
    pub(super) extras: &'a AssetExtras,
}

#[derive(Serialize, Default)]
pub(super) struct AssetExtras {
    pub(super) crs: String,
    /// The heights' vertical CRS, `EPSG:n`, when the run states one of known code.
    #[serde(rename = "verticalCrs", skip_serializing_if = "Option::is_none")]
    pub(super) vertical_crs: Option<String>,
    /// The heights' datum by name, when the run states one.
    #[serde(rename = "verticalDatum", skip_serializing_if = "Option::is_none")]
    pub(super) vertical_datum: Option<String>,
    pub(super) origin: [f64; 3],
    pub(super) lod: u8,
    pub(super) source: String,
}

#[derive(Serialize)]
pub(super) struct Scene<'a> {
    #[serde(skip_serializing_if = "is_empty")]
    pub(super) nodes: &'a [u32],
}

#[derive(Serialize)]
pub(super) struct NodeRec<'a> {
    pub(super) name: &'a str,
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub(super) children: Vec<u32>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub(super) mesh: Option<u32>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub(super) extras: Option<BuildingExtras<'a>>,
}

#[derive(Serialize)]
pub(super) struct BuildingExtras<'a> {
    pub(super) id: String,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub(super) name: Option<&'a str>,
    pub(super) zone: &'a str,
    pub(super) appearance: &'a str,
    /// Measured height in metres (non-finite values serialise as null).
    pub(super) height: f64,
    pub(super) base: f64,
    pub(super) storeys: u32,
    pub(super) roof_shape: &'static str,
    pub(super) lod: u8,
    /// Where storeys, height and roof came from, flattened into these extras.
    #[serde(flatten)]
    pub(super) provenance: ProvenanceExtras,
    /// The building's parts, listed when one of them comes from a `building:part` (its id
    /// differs from the building's): key, source id, base and top, so that every part can be
    /// traced back to the map although the meshes merge the parts.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub(super) parts: Vec<PartExtras<'a>>,
    /// The input file's other attributes (issue 47), typed, in the file's column order.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub(super) attributes: Option<AttrsExtras<'a>>,
}

/// [`crate::model::Attributes`] as a JSON object: strings, integers, numbers, booleans, dates
/// as ISO 8601 strings.
pub(crate) struct AttrsExtras<'a>(pub(crate) &'a crate::model::Attributes);

impl Serialize for AttrsExtras<'_> {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        use crate::model::AttrValue;
        use serde::ser::SerializeMap;
        let mut m = s.serialize_map(Some(self.0.len()))?;
        for (k, v) in self.0.iter() {
            match v {
                AttrValue::Text(t) | AttrValue::Date(t) => m.serialize_entry(&**k, &**t)?,
                AttrValue::Int(i) => m.serialize_entry(&**k, i)?,
                AttrValue::Real(r) => m.serialize_entry(&**k, r)?,
                AttrValue::Bool(b) => m.serialize_entry(&**k, b)?,
            }
        }
        m.end()
    }
}

/// The provenance keys of [`BuildingExtras`]: `storeys_source`, `height_source` and
/// `roof_source` (`tag`, `neighbours`, `fitted`, `model`, `kb`), `storeys_error`,
/// `height_error` (metres) and `roof_probability`, each number left out when unknown.
#[derive(Serialize)]
pub(super) struct ProvenanceExtras {
    pub(super) storeys_source: &'static str,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub(super) storeys_error: Option<f64>,
    pub(super) height_source: &'static str,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub(super) height_error: Option<f64>,
    pub(super) roof_source: &'static str,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub(super) roof_probability: Option<f64>,
}

impl From<&crate::model::Provenance> for ProvenanceExtras {
    fn from(p: &crate::model::Provenance) -> Self {
        ProvenanceExtras {
            storeys_source: p.storeys.name(),
            storeys_error: p.storeys_error,
            height_source: p.height.name(),
            height_error: p.height_error,
            roof_source: p.roof.name(),
            roof_probability: p.roof_probability,
        }
    }
}

/// One part in [`BuildingExtras::parts`].
#[derive(Serialize)]
pub(super) struct PartExtras<'a> {
    pub(super) key: &'a str,
    pub(super) id: Option<String>,
    pub(super) base: f64,
    pub(super) top: f64,
    pub(super) roof_shape: &'static str,
    /// `outline-rest` on what an outline's parts leave of it ([`crate::model::PartRole`]).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub(super) role: Option<&'static str>,
    /// What the part is when it is no house ([`crate::model::Structure`], issue 45).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub(super) structure: Option<&'static str>,
}

#[derive(Serialize)]
pub(super) struct MeshRec {
    pub(super) name: String,
    pub(super) primitives: Vec<PrimitiveRec>,
}

#[derive(Serialize)]
pub(super) struct PrimitiveRec {
    pub(super) attributes: Attributes,
    pub(super) indices: u32,
    pub(super) material: u32,
}

#[derive(Serialize)]
pub(super) struct Attributes {
    #[serde(rename = "POSITION")]
    pub(super) position: u32,
    #[serde(rename = "NORMAL")]
    pub(super) normal: u32,
    #[serde(rename = "TEXCOORD_0", skip_serializing_if = "Option::is_none")]
    pub(super) texcoord: Option<u32>,
}

/// A material's base colour texture: the index of a [`TextureRec`].
#[derive(Serialize)]
pub(super) struct TextureRef {
    pub(super) index: u32,
}

/// A texture: its image, sampled by the one sampler.
#[derive(Serialize)]
pub(super) struct TextureRec {
    pub(super) sampler: u32,
    pub(super) source: u32,
    pub(super) name: String,
}

/// An image: a PNG in a buffer view.
#[derive(Serialize)]
#[serde(rename_all = "camelCase")]
pub(super) struct ImageRec {
    pub(super) buffer_view: u32,
    pub(super) mime_type: &'static str,
    pub(super) name: String,
}

/// The sampler of every texture: linear, mipmapped, repeated both ways (a picture tiles).
#[derive(Serialize)]
#[serde(rename_all = "camelCase")]
pub(super) struct Sampler {
    pub(super) mag_filter: u32,
    pub(super) min_filter: u32,
    pub(super) wrap_s: u32,
    pub(super) wrap_t: u32,
}

/// LINEAR, LINEAR_MIPMAP_LINEAR, REPEAT.
pub(super) const SAMPLER: Sampler = Sampler {
    mag_filter: 9729,
    min_filter: 9987,
    wrap_s: 10497,
    wrap_t: 10497,
};

#[derive(Serialize)]
#[serde(rename_all = "camelCase")]
pub(super) struct MaterialRec {
    pub(super) name: String,
    #[serde(rename = "pbrMetallicRoughness")]
    pub(super) pbr: Pbr,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub(super) alpha_mode: Option<&'static str>,
}

#[derive(Serialize)]
#[serde(rename_all = "camelCase")]
pub(super) struct Pbr {
    pub(super) base_color_factor: [f32; 4],
    #[serde(skip_serializing_if = "Option::is_none")]
    pub(super) base_color_texture: Option<TextureRef>,
    pub(super) metallic_factor: f32,
    pub(super) roughness_factor: f32,
}

#[derive(Serialize)]
#[serde(rename_all = "camelCase")]
pub(super) struct AccessorRec {
    pub(super) buffer_view: u32,
    #[serde(skip_serializing_if = "is_zero")]
    pub(super) byte_offset: u64,
    pub(super) component_type: u32,
    pub(super) count: u32,
    #[serde(rename = "type")]
    pub(super) kind: &'static str,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub(super) min: Option<[f32; 3]>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub(super) max: Option<[f32; 3]>,
}

pub(super) fn is_zero(v: &u64) -> bool {
    *v == 0
}

#[derive(Serialize)]
#[serde(rename_all = "camelCase")]
pub(super) struct ViewRec {
    pub(super) buffer: u32,
    #[serde(skip_serializing_if = "is_zero")]
    pub(super) byte_offset: u64,
    pub(super) byte_length: u64,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub(super) byte_stride: Option<u32>,
    /// `None` for an image's view.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub(super) target: Option<u32>,
}

#[derive(Serialize)]
#[serde(rename_all = "camelCase")]
pub(super) struct Buffer {
    pub(super) byte_length: u64,
}
