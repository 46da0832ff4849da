//! What the GIS feature readers (`input::geojson`, `input::gpkg`) share: a feature's
//! attributes read as tags (OSM keys as they are, Overture's names mapped, a municipal height
//! or levels column found as in a shapefile), its rings grouped by nesting, its id kept or
//! numbered by position, and the report entries of what is skipped or repaired.

use std::collections::HashSet;
use std::path::Path;

use serde_json::{Map, Value};

use super::{
    BuildingTags, Footprint, FootprintKind, InputError, ReadResult, Ring, SourceId, TagInterner,
};
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
        }
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
        let (tags, kind) = self.tags(props);
        match kind {
            FootprintKind::Building => self.report.read += 1,
            FootprintKind::Part => self.report.parts_read += 1,
        }
        let id = own_id
            .or_else(|| id_column(props))
            .unwrap_or(SourceId::Feature(position));
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
        self.footprints.push(Footprint {
            id,
            kind,
            polygons,
            tags: self.interner.intern(tags),
        });
        self.positions.push(position);
    }

    /// The tags of a feature's properties, and whether it is a building or a part.
    fn tags(&self, props: &Map<String, Value>) -> (BuildingTags, FootprintKind) {
        let mut pairs: Vec<(String, String)> = Vec::new();
        for (k, v) in props {
            let Some(text) = value_text(v) else { continue };
            let key = OVERTURE_KEYS
                .iter()
                .find(|(o, _)| o == k)
                .map_or(k.as_str(), |(_, osm)| osm);
            pairs.push((key.to_string(), text));
        }
        for (key, named, candidates) in [
            (
                "height",
                self.opts.height_field.as_deref(),
                &HEIGHT_FIELDS[..],
            ),
            (
                "building:levels",
                self.opts.levels_field.as_deref(),
                &LEVELS_FIELDS[..],
            ),
        ] {
            let field = match named {
                Some(n) => props.keys().find(|k| k.eq_ignore_ascii_case(n)),
                None if pairs.iter().any(|(k, _)| k == key) => None,
                None => candidates
                    .iter()
                    .find_map(|c| props.keys().find(|k| k.eq_ignore_ascii_case(c))),
            };
            if let Some(text) = field.and_then(|f| value_text(&props[f])) {
                pairs.retain(|(k, _)| k != key);
                pairs.push((key.to_string(), text));
            }
        }
        let part = pairs.iter().any(|(k, _)| k == "building:part")
            && !pairs.iter().any(|(k, _)| k == "building");
        let tags = BuildingTags::from_pairs(pairs.iter().map(|(k, v)| (k.as_str(), v.as_str())));
        let kind = if part {
            FootprintKind::Part
        } else {
            FootprintKind::Building
        };
        (tags, kind)
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
        let mut footprints = self.footprints;
        if self.duplicate {
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
        if let Some(f) = self.opts.height_field.as_deref() {
            self.report.add(
                None,
                Outcome::Note,
                format!("{}: height taken from property {f}", self.path.display()),
            );
        }
        Ok(ReadResult {
            footprints,
            source_crs,
            streets: Default::default(),
            boundaries: Vec::new(),
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
const ID_COLUMNS: [&str; 5] = ["id", "objectid", "fid", "osm_id", "gml_id"];

/// The feature's own id from an id column holding a non-negative integer.
fn id_column(props: &Map<String, Value>) -> Option<SourceId> {
    ID_COLUMNS.iter().find_map(|c| {
        let (_, v) = props.iter().find(|(k, _)| k.eq_ignore_ascii_case(c))?;
        let n = v
            .as_u64()
            .or_else(|| v.as_str().and_then(|s| s.trim().parse().ok()))?;
        Some(SourceId::Feature(n))
    })
}
