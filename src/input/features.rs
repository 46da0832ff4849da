//! What the GIS feature readers (`input::geojson`, `input::gpkg`, `input::fgb`) share: a
//! feature's attributes read as tags (OSM keys as they are, Overture's names mapped, the
//! columns of citygen's fields found by their common names in [`TARGETS`] or named with
//! `--field TARGET=COLUMN`), its other attributes kept typed for the outputs
//! ([`crate::model::Attributes`], column names interned), its rings grouped by nesting, its id
//! kept or numbered by position, and the report entries of what is skipped or repaired.

use std::collections::{HashMap, HashSet};
use std::path::Path;
use std::sync::Arc;

use serde_json::{Map, Value};

use super::{
    BuildingTags, Footprint, FootprintKind, InputError, ReadResult, Ring, SourceId, TagInterner,
};
use crate::model::{AttrValue, Attributes};
use crate::report::{Outcome, Report};

/// Height field names tried, in order, when no field is named (compared case-insensitively).
pub(crate) const HEIGHT_FIELDS: [&str; 14] = [
    "height",
    "hauteur",
    "building_height",
    "bldg_height",
    "height_m",
    "haut",
    "h",
    "h_mean",
    "hmean",
    "max_max",
    "h_max",
    "hmax",
    "mean_mean",
    "mean",
];

/// Level-count field names tried, in order, when no field is named.
pub(crate) const LEVELS_FIELDS: [&str; 10] = [
    "building:levels",
    "levels",
    "building_l",
    "nb_etages",
    "etages",
    "nb_niveaux",
    "floors",
    "storeys",
    "stories",
    "num_floors",
];

/// How to read a shapefile or a GIS feature file (GeoJSON, GeoPackage): which attribute holds
/// the height and the levels, and the source CRS.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ShpOptions {
    /// The `.dbf` field holding the height in metres (`--shp-height-field`); auto-detected from
    /// `HEIGHT_FIELDS` when `None`. Naming a field that does not exist is an error.
    pub height_field: Option<String>,
    /// The `.dbf` field holding the number of levels; auto-detected from `LEVELS_FIELDS`.
    pub levels_field: Option<String>,
    /// The source CRS (`--src-crs`); overrides the `.prj`.
    pub src_crs: Option<crate::crs::Crs>,
    /// Columns named for citygen's fields (`--field TARGET=COLUMN`, repeatable; the target one
    /// of `input::features::TARGETS`), in the order given: the last one of a target wins.
    pub fields: Vec<(String, String)>,
    /// The GeoPackage layer to read (`--layer`); `None` takes the only or first polygon layer.
    pub layer: Option<String>,
}

impl ShpOptions {
    /// The column named for `target` (`--field`, else `--shp-height-field`/`--shp-levels-field`).
    pub(crate) fn named(&self, target: &str) -> Option<&str> {
        self.fields
            .iter()
            .rev()
            .find(|(t, _)| t == target)
            .map(|(_, c)| c.as_str())
            .or(match target {
                "height" => self.height_field.as_deref(),
                "levels" => self.levels_field.as_deref(),
                _ => None,
            })
    }
}

/// Municipal and national height column names tried after [`HEIGHT_FIELDS`] (German `HOEHE`,
/// `GEBHOEHE`; New York's `heightroof`; `HEIGHT_ROOF`; `HGT_AGL`, height above ground level).
pub(crate) const MORE_HEIGHT_FIELDS: [&str; 7] = [
    "hoehe",
    "gebhoehe",
    "gebaeudehoehe",
    "height_roof",
    "heightroof",
    "hgt_agl",
    "b3_h_dak_max",
];

/// Height columns in feet: New York City's `heightroof`.
const FEET_COLUMNS: [&str; 1] = ["heightroof"];

/// Level-count column names tried after [`LEVELS_FIELDS`] (3DBAG's `b3_bouwlagen`, German
/// `GESCHOSSE`/`ANZ_GESCHOSSE`, `NUM_FLOORS`' other spellings).
pub(crate) const MORE_LEVELS_FIELDS: [&str; 5] = [
    "b3_bouwlagen",
    "geschosse",
    "anz_geschosse",
    "numfloors",
    "num_storeys",
];

/// citygen's fields a column can give: the target's name (`--field TARGET=COLUMN`), the OSM
/// key it sets (empty: read apart), and the column names tried when none is named
/// (case-insensitively, in order) and the OSM key itself is not a column. `ground` is the
/// ground's elevation that an absolute height column counts from (3DBAG's `b3_h_maaiveld`
/// under `b3_h_dak_max`): it is taken off the height.
pub(crate) const TARGETS: [(&str, &str, &[&str]); 14] = [
    ("id", "", &ID_COLUMNS),
    ("height", "height", &[]),
    (
        "min_height",
        "min_height",
        &["minheight", "base_height", "height_min"],
    ),
    (
        "ground",
        "",
        &["b3_h_maaiveld", "ground_height", "ground_z"],
    ),
    ("levels", "building:levels", &[]),
    (
        "min_level",
        "building:min_level",
        &["min_floor", "min_level"],
    ),
    (
        "roof_shape",
        "roof:shape",
        &["roof_shape", "roofshape", "dachform", "b3_dak_type"],
    ),
    (
        "roof_height",
        "roof:height",
        &["roof_height", "roofheight", "dachhoehe"],
    ),
    (
        "roof_colour",
        "roof:colour",
        &["roof_color", "roof_colour", "roofcolor", "roofcolour"],
    ),
    (
        "colour",
        "building:colour",
        &["facade_color", "facade_colour", "colour", "color"],
    ),
    (
        "material",
        "building:material",
        &["facade_material", "material"],
    ),
    ("roof_material", "roof:material", &["roof_material"]),
    (
        "kind",
        "building",
        &["class", "subtype", "building_type", "bldg_type"],
    ),
    ("name", "name", &["name"]),
];

/// The names `--field` accepts, for its error.
pub(crate) fn target_names() -> String {
    TARGETS.iter().map(|t| t.0).collect::<Vec<_>>().join(", ")
}

/// Parses `--field TARGET=COLUMN`: an unknown target is an error naming the allowed ones.
pub fn parse_field(s: &str) -> Result<(String, String), String> {
    let Some((target, column)) = s.split_once('=') else {
        return Err(format!(
            "{s:?} is not TARGET=COLUMN (e.g. height=HOEHE); the targets are {}",
            target_names()
        ));
    };
    let target = target.trim().to_ascii_lowercase().replace('-', "_");
    let target = match target.as_str() {
        "roof_color" => "roof_colour".to_string(),
        "color" => "colour".to_string(),
        "storeys" | "floors" => "levels".to_string(),
        _ => target,
    };
    let column = column.trim();
    if !TARGETS.iter().any(|t| t.0 == target) {
        return Err(format!(
            "unknown field target {target:?} in {s:?}; the targets are {}",
            target_names()
        ));
    }
    if column.is_empty() {
        return Err(format!("{s:?} names no column"));
    }
    Ok((target, column.to_string()))
}

/// The column names tried for `target` when none is named.
fn candidates(target: &str) -> Vec<&'static str> {
    match target {
        "height" => HEIGHT_FIELDS
            .iter()
            .chain(&MORE_HEIGHT_FIELDS)
            .copied()
            .collect(),
        "levels" => LEVELS_FIELDS
            .iter()
            .chain(&MORE_LEVELS_FIELDS)
            .copied()
            .collect(),
        _ => TARGETS
            .iter()
            .find(|t| t.0 == target)
            .map(|t| t.2.to_vec())
            .unwrap_or_default(),
    }
}

/// A roof shape column's value as `roof:shape`: 3DBAG's `b3_dak_type` (`horizontal` and
/// `multiple horizontal` are flat; `slanted` says no more than that, so the knowledge base
/// chooses) and the German names; anything else as written.
fn roof_shape_value(v: &str) -> Option<String> {
    let lower = v.trim().to_lowercase();
    let mapped = match lower.as_str() {
        "horizontal" | "multiple horizontal" | "flachdach" => "flat",
        "slanted" | "could not be detected" | "no points" | "not planar" => return None,
        "satteldach" => "gabled",
        "walmdach" => "hipped",
        "pultdach" => "skillion",
        "zeltdach" => "pyramidal",
        "mansarddach" => "mansard",
        "krueppelwalmdach" | "krüppelwalmdach" => "half-hipped",
        _ => return Some(v.trim().to_string()),
    };
    Some(mapped.to_string())
}

/// Overture Maps' building properties and the OSM keys they mean.
const OVERTURE_KEYS: [(&str, &str); 8] = [
    ("num_floors", "building:levels"),
    ("roof_shape", "roof:shape"),
    ("roof_height", "roof:height"),
    ("facade_color", "building:colour"),
    ("roof_color", "roof:colour"),
    ("facade_material", "building:material"),
    ("roof_material", "roof:material"),
    ("min_floor", "building:min_level"),
];

/// Where the features go as they are read.
pub(super) struct Sink<'a> {
    path: &'a Path,
    opts: &'a ShpOptions,
    report: &'a mut Report,
    interner: TagInterner,
    footprints: Vec<Footprint>,
    /// Each footprint's 0-based position among the features, to renumber on duplicate ids.
    positions: Vec<u64>,
    ids: HashSet<SourceId>,
    duplicate: bool,
    features: u64,
    role_fixes: usize,
    /// Every column name seen, interned: each feature's attributes share these.
    keys: HashMap<String, Arc<str>>,
    /// The columns whose text values are dates (a GeoPackage `DATE`/`DATETIME` column, a
    /// FlatGeobuf `DateTime` one).
    dates: HashSet<String>,
    /// Each footprint's other attributes, by its position among the footprints, with the
    /// shapefile's id column (left out when the ids are kept).
    attributes: Vec<(usize, Attributes, Option<Arc<str>>)>,
    /// The columns of citygen's fields for the last set of column names seen.
    resolved: Option<Resolved>,
    /// A shapefile's records: numbered `shp/N` when their id column does not name every one
    /// uniquely (all or none), the fields found named in notes.
    shapefile: bool,
    /// The id column's name seen (shapefile), and the first value that is no id.
    id_column_seen: Option<String>,
    bad_id: Option<String>,
    /// The fields found in the first set of columns, for the shapefile's notes.
    first_fields: Vec<(&'static str, String)>,
}

/// Which columns give citygen's fields, for one set of column names.
struct Resolved {
    /// The column names, in the order of the properties.
    columns: Vec<String>,
    /// The ground elevation's column.
    ground: Option<String>,
    /// (target, OSM key, column) of each field found.
    fields: Vec<(&'static str, &'static str, String)>,
}

impl<'a> Sink<'a> {
    /// A sink for the features of `path`.
    pub(super) fn new(path: &'a Path, opts: &'a ShpOptions, report: &'a mut Report) -> Sink<'a> {
        Sink {
            path,
            opts,
            report,
            interner: TagInterner::default(),
            footprints: Vec::new(),
            positions: Vec::new(),
            ids: HashSet::new(),
            duplicate: false,
            features: 0,
            role_fixes: 0,
            keys: HashMap::new(),
            dates: HashSet::new(),
            attributes: Vec::new(),
            resolved: None,
            shapefile: false,
            id_column_seen: None,
            bad_id: None,
            first_fields: Vec::new(),
        }
    }

    /// A sink for the records of a shapefile: a record without an id in the id column
    /// (`--field id=`, else the first of [`ID_COLUMNS`]), or ids not unique, number every
    /// record `shp/N` by its index, the column kept as an attribute.
    pub(super) fn shapefile(
        path: &'a Path,
        opts: &'a ShpOptions,
        report: &'a mut Report,
    ) -> Sink<'a> {
        Sink {
            shapefile: true,
            ..Sink::new(path, opts, report)
        }
    }

    /// Marks the column `name` as holding dates (its text values become [`AttrValue::Date`]).
    pub(super) fn date_column(&mut self, name: &str) {
        self.dates.insert(name.to_string());
    }

    /// Adds one feature: `own_id` is the id the file gives it (else its position names it),
    /// `rings` its rings with their declared roles or why it has none, `props` its attributes.
    pub(super) fn add(
        &mut self,
        own_id: Option<SourceId>,
        rings: Result<Vec<(Ring, bool)>, String>,
        props: &Map<String, Value>,
    ) {
        let position = self.features;
        self.features += 1;
        for k in props.keys() {
            if !self.keys.contains_key(k) {
                self.keys.insert(k.clone(), Arc::from(k.as_str()));
            }
        }
        let (tags, kind, mut used) = self.tags(props);
        match kind {
            FootprintKind::Building => self.report.read += 1,
            FootprintKind::Part => self.report.parts_read += 1,
        }
        // The file's own id, else its id column; a column named with `--field id=` wins. A
        // text id of the feature's own gives way to a whole number in an id column, and wins
        // over a text one; a whole number of its own (a GeoPackage's row key) gives way to a
        // text id in a column named as one ([`IDENTITY_COLUMNS`]: the BAG's `identificatie`).
        let named = self.opts.named("id").is_some();
        let from_column = match own_id {
            Some(SourceId::Text(_)) if !named => match self.id_column(props) {
                Some((_, SourceId::Text(_))) => None,
                c => c,
            },
            Some(SourceId::Feature(_)) if !named => text_id(props, &IDENTITY_COLUMNS),
            Some(_) if !named => None,
            _ => self.id_column(props),
        };
        let fallback = if self.shapefile {
            SourceId::Shape(position)
        } else {
            SourceId::Feature(position)
        };
        let mut id_column = None;
        if self.shapefile {
            // All or none: the column stays among the attributes until every record is seen.
            if let Some((column, value)) = self.id_column_of(props) {
                id_column = Some(column.clone());
                self.id_column_seen.get_or_insert(column);
                if from_column.is_none() && self.bad_id.is_none() {
                    self.bad_id = Some(value);
                }
            } else if let Some((column, _)) = &from_column {
                // A text id from a column only text ids are looked for in (`identificatie`).
                id_column = Some(column.clone());
                self.id_column_seen.get_or_insert(column.clone());
            }
        } else if let Some((column, _)) = &from_column {
            used.push(column.clone());
        }
        let id = from_column.map(|(_, id)| id).or(own_id).unwrap_or(fallback);
        let attributes = self.attributes_of(props, &used);
        if !self.ids.insert(id) {
            self.duplicate = true;
        }
        // An OSM object (an Overpass export holds streets and land use beside the buildings)
        // is a footprint only when it is tagged as one.
        if matches!(id, SourceId::Way(_) | SourceId::Relation(_)) && tags.building.is_none() {
            self.skip(id, "an OSM object without building or building:part".into());
            return;
        }
        let rings = match rings {
            Ok(r) => r,
            Err(why) => {
                self.skip(id, why);
                return;
            }
        };
        let got = match super::rings::polygons_of(rings) {
            Ok(g) => g,
            Err(why) => {
                self.skip(id, why);
                return;
            }
        };
        self.role_fixes += got.role_fixes;
        if !got.problems.is_empty() {
            self.report.repaired += 1;
            self.report
                .add(Some(id), Outcome::Repaired, got.problems.join("; "));
        }
        for (k, v, why) in &tags.ignored {
            self.report
                .add(Some(id), Outcome::Note, format!("{k}={v} ignored: {why}"));
        }
        let polygons = got.polygons;
        if let Some(a) = attributes {
            let column = id_column.map(|c| self.keys[c.as_str()].clone());
            self.attributes.push((self.footprints.len(), a, column));
        }
        self.footprints.push(Footprint {
            id,
            kind,
            polygons,
            tags: self.interner.intern(tags),
        });
        self.positions.push(position);
    }

    /// The tags of a feature's properties, whether it is a building or a part, and the
    /// columns read into citygen's fields (left out of its other attributes).
    fn tags(&mut self, props: &Map<String, Value>) -> (BuildingTags, FootprintKind, Vec<String>) {
        let mut pairs: Vec<(String, String)> = Vec::new();
        let mut used: Vec<String> = Vec::new();
        for (k, v) in props {
            let Some(text) = value_text(v) else { continue };
            let key = OVERTURE_KEYS
                .iter()
                .find(|(o, _)| o == k)
                .map_or(k.as_str(), |(_, osm)| osm);
            if super::tags::is_known_key(key) {
                used.push(k.clone());
            }
            pairs.push((key.to_string(), text));
        }
        // Which column gives which field depends on the column names alone: resolved once
        // per distinct set of names (a GeoPackage's or FlatGeobuf's every feature shares one).
        let resolved: &Resolved = match self.resolved.take() {
            Some(r) if r.columns.iter().eq(props.keys()) => self.resolved.insert(r),
            _ => {
                let r = self.resolve(props);
                if self.first_fields.is_empty() {
                    self.first_fields = r.fields.iter().map(|(_, k, c)| (*k, c.clone())).collect();
                }
                self.resolved.insert(r)
            }
        };
        let ground = resolved.ground.as_ref().and_then(|c| {
            let g = number(&props[c])?;
            used.push(c.clone());
            Some(g)
        });
        // A column's OSM key present with a value wins over the names tried, unless named.
        let fields: Vec<(&str, &str, String)> = resolved
            .fields
            .iter()
            .filter(|(target, key, _)| {
                self.opts.named(target).is_some() || !pairs.iter().any(|(k, _)| k == key)
            })
            .map(|(t, k, c)| (*t, *k, c.clone()))
            .collect();
        for (target, key, field) in fields {
            let Some(mut text) = value_text(&props[&field]) else {
                continue;
            };
            match target {
                "roof_shape" => match roof_shape_value(&text) {
                    Some(t) => text = t,
                    None => continue,
                },
                // An absolute height over the ground's elevation: the height above it.
                "height" => {
                    if let (Some(g), Some(h)) = (ground, number(&props[&field])) {
                        text = format!("{}", h - g);
                    } else if FEET_COLUMNS.iter().any(|c| field.eq_ignore_ascii_case(c))
                        && number(&props[&field]).is_some()
                    {
                        text = format!("{text} ft");
                    }
                }
                _ => {}
            }
            used.push(field);
            pairs.retain(|(k, _)| k != key);
            pairs.push((key.to_string(), text));
        }
        let part = pairs.iter().any(|(k, _)| k == "building:part")
            && !pairs.iter().any(|(k, _)| k == "building");
        let tags = BuildingTags::from_pairs(pairs.iter().map(|(k, v)| (k.as_str(), v.as_str())));
        let kind = if part {
            FootprintKind::Part
        } else {
            FootprintKind::Building
        };
        (tags, kind, used)
    }

    /// The columns that give citygen's fields among the column names of `props`: the one
    /// named (`--field`), else the first of the names tried.
    fn resolve(&self, props: &Map<String, Value>) -> Resolved {
        let column = |target: &str| -> Option<String> {
            match self.opts.named(target) {
                Some(n) => props.keys().find(|k| k.eq_ignore_ascii_case(n)),
                None => candidates(target)
                    .iter()
                    .find_map(|c| props.keys().find(|k| k.eq_ignore_ascii_case(c))),
            }
            .cloned()
        };
        Resolved {
            columns: props.keys().cloned().collect(),
            ground: column("ground"),
            fields: TARGETS
                .iter()
                .filter(|t| !t.1.is_empty())
                .filter_map(|&(target, key, _)| Some((target, key, column(target)?)))
                .collect(),
        }
    }

    /// The feature's own id from its id column (`--field id=COLUMN`, else the first of
    /// [`ID_COLUMNS`] present) holding a non-negative whole number, and that column's name;
    /// without one, the first of [`TEXT_ID_COLUMNS`] (or the named column) holding text: a
    /// text id ([`SourceId::Text`]).
    fn id_column(&self, props: &Map<String, Value>) -> Option<(String, SourceId)> {
        let named = self.opts.named("id");
        let names: Vec<&str> = match named {
            Some(n) => vec![n],
            None => ID_COLUMNS.to_vec(),
        };
        let whole = names.iter().find_map(|c| {
            let (k, v) = props.iter().find(|(k, _)| k.eq_ignore_ascii_case(c))?;
            let n = v.as_u64().or_else(|| v.as_str().and_then(whole_number))?;
            Some((k.clone(), SourceId::Feature(n)))
        });
        if whole.is_some() {
            return whole;
        }
        match named {
            Some(n) => text_id(props, &[n]),
            None => text_id(props, &TEXT_ID_COLUMNS),
        }
    }

    /// The id column present in `props` (named, else the first of [`ID_COLUMNS`]) and its
    /// value as text (empty when null).
    fn id_column_of(&self, props: &Map<String, Value>) -> Option<(String, String)> {
        let names: Vec<&str> = match self.opts.named("id") {
            Some(n) => vec![n],
            None => ID_COLUMNS.to_vec(),
        };
        names.iter().find_map(|c| {
            let (k, v) = props.iter().find(|(k, _)| k.eq_ignore_ascii_case(c))?;
            Some((k.clone(), value_text(v).unwrap_or_default()))
        })
    }

    /// The feature's other attributes, typed, in column order: every property not `used`
    /// (nulls, arrays and objects left out); `None` when there is none.
    fn attributes_of(&self, props: &Map<String, Value>, used: &[String]) -> Option<Attributes> {
        let row: Vec<(Arc<str>, AttrValue)> = props
            .iter()
            .filter(|(k, _)| !used.contains(k))
            .filter_map(|(k, v)| {
                let value = match v {
                    Value::String(t) if self.dates.contains(k) => {
                        AttrValue::Date(t.as_str().into())
                    }
                    Value::String(t) => AttrValue::Text(t.as_str().into()),
                    Value::Bool(b) => AttrValue::Bool(*b),
                    Value::Number(n) => match n.as_i64() {
                        Some(i) => AttrValue::Int(i),
                        None => AttrValue::Real(n.as_f64().filter(|x| x.is_finite())?),
                    },
                    Value::Null | Value::Array(_) | Value::Object(_) => return None,
                };
                Some((self.keys[k.as_str()].clone(), value))
            })
            .collect();
        (!row.is_empty()).then(|| Attributes::from(row))
    }

    fn skip(&mut self, id: SourceId, why: String) {
        self.report.skipped += 1;
        self.report.add(Some(id), Outcome::Skipped, why);
    }

    /// The footprints read, the CRS given.
    pub(super) fn finish(
        self,
        source_crs: Option<crate::crs::Crs>,
    ) -> Result<ReadResult, InputError> {
        for (target, column) in self.opts.fields.iter() {
            if !self.keys.keys().any(|k| k.eq_ignore_ascii_case(column)) && self.features > 0 {
                let mut columns: Vec<&str> = self.keys.keys().map(String::as_str).collect();
                columns.sort_unstable();
                return Err(InputError::Shapefile {
                    path: self.path.to_path_buf(),
                    reason: format!(
                        "--field {target}={column}: no feature has a column {column:?}; the columns are {}",
                        columns.join(", ")
                    ),
                });
            }
        }
        let mut footprints = self.footprints;
        let path = self.path.display();
        if self.shapefile {
            for (key, column) in &self.first_fields {
                self.report.add(
                    None,
                    Outcome::Note,
                    format!("{path}: {key} taken from field {column}"),
                );
            }
        }
        // Text ids must stay distinct as XML ids (`SourceId::key`) and as text beside the
        // numbered ones (a column mixing `7` and `feature/7`): else they are not unique.
        let mut duplicate = self.duplicate;
        if !duplicate && footprints.iter().any(|f| matches!(f.id, SourceId::Text(_))) {
            let (mut keys, mut texts) = (HashSet::new(), HashSet::new());
            duplicate = !footprints
                .iter()
                .all(|f| keys.insert(f.id.key()) & texts.insert(f.id.to_string()));
        }
        let mut ids_kept = self.shapefile && self.id_column_seen.is_some();
        if let (true, Some(column)) = (self.shapefile, &self.id_column_seen) {
            let why = match &self.bad_id {
                Some(v) if v.is_empty() => Some("is empty in some records".to_string()),
                Some(v) => Some(format!("holds {v:?}, not a non-negative whole number")),
                None if duplicate => Some("is not unique".to_string()),
                None => None,
            };
            if let Some(why) = why {
                ids_kept = false;
                for (f, &p) in footprints.iter_mut().zip(&self.positions) {
                    f.id = SourceId::Shape(p);
                }
                self.report.add(
                    None,
                    Outcome::Note,
                    format!(
                        "{path}: the id column {column} {why}; every record is named by its index (shp/0 is the first), the column kept as an attribute"
                    ),
                );
            }
        } else if duplicate {
            for (f, &p) in footprints.iter_mut().zip(&self.positions) {
                f.id = SourceId::Feature(p);
            }
            self.report.add(
                None,
                Outcome::Note,
                format!(
                    "{}: the features' ids are not unique; every feature is named by its position (feature/0 is the first)",
                    self.path.display()
                ),
            );
        }
        if self.role_fixes > 0 {
            self.report.add(
                None,
                Outcome::Note,
                format!(
                    "{}: {} ring(s) had an orientation that disagreed with how they nest ; nesting was used",
                    self.path.display(),
                    self.role_fixes
                ),
            );
        }
        if let (false, Some(f)) = (self.shapefile, self.opts.height_field.as_deref()) {
            self.report.add(
                None,
                Outcome::Note,
                format!("{}: height taken from property {f}", self.path.display()),
            );
        }
        let attributes = self
            .attributes
            .into_iter()
            .filter_map(|(i, a, column)| match column {
                Some(c) if ids_kept => {
                    let row: Vec<_> = a.iter().filter(|(k, _)| *k != c).cloned().collect();
                    (!row.is_empty()).then(|| (footprints[i].id, Attributes::from(row)))
                }
                _ => Some((footprints[i].id, a)),
            })
            .collect();
        Ok(ReadResult {
            footprints,
            source_crs,
            streets: Default::default(),
            boundaries: Vec::new(),
            attributes,
        })
    }
}

/// A property as tag text: strings trimmed (empty ones dropped), numbers and booleans as
/// written; arrays, objects and nulls are not tags.
pub(super) fn value_text(v: &Value) -> Option<String> {
    match v {
        Value::String(s) if !s.trim().is_empty() => Some(s.trim().to_string()),
        Value::Number(n) => Some(n.to_string()),
        Value::Bool(b) => Some(if *b { "yes" } else { "no" }.to_string()),
        _ => None,
    }
}

/// Attribute names that hold a file's own feature ids, tried in this order (case-insensitively).
pub(super) const ID_COLUMNS: [&str; 5] = ["id", "objectid", "fid", "osm_id", "gml_id"];

/// Attribute names tried, in this order, for a text id when no column of [`ID_COLUMNS`] holds
/// a whole number: those, then the Dutch BAG's `identificatie`, Ordnance Survey's `toid`,
/// Esri's `globalid`, and `guid`, `uuid`.
pub(super) const TEXT_ID_COLUMNS: [&str; 10] = [
    "id",
    "objectid",
    "fid",
    "osm_id",
    "gml_id",
    "identificatie",
    "toid",
    "globalid",
    "guid",
    "uuid",
];

/// The text id of the first of `names` present (case-insensitively) with a text or number
/// value, and that column's name.
fn text_id(props: &Map<String, Value>, names: &[&str]) -> Option<(String, SourceId)> {
    names.iter().find_map(|c| {
        let (k, v) = props.iter().find(|(k, _)| k.eq_ignore_ascii_case(c))?;
        let text = match v {
            Value::String(_) | Value::Number(_) => value_text(v)?,
            _ => return None,
        };
        Some((k.clone(), SourceId::text(&text)))
    })
}

/// The columns of [`TEXT_ID_COLUMNS`] that name a feature's identity: a text id in one wins
/// over the feature's own whole-number id (a GeoPackage's row key, a GeoJSON `id`).
const IDENTITY_COLUMNS: [&str; 5] = ["identificatie", "toid", "globalid", "guid", "uuid"];

/// `s` (trimmed) as a non-negative whole number written as one: digits without a sign and
/// without leading zeros (`0599` is a text id: its zero would be lost).
pub(super) fn whole_number(s: &str) -> Option<u64> {
    let s = s.trim();
    let n: u64 = s.parse().ok()?;
    (n.to_string() == s).then_some(n)
}

/// A property as a number: a JSON number, or text that reads as one.
fn number(v: &Value) -> Option<f64> {
    v.as_f64()
        .or_else(|| {
            v.as_str()
                .and_then(|s| s.trim().replace(',', ".").parse().ok())
        })
        .filter(|x: &f64| x.is_finite())
}
