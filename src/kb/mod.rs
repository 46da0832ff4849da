//! The knowledge base of regional appearance (seed 003 §3.4): a zone tree
//! earth > country > region > town > district, each zone with `<info>` defaults and a circle,
//! and `<appearance>` alternatives chosen by `proba`.
//!
//! Reading is in `xml`, rule generation in `compile`. This module holds the zone tree, the
//! R-tree that finds the zone of a point, value inheritance and the [`Style`] of one building.
//!
//! Invariants: zone 0 is `earth`; a zone's parent always has a smaller index (document order);
//! [`KnowledgeBase::locate`] and [`KnowledgeBase::style_for`] never panic and depend only on
//! their arguments (no clocks, no hash order).

pub(crate) mod compile;
mod dom;
pub mod edit;
pub mod learn;
pub(crate) mod polygon;
mod strict;
pub mod tools;
mod values;
pub mod write;
pub(crate) mod xml;

use std::path::{Component, Path, PathBuf};

use rstar::primitives::{GeomWithData, Rectangle};
use rstar::RTree;

use crate::color::Color;
use crate::input::BuildingTags;
use crate::model::RoofShape;
use crate::rng::Rng;

pub use crate::model::Inference;
pub use polygon::{PolygonError, ZonePolygon};
pub use values::{
    Appearance, OpeningSplit, OpeningTree, SplitAxis, Values, WindowHeight, ZoneKind,
};
pub use xml::{KbError, KbRepair, ReadMode};

/// Mean Earth radius (IUGG), km: used for circle containment and bounding boxes.
/// The steepest `roof:angle` drawn as tagged, in degrees. Steeper tags (up to 90°, which
/// `roof:angle` allows) are drawn at this pitch with a note: near 90° the height of a roof
/// from its pitch grows without bound (89.9999° over a 10 m house is 2,858 km).
pub const MAX_TAGGED_PITCH_DEG: f64 = 85.0;

/// The highest roof a tag may ask for (`roof:height`, or `roof:levels` × floor height), in
/// metres: twice the tallest church spire (Ulm Minster's, 161.5 m above the street). Higher
/// tags are drawn at this height with a note.
pub const MAX_TAGGED_ROOF_HEIGHT_M: f64 = 320.0;

const EARTH_RADIUS_KM: f64 = 6371.0088;
/// Kilometres per degree of latitude on the mean sphere.
const KM_PER_DEG: f64 = EARTH_RADIUS_KM * std::f64::consts::PI / 180.0;

/// Built-in defaults, used where neither the KB nor the tags say anything.
pub mod defaults {
    use crate::color::Color;
    use crate::model::RoofShape;

    /// Storey height, metres.
    pub const FLOOR_HEIGHT: f64 = 3.0;
    /// Storeys above ground.
    pub const STOREYS: u32 = 2;
    /// Roof shape.
    pub const ROOF: RoofShape = RoofShape::Gabled;
    /// Roof pitch, degrees.
    pub const ROOF_ANGLE_DEG: f64 = 30.0;
    /// Walls: white.
    pub const WALL_COLOR: Color = Color::WHITE;
    /// Roof: CSS `darkred` (#8b0000).
    pub const ROOF_COLOR: Color = Color::from_rgb24(0x8b0000);
    /// Glass: CSS `lightsteelblue`.
    pub const WINDOW_COLOR: Color = Color::from_rgb24(0xb0c4de);
    /// Window frames: white.
    pub const FRAME_COLOR: Color = Color::WHITE;
    /// Doors: CSS `saddlebrown`.
    pub const DOOR_COLOR: Color = Color::from_rgb24(0x8b4513);
    /// Window width, metres.
    pub const WINDOW_WIDTH: f64 = 1.2;
    /// Main entrance door width without a `doorwidth` (metres).
    pub const DOOR_WIDTH: f64 = 1.0;
    /// The widths an entrance door is drawn at: a KB value outside is brought inside.
    pub const DOOR_WIDTH_RANGE: (f64, f64) = (0.8, 2.5);
    /// Main entrance door height without a `doorheight` (metres).
    pub const DOOR_HEIGHT: f64 = 2.2;
    /// The heights an entrance door is drawn at.
    pub const DOOR_HEIGHT_RANGE: (f64, f64) = (2.0, 2.6);
}

/// A zone circle: centre in WGS84 degrees, radius in kilometres.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Circle {
    /// Latitude of the centre, degrees, -90..=90 (`lat`).
    pub lat: f64,
    /// Longitude of the centre, degrees, -180..=180 (`lon`).
    pub lon: f64,
    /// Radius in kilometres (`dist`), positive; distances are great-circle on the mean sphere.
    pub radius_km: f64,
}

impl Circle {
    /// Great-circle (haversine) distance in km from the centre to (lon, lat).
    pub fn distance_km(&self, lon: f64, lat: f64) -> f64 {
        let (p1, p2) = (self.lat.to_radians(), lat.to_radians());
        let dp = p2 - p1;
        let dl = (lon - self.lon).to_radians();
        let a = (dp / 2.0).sin().powi(2) + p1.cos() * p2.cos() * (dl / 2.0).sin().powi(2);
        2.0 * EARTH_RADIUS_KM * a.clamp(0.0, 1.0).sqrt().asin()
    }

    /// Whether (lon, lat) lies in the circle (boundary included).
    pub fn contains(&self, lon: f64, lat: f64) -> bool {
        self.distance_km(lon, lat) <= self.radius_km
    }

    /// Lon/lat bounding boxes (degrees) that cover the circle: one, or two when the circle
    /// crosses the antimeridian. A circle reaching a pole covers every longitude.
    fn bboxes(&self) -> Vec<([f64; 2], [f64; 2])> {
        let dlat = self.radius_km / KM_PER_DEG;
        let (lat0, lat1) = (self.lat - dlat, self.lat + dlat);
        if lat0 <= -90.0 || lat1 >= 90.0 {
            return vec![([-180.0, lat0.max(-90.0)], [180.0, lat1.min(90.0)])];
        }
        // The widest longitude extent is at the latitude nearest a pole.
        let cos = lat0.abs().max(lat1.abs()).to_radians().cos();
        let dlon = dlat / cos.max(1e-9);
        if dlon >= 180.0 {
            return vec![([-180.0, lat0], [180.0, lat1])];
        }
        let lon = normalize_lon(self.lon);
        let (lon0, lon1) = (lon - dlon, lon + dlon);
        let mut out = vec![([lon0.max(-180.0), lat0], [lon1.min(180.0), lat1])];
        if lon0 < -180.0 {
            out.push(([lon0 + 360.0, lat0], [180.0, lat1]));
        }
        if lon1 > 180.0 {
            out.push(([-180.0, lat0], [lon1 - 360.0, lat1]));
        }
        out
    }
}

fn normalize_lon(lon: f64) -> f64 {
    let l = (lon + 180.0).rem_euclid(360.0) - 180.0;
    if l.is_finite() {
        l
    } else {
        0.0
    }
}

/// One zone of the tree.
#[derive(Clone, Debug, PartialEq)]
pub struct Zone {
    /// `designation` (`earth` for the root).
    pub name: String,
    /// Level of the zone, from its element name. Informational: what decides between zones is
    /// `depth`, not the kind.
    pub kind: ZoneKind,
    /// Names from the root, `/`-separated: `earth/France/Occitanie/Toulouse`.
    pub path: String,
    /// Index of the parent zone; `None` only for earth.
    pub parent: Option<usize>,
    /// 0 for earth, 1 for its children, ...
    pub depth: usize,
    /// The zone's circle (`<info lat lon dist>` or `<location>`); `None` means the zone is never
    /// matched by itself (its sub-zones still are).
    pub circle: Option<Circle>,
    /// The zone's `<polygon>` rings. A point is in the zone when it is in the circle or in any
    /// of these; a zone with neither is never matched by itself.
    pub polygons: Vec<ZonePolygon>,
    /// The zone's own `<info>` values, not inherited ones (see [`KnowledgeBase::resolved`]).
    pub info: Values,
    /// The zone's own appearances, in document order.
    pub appearances: Vec<Appearance>,
    /// Line of the zone's element.
    pub line: usize,
}

/// How a point relates to one zone's shapes ([`KnowledgeBase::zone_match`]).
#[derive(Clone, Debug, PartialEq)]
pub enum ZoneMatch {
    /// Inside the circle (`distance_km <= radius_km`), and no smaller polygon of the zone
    /// contains the point.
    Circle {
        /// Great-circle distance from the circle's centre to the point, km.
        distance_km: f64,
        /// The circle's radius, km.
        radius_km: f64,
    },
    /// Inside polygon `index` (0-based, document order) of the zone, the smallest of its
    /// shapes that contains the point.
    Polygon {
        /// 0-based index of the polygon in [`Zone::polygons`].
        index: usize,
        /// The polygon's area, km².
        area_km2: f64,
    },
    /// The zone has shapes but none contains the point; the distance to the circle's centre
    /// when it has one.
    Outside {
        /// Great-circle distance from the circle's centre to the point, km; `None` when the
        /// zone has no circle or the point is not finite.
        circle_distance_km: Option<f64>,
    },
    /// The zone has no circle and no polygon: never matched by itself.
    NoShape,
}

impl ZoneMatch {
    /// Area of the containing shape, km² (a circle counts as π r²); `None` when the point is
    /// not in the zone.
    pub fn area_km2(&self) -> Option<f64> {
        match self {
            ZoneMatch::Circle { radius_km, .. } => {
                Some(std::f64::consts::PI * radius_km * radius_km)
            }
            ZoneMatch::Polygon { area_km2, .. } => Some(*area_km2),
            _ => None,
        }
    }
}

/// A bounding box of one zone shape: (zone index, shape), the shape being [`CIRCLE_SHAPE`] or
/// the index of a polygon in [`Zone::polygons`].
type ZoneBox = GeomWithData<Rectangle<[f64; 2]>, (usize, usize)>;

/// The shape number of a zone's circle in the spatial index.
const CIRCLE_SHAPE: usize = usize::MAX;

/// The loaded knowledge base: zones in document order (zone 0 is earth) and a spatial index.
#[derive(Debug)]
pub struct KnowledgeBase {
    zones: Vec<Zone>,
    index: RTree<ZoneBox>,
    /// The file name used in messages.
    source: String,
    /// Folder that `ruleset file=` paths are relative to (the KB file's folder).
    base_dir: Option<PathBuf>,
}

/// Everything one building needs, resolved from the KB, the chosen appearance and the tags.
///
/// Heights are metres above the ground the footprint stands on. The walls run from `min_height`
/// to `eave_height`; the roof sits on top.
#[derive(Clone, Debug, PartialEq)]
pub struct Style {
    /// Top of the walls.
    pub eave_height: f64,
    /// OSM `height` when given: the top of the roof. When it is `Some` and `roof_height` is
    /// `None` on a pitched roof, `eave_height` is only a bound: the caller computes the roof
    /// height from the footprint and calls [`Style::fit_total_height`].
    pub total_height: Option<f64>,
    /// Storey height in metres: the KB's `floorsize`, default 3 m. Turns `building:levels`,
    /// `building:min_level` and `roof:levels` into heights, and is the grammar's `floorsize`.
    pub floor_height: f64,
    /// Storeys between `min_height` and `eave_height` (at least 1).
    pub storeys: u32,
    /// Roof shape: OSM `roof:shape` when it is tagged and known (an unknown value gives
    /// [`RoofShape::Flat`]), else the KB's `rooftype`, else gabled.
    pub roof: RoofShape,
    /// Roof pitch in degrees, 0 ≤ angle < 90: OSM `roof:angle` (at most [`MAX_TAGGED_PITCH_DEG`]),
    /// else the KB's `roofangle`, else 30.
    pub roof_angle_deg: f64,
    /// OSM `roof:direction`: the compass bearing (degrees from north) the main roof face looks
    /// towards, i.e. the way a skillion slopes down. `None`: chosen from the footprint.
    pub roof_direction: Option<f64>,
    /// OSM `roof:orientation=across`: a gabled roof's ridge runs parallel to the short side.
    pub roof_across: bool,
    /// `roof:height` when tagged (0 for a flat roof); `None`: computed from the angle later.
    pub roof_height: Option<f64>,
    /// Base of the walls (OSM `min_height` / `building:min_level`), 0 by default.
    pub min_height: f64,
    /// Wall colour: OSM `building:colour`, else the usual colour of `building:material`
    /// ([`material_color`]), else the KB's `color`, else white.
    pub wall_color: Color,
    /// Roof colour: OSM `roof:colour`, else the usual colour of `roof:material`, else the KB's
    /// `roofColor`, else CSS `darkred`.
    pub roof_color: Color,
    /// Glass / opening colour.
    pub window_color: Color,
    /// Window frame colour: the KB's `windowfcolor`, else white.
    pub frame_color: Color,
    /// Front door colour: the KB's `doorCol`, else CSS `saddlebrown`.
    pub door_color: Color,
    /// Window width, metres.
    pub window_width: f64,
    /// Main entrance door width, metres: the KB's `doorwidth` within
    /// [`defaults::DOOR_WIDTH_RANGE`], else [`defaults::DOOR_WIDTH`].
    pub door_width: f64,
    /// Main entrance door height, metres: the KB's `doorheight` within
    /// [`defaults::DOOR_HEIGHT_RANGE`], else [`defaults::DOOR_HEIGHT`].
    pub door_height: f64,
    /// Share (0..1) of upper-floor bays with a balcony (appearance value `balconies`).
    pub balconies: f64,
    /// LOD4 programme for buildings whose `building=*` names no type (value `programme`).
    pub programme: Option<crate::model::Programme>,
    /// Window height class: the KB's `windowheight`, else tall.
    pub window_height: WindowHeight,
    /// `framed`, `simple`, ... (lower-case).
    pub window_style: String,
    /// `glass`, ... (lower-case).
    pub window_material: String,
    /// Wall material (`BricksBasic`, OSM `building:material`, ...), when known.
    pub material: Option<String>,
    /// The chosen appearance's drawn window subdivision; `None`: one pane per window (zones'
    /// `<info>` have none).
    pub opening: Option<OpeningTree>,
    /// Path of the matched zone.
    pub zone_path: String,
    /// `<owner zone path>#<1-based appearance index>`, or `<zone path>#info` with no appearance.
    pub appearance_label: String,
    /// The chosen appearance's SELEX program ([`KnowledgeBase::selex_path`]): it lays out the
    /// facades at LOD3 instead of the rules' windows and doors. `None` when it names none (or
    /// names one outside the KB's folder, which `kb check` and the run's start refuse).
    pub selex: Option<PathBuf>,
    /// The chosen appearance's ruleset file ([`KnowledgeBase::ruleset_path`], inside the KB's
    /// folder): its buildings are derived with it instead of the rules compiled from the
    /// values (which still give the axiom's attributes: `eave`, `floorsize`, ...). `None` when
    /// it names none or names one outside the folder.
    pub ruleset: Option<PathBuf>,
    /// Whether `storeys` came from `building:levels` (then [`Style::fit_total_height`] keeps it).
    pub storeys_from_tags: bool,
    /// Whether the pitch came from `roof:angle`. A roof whose height follows from the
    /// knowledge base's pitch alone is capped at the height of its walls (the caller applies
    /// it: see `derive`); a tagged pitch is drawn as tagged.
    pub pitch_from_tags: bool,
}

impl Style {
    /// Draws the roof flat (a piece that another stands on): the walls take the whole height
    /// when `total_height` is known, and the storeys follow unless `building:levels` fixed them.
    pub fn make_flat(&mut self) {
        self.roof = RoofShape::Flat;
        self.roof_height = Some(0.0);
        if let Some(total) = self.total_height {
            self.eave_height = total.max(self.min_height + 0.1);
            if !self.storeys_from_tags {
                self.storeys = storeys_for(self.eave_height - self.min_height, self.floor_height);
            }
        }
    }

    /// Sets the roof height once known and, when `total_height` is set, moves the eave to
    /// `total_height - roof_height` (never below `min_height` + 1 m, or + half the height below
    /// 2 m), recomputing `storeys` from
    /// the floor height unless `building:levels` fixed them.
    pub fn fit_total_height(&mut self, roof_height: f64) {
        if !roof_height.is_finite() || roof_height < 0.0 {
            return;
        }
        self.roof_height = Some(roof_height);
        if let Some(total) = self.total_height {
            // Walls of at least 1 m, or half the height of a unit lower than 2 m (a 1 m shed
            // keeps its 1 m: 0.5 m of walls under 0.5 m of roof).
            let least = (0.5 * (total - self.min_height)).clamp(0.0, 1.0);
            self.eave_height = (total - roof_height).max(self.min_height + least);
            if !self.storeys_from_tags {
                self.storeys = storeys_for(self.eave_height - self.min_height, self.floor_height);
            }
        }
    }
}

/// `v` brought within `range` (a KB value out of bounds is drawn at the nearest bound), `or`
/// without a finite positive value.
fn within(v: Option<f64>, range: (f64, f64), or: f64) -> f64 {
    v.filter(|x| x.is_finite() && *x > 0.0)
        .map_or(or, |x| x.clamp(range.0, range.1))
}

fn storeys_for(wall_height: f64, floor_height: f64) -> u32 {
    let n = (wall_height / floor_height).round();
    if n.is_finite() && n >= 1.0 {
        n.min(1000.0) as u32
    } else {
        1
    }
}

impl KnowledgeBase {
    /// Reads and parses a KB file leniently ([`ReadMode::Lenient`]). `ruleset file=` paths are
    /// then relative to its folder. Returns the repairs the lenient reader made, each with its
    /// line.
    pub fn load(path: &Path) -> Result<(KnowledgeBase, Vec<KbRepair>), KbError> {
        KnowledgeBase::load_with(path, ReadMode::Lenient)
    }

    /// Reads and parses a KB file in the given mode. Files larger than 64 MiB
    /// (`MAX_FILE_BYTES`) are refused before being read. In strict mode the repairs are
    /// always empty (anything to repair is an error).
    pub fn load_with(
        path: &Path,
        mode: ReadMode,
    ) -> Result<(KnowledgeBase, Vec<KbRepair>), KbError> {
        use std::io::Read;
        let name = path.display().to_string();
        let io = |source| KbError::Io {
            file: name.clone(),
            source,
        };
        let file = std::fs::File::open(path).map_err(io)?;
        let too_big = |len: u64| KbError::Limit {
            file: name.clone(),
            line: 1,
            col: 1,
            message: format!(
                "{len} bytes is more than the {}-byte cap on knowledge-base files",
                dom::MAX_FILE_BYTES
            ),
        };
        if let Ok(meta) = file.metadata() {
            if meta.len() > dom::MAX_FILE_BYTES {
                return Err(too_big(meta.len()));
            }
        }
        // Read at most one byte past the cap: the file may grow, or be a pipe.
        let mut bytes = Vec::new();
        file.take(dom::MAX_FILE_BYTES + 1)
            .read_to_end(&mut bytes)
            .map_err(io)?;
        if bytes.len() as u64 > dom::MAX_FILE_BYTES {
            return Err(too_big(bytes.len() as u64));
        }
        let text = String::from_utf8(bytes).map_err(|e| {
            io(std::io::Error::new(
                std::io::ErrorKind::InvalidData,
                format!("not UTF-8 (byte {})", e.utf8_error().valid_up_to()),
            ))
        })?;
        let (mut kb, repairs) = KnowledgeBase::parse_str_with(&text, &name, mode)?;
        kb.base_dir = Some(path.parent().map(Path::to_path_buf).unwrap_or_default());
        Ok((kb, repairs))
    }

    /// Parses KB text leniently; `file_name` is used in errors only.
    pub fn parse_str(
        text: &str,
        file_name: &str,
    ) -> Result<(KnowledgeBase, Vec<KbRepair>), KbError> {
        KnowledgeBase::parse_str_with(text, file_name, ReadMode::Lenient)
    }

    /// Parses KB text in the given mode; `file_name` is used in errors only.
    pub fn parse_str_with(
        text: &str,
        file_name: &str,
        mode: ReadMode,
    ) -> Result<(KnowledgeBase, Vec<KbRepair>), KbError> {
        let (zones, repairs) = xml::read_zones_with(text, file_name, mode)?;
        Ok((KnowledgeBase::from_zones(zones, file_name), repairs))
    }

    /// Parses KB text in the given mode as if it were the file at `path`: errors name it, and
    /// `ruleset file=` paths are relative to its folder (what [`KnowledgeBase::load_with`]
    /// gives for the same bytes; the editor checks its draft with it).
    pub fn parse_str_at(
        text: &str,
        path: &Path,
        mode: ReadMode,
    ) -> Result<(KnowledgeBase, Vec<KbRepair>), KbError> {
        let (mut kb, repairs) =
            KnowledgeBase::parse_str_with(text, &path.display().to_string(), mode)?;
        kb.base_dir = Some(path.parent().map(Path::to_path_buf).unwrap_or_default());
        Ok((kb, repairs))
    }

    /// A knowledge base with only the earth zone and the built-in defaults (used with `--rules`
    /// and no `--kb`).
    pub fn earth_only() -> KnowledgeBase {
        match KnowledgeBase::parse_str("<earth/>", "<built-in>") {
            Ok((kb, _)) => kb,
            Err(_) => unreachable!("the built-in knowledge base parses"),
        }
    }

    /// The path of a zone (`earth/France/...`), empty for an unknown index.
    pub fn zone_path(&self, zone: usize) -> &str {
        self.zones.get(zone).map_or("", |z| z.path.as_str())
    }

    /// Builds a KB from zones (zone 0 earth, parents before children) and indexes the
    /// bounding boxes of their circles and polygons.
    fn from_zones(zones: Vec<Zone>, source: &str) -> KnowledgeBase {
        let mut boxes = Vec::new();
        for (i, z) in zones.iter().enumerate() {
            if let Some(c) = z.circle {
                for (lo, hi) in c.bboxes() {
                    boxes.push(GeomWithData::new(
                        Rectangle::from_corners(lo, hi),
                        (i, CIRCLE_SHAPE),
                    ));
                }
            }
            for (k, p) in z.polygons.iter().enumerate() {
                boxes.push(GeomWithData::new(
                    Rectangle::from_corners(p.bbox.0, p.bbox.1),
                    (i, k),
                ));
            }
        }
        KnowledgeBase {
            zones,
            index: RTree::bulk_load(boxes),
            source: source.to_string(),
            base_dir: None,
        }
    }

    /// All zones in document order; index 0 is earth.
    pub fn zones(&self) -> &[Zone] {
        &self.zones
    }

    /// One zone (`None` when out of range).
    pub fn zone(&self, i: usize) -> Option<&Zone> {
        self.zones.get(i)
    }

    /// How many polygons the zones hold, and how many vertices those have.
    pub fn polygon_counts(&self) -> (usize, usize) {
        let polygons = self.zones.iter().flat_map(|z| &z.polygons);
        (
            polygons.clone().count(),
            polygons.map(|p| p.ring.len()).sum(),
        )
    }

    /// The file name given at load time.
    pub fn source(&self) -> &str {
        &self.source
    }

    /// Index of the zone with this path (`earth/France/...`), case-sensitive.
    pub fn find(&self, path: &str) -> Option<usize> {
        self.zones.iter().position(|z| z.path == path)
    }

    /// The zone (lon, lat) falls in: the deepest zone one of whose shapes (circle,
    /// great-circle distance; or polygon) contains the point. Ties at equal depth go to the
    /// zone whose containing shape has the smaller area (the more specific description), then
    /// to the first in document order. Earth (0) when no shape contains the point or the point
    /// is not finite. A zone need not lie inside its parent's shapes: depth in the tree decides.
    pub fn locate(&self, lon: f64, lat: f64) -> usize {
        if !lon.is_finite() || !lat.is_finite() {
            return 0;
        }
        let lon = normalize_lon(lon);
        let mut best: Option<(usize, f64, usize)> = None; // (depth, area, index)
                                                          // Each box is one shape. A zone's area is that of its smallest shape containing the
                                                          // point (`zone_match`): every polygon containing the point has its box met (a polygon's
                                                          // box is exact), and the circle, whose boxes only approximate it, is tried with each
                                                          // of the zone's boxes, as `zone_match` tries it whichever box led there.
        for b in self.index.locate_all_at_point([lon, lat]) {
            let (i, shape) = b.data;
            let Some(z) = self.zones.get(i) else { continue };
            let circle = z
                .circle
                .filter(|c| c.contains(lon, lat))
                .map(|c| std::f64::consts::PI * c.radius_km * c.radius_km);
            let polygon = z
                .polygons
                .get(shape)
                .filter(|p| p.contains(lon, lat))
                .map(|p| p.area_km2);
            let area = match (circle, polygon) {
                (Some(c), Some(p)) => Some(c.min(p)),
                (c, p) => c.or(p),
            };
            let Some(area) = area else {
                continue;
            };
            let better = match best {
                None => true,
                Some((d, a, j)) => {
                    z.depth > d || (z.depth == d && (area < a || (area == a && i < j)))
                }
            };
            if better {
                best = Some((z.depth, area, i));
            }
        }
        best.map_or(0, |(_, _, i)| i)
    }

    /// How (lon, lat) relates to one zone's own shapes: the smallest containing shape, or why
    /// none contains it. Used by [`KnowledgeBase::locate`] and to explain its choice.
    pub fn zone_match(&self, zone: usize, lon: f64, lat: f64) -> ZoneMatch {
        let Some(z) = self.zones.get(zone) else {
            return ZoneMatch::NoShape;
        };
        if z.circle.is_none() && z.polygons.is_empty() {
            return ZoneMatch::NoShape;
        }
        if !lon.is_finite() || !lat.is_finite() {
            return ZoneMatch::Outside {
                circle_distance_km: None,
            };
        }
        let lon = normalize_lon(lon);
        let mut best: Option<ZoneMatch> = None;
        if let Some(c) = z.circle {
            let d = c.distance_km(lon, lat);
            if d <= c.radius_km {
                best = Some(ZoneMatch::Circle {
                    distance_km: d,
                    radius_km: c.radius_km,
                });
            }
        }
        for (k, p) in z.polygons.iter().enumerate() {
            if p.contains(lon, lat) {
                let m = ZoneMatch::Polygon {
                    index: k,
                    area_km2: p.area_km2,
                };
                if best
                    .as_ref()
                    .and_then(ZoneMatch::area_km2)
                    .is_none_or(|a| p.area_km2 < a)
                {
                    best = Some(m);
                }
            }
        }
        best.unwrap_or(ZoneMatch::Outside {
            circle_distance_km: z.circle.map(|c| c.distance_km(lon, lat)),
        })
    }

    /// Indices from earth down to `zone` (inclusive). Empty for an unknown zone.
    pub fn lineage(&self, zone: usize) -> Vec<usize> {
        let mut out = Vec::new();
        let mut cur = if zone < self.zones.len() {
            Some(zone)
        } else {
            None
        };
        while let Some(i) = cur {
            out.push(i);
            // Parents precede children, so this always terminates.
            cur = self.zones.get(i).and_then(|z| z.parent).filter(|&p| p < i);
        }
        out.reverse();
        out
    }

    /// The zone's info values inherited from earth down: each zone's `<info>` is laid over its
    /// ancestors' ([`Values::overlay`]), so the most specific zone wins for every key it sets.
    pub fn resolved(&self, zone: usize) -> Values {
        let mut v = Values::default();
        for i in self.lineage(zone) {
            if let Some(z) = self.zones.get(i) {
                v.overlay(&z.info);
            }
        }
        v
    }

    /// Per zone (in order): what its buildings may infer from tagged neighbours, its resolved
    /// `infer` value (nothing where no zone up to earth sets one).
    pub fn inference_by_zone(&self) -> Vec<Inference> {
        let mut out: Vec<Inference> = Vec::with_capacity(self.zones.len());
        for z in &self.zones {
            // Parents precede children: a zone's is its own or its parent's.
            let inherited = z
                .parent
                .and_then(|p| out.get(p).copied())
                .unwrap_or(Inference::NONE);
            out.push(z.info.infer.unwrap_or(inherited));
        }
        out
    }

    /// The appearances that apply to a zone: its own, or if it has none those of the nearest
    /// ancestor that has some. Returns the owning zone index and the slice (empty, owner 0, when
    /// no zone up to earth has any).
    pub fn appearances_for(&self, zone: usize) -> (usize, &[Appearance]) {
        for i in self.lineage(zone).into_iter().rev() {
            if let Some(z) = self.zones.get(i) {
                if !z.appearances.is_empty() {
                    return (i, &z.appearances);
                }
            }
        }
        (0, &[])
    }

    /// Which of the appearances that apply to `zone` ([`KnowledgeBase::appearances_for`]) a
    /// building of this OSM `building=*` kind may be drawn from: those whose `building` list
    /// names the kind (`None` and `yes` both stand for `yes`); if none does, those with no
    /// list; if every appearance has a list, all of them. Returns the owning zone and the
    /// indices, in appearance order (empty when no zone up to earth has an appearance).
    pub fn eligible_appearances(&self, zone: usize, kind: Option<&str>) -> (usize, Vec<usize>) {
        let (owner, apps) = self.appearances_for(zone);
        (owner, eligible(apps, kind))
    }

    /// Chooses one of the appearances that apply to `zone` for a building of this `building=*`
    /// kind ([`KnowledgeBase::eligible_appearances`]).
    ///
    /// Weights among the eligible appearances ([`appearance_weights`]): a given `proba` is
    /// used as is; appearances without one share what the given ones leave of 1 equally
    /// (nothing when they already sum to 1 or more); the weights are then normalised. If every
    /// weight is zero the choice is uniform. Draws exactly one number from `rng` when there is
    /// at least one eligible appearance. Returns (owner zone, index).
    pub fn pick_appearance(
        &self,
        zone: usize,
        kind: Option<&str>,
        rng: &mut Rng,
    ) -> Option<(usize, usize)> {
        let (owner, apps) = self.appearances_for(zone);
        let ids = eligible(apps, kind);
        let weights = proba_weights(ids.iter().map(|&i| apps[i].proba));
        rng.pick_weighted(&weights)
            .and_then(|k| ids.get(k).copied())
            .map(|i| (owner, i))
    }

    /// Resolves the style of one building in `zone`.
    ///
    /// Precedence, lowest first: [`defaults`]; the zone's [`KnowledgeBase::resolved`] info
    /// (`nbfloor`, `floorsize`, `rooftype`, `roofangle`, colours, ...); the chosen appearance's
    /// `<values>` (its ranges drawn with `rng`); then the OSM tags, which always win:
    /// - `height` (total, roof included) sets `total_height`; the eave is `height - roof:height`
    ///   when `roof:height` is tagged or the roof is flat, else the caller fits it
    ///   ([`Style::fit_total_height`]); without `height`, `building:levels` L sets the eave to
    ///   L × floor height;
    /// - `building:levels` L sets `storeys` (minus `building:min_level`);
    /// - `min_height` (else `building:min_level` × floor height) sets the base;
    /// - `roof:shape`, `roof:angle`, `roof:height`, `building:colour`, `roof:colour`,
    ///   `building:material`.
    ///
    /// Height drawing from the appearance: floors in `minFloors..=maxFloors` when given, the
    /// eave being floors × floor height clamped into `minHeight..=maxHeight`; otherwise an eave
    /// in `minHeight..maxHeight` and the storeys that fit; otherwise `nbfloor` storeys.
    /// Every override and every inconsistency fixed is described in the returned notes.
    pub fn style_for(
        &self,
        zone: usize,
        tags: &BuildingTags,
        rng: &mut Rng,
    ) -> (Style, Vec<String>) {
        let zone = if zone < self.zones.len() { zone } else { 0 };
        let pick = self.pick_appearance(zone, tags.building.as_deref(), rng);
        self.style_with_appearance(zone, pick, tags, rng)
    }

    /// [`KnowledgeBase::style_for`] with the appearance already chosen: `pick` is (owner zone,
    /// appearance index) as [`KnowledgeBase::pick_appearance`] returns it, or `None` for the
    /// zone's info values alone. Draws the heights from `rng` as `style_for` does. An
    /// out-of-range `zone` is earth; an out-of-range `pick` is ignored (info values alone).
    pub fn style_with_appearance(
        &self,
        zone: usize,
        pick: Option<(usize, usize)>,
        tags: &BuildingTags,
        rng: &mut Rng,
    ) -> (Style, Vec<String>) {
        let mut notes = Vec::new();
        let zone = if zone < self.zones.len() { zone } else { 0 };
        let zone_path = self
            .zones
            .get(zone)
            .map(|z| z.path.clone())
            .unwrap_or_else(|| "earth".into());
        let mut v = self.resolved(zone);
        let mut opening = None;
        let app = pick.and_then(|(owner, i)| {
            let z = self.zones.get(owner)?;
            Some((z, i, z.appearances.get(i)?))
        });
        let appearance_label = match app {
            Some((owner, i, app)) => {
                v.overlay(&app.values);
                opening = app.opening.clone();
                format!("{}#{}", owner.path, i + 1)
            }
            None => format!("{zone_path}#info"),
        };

        let floor_height = v
            .floor_height
            .filter(|h| h.is_finite() && *h > 0.0)
            .unwrap_or(defaults::FLOOR_HEIGHT);
        let (storeys, wall_height) = draw_heights(&v, floor_height, rng, &mut notes);

        let mut style = Style {
            eave_height: wall_height,
            total_height: None,
            floor_height,
            storeys,
            roof: v.roof.unwrap_or(defaults::ROOF),
            roof_direction: None,
            roof_across: false,
            roof_angle_deg: v
                .roof_angle
                .filter(|a| a.is_finite() && (0.0..90.0).contains(a))
                .unwrap_or(defaults::ROOF_ANGLE_DEG),
            roof_height: None,
            min_height: 0.0,
            wall_color: v.wall_color.unwrap_or(defaults::WALL_COLOR),
            roof_color: v.roof_color.unwrap_or(defaults::ROOF_COLOR),
            window_color: v.window_color.unwrap_or(defaults::WINDOW_COLOR),
            frame_color: v.frame_color.unwrap_or(defaults::FRAME_COLOR),
            door_color: v.door_color.unwrap_or(defaults::DOOR_COLOR),
            window_width: v
                .window_width
                .filter(|w| w.is_finite() && *w > 0.0)
                .unwrap_or(defaults::WINDOW_WIDTH),
            door_width: within(
                v.door_width,
                defaults::DOOR_WIDTH_RANGE,
                defaults::DOOR_WIDTH,
            ),
            door_height: within(
                v.door_height,
                defaults::DOOR_HEIGHT_RANGE,
                defaults::DOOR_HEIGHT,
            ),
            balconies: v
                .balconies
                .filter(|b| b.is_finite())
                .map_or(0.0, |b| b.clamp(0.0, 1.0)),
            programme: v.programme,
            window_height: v.window_height.unwrap_or(WindowHeight::Tall),
            window_style: v
                .window_style
                .clone()
                .unwrap_or_else(|| "framed".into())
                .to_ascii_lowercase(),
            window_material: v
                .window_material
                .clone()
                .unwrap_or_else(|| "glass".into())
                .to_ascii_lowercase(),
            material: v.material.clone(),
            opening,
            zone_path,
            appearance_label,
            selex: pick.and_then(|(owner, i)| self.selex_path(owner, i).ok().flatten()),
            ruleset: pick.and_then(|(owner, i)| self.ruleset_path(owner, i, false).ok().flatten()),
            storeys_from_tags: false,
            pitch_from_tags: false,
        };
        apply_tags(&mut style, tags, &mut notes);
        (style, notes)
    }

    /// Where an appearance's `ruleset file=` points, resolved against the KB's folder.
    /// Refuses absolute paths and paths that climb out of that folder (`..`) unless
    /// `allow_outside` is set. `Ok(None)` when the appearance names no ruleset.
    pub fn ruleset_path(
        &self,
        zone: usize,
        appearance: usize,
        allow_outside: bool,
    ) -> Result<Option<PathBuf>, KbError> {
        self.appearance_file(zone, appearance, "ruleset", allow_outside, |a| {
            a.ruleset.as_deref()
        })
    }

    /// Where an appearance's `selex file=` points, resolved against the KB's folder, with the
    /// same refusals as [`KnowledgeBase::ruleset_path`] (a SELEX program is always inside the
    /// KB's folder: no `allow_outside`). `Ok(None)` when the appearance names none.
    pub fn selex_path(&self, zone: usize, appearance: usize) -> Result<Option<PathBuf>, KbError> {
        self.appearance_file(zone, appearance, "selex", false, |a| a.selex.as_deref())
    }

    fn appearance_file(
        &self,
        zone: usize,
        appearance: usize,
        what: &str,
        allow_outside: bool,
        file: impl Fn(&Appearance) -> Option<&str>,
    ) -> Result<Option<PathBuf>, KbError> {
        let Some(app) = self
            .zones
            .get(zone)
            .and_then(|z| z.appearances.get(appearance))
        else {
            return Ok(None);
        };
        let Some(file) = file(app) else {
            return Ok(None);
        };
        let rel = Path::new(file);
        let mut depth: i64 = 0;
        let mut escapes = rel.is_absolute();
        for c in rel.components() {
            match c {
                Component::ParentDir => depth -= 1,
                Component::Normal(_) => depth += 1,
                Component::CurDir => {}
                Component::RootDir | Component::Prefix(_) => escapes = true,
            }
            if depth < 0 {
                escapes = true;
            }
        }
        if escapes && !allow_outside {
            return Err(KbError::Structure {
                file: self.source.clone(),
                line: app.line,
                message: format!(
                    "{what} file \"{file}\" lies outside the knowledge base's folder; \
                     move it next to the KB{}",
                    if what == "ruleset" {
                        " or allow outside rulesets explicitly"
                    } else {
                        ""
                    }
                ),
            });
        }
        Ok(Some(match &self.base_dir {
            Some(d) => d.join(rel),
            None => rel.to_path_buf(),
        }))
    }
}

/// Indices of the appearances a building of this kind is drawn from; see
/// [`KnowledgeBase::eligible_appearances`].
pub fn eligible(apps: &[Appearance], kind: Option<&str>) -> Vec<usize> {
    let kind = kind
        .map(str::trim)
        .filter(|k| !k.is_empty())
        .unwrap_or("yes");
    let named: Vec<usize> = (0..apps.len())
        .filter(|&i| {
            apps[i]
                .buildings
                .iter()
                .any(|b| b.eq_ignore_ascii_case(kind))
        })
        .collect();
    if !named.is_empty() {
        return named;
    }
    let open: Vec<usize> = (0..apps.len())
        .filter(|&i| apps[i].buildings.is_empty())
        .collect();
    if open.is_empty() {
        (0..apps.len()).collect()
    } else {
        open
    }
}

/// The weights [`KnowledgeBase::pick_appearance`] uses over a set of appearances, in order.
pub fn appearance_weights(apps: &[Appearance]) -> Vec<f64> {
    proba_weights(apps.iter().map(|a| a.proba))
}

/// The weights of appearances with these `proba`s, in order: given ones as they are, absent
/// ones sharing what the given leave of 1, normalised (see [`KnowledgeBase::pick_appearance`]).
pub fn proba_weights(probas: impl Iterator<Item = Option<f64>> + Clone) -> Vec<f64> {
    let given: f64 = probas.clone().flatten().sum();
    let missing = probas.clone().filter(Option::is_none).count();
    let share = if missing > 0 {
        ((1.0 - given) / missing as f64).max(0.0)
    } else {
        0.0
    };
    let raw: Vec<f64> = probas.map(|p| p.unwrap_or(share)).collect();
    let total: f64 = raw.iter().sum();
    if total > 0.0 {
        raw.iter().map(|w| w / total).collect()
    } else {
        raw
    }
}

/// Draws (storeys, eave height) from the merged values; see [`KnowledgeBase::style_for`].
fn draw_heights(v: &Values, fh: f64, rng: &mut Rng, notes: &mut Vec<String>) -> (u32, f64) {
    let ok = |x: &f64| x.is_finite() && *x > 0.0;
    let (min_h, max_h) = (v.min_height.filter(ok), v.max_height.filter(ok));
    let height_range = match (min_h, max_h) {
        (Some(a), Some(b)) => Some((a.min(b), a.max(b))),
        (Some(a), None) | (None, Some(a)) => Some((a, a)),
        (None, None) => None,
    };
    let floors = match (
        v.min_floors.filter(|f| *f > 0),
        v.max_floors.filter(|f| *f > 0),
    ) {
        (Some(a), Some(b)) => Some((a.min(b), a.max(b))),
        (Some(a), None) | (None, Some(a)) => Some((a, a)),
        (None, None) => None,
    };
    match (floors, height_range) {
        (Some((f0, f1)), hr) => {
            let n = draw_int(rng, f0, f1);
            let mut h = f64::from(n) * fh;
            if let Some((a, b)) = hr {
                let c = h.clamp(a, b);
                // A millimetre of rounding (3 x 3.3 = 9.899999...) is not a disagreement.
                if (c - h).abs() > 1e-3 {
                    notes.push(format!(
                        "appearance floors ({n} x {fh} m) and heights ({a}..{b} m) disagree: eave {c} m"
                    ));
                    h = c;
                }
            }
            (n, h)
        }
        (None, Some((a, b))) => {
            let h = if b > a { rng.range(a, b) } else { a };
            (storeys_for(h, fh), h)
        }
        (None, None) => {
            let n = v.storeys.filter(|n| *n > 0).unwrap_or(defaults::STOREYS);
            (n, f64::from(n) * fh)
        }
    }
}

/// Uniform integer in a..=b.
fn draw_int(rng: &mut Rng, a: u32, b: u32) -> u32 {
    if b <= a {
        return a;
    }
    let span = u64::from(b - a) + 1;
    a + (rng.next_u64() % span) as u32
}

/// Applies the OSM overrides; see [`KnowledgeBase::style_for`].
fn apply_tags(s: &mut Style, t: &BuildingTags, notes: &mut Vec<String>) {
    let fh = s.floor_height;
    if let Some(shape) = t.roof_shape {
        s.roof = shape;
    } else if let Some(v) = &t.invalid_roof_shape {
        // An unreadable roof:shape says the mapper saw some roof we cannot name: flat is the
        // honest drawing, not the zone's default roof.
        s.roof = RoofShape::Flat;
        notes.push(format!(
            "roof:shape={v} is not a known roof shape: roof drawn flat"
        ));
    }
    if let Some(a) = t
        .roof_angle
        .filter(|a| a.is_finite() && (0.0..90.0).contains(a))
    {
        s.pitch_from_tags = true;
        s.roof_angle_deg = if a > MAX_TAGGED_PITCH_DEG {
            notes.push(format!(
                "roof:angle={a} is steeper than {MAX_TAGGED_PITCH_DEG}°: roof drawn at {MAX_TAGGED_PITCH_DEG}°"
            ));
            MAX_TAGGED_PITCH_DEG
        } else {
            a
        };
    }
    s.roof_direction = t
        .roof_direction
        .filter(|d| d.is_finite())
        .map(|d| d.rem_euclid(360.0));
    let bounded = |what: String, h: f64, notes: &mut Vec<String>| {
        if h > MAX_TAGGED_ROOF_HEIGHT_M {
            notes.push(format!(
                "{what} gives a roof {h} m high, above {MAX_TAGGED_ROOF_HEIGHT_M} m: roof drawn {MAX_TAGGED_ROOF_HEIGHT_M} m high"
            ));
            MAX_TAGGED_ROOF_HEIGHT_M
        } else {
            h
        }
    };
    // A flat roof has no height, whatever roof:height says: `height` is then the top of the
    // walls.
    if s.roof == RoofShape::Flat {
        s.roof_height = Some(0.0);
    } else if let Some(h) = t.roof_height.filter(|h| h.is_finite() && *h >= 0.0) {
        s.roof_height = Some(bounded(format!("roof:height={h}"), h, notes));
    } else if let Some(l) = t.roof_levels.filter(|l| l.is_finite() && *l > 0.0) {
        // S3DB: without roof:height, roof:levels storeys of the zone's height.
        s.roof_height = Some(bounded(format!("roof:levels={l}"), l * fh, notes));
    }
    let min_level = t.min_level.filter(|l| l.is_finite() && *l >= 0.0);
    if let Some(m) = t.min_height.filter(|m| m.is_finite() && *m >= 0.0) {
        s.min_height = m;
    } else if let Some(l) = min_level {
        s.min_height = l * fh;
    }
    let levels = t.levels.filter(|l| l.is_finite() && *l > 0.0);
    if let Some(l) = levels {
        let above = (l - min_level.unwrap_or(0.0)).round();
        s.storeys = if above >= 1.0 {
            above.min(1000.0) as u32
        } else {
            1
        };
        s.storeys_from_tags = true;
        s.eave_height = l * fh;
    } else if s.min_height > 0.0 {
        // The KB height is a wall height: stand it on the base.
        s.eave_height += s.min_height;
    }
    if let Some(h) = t.height.filter(|h| h.is_finite() && *h > 0.0) {
        s.total_height = Some(h);
        match s.roof_height {
            Some(rh) => {
                s.eave_height = h - rh;
                if levels.is_none() {
                    s.storeys = storeys_for(s.eave_height - s.min_height, fh);
                }
            }
            // Pitched roof of unknown height: an upper bound until the caller fits it.
            None => s.eave_height = s.eave_height.min(h),
        }
    }
    if s.eave_height <= s.min_height {
        notes.push(format!(
            "eave {} m not above base {} m (check height, roof:height and min_height): walls set to one storey of {fh} m",
            s.eave_height, s.min_height
        ));
        s.eave_height = s.min_height + fh;
        s.storeys = 1;
        if let Some(h) = s.total_height {
            if h <= s.eave_height {
                s.total_height = None;
            }
        }
    }
    // A colour tag wins; else a material tag gives its usual colour.
    if let Some(c) = t
        .colour
        .or_else(|| t.material.as_deref().and_then(material_color))
    {
        s.wall_color = c;
    }
    if let Some(c) = t
        .roof_colour
        .or_else(|| t.roof_material.as_deref().and_then(material_color))
    {
        s.roof_color = c;
    }
    if let Some(m) = &t.material {
        s.material = Some(m.clone());
    }
    if t.is_roof() {
        roof_on_pillars(s, t);
    }
}

/// Thickness of a `building=roof` drawn without `min_height` (metres): the roof slab.
pub const ROOF_SLAB_M: f64 = 0.5;

/// `building=roof` / `building:part=roof` (Simple 3D Buildings): a roof with no walls under it,
/// such as a canopy or a roof on pillars. It is drawn as a slab up to `height` (else
/// `building:levels` storeys, else one storey; with `min_height` alone, [`ROOF_SLAB_M`] above
/// it), under the tagged roof if any,
/// from `min_height` (else [`ROOF_SLAB_M`] thick): flat unless `roof:shape` says otherwise,
/// never the zone's roof and storeys.
fn roof_on_pillars(s: &mut Style, t: &BuildingTags) {
    let fh = s.floor_height;
    let base_tag = t
        .min_height
        .filter(|m| m.is_finite() && *m >= 0.0)
        .or_else(|| {
            t.min_level
                .filter(|l| l.is_finite() && *l >= 0.0)
                .map(|l| l * fh)
        });
    let top = t
        .height
        .filter(|h| h.is_finite() && *h > 0.0)
        .or_else(|| {
            t.levels
                .filter(|l| l.is_finite() && *l > 0.0)
                .map(|l| l * fh)
        })
        .filter(|h| base_tag.is_none_or(|b| *h > b))
        .unwrap_or_else(|| base_tag.map_or(fh, |b| b + ROOF_SLAB_M));
    s.storeys = 1;
    s.storeys_from_tags = true;
    if t.roof_shape.is_none() {
        s.roof = RoofShape::Flat;
        s.roof_height = Some(0.0);
    }
    // The slab's top: under a roof of known height, that much lower; under one of unknown
    // height, the slab's own thickness above its base, the roof fitted into the rest.
    let eave = match s.roof_height {
        Some(rh) if rh < top => top - rh,
        Some(_) => top,
        None => top - ROOF_SLAB_M,
    };
    let base = base_tag
        .filter(|b| *b < eave)
        .unwrap_or((eave - ROOF_SLAB_M).max(0.0));
    s.min_height = base;
    s.eave_height = eave.max(base + 0.05);
    s.total_height = (top > s.eave_height + 0.05 || s.roof == RoofShape::Flat).then_some(top);
    if s.roof == RoofShape::Flat {
        s.eave_height = top;
    }
}

/// The usual colour of an OSM `building:material` / `roof:material` value, when it has one.
pub fn material_color(material: &str) -> Option<Color> {
    let rgb = match material
        .trim()
        .to_ascii_lowercase()
        .replace(['-', ' '], "_")
        .as_str()
    {
        "roof_tiles" | "tiles" | "tile" | "clay" | "terracotta" => 0xb5523b,
        "slate" => 0x4a5259,
        "metal" | "metal_sheet" | "steel" | "tin" | "zinc" => 0x8a9197,
        "copper" => 0x6f9f8a,
        "concrete" | "cement_block" => 0xa8a8a0,
        "glass" => 0xa8c8d8,
        "thatch" => 0xb8a060,
        "tar_paper" | "asphalt" | "bitumen" | "eternit" => 0x3c3c3c,
        "wood" | "timber_framing" => 0x8b5a2b,
        "gravel" => 0x9a9a92,
        "grass" | "plants" => 0x6a8a3a,
        "stone" | "sandstone" | "limestone" => 0xa89f8f,
        "brick" | "bricks" => 0xa0522d,
        "plaster" | "render" | "stucco" => 0xe8dcc8,
        "marble" => 0xe8e6e0,
        _ => return None,
    };
    Some(Color::from_rgb24(rgb))
}

#[cfg(test)]
mod tests;
