//! The semantic building model: the one value every writer consumes.
//!
//! A [`Building`] is built from the derived shape tree (or directly from a footprint) and holds
//! everything the IFC, CityGML and glTF writers need, already cut at the requested LOD. Writers
//! never see the grammar, the knowledge base or the input.
//!
//! Geometry is in the run's local frame: metres, X east, Y north, Z up, relative to
//! [`crate::export::OutputContext::origin`]. Every 3D face is planar and its outer ring is
//! counter-clockwise seen from outside the solid (its normal points out of the building).

use std::fmt;

use glam::{DVec2, DVec3};

use crate::color::material::Material;
use crate::color::Color;
use crate::geometry::Polygon;

/// Grid steps per metre of the output grid: the millimetre, the precision CityGML files are
/// written to (three decimals). The local origin is a whole number of metres, so a local
/// coordinate on this grid is on the output CRS's millimetre grid too.
pub(crate) const GRID_STEPS_PER_M: f64 = 1000.0;

/// Distinct vertices of a part (and of a footprint) are at least this far apart (metres) before
/// they are put on the grid: three grid steps, so that on the grid two distinct vertices are at
/// least √2 mm apart and a validator's 1 mm snapping merges none of them
/// (`derive::massing::grid`).
pub(crate) const MIN_VERTEX_GAP: f64 = 0.003;

/// A coordinate on the output grid: the nearest whole millimetre (`k / 1000` for the nearest
/// integer `k`, so that writing it to three decimals gives back `k` exactly).
pub(crate) fn on_grid(v: f64) -> f64 {
    (v * GRID_STEPS_PER_M).round() / GRID_STEPS_PER_M
}

/// A point's place on the output grid, in whole grid steps (millimetres): the integers its
/// coordinates are written as. Two points are one vertex in the files when their keys agree.
pub(crate) fn grid_key(p: glam::DVec3) -> (i64, i64, i64) {
    let s = |v: f64| (v * GRID_STEPS_PER_M).round() as i64;
    (s(p.x), s(p.y), s(p.z))
}

/// Where a footprint came from. Displayed as `way/123`, `relation/45` or `shp/7`
/// (shapefile record index, 0-based), or as the file's own text id
/// (`NL.IMBAG.Pand.0599100000012345`, `osgb1000012345678`, a GUID).
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum SourceId {
    /// An OSM closed way tagged `building` or `building:part`, by its OSM way id.
    Way(i64),
    /// An OSM `type=multipolygon` relation (a building or `building:part`), by its OSM relation
    /// id.
    Relation(i64),
    /// A shapefile record, by its 0-based index in the `.shp`.
    Shape(u64),
    /// A test lot given on the command line (`rules derive`).
    Lot(u64),
    /// A GeoJSON feature, by its own non-negative integer id or, without one, its 0-based
    /// position in the file (`input::geojson`).
    Feature(u64),
    /// A GIS feature whose id is text, not a non-negative whole number: a GUID, a Dutch BAG
    /// `identificatie`, an Ordnance Survey TOID (`input::features`). Interned ([`TextId`]), so
    /// the id stays `Copy` and as small as the others.
    Text(TextId),
}

/// A text id, interned for the life of the process: each distinct text is stored once (the
/// ids of every file read), compared, ordered and hashed by its text.
#[derive(Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct TextId(&'static String);

impl TextId {
    /// The interned id of `text`.
    pub fn new(text: &str) -> TextId {
        use std::collections::HashMap;
        use std::sync::{Mutex, OnceLock};
        static TEXTS: OnceLock<Mutex<HashMap<&'static str, &'static String>>> = OnceLock::new();
        let mut texts = TEXTS
            .get_or_init(Default::default)
            .lock()
            .unwrap_or_else(|e| e.into_inner());
        if let Some(&t) = texts.get(text) {
            return TextId(t);
        }
        let t: &'static String = Box::leak(Box::new(text.to_string()));
        texts.insert(t.as_str(), t);
        TextId(t)
    }

    /// The text.
    pub fn as_str(&self) -> &'static str {
        self.0.as_str()
    }

    /// The id as an XML-id fragment and file-safe name: the text when it is made of ASCII
    /// letters, digits, `_`, `-` and `.` only; else with every other character replaced by `_`
    /// and `_h` and eight hex digits of the text's hash appended, so that two texts that differ
    /// only there keep distinct keys.
    pub fn key(&self) -> String {
        let text = self.as_str();
        let safe = |c: char| c.is_ascii_alphanumeric() || matches!(c, '_' | '-' | '.');
        if !text.is_empty() && text.chars().all(safe) {
            return text.to_string();
        }
        let mut k: String = text
            .chars()
            .map(|c| if safe(c) { c } else { '_' })
            .collect();
        k.push_str(&format!("_h{:08x}", fnv1a(text.as_bytes()) >> 32));
        k
    }
}

impl fmt::Debug for TextId {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        fmt::Debug::fmt(self.as_str(), f)
    }
}

/// FNV-1a 64 of `bytes`: a fixed, platform-independent hash (a text id's seed and key).
fn fnv1a(bytes: &[u8]) -> u64 {
    bytes.iter().fold(0xcbf2_9ce4_8422_2325, |h, &b| {
        (h ^ u64::from(b)).wrapping_mul(0x0000_0100_0000_01b3)
    })
}

impl SourceId {
    /// `way_123`, `relation_45`, `shp_7`: usable in XML ids and file-safe names.
    pub fn key(&self) -> String {
        match self {
            SourceId::Text(t) => t.key(),
            _ => self.to_string().replace('/', "_"),
        }
    }

    /// A text id (`SourceId::Text`) of `text`.
    pub fn text(text: &str) -> SourceId {
        SourceId::Text(TextId::new(text))
    }

    /// A stable 64-bit value used to seed the building's random generator.
    pub fn seed_value(&self) -> u64 {
        match *self {
            SourceId::Way(i) => (i as u64).wrapping_mul(4).wrapping_add(1),
            SourceId::Relation(i) => (i as u64).wrapping_mul(4).wrapping_add(2),
            SourceId::Shape(i) => i.wrapping_mul(4).wrapping_add(3),
            SourceId::Lot(i) => i.wrapping_mul(4),
            // Apart from the others' streams without changing them.
            SourceId::Feature(i) => i.wrapping_mul(4).wrapping_add(3) ^ 0x9E37_79B9_7F4A_7C15,
            // The text's hash: the same text gives the same stream in every run and file.
            SourceId::Text(t) => fnv1a(t.as_str().as_bytes()) ^ 0xD1B5_4A32_D192_ED03,
        }
    }

    /// Parses `way/123`, `w123`, `relation/4`, `r4`, `shp/7`, `feature/9`.
    pub fn parse(s: &str) -> Option<SourceId> {
        let s = s.trim();
        let (kind, num) = if let Some((k, n)) = s.split_once('/') {
            (k, n)
        } else {
            let i = s.find(|c: char| c.is_ascii_digit() || c == '-')?;
            s.split_at(i)
        };
        match kind {
            "way" | "w" => num.parse().ok().map(SourceId::Way),
            "relation" | "r" => num.parse().ok().map(SourceId::Relation),
            "shp" | "shape" => num.parse().ok().map(SourceId::Shape),
            "lot" => num.parse().ok().map(SourceId::Lot),
            "feature" => num.parse().ok().map(SourceId::Feature),
            _ => None,
        }
    }
}

impl fmt::Display for SourceId {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            SourceId::Way(i) => write!(f, "way/{i}"),
            SourceId::Relation(i) => write!(f, "relation/{i}"),
            SourceId::Shape(i) => write!(f, "shp/{i}"),
            SourceId::Lot(i) => write!(f, "lot/{i}"),
            SourceId::Feature(i) => write!(f, "feature/{i}"),
            SourceId::Text(t) => f.write_str(t.as_str()),
        }
    }
}

/// The layout family of a building, from its `building=*` value or set by the knowledge base.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Programme {
    /// One dwelling over all storeys (house): public rooms on the ground floor, bedrooms above.
    House,
    /// Dwellings per storey around a common stair (and a corridor when the storey is large).
    Apartments,
    /// Office cells along a corridor (large storeys) or a reception with cells (small ones).
    Office,
    /// Shops (one or more units) with storage.
    Retail,
    /// One open room per storey (garages, sheds, warehouses, churches, unknown types).
    OpenPlan,
}

impl Programme {
    /// The programme for a `building=*` value. `yes` and missing values are dwellings: a
    /// house when the whole building is small (usable area over all storeys ≤ 200 m²),
    /// apartments otherwise.
    pub(crate) fn for_building(building: Option<&str>, total_area: f64) -> Programme {
        match building.map(|b| b.trim().to_ascii_lowercase()).as_deref() {
            Some(
                "house" | "detached" | "semidetached_house" | "semi" | "terrace" | "bungalow"
                | "villa" | "farm" | "cabin" | "hut" | "static_caravan",
            ) => Programme::House,
            Some("apartments" | "residential" | "flats" | "dormitory" | "block") => {
                Programme::Apartments
            }
            Some(
                "office" | "commercial" | "public" | "civic" | "government" | "school"
                | "university" | "college" | "hospital" | "hotel" | "bank" | "townhall"
                | "kindergarten" | "clinic",
            ) => Programme::Office,
            Some("retail" | "supermarket" | "kiosk" | "shop" | "mall" | "store") => {
                Programme::Retail
            }
            None | Some("yes" | "") => {
                if total_area <= 200.0 {
                    Programme::House
                } else {
                    Programme::Apartments
                }
            }
            Some(_) => Programme::OpenPlan,
        }
    }

    /// Parses a knowledge-base programme name (`house`, `apartments`, `office`, `retail`,
    /// `open`/`openplan`), case-insensitively.
    pub fn parse(s: &str) -> Option<Programme> {
        match s.trim().to_ascii_lowercase().as_str() {
            "house" | "dwelling" => Some(Programme::House),
            "apartments" | "flats" => Some(Programme::Apartments),
            "office" => Some(Programme::Office),
            "retail" | "shop" => Some(Programme::Retail),
            "open" | "openplan" | "open-plan" | "open_plan" => Some(Programme::OpenPlan),
            _ => None,
        }
    }
}

/// What a building or part is when it is not a house (issue 45): a structure gets none of a
/// house's programme. Decided once in `prepare` (`prepare::structure`) from the tags and the
/// footprint's size, carried on the parsed tags (`input::BuildingTags::structure`) and on
/// every derived [`Part::structure`]; `derive` honours it: no window, door or balcony (a tower
/// keeps only the openings of its top storey), no interior at LOD4, and a roof is drawn as its
/// slab with nothing under it. The table of tags is in docs/structures.md.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Structure {
    /// A monument or memorial: `man_made=obelisk`, `building=monument|memorial|obelisk|statue`,
    /// or `historic=monument|memorial` on a building that is not a house (see the docs).
    /// Solid, no openings.
    Monument,
    /// A column or pillar: `man_made=column`, `building=column|pillar`,
    /// `building:part=column|pillar`. Solid, no openings.
    Column,
    /// A tower: `man_made=tower|lighthouse`, a `tower:type`, `building=tower|bell_tower|
    /// campanile|minaret|lighthouse`, or a tower part of a place of worship. Openings only on
    /// its top storey (a belfry, a lantern, a platform), no door, no rooms.
    Tower,
    /// A roof with nothing under it: `building=roof|carport|canopy`,
    /// `building:part=roof|canopy`. Drawn as its roof slab; no walls of a storey, no openings.
    Roof,
    /// A bridge: `building=bridge`, `man_made=bridge`, `building:part=bridge`. Solid, no
    /// openings.
    Bridge,
    /// A building or part too small for a room (under [`SMALL_AREA`] square metres, or
    /// narrower than [`SMALL_WIDTH`]). Solid, no openings.
    Small,
}

/// A footprint under this area (square metres) holds no room: a [`Structure::Small`].
pub const SMALL_AREA: f64 = 4.0;
/// A footprint narrower than this (metres, its extent across its principal axis) holds no
/// room: a [`Structure::Small`].
pub const SMALL_WIDTH: f64 = 1.5;

impl Structure {
    /// The class as the writers and the report name it: `monument`, `column`, `tower`,
    /// `roof`, `bridge`, `small`.
    pub fn name(self) -> &'static str {
        match self {
            Structure::Monument => "monument",
            Structure::Column => "column",
            Structure::Tower => "tower",
            Structure::Roof => "roof",
            Structure::Bridge => "bridge",
            Structure::Small => "small",
        }
    }

    /// Whether it keeps any opening: a tower keeps those of its top storey; every other
    /// structure none.
    pub fn keeps_top_openings(self) -> bool {
        self == Structure::Tower
    }
}

/// Level of detail of a run (seed 003 L975-977).
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Lod {
    /// Blocks with a flat top at the overall height.
    Lod1 = 1,
    /// Real roof shapes and semantic surfaces (wall, roof, ground).
    Lod2 = 2,
    /// Storeys, facades and openings.
    Lod3 = 3,
    /// Interiors.
    Lod4 = 4,
}

impl Lod {
    /// The LOD as a number 1-4.
    pub fn number(self) -> u8 {
        self as u8
    }
}

/// Roof shapes of the OSM Simple 3D Buildings catalogue (every `roof:shape` value the wiki's
/// Key:roof:shape page documents, and `apse_gabled`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum RoofShape {
    /// `flat` (also an empty value): one horizontal face at the top of the walls.
    Flat,
    /// `skillion` (also `shed`, `lean-to`, `mono-pitched`): one plane sloping down towards
    /// `roof:direction`, or across the footprint's short side.
    Skillion,
    /// `gabled`: slopes from the straight skeleton, each wing end closed by a vertical gable wall;
    /// with `roof:orientation=across`, two planes on one ridge parallel to the short side.
    Gabled,
    /// `hipped`: a slope rising from every footprint edge.
    Hipped,
    /// `half-hipped`: gabled, each gable wall stopping at 0.6 of its height under a small hip.
    HalfHipped,
    /// `side_hipped`: gabled with one end hipped (the first hip end in ring order).
    SideHipped,
    /// `pyramidal`: one triangle per edge rising to an apex over the centroid (hipped when the
    /// footprint has holes or is not star-shaped from the centroid).
    Pyramidal,
    /// `mansard`: hipped with a steep 70° lower slope (1 m deep in plan, less on narrow wings)
    /// under a 25° upper slope; `roof:angle` is not used.
    Mansard,
    /// `gambrel`: a barn roof, gabled with a 60° lower slope and a 30° upper slope; `roof:angle`
    /// is not used.
    Gambrel,
    /// `saltbox`: two planes on one straight ridge at 35 % of the width, a short steep slope and a
    /// long one (facing `roof:direction` when tagged).
    Saltbox,
    /// `dome`: a quarter-circle profile of the footprint's inscribed radius, in 6 planar bands.
    Dome,
    /// `onion`: a bulb profile, 1.6 times the footprint's inscribed radius high.
    Onion,
    /// `round`: a barrel vault, the dome's quarter-circle profile with gable ends.
    Round,
    /// `cone`: drawn as the pyramidal roof, planar triangles to one apex.
    Cone,
    /// `gabled_height_moved`: two planes on one straight ridge moved off the middle, at 25 % of
    /// the width (the long slope facing `roof:direction` when tagged); both eaves at the top
    /// of the walls.
    GabledHeightMoved,
    /// `side_half-hipped`: gabled with one end half-hipped (the first end in ring order), the
    /// others gables.
    SideHalfHipped,
    /// `hipped-and-gabled`: hipped, each hip stopping at 0.6 of the roof's height under a small
    /// steep gable (80°) set back on top of it (a Dutch gable).
    HippedAndGabled,
    /// `bellcast_gable`: gabled with the slopes flaring out at the eaves (the lowest quarter of
    /// each slope at half the pitch).
    BellcastGable,
    /// `crosspitched`: two gabled roofs of the same height crossing at the middle of the
    /// footprint, a gable on each of the four sides of a rectangle.
    Crosspitched,
    /// `sawtooth`: repeated skillions about 8 m deep falling towards `roof:direction` (else
    /// along the long axis), each rising to a steep 80° glazed face.
    Sawtooth,
    /// `butterfly`: two planes falling inwards to a valley along the middle (an inverted
    /// gable), the outer eaves high.
    Butterfly,
    /// `apse_gabled`: gabled, with a rounded end (a church's apse) drawn as a half cone of
    /// planar faces; on a footprint without a rounded end, one end hipped.
    ApseGabled,
}

impl RoofShape {
    /// The OSM `roof:shape` value.
    pub fn osm_name(self) -> &'static str {
        match self {
            RoofShape::Flat => "flat",
            RoofShape::Skillion => "skillion",
            RoofShape::Gabled => "gabled",
            RoofShape::Hipped => "hipped",
            RoofShape::HalfHipped => "half-hipped",
            RoofShape::SideHipped => "side_hipped",
            RoofShape::Pyramidal => "pyramidal",
            RoofShape::Mansard => "mansard",
            RoofShape::Gambrel => "gambrel",
            RoofShape::Saltbox => "saltbox",
            RoofShape::Dome => "dome",
            RoofShape::Onion => "onion",
            RoofShape::Round => "round",
            RoofShape::Cone => "cone",
            RoofShape::GabledHeightMoved => "gabled_height_moved",
            RoofShape::SideHalfHipped => "side_half-hipped",
            RoofShape::HippedAndGabled => "hipped-and-gabled",
            RoofShape::BellcastGable => "bellcast_gable",
            RoofShape::Crosspitched => "crosspitched",
            RoofShape::Sawtooth => "sawtooth",
            RoofShape::Butterfly => "butterfly",
            RoofShape::ApseGabled => "apse_gabled",
        }
    }

    /// Parses OSM `roof:shape` values and the thesis spellings (`hip`, `gabbled`, `shed`, ...),
    /// case-insensitively and ignoring surrounding spaces. `None` for unknown values.
    pub fn parse(s: &str) -> Option<RoofShape> {
        let s = s.trim().to_ascii_lowercase().replace(['_', ' '], "-");
        Some(match s.as_str() {
            "flat" | "" => RoofShape::Flat,
            "skillion" | "shed" | "lean-to" | "mono-pitched" => RoofShape::Skillion,
            "gabled" | "gabbled" | "gable" | "pitched" => RoofShape::Gabled,
            "hipped" | "hip" | "hiped" => RoofShape::Hipped,
            "half-hipped" | "half-hip" => RoofShape::HalfHipped,
            "side-hipped" => RoofShape::SideHipped,
            "pyramidal" | "pyramid" => RoofShape::Pyramidal,
            "mansard" => RoofShape::Mansard,
            "gambrel" => RoofShape::Gambrel,
            "saltbox" => RoofShape::Saltbox,
            "dome" => RoofShape::Dome,
            "onion" => RoofShape::Onion,
            "round" => RoofShape::Round,
            "cone" => RoofShape::Cone,
            "gabled-height-moved" => RoofShape::GabledHeightMoved,
            "side-half-hipped" => RoofShape::SideHalfHipped,
            "hipped-and-gabled" | "hip-and-gable" => RoofShape::HippedAndGabled,
            "bellcast-gable" => RoofShape::BellcastGable,
            "crosspitched" | "cross-pitched" => RoofShape::Crosspitched,
            "sawtooth" => RoofShape::Sawtooth,
            "butterfly" => RoofShape::Butterfly,
            "apse-gabled" => RoofShape::ApseGabled,
            _ => return None,
        })
    }

    /// The CityGML 2.0 `bldg:roofType` code (SIG3D code list: 1000 flat, 1010 monopitch,
    /// 1020 dual pent, 1030 gabled, 1040 hipped, 1050 half-hipped, 1060 mansard, 1070 pavilion,
    /// 1080 cone, 1090 cupola, 1100 sawtooth, 1110 arch, 1120 pyramidal broach, 1130 combination).
    ///
    /// The new shapes: `gabled_height_moved`, `bellcast_gable` and `apse_gabled` are gabled
    /// roofs (1030: two slopes on a ridge, gable walls); `side_half-hipped` and
    /// `hipped-and-gabled` are half-hipped (1050: the code list's one class of a roof with both
    /// a hip and a gable at an end); `sawtooth` is 1100; `butterfly` is 1020, "dual pent": two
    /// pent (mono-pitch) roofs, here meeting at their low edges (the list has no inverted
    /// gable); `crosspitched`, two gabled roofs crossing, is 1130 "combination".
    pub(crate) fn citygml_code(self) -> &'static str {
        match self {
            RoofShape::Flat => "1000",
            RoofShape::Skillion => "1010",
            RoofShape::Butterfly => "1020",
            RoofShape::Gabled
            | RoofShape::Saltbox
            | RoofShape::GabledHeightMoved
            | RoofShape::BellcastGable
            | RoofShape::ApseGabled => "1030",
            RoofShape::Hipped | RoofShape::SideHipped => "1040",
            RoofShape::HalfHipped | RoofShape::SideHalfHipped | RoofShape::HippedAndGabled => {
                "1050"
            }
            RoofShape::Mansard | RoofShape::Gambrel => "1060",
            RoofShape::Pyramidal => "1070",
            RoofShape::Cone => "1080",
            RoofShape::Dome | RoofShape::Onion => "1090",
            RoofShape::Sawtooth => "1100",
            RoofShape::Round => "1110",
            RoofShape::Crosspitched => "1130",
        }
    }
}

/// A planar 3D polygon with holes. The outer ring is counter-clockwise seen from the side its
/// normal points to (outside the building); holes run the other way. Rings are not closed.
#[derive(Clone, Debug, PartialEq)]
pub struct Face {
    /// Outer ring in the local frame (metres), not closed (the first vertex is not repeated).
    pub outer: Vec<DVec3>,
    /// Hole rings, running opposite to `outer`: a wall's window and door openings at LOD3, a
    /// courtyard in a flat roof or the ground.
    pub holes: Vec<Vec<DVec3>>,
}

impl Face {
    /// A face without holes.
    pub fn new(outer: Vec<DVec3>) -> Face {
        Face {
            outer,
            holes: Vec::new(),
        }
    }

    /// Unit normal (Newell), pointing out of the building. Zero for a degenerate face.
    pub fn normal(&self) -> DVec3 {
        crate::geometry::newell_normal(&self.outer).normalize_or_zero()
    }
}

/// Window or door.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum OpeningKind {
    /// A window: a `window` terminal of the rules, glass unless its `material` says otherwise.
    Window,
    /// A door: a `door` terminal of the rules (the front door, a balcony door), opaque unless its
    /// `material` is `glass`.
    Door,
}

/// A window or door in a wall (LOD3).
///
/// `u0..u1` runs along the wall from its `start`, `z0..z1` are absolute heights. An opening
/// lies strictly inside the rectangular part of its wall (at least `OPENING_MARGIN` from every
/// border) and overlaps no other opening of the wall; its hole is also in the wall's
/// `outline.holes`, in the same order as `openings`.
#[derive(Clone, Debug, PartialEq)]
pub struct Opening {
    /// Window or door: decides the default colour and whether the pane is glass by default.
    pub kind: OpeningKind,
    /// Left edge: metres along the wall from its `start`, at least `OPENING_MARGIN`.
    pub u0: f64,
    /// Right edge: metres along the wall from its `start`, at most the wall's length minus
    /// `OPENING_MARGIN`.
    pub u1: f64,
    /// Bottom edge (sill, or the foot of a door): absolute height in metres, at least
    /// `OPENING_MARGIN` above the wall's base, so a door stands 2 cm above its floor.
    pub z0: f64,
    /// Top edge: absolute height in metres, at least `LINTEL` below the storey's top (the
    /// eave for the top storey).
    pub z1: f64,
    /// Glass or door-panel colour.
    pub color: Color,
    /// Frame colour: the terminal's `framecolor`, else the style's (the knowledge base's
    /// `windowfcolor`, white by default). The IFC and glTF writers use it only when `framed`.
    pub frame_color: Color,
    /// Transparent glass (`material=glass`).
    pub glazed: bool,
    /// With a frame (`style=framed`, SELEX `addFacadeWithFrame`).
    pub framed: bool,
    /// The frame's size when `framed` and not the writers' standard one (SELEX
    /// `addFacadeWithFrame`); `None`: the standard frame.
    pub frame_size: Option<FrameSize>,
    /// Rounded corners (SELEX `addRoundFacade`); `None`: a rectangle.
    pub rounding: Option<Rounding>,
}

impl Opening {
    /// Width along the wall.
    pub fn width(&self) -> f64 {
        self.u1 - self.u0
    }

    /// Height.
    pub fn height(&self) -> f64 {
        self.z1 - self.z0
    }

    /// The opening shrunk by `d` metres on every side, its corners' radius shrunk with it (the
    /// inner edge of a frame `d` wide).
    pub(crate) fn inset(&self, d: f64) -> Opening {
        let mut o = self.clone();
        o.u0 += d;
        o.u1 -= d;
        o.z0 += d;
        o.z1 -= d;
        if let Some(r) = &mut o.rounding {
            r.radius = (r.radius - d).max(0.0);
        }
        o
    }

    /// The opening's outline in wall coordinates (x: metres along the wall from its `start`, y:
    /// absolute height), counter-clockwise seen from outside, starting at the bottom-left
    /// corner: the rectangle `u0..u1` by `z0..z1`, its rounded corners cut by arcs of
    /// [`Rounding::segments`] straight segments. Every point lies in the rectangle; a wall's hole
    /// and the opening's own polygons are this ring (the hole reversed), so they match exactly.
    pub fn outline(&self) -> Vec<DVec2> {
        rounded_rect(
            DVec2::new(self.u0, self.z0),
            DVec2::new(self.u1, self.z1),
            self.rounding.as_ref(),
        )
    }
}

/// The rectangle from `min` to `max` (x to the right, y up), counter-clockwise from its
/// bottom-left corner, with the corners `rounding` names cut by its arcs (see
/// [`Opening::outline`]).
pub(crate) fn rounded_rect(min: DVec2, max: DVec2, rounding: Option<&Rounding>) -> Vec<DVec2> {
    let corners = [min, DVec2::new(max.x, min.y), max, DVec2::new(min.x, max.y)];
    let Some(r) = rounding.filter(|r| r.is_rounded()) else {
        return corners.to_vec();
    };
    // The corners in ring order (bottom-left, bottom-right, top-right, top-left) against
    // `Rounding::corners` (top-left, top-right, bottom-right, bottom-left).
    let rounded = [r.corners[3], r.corners[2], r.corners[1], r.corners[0]];
    let size = max - min;
    let radius = r.radius.min(0.5 * size.x.min(size.y));
    let mut ring: Vec<DVec2> = Vec::new();
    for i in 0..4 {
        let k = corners[i];
        if !rounded[i] || radius.is_nan() || radius <= 1e-4 {
            ring.push(k);
            continue;
        }
        let prev = (corners[(i + 3) % 4] - k).normalize();
        let next = (corners[(i + 1) % 4] - k).normalize();
        let centre = k + (prev + next) * radius;
        let n = r.exponent();
        let segments = r.segments.clamp(1, Rounding::MAX_SEGMENTS);
        for s in 0..=segments {
            // The ends exactly on the edges, so two arcs meeting halfway share their point.
            let (cos, sin) = match s {
                0 => (1.0, 0.0),
                s if s == segments => (0.0, 1.0),
                s => {
                    let t = f64::from(s) / f64::from(segments) * std::f64::consts::FRAC_PI_2;
                    (t.cos(), t.sin())
                }
            };
            let f = |x: f64| x.max(0.0).powf(2.0 / n);
            ring.push(centre - next * radius * f(cos) - prev * radius * f(sin));
        }
    }
    // Two arcs meeting halfway along an edge share their end point: keep it once.
    ring.dedup_by(|a, b| a.distance(*b) < 1e-9);
    if ring.len() > 1 && ring[0].distance(ring[ring.len() - 1]) < 1e-9 {
        ring.pop();
    }
    ring
}

/// An opening's frame, where it is not the standard one (SELEX `addFacadeWithFrame(label,
/// edgeExtrusion, thickness, width)`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FrameSize {
    /// Width of the frame's members in the wall's plane, metres (SELEX `thickness`).
    pub width: f64,
    /// How far the frame stands out of the wall's outer face, metres (SELEX `width`; 0: flush).
    pub protrusion: f64,
}

/// Rounded corners of an opening (SELEX `addRoundFacade(label, corners, offset, segments,
/// profile)`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Rounding {
    /// Which corners are rounded: top-left, top-right, bottom-right, bottom-left, left and right
    /// as seen from outside.
    pub corners: [bool; 4],
    /// How far from the corner each arc starts along both edges, metres (SELEX `offset`); at
    /// most half the opening's width and height where drawn.
    pub radius: f64,
    /// Straight segments of each arc (SELEX `segments`), 1 to `Rounding::MAX_SEGMENTS`.
    pub segments: u32,
    /// The arc's shape (SELEX `profile`), 0 to 1: 0.5 a quarter circle, 0.25 a straight chamfer,
    /// towards 1 a square corner, towards 0 a concave cut. Drawn as the superellipse of exponent
    /// `2^(4 profile - 1)` (`Rounding::exponent`).
    pub profile: f64,
}

impl Rounding {
    /// The most segments an arc is drawn with.
    pub(crate) const MAX_SEGMENTS: u32 = 32;

    /// Whether any corner is rounded by a usable radius.
    pub(crate) fn is_rounded(&self) -> bool {
        self.corners.iter().any(|c| *c) && self.radius.is_finite() && self.radius > 0.0
    }

    /// The superellipse exponent of the profile: 2 for 0.5 (a circle), 1 for 0.25 (a
    /// chamfer), 8 for 1, 0.5 for 0.
    pub(crate) fn exponent(&self) -> f64 {
        let p = if self.profile.is_finite() {
            self.profile.clamp(0.0, 1.0)
        } else {
            0.5
        };
        2f64.powf(4.0 * p - 1.0)
    }
}

/// Smallest distance between an opening and the border of its wall, or another opening
/// (metres). Keeps wall polygons with holes valid (no touching rings).
pub(crate) const OPENING_MARGIN: f64 = 0.02;

/// Least wall between an opening's head and the top of its storey (metres): the lintel and the
/// floor above. A door that filled its storey would also leave a strip of wall 2 cm high above
/// it, whose long thin triangles a validator finds tilted once the opening's corners are
/// rounded to the millimetre (val3dity's 204).
pub(crate) const LINTEL: f64 = 0.3;

/// Height of a balcony's railing above its slab (metres): the writers draw it, and the facade
/// rules keep a balcony clear of neighbours up to it.
pub(crate) const RAILING_HEIGHT: f64 = 1.0;

/// A balcony on a wall (LOD3): a slab of `depth` metres in front of the wall at floor height
/// `z`, spanning `u0..u1` along it, with a railing.
#[derive(Clone, Debug, PartialEq)]
pub struct Balcony {
    /// Start along the wall, metres from its `start` (0 or more).
    pub u0: f64,
    /// End along the wall, metres from its `start` (at most the wall's length).
    pub u1: f64,
    /// Absolute height of the balcony's floor (the bottom of the `balcony` terminal), metres.
    pub z: f64,
    /// How far the slab reaches out from the wall's outer face, metres (1.2 m for every balcony
    /// the rules make).
    pub depth: f64,
    /// Colour of the slab: the terminal's `color`, else the part's wall colour (the writers draw the
    /// railing in its own iron and glass colours).
    pub color: Color,
}

/// One exterior wall: the piece of the building envelope standing on one footprint edge.
///
/// `start` and `end` are the edge's endpoints on the footprint (outer ring counter-clockwise,
/// so the outside is on the right of start->end). The wall body lies inside the footprint:
/// the outer face is on the footprint edge and the wall is `thickness` thick towards the inside.
/// `outline` is the outer face: it starts at (start, base_z), goes to (end, base_z), then up;
/// it is a rectangle, or a pentagon/trapezoid where the wall closes a gable. At LOD3 its holes
/// are the openings' rectangles.
#[derive(Clone, Debug, PartialEq)]
pub struct Wall {
    /// Start of the footprint edge, local frame (metres).
    pub start: DVec2,
    /// End of the footprint edge, local frame (metres).
    pub end: DVec2,
    /// Bottom of the wall, metres: the part's base, or at LOD3 its storey's floor.
    pub base_z: f64,
    /// Height of the wall top at the eave (the rectangular part).
    pub top_z: f64,
    /// Thickness in metres, measured inwards from the footprint edge (0.3 m for every exterior
    /// wall citygen derives).
    pub thickness: f64,
    /// The outer face, on the footprint edge, normal pointing out of the building.
    pub outline: Face,
    /// Index of the storey (in [`Part::levels`]) the wall belongs to; 0 below LOD3, where a wall
    /// spans all storeys.
    pub storey: usize,
    /// Windows and doors (LOD3).
    pub openings: Vec<Opening>,
    /// Balconies (LOD3).
    pub balconies: Vec<Balcony>,
    /// Share (0..=1) of the wall's rectangle (its length by `base_z..top_z`) that faces a
    /// neighbouring building or another part of this one, from the ground up to that
    /// neighbour's top (LOD3 and above, else 0): a party wall where it is 1, and no window,
    /// door or balcony is cut where it faces one (`derive::frontage`).
    pub party: f64,
}

impl Wall {
    /// Length of the wall along its footprint edge.
    pub fn length(&self) -> f64 {
        self.start.distance(self.end)
    }
}

/// A building part: one vertical extrusion of one footprint with one roof.
#[derive(Clone, Debug, PartialEq)]
pub struct Part {
    /// Stable suffix for identifiers within the building ("p0", "p1", ...).
    pub key: String,
    /// Footprint in the local frame.
    pub footprint: Polygon,
    /// Bottom of the part (`min_height`).
    pub base_z: f64,
    /// Top of the walls (the eave). Equal to `top_z` for a flat roof.
    pub eave_z: f64,
    /// Highest point of the part (ridge or flat top).
    pub top_z: f64,
    /// Storeys above ground in this part (at least 1).
    pub storeys: u32,
    /// Floor elevation of each storey, ascending, the first at `base_z` (`storeys` values; the
    /// last storey ends at `eave_z`).
    pub levels: Vec<f64>,
    /// Wall colour: the mass's `color` attribute in the rules, else the style's (OSM
    /// `building:colour`, then `building:material`, then the knowledge base's `color`, white by
    /// default).
    pub wall_color: Color,
    /// Roof colour: the mass's `roofcolor` attribute in the rules, else the style's (OSM
    /// `roof:colour`, then `roof:material`, then the knowledge base's `roofColor`, CSS `darkred` by
    /// default).
    pub roof_color: Color,
    /// What the walls are made of (issue 49): the style's `building:material`, else the
    /// knowledge base's `material` ([`Material::parse`]); how the writers make them reflect.
    pub wall_material: Material,
    /// What the roof is made of: the style's `roof:material` ([`Material::parse`]).
    pub roof_material: Material,
    /// The roof shape derived for the part, or [`RoofShape::Flat`] when it fell back to flat (or is
    /// under 5 cm high). At LOD1, where every part is a flat-topped block, it still names the
    /// derived shape.
    pub roof_shape: RoofShape,
    /// Exterior walls: one per footprint edge, outer ring then holes, in ring order.
    pub walls: Vec<Wall>,
    /// Roof surfaces (one per roof plane; a flat roof is one face with the footprint's holes).
    pub roof: Vec<Face>,
    /// The ground surface at `base_z`, normal pointing down.
    pub ground: Face,
    /// The interior, one plan per storey (LOD4; empty below).
    pub interior: Vec<StoreyInterior>,
    /// The footprint the part was derived from: its `building:part` (or the outline, for the
    /// part the outline's own tags give), so that every part can be traced back to the map.
    /// Writers record it where it differs from the building's id, or where the part is the
    /// outline's uncovered rest ([`PartRole::OutlineRest`]). `None` for parts built without a
    /// source (tests, `rules derive` lots).
    pub source: Option<SourceId>,
    /// What the part is of its source: the footprint itself, or what an outline's parts leave
    /// uncovered of it.
    pub role: PartRole,
    /// The structure the part is (issue 45), `None` for a part of a house: what its
    /// facades and interior honour, and what the writers record (`structure`).
    pub structure: Option<Structure>,
    /// The bays and windows its rules lay out on its walls (issue 49), when the knowledge
    /// base's rules draw the part: what a LOD2 facade texture shows. `None` for a structure, a
    /// ruleset file's part and parts built without rules.
    pub rhythm: Option<Rhythm>,
    /// The cornice along the top of its walls (LOD3 and above, flat roofs, where the knowledge
    /// base's `cornice` asks; issue 49): `None` elsewhere.
    pub cornice: Option<Cornice>,
    /// The eaves: its roof planes carried out past the walls (LOD3 and above, pitched roofs,
    /// where the knowledge base's `eaves` asks; issue 49): `None` elsewhere.
    pub eaves: Option<Eaves>,
}

/// A cornice (issue 49): a moulded band along the top of a flat-roofed part's walls, standing
/// out of them, its top at the part's eave. The writers draw its profile
/// (`export::lod3geom::cornice_solids`): mitred where two drawn edges meet, square where an edge
/// is not drawn.
#[derive(Clone, Debug, PartialEq)]
pub struct Cornice {
    /// How far its front stands out of the wall's outer face (metres).
    pub depth: f64,
    /// Its height below the wall's top (metres).
    pub height: f64,
    /// Per footprint edge (outer ring then holes, in ring order, as the part's walls of a
    /// storey): whether the cornice runs along it (not on a party wall, nor where it would meet
    /// a neighbour, another part or the part's own wings: `derive::trim`).
    pub edges: Vec<bool>,
    /// Its colour: the part's wall colour lightened, as a stone or stucco moulding.
    pub color: Color,
}

/// Eaves (issue 49): a pitched roof's planes carried past the walls by `overhang` metres
/// (measured in plan, square to the wall) along its eaves and verges, as a board `thickness`
/// thick under the roof's surface (`export::lod3geom::eaves_solids`).
#[derive(Clone, Debug, PartialEq)]
pub struct Eaves {
    /// How far the roof reaches past the wall's outer face, in plan (metres).
    pub overhang: f64,
    /// Thickness of the overhang, vertical (metres).
    pub thickness: f64,
    /// Per footprint edge, as [`Cornice::edges`]: whether the roof overhangs it.
    pub edges: Vec<bool>,
    /// Colour of its underside (the soffit): the part's wall colour; its top is the roof's.
    pub soffit: Color,
}

/// The facade rhythm of a part's walls as the knowledge base's rules lay it out at LOD3
/// (`kb::compile`: `repeat(X, bay)` of pier, window, pier; each storey split into sill,
/// window and lintel): what a LOD2 wall's facade texture draws (`export::texture`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Rhythm {
    /// Bay width (metres): a window and a pier on each side.
    pub bay: f64,
    /// Window width (metres), in the middle of the bay.
    pub window: f64,
    /// Height of the sill above the storey's floor, as a share of the storey.
    pub sill: f64,
    /// Height of the window, as a share of the storey.
    pub height: f64,
}

/// What a part is of its source footprint ([`Part::source`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum PartRole {
    /// The footprint itself: a `building:part`, or an outline drawn whole.
    #[default]
    Own,
    /// What an outline's `building:part`s leave uncovered of it, drawn with the outline's own
    /// tags (issue 45): written with the outline's id and the role `outline-rest`.
    OutlineRest,
}

impl PartRole {
    /// The role as the writers record it beside the source id (`sourceRole`), `None` for
    /// [`PartRole::Own`], which they do not write.
    pub fn name(self) -> Option<&'static str> {
        match self {
            PartRole::Own => None,
            PartRole::OutlineRest => Some("outline-rest"),
        }
    }
}

impl Part {
    /// The part's source where the writers record it on the part: a `building:part`'s id (not
    /// the building's own), or the outline's id on its uncovered rest
    /// ([`PartRole::OutlineRest`]).
    pub(crate) fn traced_source(&self, building: SourceId) -> Option<SourceId> {
        self.source
            .filter(|s| *s != building || self.role != PartRole::Own)
    }

    /// The part's top above the building's ground (`ground`: [`Building::ground_z`]), as OSM's
    /// `height`: what the writers give as its height.
    pub fn height_above(&self, ground: f64) -> f64 {
        self.top_z - ground
    }
}

/// The interior of one storey of a part (LOD4): rooms, the interior walls between them, the
/// doors in those walls, and the stair core.
///
/// Rooms partition the storey's usable area (the footprint inside the exterior walls): their
/// polygons are the cells of the partition, so two neighbouring rooms share an edge; an
/// interior wall is centred on that shared edge and is `thickness` thick (writers give it a
/// body of half the thickness on each side). The entrance from outside is the LOD3 front door.
#[derive(Clone, Debug, PartialEq)]
pub struct StoreyInterior {
    /// Index of the storey in [`Part::levels`].
    pub storey: usize,
    /// Top of this storey's floor slab (the storey's level).
    pub floor_z: f64,
    /// Underside of the ceiling (the next storey's slab, or the eave).
    pub ceiling_z: f64,
    /// The rooms, which partition the storey's usable area; [`InteriorWall::rooms`] indexes into
    /// this list.
    pub rooms: Vec<Room>,
    /// Interior walls, each once (never duplicated for its two rooms).
    pub walls: Vec<InteriorWall>,
    /// Doors in interior walls.
    pub doors: Vec<InteriorDoor>,
    /// The stair rising from this storey to the next, if any. Every storey of a part has its
    /// stair at the same place.
    pub stair: Option<Stair>,
}

/// A room (or the hall, a corridor, the stair core) of a storey plan.
#[derive(Clone, Debug, PartialEq)]
pub struct Room {
    /// Simple polygon in the local frame, inside the storey's usable area.
    pub polygon: Polygon,
    /// What the room is for, lower case, e.g. `living room`, `bedroom`, `hall`, `stair`.
    pub usage: String,
    /// A name unique in the storey, e.g. `Bedroom 2`.
    pub name: String,
}

/// An interior wall on the shared boundary of two rooms: the centre line from `a` to `b`.
#[derive(Clone, Debug, PartialEq)]
pub struct InteriorWall {
    /// One end of the centre line, local frame (metres).
    pub a: DVec2,
    /// The other end of the centre line, local frame (metres).
    pub b: DVec2,
    /// Thickness in metres, centred on the line from `a` to `b` (0.1 m partitions).
    pub thickness: f64,
    /// The two rooms it separates (indices in [`StoreyInterior::rooms`]).
    pub rooms: [usize; 2],
}

/// A door in an interior wall: `u0..u1` metres along the wall from `a`, from the floor up to
/// `height`. It lies inside the wall with at least `OPENING_MARGIN` to its ends.
#[derive(Clone, Debug, PartialEq)]
pub struct InteriorDoor {
    /// Index in [`StoreyInterior::walls`].
    pub wall: usize,
    /// Start of the door opening, metres along the wall from its `a`.
    pub u0: f64,
    /// End of the opening, metres along the wall from its `a`.
    pub u1: f64,
    /// Height of the door above the storey's floor, metres: 2.1 m, lowered to fit a low storey.
    pub height: f64,
}

/// A straight stair flight inside a stair core: it rises from the storey's floor to the next
/// storey's floor over `footprint`, in the direction `run` (unit vector in the plan).
#[derive(Clone, Debug, PartialEq)]
pub struct Stair {
    /// The flight's outline (a rectangle) in the local frame.
    pub footprint: Polygon,
    /// Direction of the climb in plan: a unit vector in the local frame (X east, Y north).
    pub run: DVec2,
    /// Height climbed (floor to next floor).
    pub rise: f64,
    /// Number of risers.
    pub risers: u32,
}

/// A building: the unit every writer emits, with its parts.
#[derive(Clone, Debug, PartialEq)]
pub struct Building {
    /// Where it came from (`way/123`, `relation/45`, `shp/7`).
    pub id: SourceId,
    /// OSM `name` or a shapefile name field, when any.
    pub name: Option<String>,
    /// Path of the matched knowledge-base zone, e.g. `earth/France/Occitanie/Toulouse`.
    pub zone: String,
    /// Which appearance was chosen (e.g. `Toulouse#1`) or which ruleset was used.
    pub appearance: String,
    /// Lowest base of all parts (the terrain height of the building, 0 without terrain, for a
    /// building on the ground; higher for one whose every part floats).
    pub base_z: f64,
    /// The ground the building stands on (its lot's, 0 without terrain): heights above the
    /// ground (`measured_height`, a part's height and min height in the writers) count from
    /// it.
    pub ground_z: f64,
    /// Overall height: the highest top above the ground (`ground_z`), as OSM's `height`.
    pub measured_height: f64,
    /// Storeys above ground of the tallest part.
    pub storeys_above_ground: u32,
    /// Roof shape of the tallest part.
    pub roof_shape: RoofShape,
    /// The parts, in derivation order (the outline when it is drawn, then the `building:part`s
    /// in id order); each has a distinct [`Part::key`].
    pub parts: Vec<Part>,
    /// The LOD the geometry was cut at.
    pub lod: Lod,
    /// What the LOD3 facade rules left out or added on this building (for the report).
    pub facade: FacadeCounts,
    /// Where `storeys_above_ground`, `measured_height` and `roof_shape` came from, with their
    /// uncertainty (those of the tallest part, as the values themselves): written by every
    /// writer and counted in the report.
    pub provenance: Provenance,
    /// The input file's own attributes that citygen does not read itself (issue 47), carried
    /// into every output; `None` for OSM input and for a feature without any.
    pub attributes: Option<Attributes>,
}

/// A value of an input attribute, typed as the file types it.
#[derive(Clone, Debug, PartialEq)]
pub enum AttrValue {
    /// Text.
    Text(Box<str>),
    /// A whole number.
    Int(i64),
    /// A real number (always finite).
    Real(f64),
    /// A boolean.
    Bool(bool),
    /// A date or date-time, as the file writes it (ISO 8601, `2021-05-04` or
    /// `2021-05-04T10:00:00Z`).
    Date(Box<str>),
}

/// The input attributes of one feature in the file's column order: each name is interned (one
/// allocation per column of the file, shared by every feature), the whole row shared by the
/// building and its copies.
pub type Attributes = std::sync::Arc<[(std::sync::Arc<str>, AttrValue)]>;

/// What the LOD3 facade rules (`derive::frontage`) did to one building, or summed over a run.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct FacadeCounts {
    /// Windows and doors the rules put where the wall faces a neighbour: left out.
    pub openings_on_party_walls: usize,
    /// Balconies there: left out.
    pub balconies_on_party_walls: usize,
    /// Balconies whose slab would reach into a footprint (a neighbour's, another part's or
    /// their own part's, issue 45): narrowed to the longest free stretch, or left out.
    #[serde(default)]
    pub balconies_clipped: usize,
    /// Main entrances placed (one per building standing on the ground that has room for one).
    pub entrances: usize,
    /// Buildings standing on the ground with no ground-storey wall free for a door of at least
    /// 0.8 by 2.0 m: no entrance.
    pub without_entrance: usize,
    /// Doors the rules put where there is no ground or balcony under them (the base of a raised
    /// part, an upper storey): made windows, or left out where no window fits.
    pub doors_off_ground: usize,
    /// Ground-storey doors besides the main entrance: made windows.
    pub extra_doors: usize,
    /// Balcony doors that would be narrower than 0.8 m or lower than 2.0 m as drawn: left out.
    pub doors_too_small: usize,
    /// Window panes placed on runs of short wall edges (curved and many-edged walls).
    pub run_windows: usize,
    /// Wall area facing a neighbour, square metres (of the walls' rectangles: length by storey
    /// height).
    pub party_wall_area: f64,
    /// All wall area, square metres (the same rectangles).
    pub wall_area: f64,
}

impl FacadeCounts {
    /// Adds `o`'s counts to these.
    pub fn add(&mut self, o: &FacadeCounts) {
        self.openings_on_party_walls += o.openings_on_party_walls;
        self.balconies_on_party_walls += o.balconies_on_party_walls;
        self.balconies_clipped += o.balconies_clipped;
        self.entrances += o.entrances;
        self.without_entrance += o.without_entrance;
        self.doors_off_ground += o.doors_off_ground;
        self.extra_doors += o.extra_doors;
        self.doors_too_small += o.doors_too_small;
        self.run_windows += o.run_windows;
        self.party_wall_area += o.party_wall_area;
        self.wall_area += o.wall_area;
    }
}

impl Building {
    /// A stable identifier usable in XML ids and IFC names: the source id with `/` replaced,
    /// e.g. `way_123`.
    pub fn key(&self) -> String {
        self.id.key()
    }

    /// Number of planar polygons of the building's surfaces, about as CityGML writes them: walls,
    /// roof faces and grounds, plus at LOD3 one per window or door and the 9 faces of each
    /// balcony (a 6-face slab and 3 railing panels), and at LOD4 per storey each room's floor,
    /// ceiling and sides, 6 faces per interior wall and door leaf and per stair step.
    pub(crate) fn polygon_count(&self) -> usize {
        self.parts
            .iter()
            .map(|p| {
                let facade: usize = p
                    .walls
                    .iter()
                    .map(|w| w.openings.len() + 9 * w.balconies.len())
                    .sum();
                let interior: usize = p
                    .interior
                    .iter()
                    .map(|s| {
                        let rooms: usize = s.rooms.iter().map(|r| 2 + r.polygon.outer.len()).sum();
                        let stair = s.stair.as_ref().map_or(0, |st| 6 * st.risers as usize);
                        rooms + 6 * (s.walls.len() + s.doors.len()) + stair
                    })
                    .sum();
                p.walls.len() + p.roof.len() + 1 + facade + interior
            })
            .sum()
    }

    /// Checks that every height, coordinate and extent of the building's exterior is finite: its
    /// heights, and per part its heights, footprint, ground, walls (ends, heights, thickness,
    /// outline, openings and balconies), storey levels and roof (interiors are not checked: the
    /// writers leave out a storey interior whose heights are not finite). The error names the
    /// building and what is not finite, e.g. `building way/1: a coordinate of wall 2 of part p0
    /// is not finite`. Every writer calls it before writing anything of a building, so that a
    /// refused building leaves nothing half-written.
    pub(crate) fn check_finite(&self) -> Result<(), NotFinite> {
        if self.all_finite() {
            return Ok(());
        }
        self.find_non_finite()
    }

    /// Whether every number [`Building::check_finite`] checks is finite: one pass without a
    /// branch per number (an exponent of all ones is an infinity or a NaN).
    fn all_finite(&self) -> bool {
        let mut c = FiniteCheck(0);
        self.walk_numbers(&mut c);
        c.0 != FiniteCheck::EXP
    }

    /// Every number of the building's exterior, in a fixed order: its heights, and per part its
    /// heights, footprint, ground, walls (ends, heights, thickness, outline, openings and
    /// balconies), storey levels and roof.
    fn walk_numbers<N: Numbers>(&self, c: &mut N) {
        c.v(self.base_z);
        c.v(self.measured_height);
        for p in &self.parts {
            c.v(p.base_z);
            c.v(p.eave_z);
            c.v(p.top_z);
            for r in p.footprint.rings() {
                c.p2(r);
            }
            c.face(&p.ground);
            for w in &p.walls {
                c.p2(&[w.start, w.end]);
                c.v(w.base_z);
                c.v(w.top_z);
                c.v(w.thickness);
                c.face(&w.outline);
                for o in &w.openings {
                    c.v(o.u0);
                    c.v(o.u1);
                    c.v(o.z0);
                    c.v(o.z1);
                }
                for b in &w.balconies {
                    c.v(b.u0);
                    c.v(b.u1);
                    c.v(b.z);
                    c.v(b.depth);
                }
            }
            for z in &p.levels {
                c.v(*z);
            }
            for r in &p.roof {
                c.face(r);
            }
        }
    }

    /// Moves the whole building up by `dz` metres (its ground height, issue 44): every part's
    /// heights, storey levels, walls with their openings and balconies, roof, ground and
    /// interiors. Plans and relative sizes (wall heights, door heights, stair rises) do not
    /// change.
    pub(crate) fn raise(&mut self, dz: f64) {
        let up = |f: &mut Face| {
            for p in f.outer.iter_mut().chain(f.holes.iter_mut().flatten()) {
                p.z += dz;
            }
        };
        self.base_z += dz;
        self.ground_z += dz;
        for p in &mut self.parts {
            p.base_z += dz;
            p.eave_z += dz;
            p.top_z += dz;
            p.levels.iter_mut().for_each(|z| *z += dz);
            up(&mut p.ground);
            p.roof.iter_mut().for_each(up);
            for w in &mut p.walls {
                w.base_z += dz;
                w.top_z += dz;
                up(&mut w.outline);
                for o in &mut w.openings {
                    o.z0 += dz;
                    o.z1 += dz;
                }
                w.balconies.iter_mut().for_each(|b| b.z += dz);
            }
            for s in &mut p.interior {
                s.floor_z += dz;
                s.ceiling_z += dz;
            }
        }
    }

    /// A 64-bit digest of what the building is: its id, zone, appearance and provenance, the counts of its
    /// parts, walls, openings, balconies, roof faces and LOD4 rooms, and every number
    /// `Building::check_finite` checks, bit for bit. Two runs that derived the building alike
    /// give the same digest; shard manifests record it per building, so that a merge (or a
    /// test) can tell that sharding changed no building. Not cryptographic.
    pub fn digest(&self) -> u64 {
        let mut d = Digest(0x6a09_e667_f3bc_c908);
        for s in [&self.id.to_string(), &self.zone, &self.appearance] {
            d.bytes(s.as_bytes());
        }
        let p = &self.provenance;
        for s in [p.storeys, p.height, p.roof] {
            d.bytes(s.name().as_bytes());
        }
        for x in [p.storeys_error, p.height_error, p.roof_probability] {
            d.word(x.map_or(u64::MAX, f64::to_bits));
        }
        // Only with attributes: the digest of a building without them is unchanged.
        for (k, v) in self.attributes.iter().flat_map(|a| a.iter()) {
            d.bytes(k.as_bytes());
            d.bytes(format!("{v:?}").as_bytes());
        }
        d.word(self.parts.len() as u64);
        for p in &self.parts {
            d.word(p.walls.len() as u64);
            d.word(p.roof.len() as u64);
            for w in &p.walls {
                d.word(((w.openings.len() as u64) << 32) | w.balconies.len() as u64);
            }
            for s in &p.interior {
                d.word(((s.rooms.len() as u64) << 32) | s.walls.len() as u64);
                for r in &s.rooms {
                    d.p2(&r.polygon.outer);
                }
            }
        }
        self.walk_numbers(&mut d);
        d.0
    }

    /// The error of [`Building::check_finite`] for a building that is not all finite.
    fn find_non_finite(&self) -> Result<(), NotFinite> {
        let building = self.id;
        let f2 = |p: &DVec2| p.is_finite();
        let f3 = |p: &DVec3| p.is_finite();
        let face_ok = |f: &Face| f.outer.iter().all(f3) && f.holes.iter().flatten().all(f3);
        if !(self.base_z.is_finite() && self.measured_height.is_finite()) {
            return Err(NotFinite::Heights { building });
        }
        for p in &self.parts {
            let part = || p.key.clone();
            if !(p.base_z.is_finite() && p.eave_z.is_finite() && p.top_z.is_finite()) {
                return Err(NotFinite::PartHeight {
                    building,
                    part: part(),
                });
            }
            if !p.footprint.rings().flatten().all(f2) {
                return Err(NotFinite::Footprint {
                    building,
                    part: part(),
                });
            }
            if !face_ok(&p.ground) {
                return Err(NotFinite::Ground {
                    building,
                    part: part(),
                });
            }
            for (wall, w) in p.walls.iter().enumerate() {
                let ok = f2(&w.start)
                    && f2(&w.end)
                    && w.base_z.is_finite()
                    && w.top_z.is_finite()
                    && w.thickness.is_finite()
                    && face_ok(&w.outline);
                if !ok {
                    return Err(NotFinite::Wall {
                        building,
                        part: part(),
                        wall,
                    });
                }
                let openings = w.openings.iter().flat_map(|o| [o.u0, o.u1, o.z0, o.z1]);
                let balconies = w.balconies.iter().flat_map(|b| [b.u0, b.u1, b.z, b.depth]);
                if !openings.chain(balconies).all(f64::is_finite) {
                    return Err(NotFinite::OpeningOrBalcony {
                        building,
                        part: part(),
                        wall,
                    });
                }
            }
            if !p.levels.iter().all(|z| z.is_finite()) {
                return Err(NotFinite::Level {
                    building,
                    part: part(),
                });
            }
            if !p.roof.iter().all(face_ok) {
                return Err(NotFinite::Roof {
                    building,
                    part: part(),
                });
            }
        }
        Ok(())
    }
}

/// Why [`Building::check_finite`] refuses a building: what of it is not finite (the first
/// found), with the building's id and the part's key (and the wall's index).
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub(crate) enum NotFinite {
    /// Its base or measured height.
    #[error("building {building}: the base or measured height is not finite")]
    Heights {
        /// The building.
        building: SourceId,
    },
    /// A height of a part.
    #[error("building {building}: the height of part {part} is not finite")]
    PartHeight {
        /// The building.
        building: SourceId,
        /// The part\'s key.
        part: String,
    },
    /// A footprint coordinate of a part.
    #[error("building {building}: a footprint coordinate of part {part} is not finite")]
    Footprint {
        /// The building.
        building: SourceId,
        /// The part\'s key.
        part: String,
    },
    /// A ground coordinate of a part.
    #[error("building {building}: a ground coordinate of part {part} is not finite")]
    Ground {
        /// The building.
        building: SourceId,
        /// The part\'s key.
        part: String,
    },
    /// An end, height, thickness or outline coordinate of a wall.
    #[error("building {building}: a coordinate of wall {wall} of part {part} is not finite")]
    Wall {
        /// The building.
        building: SourceId,
        /// The part's key.
        part: String,
        /// The wall's index in the part.
        wall: usize,
    },
    /// An opening or balcony of a wall.
    #[error(
        "building {building}: an opening or balcony of wall {wall} of part {part} is not finite"
    )]
    OpeningOrBalcony {
        /// The building.
        building: SourceId,
        /// The part's key.
        part: String,
        /// The wall's index in the part.
        wall: usize,
    },
    /// A storey level of a part.
    #[error("building {building}: a storey level of part {part} is not finite")]
    Level {
        /// The building.
        building: SourceId,
        /// The part\'s key.
        part: String,
    },
    /// A roof coordinate of a part.
    #[error("building {building}: a roof coordinate of part {part} is not finite")]
    Roof {
        /// The building.
        building: SourceId,
        /// The part\'s key.
        part: String,
    },
}

/// What [`Building::walk_numbers`] hands each number to.
trait Numbers {
    fn v(&mut self, v: f64);

    #[inline]
    fn p2(&mut self, ps: &[DVec2]) {
        for p in ps {
            self.v(p.x);
            self.v(p.y);
        }
    }

    #[inline]
    fn p3(&mut self, ps: &[DVec3]) {
        for p in ps {
            self.v(p.x);
            self.v(p.y);
            self.v(p.z);
        }
    }

    #[inline]
    fn face(&mut self, f: &Face) {
        self.p3(&f.outer);
        for h in &f.holes {
            self.p3(h);
        }
    }
}

/// The accumulator of [`Building::all_finite`]: the largest exponent field seen (all ones for
/// an infinity or a NaN), so that a check has no branch.
struct FiniteCheck(u64);

impl FiniteCheck {
    const EXP: u64 = 0x7FF0_0000_0000_0000;
}

impl Numbers for FiniteCheck {
    #[inline]
    fn v(&mut self, v: f64) {
        self.0 = self.0.max(v.to_bits() & FiniteCheck::EXP);
    }
}

/// The accumulator of [`Building::digest`]: each 64-bit word mixed in (multiply, rotate, xor;
/// the finaliser of splitmix64 on every word, so that one changed bit changes the digest).
struct Digest(u64);

impl Digest {
    #[inline]
    fn word(&mut self, w: u64) {
        let mut z = w.wrapping_add(0x9e37_79b9_7f4a_7c15);
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^= z >> 31;
        self.0 = (self.0.rotate_left(23) ^ z).wrapping_mul(0x0000_0100_0000_01b3);
    }

    fn bytes(&mut self, b: &[u8]) {
        self.word(b.len() as u64);
        for c in b.chunks(8) {
            let mut w = [0u8; 8];
            w[..c.len()].copy_from_slice(c);
            self.word(u64::from_le_bytes(w));
        }
    }
}

impl Numbers for Digest {
    #[inline]
    fn v(&mut self, v: f64) {
        self.word(v.to_bits());
    }
}

/// What a zone's appearances say about one kind's roofs and storeys, the regional prior of the
/// height and roof estimator (`prepare::estimate`), from `KnowledgeBase::roof_mix`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct RoofMix {
    /// The share of the eligible appearances' weight whose roof is not flat (the zone's info
    /// `rooftype`, else gabled, where an appearance sets none).
    pub pitched: f64,
    /// The pitched shape of most weight (gabled when none is pitched).
    pub shape: RoofShape,
    /// The roof pitch of that shape's appearances, else the zone's, else 30°.
    pub angle_deg: f64,
    /// The storey height of most weight (`floorsize`), else 3 m.
    pub floor_height: f64,
    /// The usual storeys of the zone's built-up fabric: its resolved `nbfloor` (clamped to
    /// 1..=12), at most 3 outside the KB's towns (a country's `nbfloor` describes its cities'
    /// blocks, not its small towns and villages). The level the height estimate rises to
    /// where the place is dense.
    pub storeys: f64,
    /// The zone is a town or part of one (a `<town>`, `<district>` or deeper zone).
    pub urban: bool,
}

impl RoofMix {
    /// Without a knowledge base: half pitched (gabled at 30°), 3 m storeys.
    pub(crate) const DEFAULT: RoofMix = RoofMix {
        pitched: 0.5,
        shape: RoofShape::Gabled,
        angle_deg: 30.0,
        floor_height: 3.0,
        storeys: 2.0,
        urban: false,
    };
}

/// Where a value a building is drawn with came from (issue 42: nothing invented silently).
#[derive(
    Clone, Copy, Debug, Default, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize,
)]
#[serde(rename_all = "lowercase")]
pub enum ValueSource {
    /// The building's own tag or GIS attribute.
    Tag,
    /// Its tagged neighbours (similarity- and distance-weighted votes over the model).
    Neighbours,
    /// The estimator fitted on this run's tagged buildings (cross-validated in the run).
    Fitted,
    /// The compact model shipped with the knowledge base (fitted offline, `docs/truth.md`).
    Model,
    /// The knowledge base's appearance, drawn from the zone's mix.
    #[default]
    Kb,
}

impl ValueSource {
    /// The word written in every output: `tag`, `neighbours`, `fitted`, `model`, `kb`.
    pub fn name(self) -> &'static str {
        match self {
            ValueSource::Tag => "tag",
            ValueSource::Neighbours => "neighbours",
            ValueSource::Fitted => "fitted",
            ValueSource::Model => "model",
            ValueSource::Kb => "kb",
        }
    }
}

/// Where a building's storeys, height and roof came from, with their uncertainty: written as
/// attributes in every output and counted in the report. Set on the tags by the estimator
/// (`prepare::estimate`); a building without one has tag or KB provenance from its tags.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Provenance {
    /// Source of the storey count.
    pub storeys: ValueSource,
    /// Its uncertainty, ± storeys (the estimator's cross-validated or fitted mean absolute
    /// error, or half the KB's range); `None` for a tag.
    pub storeys_error: Option<f64>,
    /// Source of the height (top of the roof above the base).
    pub height: ValueSource,
    /// Its uncertainty, ± metres; `None` for a tag.
    pub height_error: Option<f64>,
    /// Source of the roof shape.
    pub roof: ValueSource,
    /// The probability that the roof's family (flat or pitched) is right; `None` for a tag.
    pub roof_probability: Option<f64>,
}

impl Provenance {
    /// These values as the writers write them: every uncertainty and probability rounded to
    /// 0.001 (a non-finite or negative one dropped, a probability kept within 0..=1), so
    /// that every output says the same number.
    pub(crate) fn rounded(self) -> Provenance {
        let r = |x: Option<f64>| {
            x.filter(|v| v.is_finite() && *v >= 0.0)
                .map(|v| (v * 1000.0).round() / 1000.0)
        };
        Provenance {
            storeys_error: r(self.storeys_error),
            height_error: r(self.height_error),
            roof_probability: r(self.roof_probability).map(|p| p.min(1.0)),
            ..self
        }
    }
}

/// The `infer` attribute: which values of an untagged building may come from its tagged
/// neighbours. Written as `none`, `all`, or a comma-separated list of `levels`, `roof` and
/// `colour` (`color` accepted).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Inference {
    /// Storeys, from the neighbours' `building:levels` (or `height` over the floor height).
    pub levels: bool,
    /// Roof shape, from the neighbours' `roof:shape`.
    pub roof: bool,
    /// Wall and roof colours, from the neighbours' `building:colour` and `roof:colour`.
    pub colour: bool,
}

impl Inference {
    /// Nothing is inferred.
    pub const NONE: Inference = Inference {
        levels: false,
        roof: false,
        colour: false,
    };
    /// Everything that can be is inferred.
    pub const ALL: Inference = Inference {
        levels: true,
        roof: true,
        colour: true,
    };

    /// Parses the attribute (case-insensitive); `None` for an unknown word.
    pub fn parse(s: &str) -> Option<Inference> {
        let s = s.trim().to_ascii_lowercase();
        match s.as_str() {
            "none" | "no" | "off" => return Some(Inference::NONE),
            "all" | "yes" | "on" => return Some(Inference::ALL),
            _ => {}
        }
        let mut out = Inference::NONE;
        for w in s.split([',', ' ']).map(str::trim).filter(|w| !w.is_empty()) {
            match w {
                "levels" | "storeys" | "height" => out.levels = true,
                "roof" | "roofs" => out.roof = true,
                "colour" | "color" | "colours" | "colors" => out.colour = true,
                _ => return None,
            }
        }
        Some(out)
    }

    /// Whether anything is inferred.
    pub fn any(self) -> bool {
        self.levels || self.roof || self.colour
    }

    /// The attribute as written back: `none` or the list.
    pub(crate) fn as_string(self) -> String {
        let words: Vec<&str> = [
            (self.levels, "levels"),
            (self.roof, "roof"),
            (self.colour, "colour"),
        ]
        .into_iter()
        .filter_map(|(on, w)| on.then_some(w))
        .collect();
        if words.is_empty() {
            "none".into()
        } else {
            words.join(",")
        }
    }
}

/// The ground's heights on a regular grid of the run's local frame (issue 44: terrain from a
/// DEM): what the DEM reader hands on, resampled into the frame the buildings are in, for the
/// terrain the writers write. Heights are metres in the DEM's vertical datum.
#[derive(Clone, Debug, PartialEq)]
pub struct ElevationGrid {
    /// Local-frame (x, y) of sample (0, 0), the south-west corner of the grid.
    pub origin: DVec2,
    /// Distance between neighbouring samples along x and along y, metres (> 0).
    pub step: f64,
    /// Samples along x (columns).
    pub nx: usize,
    /// Samples along y (rows).
    pub ny: usize,
    /// Heights row by row from the south (`z[j * nx + i]` is at `origin + step * (i, j)`);
    /// `NaN` where the DEM has no data.
    pub z: Vec<f32>,
}

impl ElevationGrid {
    /// The sample at column `i`, row `j`; `None` outside the grid or where it has no data.
    pub fn get(&self, i: usize, j: usize) -> Option<f64> {
        if i >= self.nx || j >= self.ny {
            return None;
        }
        let v = *self.z.get(j * self.nx + i)?;
        v.is_finite().then_some(f64::from(v))
    }

    /// The height at local point `p`, bilinear between the four samples around it; `None`
    /// outside the grid or when one of the four has no data.
    pub fn height_at(&self, p: DVec2) -> Option<f64> {
        if self.step.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater)
            || self.nx == 0
            || self.ny == 0
        {
            return None;
        }
        let g = (p - self.origin) / self.step;
        let (max_i, max_j) = ((self.nx - 1) as f64, (self.ny - 1) as f64);
        if !(g.x >= 0.0 && g.y >= 0.0 && g.x <= max_i && g.y <= max_j) {
            return None;
        }
        // The cell's lower-left sample, kept one short of the last so the point at the far
        // edge interpolates inside the last cell.
        let i = (g.x.floor() as usize).min(self.nx.saturating_sub(2));
        let j = (g.y.floor() as usize).min(self.ny.saturating_sub(2));
        let (fx, fy) = (g.x - i as f64, g.y - j as f64);
        // Samples of weight 0 are not needed: a point on a sample or an edge between two
        // known samples has a height even beside a nodata sample.
        let mut sum = 0.0;
        for (di, dj, w) in [
            (0, 0, (1.0 - fx) * (1.0 - fy)),
            (1, 0, fx * (1.0 - fy)),
            (0, 1, (1.0 - fx) * fy),
            (1, 1, fx * fy),
        ] {
            if w > 0.0 {
                sum += w * self.get(i + di, j + dj)?;
            }
        }
        Some(sum)
    }
}

/// A triangulated terrain surface (TIN) for one output file (a run, or one tile of it), in the
/// local frame: what the writers write as CityGML/CityJSON `TINRelief`, a glTF terrain node,
/// the IFC site's terrain and a 3D Tiles terrain content.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Terrain {
    /// The TIN's points (local frame, metres; z in the output's vertical datum).
    pub vertices: Vec<DVec3>,
    /// Triangles as indices into `vertices`, counter-clockwise seen from above.
    pub triangles: Vec<[u32; 3]>,
    /// The largest vertical distance, metres, between the TIN and the grid it simplifies.
    pub tolerance: f64,
}

/// What the heights of a run's outputs are measured from (issue 44). Without terrain (no
/// `--dem`, no `--ground-height`) a run states none: every building stands on z = 0.
#[derive(Clone, Debug, PartialEq)]
pub enum VerticalDatum {
    /// Heights above a geoid or mean sea level (orthometric), as a DEM gives them: the
    /// datum's EPSG code when the DEM names it (e.g. 5773 for EGM96, 3855 for EGM2008), and a
    /// name for headers.
    Orthometric {
        /// EPSG code of the vertical CRS, when known.
        epsg: Option<u32>,
        /// Its name (e.g. `EGM96 height`), or a description when the code is unknown.
        name: String,
    },
}

#[cfg(test)]
mod source_id_tests {
    use super::*;

    #[test]
    fn text_ids_are_interned_keyed_as_xml_ids_and_seeded_by_their_text() {
        let bag = SourceId::text("NL.IMBAG.Pand.0599100000012345");
        assert_eq!(bag, SourceId::text("NL.IMBAG.Pand.0599100000012345"));
        assert_eq!(bag.to_string(), "NL.IMBAG.Pand.0599100000012345");
        assert_eq!(bag.key(), "NL.IMBAG.Pand.0599100000012345");
        assert_eq!(std::mem::size_of::<SourceId>(), 16);
        // Not XML-id characters: replaced, and the text's hash appended.
        let guid = SourceId::text("{3F2504E0-4F89-11D3-9A0C-0305E82C3301}");
        assert_eq!(
            guid.key(),
            format!(
                "_3F2504E0-4F89-11D3-9A0C-0305E82C3301__h{:08x}",
                fnv1a(b"{3F2504E0-4F89-11D3-9A0C-0305E82C3301}") >> 32
            )
        );
        assert_ne!(SourceId::text("a b").key(), SourceId::text("a:b").key());
        assert!(SourceId::text("").key().starts_with("_h"));
        // The seed is the text's, fixed: the same in every run (pinned) and apart from the
        // numbered ids'.
        assert_eq!(fnv1a(b"a"), 0xaf63_dc4c_8601_ec8c);
        assert_eq!(
            SourceId::text("osgb1000012345678").seed_value(),
            fnv1a(b"osgb1000012345678") ^ 0xD1B5_4A32_D192_ED03
        );
        assert_ne!(
            SourceId::text("7").seed_value(),
            SourceId::Feature(7).seed_value()
        );
        // Ordered by text, after the numbered ids.
        assert!(SourceId::text("b") > SourceId::text("a"));
        assert!(SourceId::text("a") > SourceId::Feature(u64::MAX));
    }
}

#[cfg(test)]
mod elevation_tests {
    use super::*;

    #[test]
    fn bilinear_inside_none_outside_and_at_nodata() {
        // z = x + 10 y on a 3 x 2 grid of 2 m, origin (100, 200).
        let g = ElevationGrid {
            origin: DVec2::new(100.0, 200.0),
            step: 2.0,
            nx: 3,
            ny: 2,
            z: vec![0.0, 2.0, 4.0, 20.0, 22.0, f32::NAN],
        };
        let h = g.height_at(DVec2::new(101.0, 201.0)).unwrap();
        assert!((h - 11.0).abs() < 1e-9, "{h}");
        // The far corner of the first cell, on the grid's edge.
        assert_eq!(g.height_at(DVec2::new(102.0, 202.0)), Some(22.0));
        assert_eq!(g.height_at(DVec2::new(99.9, 201.0)), None);
        assert_eq!(
            g.height_at(DVec2::new(103.0, 201.0)),
            None,
            "a nodata corner"
        );
        assert_eq!(g.get(2, 1), None);
    }
}

/// How built-up a footprint's surroundings are: the built-up share of the ground within
/// 250 m (issue 42: a village's houses and a centre's blocks draw different appearances).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Density {
    /// Under 10 % built: villages, suburbs of detached houses, the countryside.
    Low,
    /// 10 to 25 % built: towns, suburbs of rows and small blocks.
    Medium,
    /// 25 % built or more: town and city centres.
    High,
}

impl Density {
    /// The class of a built-up share (0..1).
    pub fn of_share(share: f64) -> Density {
        if share >= 0.25 {
            Density::High
        } else if share >= 0.10 {
            Density::Medium
        } else {
            Density::Low
        }
    }

    /// The word the knowledge base writes: `low`, `medium`, `high`.
    pub fn name(self) -> &'static str {
        match self {
            Density::Low => "low",
            Density::Medium => "medium",
            Density::High => "high",
        }
    }

    /// The class a knowledge-base word names.
    pub fn parse(s: &str) -> Option<Density> {
        match s {
            "low" => Some(Density::Low),
            "medium" => Some(Density::Medium),
            "high" => Some(Density::High),
            _ => None,
        }
    }
}

/// A footprint's place among its neighbours, as the knowledge base's appearance conditions
/// read it (set on the tags by `prepare` when the KB has conditions; the footprint's own area
/// is read from the lot when the building is derived).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Form {
    /// It shares a wall with a neighbour (at least a tenth of its outline touches another).
    pub attached: bool,
    /// Its surroundings' built-up class.
    pub density: Density,
}
