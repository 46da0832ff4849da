//! `citygen kb learn`: the tag statistics of an extract written as a knowledge base, so that a
//! user can start from their city's own data and edit it.
//!
//! Pure functions: [`Sample`]s (one per building, from its parsed tags and representative
//! point) in, the KB text out; reading the input and writing the file are the caller's
//! (`app::kb::learn_kb`).
//!
//! **Grouping.** Either a grid ([`Grouping::Grid`]): rows of `metres` in latitude, each row cut
//! into columns of `metres` at the row's middle latitude (an equirectangular projection per
//! row, so that every cell is a lon/lat rectangle and binning agrees with the polygon the KB
//! holds); the extract is one `<town>` (the rectangle around its cells) and every cell with
//! buildings one `<district>`. Or the zones of a given knowledge base ([`Grouping::Zones`]):
//! each building goes to the zone [`KnowledgeBase::locate`] gives it, and the zones holding
//! buildings (with their ancestors) are written with their circles and polygons.
//!
//! **Upward inheritance.** A zone with fewer than `min_samples` tagged values of an attribute
//! takes that attribute's distribution from its parent (a cell's parent is the extract; the
//! extract's, and a KB's earth's, parent is the built-in defaults, i.e. the attribute is not
//! written). A zone's statistics are those of every building in it, its sub-zones' included.
//!
//! **Appearances.** The joint distribution of storeys (`building:levels`) and roof shape
//! (`roof:shape`): when one zone's data give both and at least `min_samples` buildings are
//! tagged with both, their joint counts fitted to the two marginals (iterative proportional
//! fitting); otherwise the product of the marginals. Each (storeys, roof) combination is an
//! appearance with `minFloors` = `maxFloors` and `bdRooftype`; beyond `max_appearances` the
//! cheapest neighbouring storeys of one roof are merged into a range (drawn uniformly), or a
//! rare roof whose storeys are all in one appearance is folded into the nearest appearance of
//! the most common roof (the cost of each step: the L1 error it adds to the joint). Each
//! appearance's `color`, `roofColor` and `floorsize` are the most frequent colour and median
//! floor height of the zone's buildings of that combination when the attribute is the zone's
//! own and at least `MIN_PER_APPEARANCE` of them are tagged, else the zone's (an inherited
//! one: the parent's overall value). Probas are rounded to 4 decimals summing
//! to exactly 1. A zone writes appearances only where one of their attributes is its own; the
//! others inherit their parent's (the KB's rule: the nearest zone with appearances).
//!
//! **Per-kind groups.** Buildings are sorted into the kind classes of `KIND_CLASSES` by their
//! `building=*` (houses; flats and commercial; industrial; any other kind, `yes` and none in no
//! class). In a zone that writes appearances, a class with at least `min_samples` tagged values
//! of its own of one of the appearance attributes (storeys, roof shape, floor height, colour,
//! roof colour) gets its own group of appearances, written with `building="..."` naming the
//! class's full list of kinds (the reader's appearance filter, `kb::eligible`): learned as
//! above from that class's buildings only (those its zone's values describe), each attribute
//! the class has fewer than `min_samples` of taken from the zone's unfiltered values. The
//! unfiltered appearances (no `building` list) serve `building=yes`, kinds in no class, and
//! classes without a group of their own: for an attribute some class draws from its own
//! group, they are learned from the buildings outside those classes (when `min_samples` of
//! them are tagged; else from all), so no class weighs twice in the zone's mix. Each group has
//! at most `max_appearances` appearances and probas summing to 1. The kinds are also counted
//! per zone in a comment.
//!
//! Deterministic: ordered maps only, ties broken by key; the same samples give the same bytes.

use std::collections::BTreeMap;

use super::compile::color_word;
use super::KnowledgeBase;
use crate::input::BuildingTags;
use crate::model::RoofShape;

mod fit;
mod format;
mod groups;
mod tally;
mod text;

use groups::{grid_groups, zone_groups};

/// Default grid cell size, metres.
pub(crate) const DEFAULT_GRID_M: f64 = 500.0;
/// Default least number of tagged values of an attribute for a zone to have its own
/// distribution of it.
pub(crate) const DEFAULT_MIN_SAMPLES: usize = 20;
/// Default most appearances per zone.
pub(crate) const DEFAULT_MAX_APPEARANCES: usize = 12;
/// Least tagged buildings of one appearance's (storeys, roof) combination for the appearance to
/// take their most frequent colour or median floor height instead of the zone's.
pub(crate) const MIN_PER_APPEARANCE: usize = 5;
/// The kind classes that get appearance groups of their own: (name, the `building=*` kinds of
/// the class, written as the group's `building` list).
pub(crate) const KIND_CLASSES: [(&str, &[&str]); 3] = [
    (
        "houses",
        &[
            "house",
            "detached",
            "semidetached_house",
            "terrace",
            "bungalow",
            "farm",
            "cabin",
            "hut",
        ],
    ),
    (
        "flats and commercial",
        &[
            "apartments",
            "residential",
            "commercial",
            "office",
            "retail",
            "civic",
            "public",
            "hotel",
            "school",
            "university",
            "college",
            "hospital",
            "government",
            "dormitory",
            "church",
            "kindergarten",
        ],
    ),
    (
        "industrial",
        &[
            "industrial",
            "warehouse",
            "garage",
            "garages",
            "shed",
            "barn",
            "farm_auxiliary",
            "hangar",
            "manufacture",
            "service",
            "storage_tank",
            "greenhouse",
            "carport",
        ],
    ),
];

/// The index in [`KIND_CLASSES`] of the class of a `building=*` kind (`None`: in no class).
pub(crate) fn kind_class(kind: Option<&str>) -> Option<usize> {
    let k = kind?.trim();
    KIND_CLASSES
        .iter()
        .position(|(_, kinds)| kinds.iter().any(|x| x.eq_ignore_ascii_case(k)))
}

/// Floor heights outside this range (metres) are not learned: a `height` that includes an
/// untagged roof, or a mistyped level count.
pub(crate) const FLOOR_HEIGHT_RANGE: (f64, f64) = (2.0, 6.0);
/// The most grid cells with buildings: about 300 bytes to 3 KB each, more would pass the
/// 64 MiB a knowledge-base file may have.
pub const MAX_CELLS: usize = 100_000;
/// The latitudes a grid may cover (degrees): near the poles a column would span the globe.
pub(crate) const MAX_GRID_LATITUDE: f64 = 85.0;

/// What one building says, from its parsed tags.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Sample {
    /// Representative point, WGS84 (lon, lat) degrees: the point the generator locates.
    pub lonlat: (f64, f64),
    /// Storeys above ground: `building:levels` minus `building:min_level`, rounded, at least 1
    /// (as the generator reads them).
    pub storeys: Option<u32>,
    /// Storey height, metres: (`height` - `roof:height` when tagged, 0 for a flat roof) /
    /// `building:levels`, when both are tagged, the building stands on the ground (no
    /// `min_height`, no `building:min_level`) and the result lies in `FLOOR_HEIGHT_RANGE`.
    pub floor_height: Option<f64>,
    /// `roof:shape` (known values only).
    pub roof: Option<RoofShape>,
    /// `building:colour` as the KB writes colours (a CSS name or `#rrggbb`).
    pub wall_colour: Option<String>,
    /// `roof:colour`, likewise.
    pub roof_colour: Option<String>,
    /// `building:material` (lower case; values that are no plain word are left out).
    pub material: Option<String>,
    /// `building=*` (lower case), for the comments.
    pub kind: Option<String>,
}

impl Sample {
    /// The sample of one building. `None` for `building=roof` (a canopy, drawn by its own rule
    /// whatever the KB says) and for a point that is not finite.
    pub fn from_tags(lonlat: (f64, f64), t: &BuildingTags) -> Option<Sample> {
        if t.is_roof() || !lonlat.0.is_finite() || !lonlat.1.is_finite() {
            return None;
        }
        let levels = t.levels.filter(|l| l.is_finite() && *l > 0.0);
        let min_level = t.min_level.filter(|l| l.is_finite() && *l >= 0.0);
        let storeys = levels.map(|l| {
            let above = (l - min_level.unwrap_or(0.0)).round();
            if above >= 1.0 {
                above.min(1000.0) as u32
            } else {
                1
            }
        });
        let grounded = t.min_height.is_none() && min_level.is_none();
        let floor_height = match (t.height.filter(|h| h.is_finite() && *h > 0.0), levels) {
            (Some(h), Some(l)) if grounded => {
                let roof = if t.roof_shape == Some(RoofShape::Flat) {
                    0.0
                } else {
                    t.roof_height
                        .filter(|r| r.is_finite() && *r >= 0.0)
                        .unwrap_or(0.0)
                };
                let f = (h - roof) / l;
                (f.is_finite() && (FLOOR_HEIGHT_RANGE.0..=FLOOR_HEIGHT_RANGE.1).contains(&f))
                    .then_some(f)
            }
            _ => None,
        };
        Some(Sample {
            lonlat,
            storeys,
            floor_height,
            roof: t.roof_shape,
            wall_colour: t.colour.map(color_word),
            roof_colour: t.roof_colour.map(color_word),
            material: t.material.clone().filter(|m| is_plain_word(m)),
            kind: t.building.clone(),
        })
    }
}

/// A value the KB can hold as a `token` without escaping: printable, none of `&<>"'`, at most
/// 64 characters.
fn is_plain_word(s: &str) -> bool {
    !s.is_empty()
        && s.chars().count() <= 64
        && s.trim() == s
        && !s
            .chars()
            .any(|c| c.is_control() || matches!(c, '&' | '<' | '>' | '"' | '\''))
}

/// How buildings are grouped into zones.
#[derive(Clone, Copy, Debug)]
pub enum Grouping<'a> {
    /// Square cells of this many metres (at least 1).
    Grid {
        /// Cell side, metres.
        metres: f64,
    },
    /// The deepest zone of this knowledge base.
    Zones(&'a KnowledgeBase),
}

/// What to learn and how to write it.
#[derive(Clone, Debug)]
pub struct LearnOptions<'a> {
    /// Grid or zones.
    pub grouping: Grouping<'a>,
    /// Least tagged values of an attribute for a zone's own distribution (at least 1).
    pub min_samples: usize,
    /// Most appearances per zone (at least 1).
    pub max_appearances: usize,
    /// The extract's name: the town's designation (grid) and the header.
    pub name: String,
    /// The input file as the user gave it, for the header.
    pub source: String,
}

/// The learned knowledge base.
#[derive(Clone, Debug, PartialEq)]
pub struct Learned {
    /// The KB text (UTF-8 XML, schemas/kb.xsd).
    pub text: String,
    /// Buildings learned from.
    pub samples: usize,
    /// Zones written, earth included.
    pub zones: usize,
    /// Appearances written in all zones.
    pub appearances: usize,
    /// Per-kind appearance groups (with a `building` list) written in all zones.
    pub kind_groups: usize,
    /// Zones with at least one attribute of their own (the others only inherit).
    pub zones_with_own_data: usize,
}

/// The attributes learned, in the order of the counts.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Attr {
    Storeys,
    Roof,
    FloorHeight,
    WallColour,
    RoofColour,
    Material,
}

const ATTRS: [Attr; 6] = [
    Attr::Storeys,
    Attr::Roof,
    Attr::FloorHeight,
    Attr::WallColour,
    Attr::RoofColour,
    Attr::Material,
];

impl Attr {
    fn name(self) -> &'static str {
        match self {
            Attr::Storeys => "storeys",
            Attr::Roof => "roof shape",
            Attr::FloorHeight => "floor height",
            Attr::WallColour => "colour",
            Attr::RoofColour => "roof colour",
            Attr::Material => "material",
        }
    }

    fn has(self, s: &Sample) -> bool {
        match self {
            Attr::Storeys => s.storeys.is_some(),
            Attr::Roof => s.roof.is_some(),
            Attr::FloorHeight => s.floor_height.is_some(),
            Attr::WallColour => s.wall_colour.is_some(),
            Attr::RoofColour => s.roof_colour.is_some(),
            Attr::Material => s.material.is_some(),
        }
    }
}

/// A zone's shape as written.
#[derive(Clone, Debug, PartialEq)]
enum Shape {
    /// Earth: none.
    Earth,
    /// A lon/lat rectangle: west, south, east, north.
    Rect([f64; 4]),
    /// A KB zone's own circle (lat, lon, km) and polygon rings.
    Kept {
        circle: Option<(f64, f64, f64)>,
        polygons: Vec<Vec<[f64; 2]>>,
    },
}

/// One zone of the output.
#[derive(Clone, Debug)]
struct Group {
    element: &'static str,
    name: String,
    parent: Option<usize>,
    shape: Shape,
    /// Every sample in the zone or its sub-zones, ascending.
    members: Vec<usize>,
}

/// Why [`learn`] writes no knowledge base.
#[derive(Debug, thiserror::Error)]
pub enum LearnError {
    /// No sample has a finite position.
    #[error("no building to learn from")]
    NoBuilding,
    /// A grid cell under 1 m (or not a number).
    #[error("a grid of {metres} m: cells must be at least 1 m")]
    GridCell {
        /// The cell size asked for.
        metres: f64,
    },
    /// Buildings beyond the latitudes a grid covers.
    #[error(
        "buildings at latitude {latitude:.2}: a grid covers latitudes -{lat} to {lat} only (use \
         --zones)",
        lat = MAX_GRID_LATITUDE
    )]
    GridLatitude {
        /// The farthest latitude found.
        latitude: f64,
    },
    /// A grid with more cells than a learned knowledge base may have.
    #[error(
        "a grid of {metres} m puts the buildings in {cells} cells, more than the {max} a learned \
         knowledge base may have: use larger cells (--grid)",
        max = MAX_CELLS
    )]
    GridCells {
        /// The cell size, as written.
        metres: String,
        /// The cells the buildings fall in.
        cells: usize,
    },
    /// Buildings spanning more than a grid covers in longitude.
    #[error(
        "the buildings span longitudes {west:.4} to {east:.4}: a grid covers at most 180° \
         between -180 and 180 (an extract across the antimeridian needs --zones)"
    )]
    GridLongitudes {
        /// The westernmost longitude.
        west: f64,
        /// The easternmost.
        east: f64,
    },
    /// The text would pass the size a knowledge base may have.
    #[error(
        "the learned knowledge base would be {bytes} bytes, more than the {max} a knowledge base \
         may have: use larger cells (--grid) or fewer zones"
    )]
    TooLarge {
        /// The text's size.
        bytes: usize,
        /// The cap.
        max: u64,
    },
}

/// Learns a knowledge base from `samples`; `Err` with a message when there is nothing to learn
/// from (no sample) or the grid cannot hold the extract.
pub fn learn(samples: &[Sample], o: &LearnOptions<'_>) -> Result<Learned, LearnError> {
    let samples: Vec<&Sample> = samples
        .iter()
        .filter(|s| s.lonlat.0.is_finite() && s.lonlat.1.is_finite())
        .collect();
    if samples.is_empty() {
        return Err(LearnError::NoBuilding);
    }
    let min = o.min_samples.max(1);
    let max_apps = o.max_appearances.max(1);
    let groups = match o.grouping {
        Grouping::Grid { metres } => grid_groups(&samples, metres, &o.name)?,
        Grouping::Zones(kb) => zone_groups(&samples, kb),
    };
    let any = ATTRS.iter().any(|a| samples.iter().any(|s| a.has(s)));
    let mut w = Writer::new(&samples, &groups, min, max_apps);
    w.header(o, any);
    if any {
        w.group(0, 0);
    } else {
        w.defaults_only();
    }
    let text = w.out;
    if text.len() as u64 > super::dom::MAX_FILE_BYTES {
        return Err(LearnError::TooLarge {
            bytes: text.len(),
            max: super::dom::MAX_FILE_BYTES,
        });
    }
    Ok(Learned {
        text,
        samples: samples.len(),
        zones: w.zones,
        appearances: w.appearances,
        kind_groups: w.kind_groups,
        zones_with_own_data: w.own,
    })
}

/// Rounds to 7 decimals (about 1 cm), the precision the polygons are written with.
fn round7(x: f64) -> f64 {
    (x * 1e7).round() / 1e7
}

/// The joint distribution of (roof key, storeys; 0 for none), summing to 1.
type Joint = BTreeMap<(&'static str, u32), f64>;

/// Writes the groups as XML.
struct Writer<'a> {
    samples: &'a [&'a Sample],
    groups: &'a [Group],
    min: usize,
    max_apps: usize,
    out: String,
    zones: usize,
    appearances: usize,
    kind_groups: usize,
    own: usize,
    /// Per group and attribute: its tagged members. Indices from `groups.len()` on are the
    /// per-kind groups (see `classes`): a class's tagged members in one zone.
    counts: Vec<[usize; 6]>,
    /// Per group and attribute: the tagged samples its appearances and info describe.
    data: Vec<[Vec<usize>; 6]>,
    /// Per group and attribute: whether `data` is the rest (the samples outside its sub-zones
    /// that have that attribute of their own) rather than the whole zone.
    rest: Vec<[bool; 6]>,
    /// Per group: its sub-zones, in order.
    children: Vec<Vec<usize>>,
    /// Per group: its per-kind groups, (class index in [`KIND_CLASSES`], index in `counts`,
    /// `data` and `rest`), by class.
    classes: Vec<Vec<(usize, usize)>>,
    /// What a parent gives every sub-zone that inherits it, computed once.
    cache: std::cell::RefCell<Cache>,
}

/// The values a group's data give, by group (and attribute), kept for its sub-zones.
#[derive(Default)]
struct Cache {
    storeys: BTreeMap<usize, BTreeMap<u32, f64>>,
    roofs: BTreeMap<usize, BTreeMap<&'static str, f64>>,
    joints: BTreeMap<(Option<usize>, Option<usize>), (Joint, String)>,
    modes: BTreeMap<(usize, usize), Option<String>>,
    floors: BTreeMap<usize, Option<f64>>,
}

#[cfg(test)]
mod tests;
