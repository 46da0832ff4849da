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
//! own and at least [`MIN_PER_APPEARANCE`] of them are tagged, else the zone's (an inherited
//! one: the parent's overall value). Probas are rounded to 4 decimals summing
//! to exactly 1. A zone writes appearances only where one of their attributes is its own; the
//! others inherit their parent's (the KB's rule: the nearest zone with appearances).
//!
//! **Per-kind groups.** Buildings are sorted into the kind classes of [`KIND_CLASSES`] by their
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
use std::fmt::Write as _;

use super::compile::color_word;
use super::{defaults, KnowledgeBase, ZoneKind, KM_PER_DEG};
use crate::input::BuildingTags;
use crate::model::RoofShape;

/// Default grid cell size, metres.
pub const DEFAULT_GRID_M: f64 = 500.0;
/// Default least number of tagged values of an attribute for a zone to have its own
/// distribution of it.
pub const DEFAULT_MIN_SAMPLES: usize = 20;
/// Default most appearances per zone.
pub const DEFAULT_MAX_APPEARANCES: usize = 12;
/// Least tagged buildings of one appearance's (storeys, roof) combination for the appearance to
/// take their most frequent colour or median floor height instead of the zone's.
pub const MIN_PER_APPEARANCE: usize = 5;
/// The kind classes that get appearance groups of their own: (name, the `building=*` kinds of
/// the class, written as the group's `building` list).
pub const KIND_CLASSES: [(&str, &[&str]); 3] = [
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
pub fn kind_class(kind: Option<&str>) -> Option<usize> {
    let k = kind?.trim();
    KIND_CLASSES
        .iter()
        .position(|(_, kinds)| kinds.iter().any(|x| x.eq_ignore_ascii_case(k)))
}

/// Floor heights outside this range (metres) are not learned: a `height` that includes an
/// untagged roof, or a mistyped level count.
pub const FLOOR_HEIGHT_RANGE: (f64, f64) = (2.0, 6.0);
/// The most grid cells with buildings: about 300 bytes to 3 KB each, more would pass the
/// 64 MiB a knowledge-base file may have.
pub const MAX_CELLS: usize = 100_000;
/// The latitudes a grid may cover (degrees): near the poles a column would span the globe.
pub const MAX_GRID_LATITUDE: f64 = 85.0;

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
    /// `min_height`, no `building:min_level`) and the result lies in [`FLOOR_HEIGHT_RANGE`].
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

/// Learns a knowledge base from `samples`; `Err` with a message when there is nothing to learn
/// from (no sample) or the grid cannot hold the extract.
pub fn learn(samples: &[Sample], o: &LearnOptions<'_>) -> Result<Learned, String> {
    let samples: Vec<&Sample> = samples
        .iter()
        .filter(|s| s.lonlat.0.is_finite() && s.lonlat.1.is_finite())
        .collect();
    if samples.is_empty() {
        return Err("no building to learn from".into());
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
        return Err(format!(
            "the learned knowledge base would be {} bytes, more than the {} a knowledge base may \
             have: use larger cells (--grid) or fewer zones",
            text.len(),
            super::dom::MAX_FILE_BYTES
        ));
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

/// The grid's cells as zones under one town: group 0 earth, 1 the town, then the cells by row
/// (south to north) and column (west to east).
fn grid_groups(samples: &[&Sample], metres: f64, name: &str) -> Result<Vec<Group>, String> {
    if !(metres.is_finite() && metres >= 1.0) {
        return Err(format!("a grid of {metres} m: cells must be at least 1 m"));
    }
    let lat_min = samples
        .iter()
        .map(|s| s.lonlat.1)
        .fold(f64::INFINITY, f64::min);
    let lat_max = samples
        .iter()
        .map(|s| s.lonlat.1)
        .fold(f64::NEG_INFINITY, f64::max);
    let lon_min = samples
        .iter()
        .map(|s| s.lonlat.0)
        .fold(f64::INFINITY, f64::min);
    if lat_min < -MAX_GRID_LATITUDE || lat_max > MAX_GRID_LATITUDE {
        return Err(format!(
            "buildings at latitude {:.2}: a grid covers latitudes -{MAX_GRID_LATITUDE} to \
             {MAX_GRID_LATITUDE} only (use --zones)",
            if lat_max > MAX_GRID_LATITUDE {
                lat_max
            } else {
                lat_min
            }
        ));
    }
    // Anchored on the south-west corner of the data, floored to the written precision.
    let lat0 = (lat_min * 1e7).floor() / 1e7;
    let lon0 = (lon_min * 1e7).floor() / 1e7;
    let dlat = metres / (KM_PER_DEG * 1000.0);
    let lat_edge = |j: i64| round7(lat0 + j as f64 * dlat);
    let dlon = |j: i64| {
        let mid = (lat0 + (j as f64 + 0.5) * dlat).clamp(-89.0, 89.0);
        dlat / mid.to_radians().cos()
    };
    let lon_edge = |j: i64, i: i64| round7(lon0 + i as f64 * dlon(j));
    // Half-open cells on the written (rounded) edges, so that binning and the polygons agree.
    let bin = |v: f64, start: i64, edge: &dyn Fn(i64) -> f64| {
        let mut k = start;
        while v < edge(k) {
            k -= 1;
        }
        while v >= edge(k + 1) {
            k += 1;
        }
        k
    };
    let mut cells: BTreeMap<(i64, i64), Vec<usize>> = BTreeMap::new();
    for (k, s) in samples.iter().enumerate() {
        let (lon, lat) = s.lonlat;
        let j = bin(lat, ((lat - lat0) / dlat).floor() as i64, &lat_edge);
        let i = bin(lon, ((lon - lon0) / dlon(j)).floor() as i64, &|i| {
            lon_edge(j, i)
        });
        cells.entry((j, i)).or_default().push(k);
    }
    if cells.len() > MAX_CELLS {
        return Err(format!(
            "a grid of {} m puts the buildings in {} cells, more than the {MAX_CELLS} a learned \
             knowledge base may have: use larger cells (--grid)",
            num(metres, 3),
            cells.len()
        ));
    }
    let rect = |j: i64, i: i64| {
        [
            lon_edge(j, i),
            lat_edge(j),
            lon_edge(j, i + 1),
            lat_edge(j + 1),
        ]
    };
    let mut bounds = [
        f64::INFINITY,
        f64::INFINITY,
        f64::NEG_INFINITY,
        f64::NEG_INFINITY,
    ];
    for &(j, i) in cells.keys() {
        let r = rect(j, i);
        bounds = [
            bounds[0].min(r[0]),
            bounds[1].min(r[1]),
            bounds[2].max(r[2]),
            bounds[3].max(r[3]),
        ];
    }
    if bounds[0] < -180.0 || bounds[2] > 180.0 || bounds[2] - bounds[0] > 180.0 {
        return Err(format!(
            "the buildings span longitudes {:.4} to {:.4}: a grid covers at most 180° between \
             -180 and 180 (an extract across the antimeridian needs --zones)",
            bounds[0], bounds[2]
        ));
    }
    let mut groups = vec![
        // Earth holds no sample: the extract (the town) is the top of the statistics, and
        // earth's are the built-in defaults.
        Group {
            element: "earth",
            name: "earth".into(),
            parent: None,
            shape: Shape::Earth,
            members: Vec::new(),
        },
        Group {
            element: "town",
            name: designation(name),
            parent: Some(0),
            shape: Shape::Rect(bounds),
            members: (0..samples.len()).collect(),
        },
    ];
    for ((j, i), members) in cells {
        groups.push(Group {
            element: "district",
            name: format!("row {} col {}", j, i),
            parent: Some(1),
            shape: Shape::Rect(rect(j, i)),
            members,
        });
    }
    Ok(groups)
}

/// The zones of `kb` that hold buildings, with their ancestors, in document order (earth
/// first).
fn zone_groups(samples: &[&Sample], kb: &KnowledgeBase) -> Vec<Group> {
    let zones = kb.zones();
    let mut members: Vec<Vec<usize>> = vec![Vec::new(); zones.len().max(1)];
    for (k, s) in samples.iter().enumerate() {
        for z in kb.lineage(kb.locate(s.lonlat.0, s.lonlat.1)) {
            if let Some(m) = members.get_mut(z) {
                m.push(k);
            }
        }
    }
    let mut index: Vec<Option<usize>> = vec![None; zones.len()];
    let mut groups: Vec<Group> = Vec::new();
    for (z, zone) in zones.iter().enumerate() {
        if z > 0 && members[z].is_empty() {
            continue;
        }
        index[z] = Some(groups.len());
        let parent = zone.parent.and_then(|p| index.get(p).copied().flatten());
        groups.push(Group {
            element: match zone.kind {
                ZoneKind::Earth => "earth",
                ZoneKind::Country => "country",
                ZoneKind::Region => "region",
                ZoneKind::Town => "town",
                ZoneKind::District => "district",
                ZoneKind::Other(_) => "zone",
            },
            name: if z == 0 {
                "earth".into()
            } else {
                designation(&zone.name)
            },
            parent: if z == 0 { None } else { parent.or(Some(0)) },
            shape: if z == 0 {
                Shape::Earth
            } else {
                Shape::Kept {
                    circle: zone.circle.map(|c| (c.lat, c.lon, c.radius_km)),
                    polygons: zone.polygons.iter().map(|p| p.ring.clone()).collect(),
                }
            },
            members: std::mem::take(&mut members[z]),
        });
    }
    groups
}

/// A name the strict reader takes as a designation: no `/`, no tab or line break, trimmed,
/// not empty.
fn designation(name: &str) -> String {
    let s: String = name
        .chars()
        .map(|c| if c == '/' || c.is_control() { ' ' } else { c })
        .collect();
    let s = s.split_whitespace().collect::<Vec<_>>().join(" ");
    if s.is_empty() {
        "extract".into()
    } else {
        s
    }
}

/// `s` with `& < > "` escaped, for an attribute value.
fn escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

/// `s` made safe inside an XML comment (no `--`, no trailing `-`, no control character).
fn comment_text(s: &str) -> String {
    let mut t: String = s
        .chars()
        .map(|c| if c.is_control() { ' ' } else { c })
        .collect();
    while t.contains("--") {
        t = t.replace("--", "- ");
    }
    if t.ends_with('-') {
        t.push(' ');
    }
    t
}

/// Compact number: at most `decimals` decimals, no trailing zeros.
fn num(x: f64, decimals: usize) -> String {
    let s = format!("{x:.decimals$}");
    let s = if s.contains('.') {
        s.trim_end_matches('0').trim_end_matches('.')
    } else {
        &s
    };
    if s == "-0" {
        "0".into()
    } else {
        s.to_string()
    }
}

/// A coordinate with its 7 decimals.
fn coord(x: f64) -> String {
    num(round7(x), 7)
}

/// The most frequent value, ties to the smallest.
fn mode<'a>(values: impl Iterator<Item = &'a str>) -> Option<String> {
    let mut counts: BTreeMap<&str, usize> = BTreeMap::new();
    for v in values {
        *counts.entry(v).or_default() += 1;
    }
    let mut best: Option<(&str, usize)> = None;
    for (v, n) in counts {
        if best.is_none_or(|(_, b)| n > b) {
            best = Some((v, n));
        }
    }
    best.map(|(v, _)| v.to_string())
}

/// The median (the lower middle of an even count).
fn median(mut v: Vec<f64>) -> Option<f64> {
    v.sort_by(f64::total_cmp);
    v.get(v.len().saturating_sub(1) / 2).copied()
}

/// A roof shape as a key: its OSM name; `""` for none.
fn roof_key(r: Option<RoofShape>) -> &'static str {
    r.map_or("", RoofShape::osm_name)
}

/// The joint distribution of (roof key, storeys; 0 for none), summing to 1.
type Joint = BTreeMap<(&'static str, u32), f64>;

/// Fits `seed` (rows: storeys, columns: roofs; counts) to the two marginals by iterative
/// proportional fitting. A thousandth of a sample's worth of the product of the marginals is
/// added to the seed first, so that every combination is possible and the fit exists (a
/// storeys value seen only on buildings without a roof tag still gets the roof distribution);
/// combinations left under [`MIN_MASS`] are dropped.
fn fit_joint(
    seed: &BTreeMap<(u32, &'static str), f64>,
    rows: &BTreeMap<u32, f64>,
    cols: &BTreeMap<&'static str, f64>,
) -> Joint {
    let r: Vec<(u32, f64)> = rows.iter().map(|(k, v)| (*k, *v)).collect();
    let c: Vec<(&'static str, f64)> = cols.iter().map(|(k, v)| (*k, *v)).collect();
    let mut m: Vec<Vec<f64>> = r
        .iter()
        .map(|(s, ps)| {
            c.iter()
                .map(|(roof, pr)| seed.get(&(*s, *roof)).copied().unwrap_or(0.0) + 1e-3 * ps * pr)
                .collect()
        })
        .collect();
    for _ in 0..1000 {
        for (row, (_, p)) in m.iter_mut().zip(&r) {
            let sum: f64 = row.iter().sum();
            if sum > 0.0 {
                row.iter_mut().for_each(|x| *x *= p / sum);
            }
        }
        let mut worst: f64 = 0.0;
        for (j, (_, p)) in c.iter().enumerate() {
            let sum: f64 = m.iter().map(|row| row[j]).sum();
            if sum > 0.0 {
                m.iter_mut().for_each(|row| row[j] *= p / sum);
            }
            worst = worst.max((sum - p).abs());
        }
        if worst < 1e-12 {
            break;
        }
    }
    let mut out = Joint::new();
    let total: f64 = m.iter().flatten().sum();
    for (row, (s, _)) in m.iter().zip(&r) {
        for (x, (roof, _)) in row.iter().zip(&c) {
            if total > 0.0 && x / total >= MIN_MASS {
                out.insert((*roof, *s), x / total);
            }
        }
    }
    normalise(out)
}

/// The least mass of a fitted combination: half the smallest proba written (0.0001).
const MIN_MASS: f64 = 5e-5;

/// One appearance before writing: a roof key, a storeys range (0..=0 for none) and its mass.
#[derive(Clone, Debug, PartialEq)]
struct Bin {
    roof: &'static str,
    lo: u32,
    hi: u32,
    mass: f64,
}

/// The L1 error of a bin drawn uniformly over its range against the joint.
fn bin_cost(b: &Bin, joint: &Joint) -> f64 {
    let w = f64::from(b.hi - b.lo + 1);
    (b.lo..=b.hi)
        .map(|s| (joint.get(&(b.roof, s)).copied().unwrap_or(0.0) - b.mass / w).abs())
        .sum()
}

/// At most `max` bins for `joint`: one per combination, then greedily the cheapest step (in
/// added L1 error) of merging two neighbouring storeys bins of one roof, or folding a roof that
/// has one bin into the nearest bin of the most common other roof. Returns the bins (by roof,
/// then storeys) and what was merged, for the comment.
fn merge_bins(joint: &Joint, max: usize) -> (Vec<Bin>, Vec<String>) {
    let mut bins: Vec<Bin> = joint
        .iter()
        .map(|(&(roof, s), &mass)| Bin {
            roof,
            lo: s,
            hi: s,
            mass,
        })
        .collect();
    let combinations = bins.len();
    let mut folded: Vec<String> = Vec::new();
    // Each bin's error, and the error a merge of bins k and k + 1 (same roof) would add: only
    // the neighbours of a merge change, so a step costs a scan of the bins.
    let merge_delta = |bins: &[Bin], cost: &[f64], k: usize| -> Option<f64> {
        let (a, b) = (bins.get(k)?, bins.get(k + 1)?);
        if a.roof != b.roof {
            return None;
        }
        let m = Bin {
            roof: a.roof,
            lo: a.lo,
            hi: b.hi,
            mass: a.mass + b.mass,
        };
        Some(bin_cost(&m, joint) - cost[k] - cost[k + 1])
    };
    let mut cost: Vec<f64> = bins.iter().map(|b| bin_cost(b, joint)).collect();
    let all_deltas = |bins: &[Bin], cost: &[f64]| -> Vec<Option<f64>> {
        (0..bins.len().saturating_sub(1))
            .map(|k| merge_delta(bins, cost, k))
            .collect()
    };
    let mut delta = all_deltas(&bins, &cost);
    while bins.len() > max.max(1) {
        // (added error, merge k with k + 1 | fold k)
        let mut best: Option<(f64, usize, bool)> = None;
        for (k, d) in delta.iter().enumerate() {
            if let Some(d) = *d {
                if best.is_none_or(|(e, _, _)| d < e) {
                    best = Some((d, k, false));
                }
            }
        }
        let roofs: BTreeMap<&str, (usize, f64)> =
            bins.iter().fold(BTreeMap::new(), |mut acc, b| {
                let e = acc.entry(b.roof).or_insert((0, 0.0));
                e.0 += 1;
                e.1 += b.mass;
                acc
            });
        if roofs.len() > 1 {
            for (k, b) in bins.iter().enumerate() {
                if roofs.get(b.roof).is_some_and(|r| r.0 == 1) {
                    let d = 2.0 * b.mass - cost[k];
                    if best.is_none_or(|(e, _, _)| d < e) {
                        best = Some((d, k, true));
                    }
                }
            }
        }
        let Some((_, k, fold)) = best else { break };
        if !fold {
            let b = bins.remove(k + 1);
            cost.remove(k + 1);
            delta.remove(k);
            bins[k].hi = b.hi;
            bins[k].mass += b.mass;
            cost[k] = bin_cost(&bins[k], joint);
            if k > 0 {
                delta[k - 1] = merge_delta(&bins, &cost, k - 1);
            }
            if k < delta.len() {
                delta[k] = merge_delta(&bins, &cost, k);
            }
            continue;
        }
        let gone = bins.remove(k);
        // The most common other roof (ties: the first by name), its bin nearest in storeys.
        let mut target_roof: Option<(&str, f64)> = None;
        for (r, (_, m)) in &roofs {
            if *r != gone.roof && target_roof.is_none_or(|(_, tm)| *m > tm) {
                target_roof = Some((r, *m));
            }
        }
        let Some((tr, _)) = target_roof else { break };
        let gap = |b: &Bin| {
            if b.hi < gone.lo {
                gone.lo - b.hi
            } else {
                b.lo.saturating_sub(gone.hi)
            }
        };
        let Some(t) = (0..bins.len())
            .filter(|&i| bins[i].roof == tr)
            .min_by_key(|&i| (gap(&bins[i]), i))
        else {
            break;
        };
        bins[t].mass += gone.mass;
        folded.push(format!(
            "roof {} ({} %) folded into {}",
            if gone.roof.is_empty() {
                "untagged"
            } else {
                gone.roof
            },
            num(100.0 * gone.mass, 1),
            tr
        ));
        // Rare: everything again.
        cost = bins.iter().map(|b| bin_cost(b, joint)).collect();
        delta = all_deltas(&bins, &cost);
    }
    let mut notes = Vec::new();
    if bins.len() < combinations {
        let ranges = bins.iter().filter(|b| b.hi > b.lo).count();
        notes.push(format!(
            "{} appearances from {combinations} (storeys, roof) combinations: {ranges} merge \
             neighbouring storeys into a range drawn uniformly{}",
            bins.len(),
            if folded.is_empty() {
                String::new()
            } else {
                format!("; {}", folded.join("; "))
            }
        ));
    }
    (bins, notes)
}

/// Probabilities in units of 1/10,000 summing to exactly 10,000 (largest remainders; ties to
/// the first).
fn round_probas(masses: &[f64]) -> Vec<u32> {
    const UNITS: f64 = 10_000.0;
    let total: f64 = masses.iter().sum();
    if masses.is_empty() || total <= 0.0 {
        return vec![0; masses.len()];
    }
    let exact: Vec<f64> = masses.iter().map(|m| m / total * UNITS).collect();
    let mut units: Vec<u32> = exact.iter().map(|x| x.floor() as u32).collect();
    let short = 10_000u32.saturating_sub(units.iter().sum());
    let mut order: Vec<usize> = (0..masses.len()).collect();
    order.sort_by(|&a, &b| {
        let fa = exact[a] - exact[a].floor();
        let fb = exact[b] - exact[b].floor();
        fb.total_cmp(&fa).then(a.cmp(&b))
    });
    for &i in order.iter().cycle().take(short as usize) {
        units[i] += 1;
    }
    units
}

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

impl<'a> Writer<'a> {
    /// Counts, and what each zone's values describe. A zone's values serve only the buildings
    /// that use them: those in it but in no sub-zone with that attribute of its own. So they are
    /// learned from those (the rest) when it holds at least `min` tagged values, else from the
    /// whole zone; drawn over the extract, every building then follows the distribution of the
    /// buildings around it that use the same values, and the extract's overall distribution is
    /// kept.
    fn new(samples: &'a [&'a Sample], groups: &'a [Group], min: usize, max_apps: usize) -> Self {
        let counts: Vec<[usize; 6]> = groups
            .iter()
            .map(|g| ATTRS.map(|a| g.members.iter().filter(|&&k| a.has(samples[k])).count()))
            .collect();
        let mut children: Vec<Vec<usize>> = vec![Vec::new(); groups.len()];
        for (i, g) in groups.iter().enumerate() {
            if let Some(p) = g.parent.filter(|&p| p < i) {
                children[p].push(i);
            }
        }
        let mut data = Vec::with_capacity(groups.len());
        let mut rest = Vec::with_capacity(groups.len());
        for (g, grp) in groups.iter().enumerate() {
            let mut d: [Vec<usize>; 6] = Default::default();
            let mut r = [false; 6];
            for (ai, &a) in ATTRS.iter().enumerate() {
                let tagged: Vec<usize> = grp
                    .members
                    .iter()
                    .copied()
                    .filter(|&k| a.has(samples[k]))
                    .collect();
                // The members of the outermost sub-zones with the attribute of their own.
                let mut excluded = std::collections::BTreeSet::new();
                let mut stack: Vec<usize> = children[g].clone();
                while let Some(c) = stack.pop() {
                    if counts[c][ai] >= min {
                        excluded.extend(groups[c].members.iter().copied());
                    } else {
                        stack.extend(children[c].iter().copied());
                    }
                }
                let left: Vec<usize> = tagged
                    .iter()
                    .copied()
                    .filter(|k| !excluded.contains(k))
                    .collect();
                if !excluded.is_empty() && left.len() >= min {
                    d[ai] = left;
                    r[ai] = true;
                } else {
                    d[ai] = tagged;
                }
            }
            data.push(d);
            rest.push(r);
        }
        // Per-kind groups: a class with `min` tagged values of an attribute in the zone; its
        // values from the class's part of what the zone's describe (the rest, when that holds
        // `min`), else of the whole zone.
        let mut counts = counts;
        let mut classes: Vec<Vec<(usize, usize)>> = vec![Vec::new(); groups.len()];
        for (g, grp) in groups.iter().enumerate() {
            for ci in 0..KIND_CLASSES.len() {
                let in_class = |k: &usize| kind_class(samples[*k].kind.as_deref()) == Some(ci);
                let mut d: [Vec<usize>; 6] = Default::default();
                let mut n = [0usize; 6];
                let mut r = [false; 6];
                let mut own = false;
                for (ai, &a) in ATTRS.iter().enumerate() {
                    let whole: Vec<usize> = grp
                        .members
                        .iter()
                        .copied()
                        .filter(|k| a.has(samples[*k]) && in_class(k))
                        .collect();
                    n[ai] = whole.len();
                    if whole.len() < min {
                        continue;
                    }
                    own |= ai < 5;
                    let left: Vec<usize> = data[g][ai].iter().copied().filter(in_class).collect();
                    if rest[g][ai] && left.len() >= min {
                        d[ai] = left;
                        r[ai] = true;
                    } else {
                        d[ai] = whole;
                    }
                }
                if own {
                    classes[g].push((ci, data.len()));
                    data.push(d);
                    rest.push(r);
                    counts.push(n);
                }
            }
        }
        // The unfiltered appearances serve `building=yes` and the classes without a group of
        // their own: for an attribute that some class draws from its own group, they are
        // learned from the buildings outside those classes (when `min` of them are tagged), so
        // that the class's values are not counted twice in the zone's mix.
        for (g, cls) in classes.iter().enumerate() {
            for ai in 0..ATTRS.len() {
                let grouped: Vec<usize> = cls
                    .iter()
                    .filter(|(_, di)| counts[*di][ai] >= min)
                    .map(|(ci, _)| *ci)
                    .collect();
                if grouped.is_empty() {
                    continue;
                }
                let left: Vec<usize> = data[g][ai]
                    .iter()
                    .copied()
                    .filter(|&k| {
                        kind_class(samples[k].kind.as_deref()).is_none_or(|c| !grouped.contains(&c))
                    })
                    .collect();
                if left.len() >= min {
                    data[g][ai] = left;
                }
            }
        }
        Writer {
            samples,
            groups,
            min,
            max_apps,
            out: String::new(),
            zones: 0,
            appearances: 0,
            kind_groups: 0,
            own: 0,
            counts,
            data,
            rest,
            children,
            classes,
            cache: Default::default(),
        }
    }

    fn index(a: Attr) -> usize {
        ATTRS.iter().position(|&x| x == a).unwrap_or(0)
    }

    fn count(&self, g: usize, a: Attr) -> usize {
        self.counts[g][Self::index(a)]
    }

    /// The group whose data give `g` attribute `a`: `g` with at least `min` tagged values, else
    /// its parent's, up to none (the built-in defaults).
    fn source(&self, g: usize, a: Attr) -> Option<usize> {
        let mut cur = Some(g);
        while let Some(c) = cur {
            if self.count(c, a) >= self.min {
                return Some(c);
            }
            cur = self.groups[c].parent;
        }
        None
    }

    /// The tagged samples group `g`'s values of `a` describe (see [`Writer::new`]).
    fn tagged<'s>(&'s self, g: usize, a: Attr) -> impl Iterator<Item = &'s Sample> + 's {
        self.data[g][Self::index(a)]
            .iter()
            .map(|&k| self.samples[k])
    }

    /// [`Writer::storeys_dist_of`], computed once per group (a big parent serves many cells).
    fn storeys_dist(&self, g: usize) -> BTreeMap<u32, f64> {
        if let Some(d) = self.cache.borrow().storeys.get(&g) {
            return d.clone();
        }
        let d = self.storeys_dist_of(g);
        self.cache.borrow_mut().storeys.insert(g, d.clone());
        d
    }

    /// [`Writer::roof_dist_of`], computed once per group.
    fn roof_dist(&self, g: usize) -> BTreeMap<&'static str, f64> {
        if let Some(d) = self.cache.borrow().roofs.get(&g) {
            return d.clone();
        }
        let d = self.roof_dist_of(g);
        self.cache.borrow_mut().roofs.insert(g, d.clone());
        d
    }

    /// [`Writer::joint_of`], computed once per pair of sources.
    fn joint(&self, ss: Option<usize>, sr: Option<usize>) -> (Joint, String) {
        if let Some(j) = self.cache.borrow().joints.get(&(ss, sr)) {
            return j.clone();
        }
        let j = self.joint_of(ss, sr);
        self.cache.borrow_mut().joints.insert((ss, sr), j.clone());
        j
    }

    fn storeys_dist_of(&self, g: usize) -> BTreeMap<u32, f64> {
        let mut m: BTreeMap<u32, f64> = BTreeMap::new();
        for s in self.tagged(g, Attr::Storeys) {
            *m.entry(s.storeys.unwrap_or(1)).or_default() += 1.0;
        }
        normalise(m)
    }

    fn roof_dist_of(&self, g: usize) -> BTreeMap<&'static str, f64> {
        let mut m: BTreeMap<&'static str, f64> = BTreeMap::new();
        for s in self.tagged(g, Attr::Roof) {
            *m.entry(roof_key(s.roof)).or_default() += 1.0;
        }
        normalise(m)
    }

    /// The joint (roof, storeys) distribution a zone's appearances draw, and how it was made.
    fn joint_of(&self, ss: Option<usize>, sr: Option<usize>) -> (Joint, String) {
        match (ss, sr) {
            (None, None) => (Joint::new(), String::new()),
            (Some(a), None) => (
                self.storeys_dist(a)
                    .into_iter()
                    .map(|(s, p)| (("", s), p))
                    .collect(),
                "storeys only (no roof shape learned)".into(),
            ),
            (None, Some(b)) => (
                self.roof_dist(b)
                    .into_iter()
                    .map(|(r, p)| ((r, 0), p))
                    .collect(),
                "roof shape only (no storeys learned)".into(),
            ),
            (Some(a), Some(b)) => {
                let rows = self.storeys_dist(a);
                let cols = self.roof_dist(b);
                let roofed: std::collections::BTreeSet<usize> = self.data[b]
                    [Self::index(Attr::Roof)]
                .iter()
                .copied()
                .collect();
                let both: Vec<&Sample> = self.data[a][Self::index(Attr::Storeys)]
                    .iter()
                    .filter(|k| roofed.contains(k))
                    .map(|&k| self.samples[k])
                    .collect();
                if a == b && both.len() >= self.min {
                    let mut seed: BTreeMap<(u32, &'static str), f64> = BTreeMap::new();
                    for s in &both {
                        *seed
                            .entry((s.storeys.unwrap_or(1), roof_key(s.roof)))
                            .or_default() += 1.0;
                    }
                    (
                        fit_joint(&seed, &rows, &cols),
                        format!(
                            "storeys and roof shape jointly: the {} buildings tagged with both, \
                             fitted to the two distributions",
                            both.len()
                        ),
                    )
                } else {
                    let mut j = Joint::new();
                    for (s, ps) in &rows {
                        for (r, pr) in &cols {
                            j.insert((r, *s), ps * pr);
                        }
                    }
                    (
                        j,
                        format!(
                            "storeys and roof shape independently ({} buildings tagged with both, \
                             fewer than {} or from different zones)",
                            both.len(),
                            self.min
                        ),
                    )
                }
            }
        }
    }

    /// The samples of group `src` tagged with `a` that match a bin (its roof and storeys range).
    fn matching<'s>(
        &'s self,
        src: usize,
        a: Attr,
        bin: &'s Bin,
    ) -> impl Iterator<Item = &'s Sample> + 's {
        self.tagged(src, a).filter(move |s| {
            let roof_ok = bin.roof.is_empty() || roof_key(s.roof) == bin.roof;
            let storeys_ok =
                bin.hi == 0 || s.storeys.is_some_and(|n| (bin.lo..=bin.hi).contains(&n));
            roof_ok && storeys_ok
        })
    }

    /// The colour (or material) `a` of group `g`'s appearance `bin` (`None`: of its info): the
    /// most frequent among the bin's buildings when the attribute is `g`'s own and
    /// [`MIN_PER_APPEARANCE`] of them are tagged, else the most frequent of the source's.
    fn colour_for(
        &self,
        g: usize,
        src: Option<usize>,
        a: Attr,
        bin: Option<&Bin>,
    ) -> Option<String> {
        let src = src?;
        let get = |s: &Sample| match a {
            Attr::WallColour => s.wall_colour.clone(),
            Attr::RoofColour => s.roof_colour.clone(),
            _ => s.material.clone(),
        };
        if let Some(b) = bin.filter(|_| src == g) {
            let own: Vec<String> = self.matching(src, a, b).filter_map(get).collect();
            if own.len() >= MIN_PER_APPEARANCE {
                return mode(own.iter().map(String::as_str));
            }
        }
        let key = (src, Self::index(a));
        if let Some(c) = self.cache.borrow().modes.get(&key) {
            return c.clone();
        }
        let all: Vec<String> = self.tagged(src, a).filter_map(get).collect();
        let c = mode(all.iter().map(String::as_str));
        self.cache.borrow_mut().modes.insert(key, c.clone());
        c
    }

    /// The floor height of group `g`'s appearance `bin` (`None`: of its info), as
    /// [`Writer::colour_for`] with the median.
    fn floor_for(&self, g: usize, src: Option<usize>, bin: Option<&Bin>) -> Option<f64> {
        let src = src?;
        if let Some(b) = bin.filter(|_| src == g) {
            let own: Vec<f64> = self
                .matching(src, Attr::FloorHeight, b)
                .filter_map(|s| s.floor_height)
                .collect();
            if own.len() >= MIN_PER_APPEARANCE {
                return median(own);
            }
        }
        if let Some(f) = self.cache.borrow().floors.get(&src) {
            return *f;
        }
        let f = median(
            self.tagged(src, Attr::FloorHeight)
                .filter_map(|s| s.floor_height)
                .collect(),
        );
        self.cache.borrow_mut().floors.insert(src, f);
        f
    }

    fn line(&mut self, indent: usize, text: &str) {
        for _ in 0..indent {
            self.out.push_str("  ");
        }
        self.out.push_str(text);
        self.out.push('\n');
    }

    fn header(&mut self, o: &LearnOptions<'_>, any: bool) {
        self.out
            .push_str("<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<!--\n");
        let grouping = match o.grouping {
            Grouping::Grid { metres } => format!(
                "a grid of {} m cells (rows of {} m of latitude, each cut into columns of {} m \
                 at its middle latitude: lon/lat rectangles), the extract being one town",
                num(metres, 3),
                num(metres, 3),
                num(metres, 3)
            ),
            Grouping::Zones(kb) => format!("the zones of {}", kb.source()),
        };
        let lines = [
            format!(
                "Learned by `citygen kb learn` from {} ({}): {} buildings.",
                o.name,
                o.source,
                self.samples.len()
            ),
            format!("Grouping: {grouping}."),
            format!(
                "A zone with fewer than {} tagged values of an attribute takes it from its parent \
                 (up to the built-in defaults, where the attribute is not written).",
                self.min
            ),
            "Each <info> states the values in force in its zone (its own or its parent's): \
             nbfloor the median storeys (building:levels), rooftype the most frequent \
             roof:shape, floorsize the median of (height - roof:height) / building:levels, \
             color, roofColor and material the most frequent building:colour, roof:colour and \
             building:material."
                .into(),
            format!(
                "Appearances, drawn by proba, reproduce the distribution of (storeys, roof \
                 shape); at most {} per zone and group, the rare tail merged as each zone says. Colours \
                 and floorsize per appearance from its own buildings when {} or more are \
                 tagged (in a zone where they are its own), else the zone's. A zone without appearances uses its parent's.",
                self.max_apps, MIN_PER_APPEARANCE
            ),
            format!(
                "Per building=* kind class (houses; flats and commercial; industrial): where a \
                 zone's buildings of one class have {} or more tagged values of their own, the \
                 class has its own appearances, with building=\"...\" naming the class's kinds, \
                 learned from that class's buildings only (what it has too few of: the zone's). \
                 The appearances without a building list are learned from all buildings and \
                 serve building=yes, other kinds and the classes without their own.",
                self.min
            ),
            "Edit freely, then check it with citygen's kb check in strict mode.".into(),
        ];
        for l in lines {
            let text = comment_text(&l);
            let _ = writeln!(self.out, "  {text}");
        }
        if !any {
            let _ = writeln!(
                self.out,
                "  {}",
                comment_text(
                    "No building of the extract is tagged with building:levels, roof:shape, \
                     height, building:colour, roof:colour or building:material: nothing to \
                     learn. The earth below holds the built-in defaults."
                )
            );
        }
        self.out.push_str("-->\n");
    }

    /// The KB when nothing was learned: earth with the built-in defaults.
    fn defaults_only(&mut self) {
        self.zones = 1;
        let info = format!(
            "<info color=\"{}\" nbfloor=\"{}\" floorsize=\"{}\" rooftype=\"{}\" roofColor=\"{}\"/>",
            color_word(defaults::WALL_COLOR),
            defaults::STOREYS,
            num(defaults::FLOOR_HEIGHT, 2),
            defaults::ROOF.osm_name(),
            color_word(defaults::ROOF_COLOR)
        );
        self.line(0, "<earth>");
        self.line(1, &info);
        self.line(0, "</earth>");
    }

    fn group(&mut self, g: usize, indent: usize) {
        self.zones += 1;
        let groups = self.groups;
        let grp = &groups[g];
        let element = grp.element;
        let src: Vec<Option<usize>> = ATTRS.iter().map(|&a| self.source(g, a)).collect();
        let src_of = |a: Attr| src[ATTRS.iter().position(|&x| x == a).unwrap_or(0)];
        let own_any = ATTRS[..5].iter().any(|&a| src_of(a) == Some(g));
        if ATTRS.iter().any(|&a| src_of(a) == Some(g)) {
            self.own += 1;
        }
        // The comment: counts, sources, kinds.
        let mut parts = Vec::new();
        for &a in &ATTRS {
            let n = self.count(g, a);
            let from = match src_of(a) {
                Some(s) if s == g && self.rest[g][Self::index(a)] => format!(
                    " (values from the {} outside sub-zones of their own)",
                    self.data[g][Self::index(a)].len()
                ),
                Some(s) if s == g => String::new(),
                Some(s) => format!(" (from {})", self.groups[s].name),
                None => " (built-in default)".into(),
            };
            parts.push(format!("{} {n}{from}", a.name()));
        }
        let mut kinds: BTreeMap<&str, usize> = BTreeMap::new();
        for &k in &grp.members {
            *kinds
                .entry(self.samples[k].kind.as_deref().unwrap_or("(none)"))
                .or_default() += 1;
        }
        let mut kinds: Vec<(&str, usize)> = kinds.into_iter().collect();
        kinds.sort_by(|a, b| b.1.cmp(&a.1).then(a.0.cmp(b.0)));
        let kind_list: Vec<String> = kinds
            .iter()
            .take(6)
            .map(|(k, n)| format!("{k} {n}"))
            .collect();
        let more = if kinds.len() > 6 {
            format!(", {} more kinds", kinds.len() - 6)
        } else {
            String::new()
        };
        let open = if element == "earth" {
            "<earth>".to_string()
        } else {
            format!("<{element} designation=\"{}\">", escape(&grp.name))
        };
        self.line(indent, &open);
        let inner = indent + 1;
        if grp.members.is_empty() {
            self.line(inner, "<!-- Built-in defaults: no building of its own. -->");
        }
        let comment = format!(
            "<!-- {}: {} buildings; tagged: {}. Kinds (building=*): {}{}. -->",
            comment_text(&grp.name),
            grp.members.len(),
            parts.join(", "),
            comment_text(&kind_list.join(", ")),
            comment_text(&more)
        );
        if !grp.members.is_empty() {
            self.line(inner, &comment);
        }
        // <info>: shape and the values in force.
        let mut info = String::from("<info");
        if let Shape::Kept {
            circle: Some((lat, lon, km)),
            ..
        } = &grp.shape
        {
            let _ = write!(
                info,
                " lat=\"{}\" lon=\"{}\" dist=\"{}\"",
                coord(*lat),
                coord(*lon),
                num(*km, 6)
            );
        }
        let ss = src_of(Attr::Storeys);
        let sr = src_of(Attr::Roof);
        if let Some(s) = ss {
            let d = self.storeys_dist(s);
            let mut acc = 0.0;
            let med = d
                .iter()
                .find(|(_, p)| {
                    acc += *p;
                    acc >= 0.5 - 1e-9
                })
                .map(|(n, _)| *n);
            if let Some(n) = med {
                let _ = write!(info, " nbfloor=\"{n}\"");
            }
        }
        if let Some(f) = self.floor_for(g, src_of(Attr::FloorHeight), None) {
            let _ = write!(info, " floorsize=\"{}\"", num(f, 2));
        }
        if let Some(r) = sr {
            let d = self.roof_dist(r);
            let mut best: Option<(&str, f64)> = None;
            for (k, p) in d {
                if best.is_none_or(|(_, b)| p > b) {
                    best = Some((k, p));
                }
            }
            if let Some((k, _)) = best {
                let _ = write!(info, " rooftype=\"{k}\"");
            }
        }
        for (attr, a) in [
            ("color", Attr::WallColour),
            ("roofColor", Attr::RoofColour),
            ("material", Attr::Material),
        ] {
            if let Some(c) = self.colour_for(g, src_of(a), a, None) {
                let _ = write!(info, " {attr}=\"{}\"", escape(&c));
            }
        }
        info.push_str("/>");
        if info != "<info/>" {
            self.line(inner, &info);
        }
        match &grp.shape {
            Shape::Rect([w, s, e, n]) => {
                let (w, s, e, n) = (coord(*w), coord(*s), coord(*e), coord(*n));
                let p = format!("<polygon points=\"{w} {s}, {e} {s}, {e} {n}, {w} {n}\"/>");
                self.line(inner, &p);
            }
            Shape::Kept { polygons, .. } => {
                for ring in polygons {
                    let pts: Vec<String> = ring
                        .iter()
                        .map(|[lon, lat]| format!("{} {}", coord(*lon), coord(*lat)))
                        .collect();
                    let p = format!("<polygon points=\"{}\"/>", pts.join(", "));
                    self.line(inner, &p);
                }
            }
            Shape::Earth => {}
        }
        // Appearances.
        if own_any {
            self.appearances_of(g, &src, inner, None);
            for (ci, v) in self.classes[g].clone() {
                let class_src: Vec<Option<usize>> = ATTRS
                    .iter()
                    .enumerate()
                    .map(|(ai, _)| {
                        if self.counts[v][ai] >= self.min {
                            Some(v)
                        } else {
                            src[ai]
                        }
                    })
                    .collect();
                self.appearances_of(v, &class_src, inner, Some(ci));
                self.kind_groups += 1;
            }
        } else if grp.parent.is_some() {
            self.line(
                inner,
                "<!-- No attribute of its own (too few tags): the appearances above apply. -->",
            );
        }
        for c in self.children[g].clone() {
            self.group(c, inner);
        }
        if element == "earth" {
            self.line(indent, "</earth>");
        } else {
            self.line(indent, &format!("</{element}>"));
        }
    }

    /// Writes the appearances of `g` (a zone, or a per-kind group for `class`), whose values
    /// come from `src` (per attribute).
    fn appearances_of(
        &mut self,
        g: usize,
        src: &[Option<usize>],
        indent: usize,
        class: Option<usize>,
    ) {
        let at = |a: Attr| src[ATTRS.iter().position(|&x| x == a).unwrap_or(0)];
        let (joint, how) = self.joint(at(Attr::Storeys), at(Attr::Roof));
        let (mut bins, notes) = if joint.is_empty() {
            // Colours or floor heights alone: one appearance.
            (
                vec![Bin {
                    roof: "",
                    lo: 0,
                    hi: 0,
                    mass: 1.0,
                }],
                Vec::new(),
            )
        } else {
            merge_bins(&joint, self.max_apps)
        };
        let units = round_probas(&bins.iter().map(|b| b.mass).collect::<Vec<_>>());
        let mut dropped = 0;
        let mut kept: Vec<(Bin, u32)> = Vec::new();
        for (b, u) in bins.drain(..).zip(units) {
            if u == 0 {
                dropped += 1;
            } else {
                kept.push((b, u));
            }
        }
        kept.sort_by(|(a, ua), (b, ub)| ub.cmp(ua).then(a.roof.cmp(b.roof)).then(a.lo.cmp(&b.lo)));
        let mut about = Vec::new();
        if let Some(ci) = class {
            let own: Vec<String> = ATTRS[..5]
                .iter()
                .enumerate()
                .filter(|&(ai, _)| src[ai] == Some(g))
                .map(|(ai, a)| format!("{} {}", a.name(), self.counts[g][ai]))
                .collect();
            about.push(format!(
                "for {} (building={}), from their tagged values: {}; the rest as the zone's",
                KIND_CLASSES[ci].0,
                KIND_CLASSES[ci].1.join(","),
                own.join(", ")
            ));
        }
        if !how.is_empty() {
            about.push(how);
        }
        about.extend(notes);
        if dropped > 0 {
            about.push(format!("{dropped} combinations under 0.00005 left out"));
        }
        if !about.is_empty() {
            let c = format!("<!-- Appearances: {}. -->", comment_text(&about.join("; ")));
            self.line(indent, &c);
        }
        for (b, u) in kept {
            let with_bin = (!joint.is_empty()).then_some(&b);
            let mut v = format!("<values proba=\"{}\"", num(f64::from(u) / 10_000.0, 4));
            if !b.roof.is_empty() {
                let _ = write!(v, " bdRooftype=\"{}\"", b.roof);
            }
            if b.hi > 0 {
                let _ = write!(v, " minFloors=\"{}\" maxFloors=\"{}\"", b.lo, b.hi);
            }
            if let Some(f) = self.floor_for(g, at(Attr::FloorHeight), with_bin) {
                let _ = write!(v, " floorsize=\"{}\"", num(f, 2));
            }
            for (attr, a) in [("color", Attr::WallColour), ("roofColor", Attr::RoofColour)] {
                if let Some(c) = self.colour_for(g, at(a), a, with_bin) {
                    let _ = write!(v, " {attr}=\"{}\"", escape(&c));
                }
            }
            v.push_str("/>");
            let open = match class {
                Some(ci) => format!("<appearance building=\"{}\">", KIND_CLASSES[ci].1.join(",")),
                None => "<appearance>".to_string(),
            };
            self.line(indent, &open);
            self.line(indent + 1, &v);
            self.line(indent, "</appearance>");
            self.appearances += 1;
        }
    }
}

fn normalise<K: Ord>(m: BTreeMap<K, f64>) -> BTreeMap<K, f64> {
    let total: f64 = m.values().sum();
    if total <= 0.0 {
        return m;
    }
    m.into_iter().map(|(k, v)| (k, v / total)).collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::kb::ReadMode;

    fn sample(lon: f64, lat: f64, storeys: Option<u32>, roof: Option<RoofShape>) -> Sample {
        Sample {
            lonlat: (lon, lat),
            storeys,
            roof,
            ..Sample::default()
        }
    }

    fn grid(metres: f64, min: usize) -> LearnOptions<'static> {
        LearnOptions {
            grouping: Grouping::Grid { metres },
            min_samples: min,
            max_appearances: DEFAULT_MAX_APPEARANCES,
            name: "test".into(),
            source: "test.osm.pbf".into(),
        }
    }

    fn strict(text: &str) -> KnowledgeBase {
        match KnowledgeBase::parse_str_with(text, "learned.xml", ReadMode::Strict) {
            Ok((kb, _)) => kb,
            Err(e) => panic!("{e}\n{text}"),
        }
    }

    /// Metres to degrees of latitude.
    fn deg(m: f64) -> f64 {
        m / (KM_PER_DEG * 1000.0)
    }

    #[test]
    fn grid_bins_points_into_the_cells_the_kb_locates_them_in() {
        // 3 x 3 points 400 m apart on a 500 m grid at 43.7° N: every point in its own cell
        // (the anchor is the south-west point), and the learned KB locates it there.
        let mut samples = Vec::new();
        for r in 0..3 {
            for c in 0..3 {
                let lat = 43.7 + deg(10.0 + 600.0 * f64::from(r));
                let lon = 7.4 + deg(10.0 + 600.0 * f64::from(c)) / 43.7f64.to_radians().cos();
                samples.push(sample(lon, lat, Some(r * 3 + c + 1), None));
            }
        }
        let l = learn(&samples, &grid(500.0, 1)).unwrap();
        assert_eq!(l.zones, 2 + 9, "{}", l.text);
        let kb = strict(&l.text);
        let mut seen = std::collections::BTreeSet::new();
        for s in &samples {
            let z = kb.locate(s.lonlat.0, s.lonlat.1);
            let zone = kb.zone(z).unwrap();
            assert_eq!(zone.kind, ZoneKind::District, "{}", zone.path);
            // Each cell has its one building's storeys as its own appearance.
            let (owner, apps) = kb.appearances_for(z);
            assert_eq!(owner, z);
            assert_eq!(apps.len(), 1);
            assert_eq!(apps[0].values.min_floors, s.storeys);
            seen.insert(z);
        }
        assert_eq!(seen.len(), 9);
        // Two points 100 m apart share a cell.
        let two = [
            sample(7.4, 43.7, Some(2), None),
            sample(7.4 + deg(100.0), 43.7, Some(3), None),
        ];
        let l = learn(&two, &grid(500.0, 1)).unwrap();
        assert_eq!(l.zones, 3);
    }

    #[test]
    fn cells_with_too_few_samples_inherit_from_the_extract() {
        // Cell A: 30 buildings, 5 storeys, flat. Cell B (2 km east): 4 buildings, 2 storeys,
        // gabled. With min 20, B has too few of either and takes the extract's distribution.
        let mut samples = Vec::new();
        for k in 0..30 {
            samples.push(sample(
                7.4 + deg(f64::from(k)),
                43.7,
                Some(5),
                Some(RoofShape::Flat),
            ));
        }
        for k in 0..4 {
            samples.push(sample(
                7.4 + deg(2000.0 + f64::from(k)),
                43.7,
                Some(2),
                Some(RoofShape::Gabled),
            ));
        }
        let l = learn(&samples, &grid(500.0, 20)).unwrap();
        let kb = strict(&l.text);
        let town = kb.find("earth/test").unwrap();
        let a = kb.locate(samples[0].lonlat.0, samples[0].lonlat.1);
        let b = kb.locate(samples[31].lonlat.0, samples[31].lonlat.1);
        assert_ne!(a, b);
        // A: its own, one appearance 5 storeys flat.
        let (owner_a, apps_a) = kb.appearances_for(a);
        assert_eq!(owner_a, a);
        assert_eq!(apps_a.len(), 1);
        assert_eq!(apps_a[0].values.roof, Some(RoofShape::Flat));
        // B: none of its own: the town's, 30/34 and 4/34.
        let (owner_b, apps_b) = kb.appearances_for(b);
        assert_eq!(owner_b, town, "{}", l.text);
        let probas: Vec<f64> = apps_b.iter().map(|x| x.proba.unwrap()).collect();
        assert_eq!(probas, vec![0.8824, 0.1176]);
        assert_eq!(apps_b[1].values.min_floors, Some(2));
        // The info of B states the inherited values.
        assert_eq!(kb.resolved(b).storeys, Some(5));
        assert!(l.text.contains("storeys 4 (from test)"), "{}", l.text);
        // Below the minimum everywhere: built-in defaults, nothing learned.
        let l = learn(&samples, &grid(500.0, 100)).unwrap();
        assert_eq!(l.appearances, 0, "{}", l.text);
        assert!(l.text.contains("storeys 34 (built-in default)"));
        strict(&l.text);
    }

    #[test]
    fn the_rare_tail_merges_into_ranges_and_probas_sum_to_one() {
        // 40 storeys values of one roof and a rare roof: at most 12 appearances.
        let mut joint = Joint::new();
        for s in 1..=40u32 {
            joint.insert(("flat", s), 1.0 / f64::from(s));
        }
        joint.insert(("dome", 3), 0.05);
        let total: f64 = joint.values().sum();
        joint.values_mut().for_each(|v| *v /= total);
        let (bins, notes) = merge_bins(&joint, 12);
        assert_eq!(bins.len(), 12);
        let mass: f64 = bins.iter().map(|b| b.mass).sum();
        assert!((mass - 1.0).abs() < 1e-12);
        // The common low storeys stay exact, the tail is a range.
        assert!(bins
            .iter()
            .any(|b| b.roof == "flat" && b.lo == 1 && b.hi == 1));
        assert!(bins.iter().any(|b| b.hi == 40 && b.lo < 40));
        // Ranges of one roof cover its storeys without gaps or overlaps.
        let flat: Vec<&Bin> = bins.iter().filter(|b| b.roof == "flat").collect();
        for w in flat.windows(2) {
            assert_eq!(w[0].hi + 1, w[1].lo);
        }
        assert!(
            notes[0].contains("from 41 (storeys, roof) combinations"),
            "{notes:?}"
        );
        let units = round_probas(&bins.iter().map(|b| b.mass).collect::<Vec<_>>());
        assert_eq!(units.iter().sum::<u32>(), 10_000);
        // Folding: 13 roofs of one storey each into 12 appearances folds the rarest.
        let roofs = [
            "flat",
            "gabled",
            "hipped",
            "dome",
            "onion",
            "round",
            "cone",
            "skillion",
            "pyramidal",
            "mansard",
            "gambrel",
            "saltbox",
            "half-hipped",
        ];
        let mut joint = Joint::new();
        for (k, r) in roofs.iter().enumerate() {
            joint.insert((r, 2), if k == 4 { 0.001 } else { 1.0 });
        }
        let (bins, notes) = merge_bins(&joint, 12);
        assert_eq!(bins.len(), 12);
        assert!(!bins.iter().any(|b| b.roof == "onion"));
        assert!(notes[0].contains("roof onion"), "{notes:?}");
    }

    #[test]
    fn joint_fit_keeps_both_marginals() {
        let mut seed = BTreeMap::new();
        seed.insert((2, "gabled"), 8.0);
        seed.insert((5, "flat"), 2.0);
        let rows: BTreeMap<u32, f64> = [(2, 0.5), (5, 0.3), (9, 0.2)].into();
        let cols: BTreeMap<&'static str, f64> = [("flat", 0.6), ("gabled", 0.4)].into();
        let j = fit_joint(&seed, &rows, &cols);
        for (s, p) in &rows {
            let m: f64 = j.iter().filter(|((_, k), _)| k == s).map(|(_, v)| v).sum();
            assert!((m - p).abs() < 1e-4, "storeys {s}: {m}");
        }
        for (r, p) in &cols {
            let m: f64 = j.iter().filter(|((k, _), _)| k == r).map(|(_, v)| v).sum();
            assert!((m - p).abs() < 1e-4, "roof {r}: {m}");
        }
    }

    #[test]
    fn learning_is_deterministic_and_strict_valid() {
        let mut samples = Vec::new();
        let roofs = [RoofShape::Flat, RoofShape::Hipped, RoofShape::Gabled];
        for k in 0..500u32 {
            let x = f64::from(k % 25) * 97.0;
            let y = f64::from(k / 25) * 83.0;
            let mut s = sample(
                7.4 + deg(x) / 0.72,
                43.7 + deg(y),
                (k % 7 != 0).then_some(1 + (k * 7919) % 23),
                (k % 3 != 0).then_some(roofs[(k as usize * 31) % 3]),
            );
            s.wall_colour = (k % 4 == 0).then(|| ["white", "#f3e5c0"][(k % 8 / 4) as usize].into());
            s.floor_height = (k % 5 == 0).then_some(2.8 + f64::from(k % 3) * 0.2);
            s.material = (k % 6 == 0).then(|| "plaster".into());
            s.kind = Some(["apartments", "yes", "house"][(k % 3) as usize].into());
            samples.push(s);
        }
        let a = learn(&samples, &grid(500.0, 20)).unwrap();
        let mut reversed = samples.clone();
        reversed.reverse();
        let b = learn(&samples, &grid(500.0, 20)).unwrap();
        assert_eq!(a.text, b.text);
        // Input order changes nothing but the order of equal-key samples.
        let c = learn(&reversed, &grid(500.0, 20)).unwrap();
        assert_eq!(a.text, c.text);
        let kb = strict(&a.text);
        let mut kind_groups = 0;
        for z in kb.zones() {
            // Per group (the appearances with one `building` list): the cap, probas summing to 1.
            let mut groups: BTreeMap<Vec<String>, Vec<f64>> = BTreeMap::new();
            for x in &z.appearances {
                groups
                    .entry(x.buildings.clone())
                    .or_default()
                    .push(x.proba.unwrap());
            }
            for (list, probas) in &groups {
                assert!(probas.len() <= DEFAULT_MAX_APPEARANCES, "{}", z.path);
                let sum: f64 = probas.iter().sum();
                assert!((sum - 1.0).abs() < 1e-9, "{} {list:?}: {sum}", z.path);
                kind_groups += usize::from(!list.is_empty());
            }
        }
        assert_eq!(kind_groups, a.kind_groups);
        assert!(a.kind_groups > 0, "{}", a.text);
        let r = crate::kb::tools::report_for(&kb, ReadMode::Strict, Vec::new(), false);
        assert!(r.warnings.is_empty() && r.errors.is_empty(), "{r}");
    }

    #[test]
    fn a_kind_class_with_enough_samples_gets_its_own_group() {
        // One cell: 30 houses of 2 storeys, gabled; 25 apartments of 8 storeys, flat; 5 sheds
        // of 1 storey (too few for a group); 10 `yes` of 4 storeys. With min 20: a group for
        // houses, one for flats, none for industrial; the unfiltered group from all 70 (in the
        // town and in its cell alike): the 15 outside the grouped classes are under 20.
        let mut samples = Vec::new();
        let mut add = |n: u32, kind: &str, storeys: u32, roof: RoofShape| {
            for k in 0..n {
                let mut s = sample(7.4 + deg(f64::from(k)), 43.7, Some(storeys), Some(roof));
                s.kind = Some(kind.into());
                samples.push(s);
            }
        };
        add(30, "house", 2, RoofShape::Gabled);
        add(25, "apartments", 8, RoofShape::Flat);
        add(5, "shed", 1, RoofShape::Flat);
        add(10, "yes", 4, RoofShape::Flat);
        let l = learn(&samples, &grid(500.0, 20)).unwrap();
        // The town and its one cell, two each.
        assert_eq!(l.kind_groups, 4, "{}", l.text);
        let kb = strict(&l.text);
        let z = kb.locate(samples[0].lonlat.0, samples[0].lonlat.1);
        let (owner, apps) = kb.appearances_for(z);
        let houses: Vec<String> = KIND_CLASSES[0].1.iter().map(|k| k.to_string()).collect();
        let flats: Vec<String> = KIND_CLASSES[1].1.iter().map(|k| k.to_string()).collect();
        // A house: only its class's appearance, 2 storeys gabled.
        let (_, h) = kb.eligible_appearances(z, Some("detached"));
        assert_eq!(h.len(), 1, "{}", l.text);
        assert_eq!(apps[h[0]].buildings, houses);
        assert_eq!(apps[h[0]].values.min_floors, Some(2));
        assert_eq!(apps[h[0]].values.roof, Some(RoofShape::Gabled));
        let (_, f) = kb.eligible_appearances(z, Some("office"));
        assert_eq!(apps[f[0]].buildings, flats);
        assert_eq!(apps[f[0]].values.min_floors, Some(8));
        // A shed (its class has no group) and `yes`: the unfiltered appearances, from all 70.
        let (_, s) = kb.eligible_appearances(z, Some("shed"));
        let (_, y) = kb.eligible_appearances(z, None);
        assert_eq!(s, y);
        assert!(s.iter().all(|&i| apps[i].buildings.is_empty()));
        let storeys: std::collections::BTreeSet<Option<u32>> =
            s.iter().map(|&i| apps[i].values.min_floors).collect();
        assert_eq!(storeys.len(), 4, "{}", l.text);
        // No industrial list anywhere.
        assert!(!kb
            .zones()
            .iter()
            .flat_map(|z| &z.appearances)
            .any(|a| a.buildings.iter().any(|b| b == "shed")));
        let _ = owner;
        // With 25 `yes` more (40 outside the grouped classes): the unfiltered group is learned
        // from those alone, so the houses' 2 and the flats' 8 storeys are not counted twice.
        let mut more = samples.clone();
        for k in 0..25 {
            let mut s = sample(
                7.4 + deg(f64::from(100 + k)),
                43.7,
                Some(4),
                Some(RoofShape::Flat),
            );
            s.kind = Some("yes".into());
            more.push(s);
        }
        let l = learn(&more, &grid(500.0, 20)).unwrap();
        let kb = strict(&l.text);
        let z = kb.locate(more[0].lonlat.0, more[0].lonlat.1);
        let (_, apps) = kb.appearances_for(z);
        let (_, y) = kb.eligible_appearances(z, None);
        let storeys: std::collections::BTreeSet<Option<u32>> =
            y.iter().map(|&i| apps[i].values.min_floors).collect();
        assert!(
            !storeys.contains(&Some(2)) && !storeys.contains(&Some(8)),
            "{}",
            l.text
        );
        // With min 26: only the houses (30) have enough.
        let l = learn(&samples, &grid(500.0, 26)).unwrap();
        assert_eq!(l.kind_groups, 2, "{}", l.text);
        strict(&l.text);
        assert_eq!(kind_class(Some("Terrace")), Some(0));
        assert_eq!(kind_class(Some("yes")), None);
        assert_eq!(kind_class(None), None);
    }

    #[test]
    fn nothing_to_learn_gives_the_defaults_or_an_error() {
        assert!(learn(&[], &grid(500.0, 20)).is_err());
        let bare = [sample(7.4, 43.7, None, None)];
        let l = learn(&bare, &grid(500.0, 20)).unwrap();
        assert!(l.text.contains("nothing to"), "{}", l.text);
        let kb = strict(&l.text);
        assert_eq!(kb.zones().len(), 1);
        assert!(learn(&bare, &grid(0.0, 20)).is_err());
        let polar = [sample(7.4, 88.0, Some(2), None)];
        assert!(learn(&polar, &grid(500.0, 1)).is_err());
        let wide = [
            sample(-179.0, 10.0, Some(2), None),
            sample(179.0, 10.0, Some(2), None),
        ];
        assert!(learn(&wide, &grid(500.0, 1)).is_err());
    }

    #[test]
    fn zones_of_a_kb_group_and_inherit_along_its_tree() {
        let kb_text = r#"<earth><town designation="A &amp; B"><info lat="43.7" lon="7.4" dist="2"/>
            <district designation="Core"><polygon points="7.39 43.69, 7.41 43.69, 7.41 43.71, 7.39 43.71"/></district>
            <district designation="Empty"><info lat="10" lon="10" dist="1"/></district>
            </town></earth>"#;
        let (zkb, _) = KnowledgeBase::parse_str(kb_text, "zones.xml").unwrap();
        let mut samples = Vec::new();
        for k in 0..25 {
            samples.push(sample(7.4, 43.7 + deg(f64::from(k)), Some(3), None));
        }
        for k in 0..5 {
            samples.push(sample(7.42, 43.7 + deg(f64::from(k)), Some(8), None));
        }
        samples.push(sample(0.0, 0.0, Some(1), None));
        let o = LearnOptions {
            grouping: Grouping::Zones(&zkb),
            ..grid(500.0, 20)
        };
        let l = learn(&samples, &o).unwrap();
        let kb = strict(&l.text);
        let paths: Vec<&str> = kb.zones().iter().map(|z| z.path.as_str()).collect();
        assert_eq!(paths, ["earth", "earth/A & B", "earth/A & B/Core"]);
        // Earth holds all 31, the town 30 (its own distribution), Core 25.
        let core = kb.find("earth/A & B/Core").unwrap();
        assert_eq!(kb.zone(core).unwrap().appearances.len(), 1);
        let town = kb.find("earth/A & B").unwrap();
        assert_eq!(kb.zone(town).unwrap().appearances.len(), 2);
        assert_eq!(kb.locate(7.42, 43.7), town);
    }

    #[test]
    fn samples_read_the_tags_as_the_generator_does() {
        let t = BuildingTags {
            levels: Some(4.6),
            min_level: Some(1.0),
            height: Some(14.0),
            roof_shape: Some(RoofShape::Hipped),
            building: Some("apartments".into()),
            material: Some("brick & mortar".into()),
            ..BuildingTags::default()
        };
        let s = Sample::from_tags((7.4, 43.7), &t).unwrap();
        assert_eq!(s.storeys, Some(4));
        assert_eq!(s.floor_height, None, "not on the ground");
        assert_eq!(s.material, None, "not a plain word");
        let t = BuildingTags {
            levels: Some(4.0),
            height: Some(14.0),
            roof_height: Some(2.0),
            ..BuildingTags::default()
        };
        assert_eq!(
            Sample::from_tags((7.4, 43.7), &t).unwrap().floor_height,
            Some(3.0)
        );
        let roof = BuildingTags {
            building: Some("roof".into()),
            ..BuildingTags::default()
        };
        assert_eq!(Sample::from_tags((7.4, 43.7), &roof), None);
    }
}
