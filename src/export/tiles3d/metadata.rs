//! `EXT_structural_metadata` of a content: the schema (one class, `building`) and the property
//! table, one row per building in write order (the row is the building's feature id), stored
//! as binary columns in the GLB's buffer. The input file's other columns (GIS footprints) are
//! `STRING` properties `attr_<name>` of the contents whose buildings have them.

use serde_json::{json, Value};

use crate::model::{AttrValue, Attributes, Building};

use super::glb::Bin;

/// The schema's id, and its one class.
const SCHEMA_ID: &str = "citygen";
const CLASS: &str = "building";

/// The properties of every building (one entry per row).
#[derive(Default)]
pub(crate) struct Rows {
    id: Vec<String>,
    name: Vec<String>,
    zone: Vec<String>,
    appearance: Vec<String>,
    height: Vec<f64>,
    base_height: Vec<f64>,
    storeys: Vec<u32>,
    roof_shape: Vec<&'static str>,
    /// Sources of storeys, height and roof ([`crate::model::ValueSource::name`]).
    sources: [Vec<&'static str>; 3],
    /// Storeys error, height error, roof probability; [`NO_DATA`] when unknown.
    uncertainty: [Vec<f32>; 3],
    /// The input file's other columns of each building (GIS footprints, issue 47).
    attributes: Vec<Option<Attributes>>,
}

/// The `noData` of the uncertainty columns (an error or a probability is never negative).
const NO_DATA: f32 = -1.0;

/// The provenance properties: (source key, uncertainty key, the uncertainty's description).
const PROVENANCE: [(&str, &str, &str); 3] = [
    (
        "storeysSource",
        "storeysError",
        "Uncertainty of the storeys, ± storeys; -1 when unknown (a tag).",
    ),
    (
        "heightSource",
        "heightError",
        "Uncertainty of the height, ± metres; -1 when unknown (a tag).",
    ),
    (
        "roofSource",
        "roofProbability",
        "Probability (0..1) that the roof's family (flat or pitched) is right; -1 when unknown (a tag).",
    ),
];

impl Rows {
    /// Adds `b`'s row; `base_height` is its base as an ellipsoidal height.
    pub(crate) fn push(&mut self, b: &Building, base_height: f64) {
        self.id.push(b.id.to_string());
        self.name.push(b.name.clone().unwrap_or_default());
        self.zone.push(b.zone.clone());
        self.appearance.push(b.appearance.clone());
        self.height.push(b.measured_height);
        self.base_height.push(base_height);
        self.storeys.push(b.storeys_above_ground);
        self.roof_shape.push(b.roof_shape.osm_name());
        let p = &b.provenance;
        for (col, source) in self.sources.iter_mut().zip([p.storeys, p.height, p.roof]) {
            col.push(source.name());
        }
        let values = [p.storeys_error, p.height_error, p.roof_probability];
        for (col, v) in self.uncertainty.iter_mut().zip(values) {
            col.push(v.map_or(NO_DATA, |v| v as f32));
        }
        self.attributes.push(b.attributes.clone());
    }

    /// The input's columns of these rows, in first-seen order: (the schema's property id, the
    /// column's name). An id is `attr_` and the name with every character outside
    /// `[A-Za-z0-9_]` as `_` (the metadata spec's identifiers), `_2`, `_3`... on a clash.
    fn columns(&self) -> Vec<(String, std::sync::Arc<str>)> {
        let mut out: Vec<(String, std::sync::Arc<str>)> = Vec::new();
        for a in self.attributes.iter().flatten() {
            for (name, _) in a.iter() {
                if out.iter().any(|(_, n)| n == name) {
                    continue;
                }
                let base: String = std::iter::once("attr_".to_string())
                    .chain(name.chars().map(|c| {
                        if c.is_ascii_alphanumeric() || c == '_' {
                            c.to_string()
                        } else {
                            "_".to_string()
                        }
                    }))
                    .collect();
                let mut id = base.clone();
                let mut n = 1;
                while out.iter().any(|(i, _)| *i == id) {
                    n += 1;
                    id = format!("{base}_{n}");
                }
                out.push((id, name.clone()));
            }
        }
        out
    }

    /// Rows so far.
    pub(crate) fn len(&self) -> usize {
        self.id.len()
    }
}

/// A column's value as the text of its `STRING` property: text and dates as written, numbers
/// as Rust prints them (shortest round trip), booleans `true`/`false`.
fn attr_text(v: &AttrValue) -> String {
    match v {
        AttrValue::Text(t) | AttrValue::Date(t) => t.to_string(),
        AttrValue::Int(i) => i.to_string(),
        AttrValue::Real(x) => x.to_string(),
        AttrValue::Bool(b) => b.to_string(),
    }
}

/// The schema of the `building` class, with a `STRING` property per input column of `rows`.
/// Columns are strings whatever their type in the file: a column's type may differ between
/// the features of a GeoJSON file, and a content holds a share of them; the other formats
/// keep the types.
pub(crate) fn schema(rows: &Rows) -> Value {
    let string = |description: &str| json!({"type": "STRING", "description": description});
    let mut schema = json!({
        "id": SCHEMA_ID,
        "name": "citygen buildings",
        "classes": {
            CLASS: {
                "name": "Building",
                "description": "A building generated by citygen from a map footprint.",
                "properties": {
                    "id": string("The source footprint: way/123, relation/45, shp/7."),
                    "name": {
                        "type": "STRING",
                        "description": "The map's name of the building; empty when it has none.",
                        "noData": ""
                    },
                    "zone": string("The knowledge-base zone that styled it."),
                    "appearance": string("The appearance (or ruleset) chosen in that zone."),
                    "height": {
                        "type": "SCALAR",
                        "componentType": "FLOAT64",
                        "description": "Measured height: highest top minus lowest base, metres."
                    },
                    "baseHeight": {
                        "type": "SCALAR",
                        "componentType": "FLOAT64",
                        "description": "Ellipsoidal height of the lowest base, metres."
                    },
                    "storeys": {
                        "type": "SCALAR",
                        "componentType": "UINT32",
                        "description": "Storeys above ground of the tallest part."
                    },
                    "roofShape": string("Roof shape of the tallest part (OSM roof:shape).")
                }
            }
        }
    });
    if let Some(props) = schema["classes"][CLASS]["properties"].as_object_mut() {
        for ((source, value, description), what) in
            PROVENANCE.iter().zip(["storeys", "height", "roof"])
        {
            props.insert(
                (*source).into(),
                string(&format!(
                    "Where the {what} came from: tag, neighbours, fitted, model or kb."
                )),
            );
            props.insert(
                (*value).into(),
                json!({
                    "type": "SCALAR",
                    "componentType": "FLOAT32",
                    "noData": NO_DATA,
                    "description": description
                }),
            );
        }
        for (id, name) in rows.columns() {
            props.insert(
                id,
                json!({
                    "type": "STRING",
                    "name": &*name,
                    "description": format!("The input file's column {name:?}, as text; empty when the building has none."),
                    "noData": ""
                }),
            );
        }
    }
    schema
}

/// The property table of some rows, its columns as bytes ([`table`]), ready to be laid out in
/// a content's buffer ([`property_table`]): computed once for the contents of a tile, whose
/// rows are the same.
pub(crate) struct Table {
    count: usize,
    /// (property, its buffer views' bytes: `values`, and for a string column `stringOffsets`)
    /// in buffer order.
    columns: Vec<(String, Column)>,
}

/// The bytes of one column of a [`Table`].
enum Column {
    Strings { values: Vec<u8>, offsets: Vec<u8> },
    Values(Vec<u8>),
}

/// The [`Table`] of `rows`. A string column whose strings are all empty (no building has a
/// name) is left out: glTF allows no empty buffer view, and the schema's properties are
/// optional (`name`'s no-data value is the empty string).
pub(crate) fn table(rows: &Rows) -> Table {
    let mut columns = Vec::new();
    let attr_cols: Vec<(String, Vec<String>)> = rows
        .columns()
        .iter()
        .map(|(id, name)| {
            let col = rows
                .attributes
                .iter()
                .map(|a| {
                    a.as_ref()
                        .and_then(|a| a.iter().find(|(k, _)| k == name))
                        .map_or(String::new(), |(_, v)| attr_text(v))
                })
                .collect();
            (id.clone(), col)
        })
        .collect();
    let string_cols: [(&str, Vec<&str>); 8] = [
        ("id", rows.id.iter().map(String::as_str).collect()),
        ("name", rows.name.iter().map(String::as_str).collect()),
        ("zone", rows.zone.iter().map(String::as_str).collect()),
        (
            "appearance",
            rows.appearance.iter().map(String::as_str).collect(),
        ),
        ("roofShape", rows.roof_shape.clone()),
        (PROVENANCE[0].0, rows.sources[0].clone()),
        (PROVENANCE[1].0, rows.sources[1].clone()),
        (PROVENANCE[2].0, rows.sources[2].clone()),
    ];
    let attr_refs = attr_cols
        .iter()
        .map(|(id, col)| (id.as_str(), col.iter().map(String::as_str).collect()));
    for (key, col) in string_cols.into_iter().chain(attr_refs) {
        let mut values = Vec::new();
        let mut offsets: Vec<u8> = Vec::with_capacity(4 * (col.len() + 1));
        offsets.extend_from_slice(&0u32.to_le_bytes());
        for v in col {
            values.extend_from_slice(v.as_bytes());
            // A column past 4 GiB wraps here, but makes the GLB too large: `write_glb` refuses it.
            offsets.extend_from_slice(&(values.len() as u32).to_le_bytes());
        }
        if values.is_empty() {
            continue;
        }
        columns.push((key.to_owned(), Column::Strings { values, offsets }));
    }
    for (key, col) in [("height", &rows.height), ("baseHeight", &rows.base_height)] {
        let data: Vec<u8> = col.iter().flat_map(|v| v.to_le_bytes()).collect();
        columns.push((key.to_owned(), Column::Values(data)));
    }
    let data: Vec<u8> = rows.storeys.iter().flat_map(|v| v.to_le_bytes()).collect();
    columns.push(("storeys".into(), Column::Values(data)));
    for ((_, key, _), col) in PROVENANCE.iter().zip(&rows.uncertainty) {
        let data: Vec<u8> = col.iter().flat_map(|v| v.to_le_bytes()).collect();
        columns.push(((*key).into(), Column::Values(data)));
    }
    Table {
        count: rows.len(),
        columns,
    }
}

/// The property table `t`, its columns appended to `bin`.
pub(crate) fn property_table(t: &Table, bin: &mut Bin) -> Value {
    let mut props = serde_json::Map::new();
    for (key, col) in &t.columns {
        let prop = match col {
            Column::Strings { values, offsets } => {
                let values = bin.view(values, None);
                let string_offsets = bin.view(offsets, None);
                json!({"values": values, "stringOffsets": string_offsets, "stringOffsetType": "UINT32"})
            }
            Column::Values(data) => json!({"values": bin.view(data, None)}),
        };
        props.insert(key.clone(), prop);
    }
    json!({
        "name": "buildings",
        "class": CLASS,
        "count": t.count,
        "properties": props
    })
}
