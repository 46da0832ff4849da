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

pub(crate) mod boundaries;
mod choice;
pub(crate) mod compile;
mod dom;
pub mod edit;
pub mod learn;
pub(crate) mod polygon;
mod strict;
mod style;
pub mod tools;
mod values;
pub mod write;
pub(crate) mod xml;

use std::path::{Path, PathBuf};

use rstar::primitives::{GeomWithData, Rectangle};
use rstar::RTree;

use crate::color::Color;
use crate::model::RoofShape;

pub use crate::model::Inference;
pub(crate) use boundaries::{BoundaryZones, Located};
pub(crate) use choice::{eligible, proba_weights};
pub use polygon::ZonePolygon;
pub use style::{material_color, Style, ROOF_SLAB_M};
pub use values::{
    Appearance, Conditions, OpeningSplit, OpeningTree, SplitAxis, Values, WindowHeight, ZoneKind,
};
pub use xml::{KbError, KbRepair, ReadMode};

/// Mean Earth radius (IUGG), km: used for circle containment and bounding boxes.
/// The steepest `roof:angle` drawn as tagged, in degrees. Steeper tags (up to 90°, which
/// `roof:angle` allows) are drawn at this pitch with a note: near 90° the height of a roof
/// from its pitch grows without bound (89.9999° over a 10 m house is 2,858 km).
pub(crate) const MAX_TAGGED_PITCH_DEG: f64 = 85.0;

/// The highest roof a tag may ask for (`roof:height`, or `roof:levels` × floor height), in
/// metres: twice the tallest church spire (Ulm Minster's, 161.5 m above the street). Higher
/// tags are drawn at this height with a note.
pub(crate) const MAX_TAGGED_ROOF_HEIGHT_M: f64 = 320.0;

const EARTH_RADIUS_KM: f64 = 6371.0088;
/// Kilometres per degree of latitude on the mean sphere.
const KM_PER_DEG: f64 = EARTH_RADIUS_KM * std::f64::consts::PI / 180.0;

/// Built-in defaults, used where neither the KB nor the tags say anything.
pub mod defaults {
    use crate::color::Color;
    use crate::model::RoofShape;

    /// Storey height, metres.
    pub(crate) const FLOOR_HEIGHT: f64 = 3.0;
    /// Storeys above ground.
    pub(crate) const STOREYS: u32 = 2;
    /// Roof shape.
    pub(crate) const ROOF: RoofShape = RoofShape::Gabled;
    /// Roof pitch, degrees.
    pub(crate) const ROOF_ANGLE_DEG: f64 = 30.0;
    /// Walls: white.
    pub(crate) const WALL_COLOR: Color = Color::WHITE;
    /// Roof: CSS `darkred` (#8b0000).
    pub(crate) const ROOF_COLOR: Color = Color::from_rgb24(0x8b0000);
    /// Glass: CSS `lightsteelblue`.
    pub(crate) const WINDOW_COLOR: Color = Color::from_rgb24(0xb0c4de);
    /// Window frames: white.
    pub(crate) const FRAME_COLOR: Color = Color::WHITE;
    /// Doors: CSS `saddlebrown`.
    pub(crate) const DOOR_COLOR: Color = Color::from_rgb24(0x8b4513);
    /// Window width, metres.
    pub(crate) const WINDOW_WIDTH: f64 = 1.2;
    /// Main entrance door width without a `doorwidth` (metres).
    pub(crate) const DOOR_WIDTH: f64 = 1.0;
    /// The widths an entrance door is drawn at: a KB value outside is brought inside.
    pub(crate) const DOOR_WIDTH_RANGE: (f64, f64) = (0.8, 2.5);
    /// Main entrance door height without a `doorheight` (metres).
    pub(crate) const DOOR_HEIGHT: f64 = 2.2;
    /// The narrowest window or door drawn without a `minopeningwidth` (metres, issue 45).
    pub(crate) const MIN_OPENING_WIDTH: f64 = 0.4;
    /// The heights an entrance door is drawn at.
    pub(crate) const DOOR_HEIGHT_RANGE: (f64, f64) = (2.0, 2.6);
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
    pub(crate) fn distance_km(&self, lon: f64, lat: f64) -> f64 {
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

/// How a point relates to one zone's shapes (`KnowledgeBase::zone_match`).
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
    pub(crate) fn area_km2(&self) -> Option<f64> {
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
    pub(crate) fn parse_str_at(
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
    pub(crate) fn earth_only() -> KnowledgeBase {
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
        self.locate_where(lon, lat, |_| true).unwrap_or(0)
    }

    /// The deepest zone of `root`'s subtree (`root` included) containing (lon, lat), by
    /// [`KnowledgeBase::locate`]'s rules; `root` itself when none does.
    pub(crate) fn locate_within(&self, root: usize, lon: f64, lat: f64) -> usize {
        self.locate_where(lon, lat, |i| self.is_within(i, root))
            .unwrap_or(root)
    }

    /// Whether zone `zone` is `root` or below it.
    pub(crate) fn is_within(&self, mut zone: usize, root: usize) -> bool {
        // Parents precede children: walking up from `zone` passes `root` or goes below it.
        while zone > root {
            match self.zones.get(zone).and_then(|z| z.parent) {
                Some(p) if p < zone => zone = p,
                _ => return false,
            }
        }
        zone == root
    }

    /// [`KnowledgeBase::locate`] among the zones `keep` accepts; `None` when no shape of those
    /// contains the point or the point is not finite.
    fn locate_where(&self, lon: f64, lat: f64, keep: impl Fn(usize) -> bool) -> Option<usize> {
        if !lon.is_finite() || !lat.is_finite() {
            return None;
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
            if !keep(i) {
                continue;
            }
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
        best.map(|(_, _, i)| i)
    }

    /// How (lon, lat) relates to one zone's own shapes: the smallest containing shape, or why
    /// none contains it. Used by [`KnowledgeBase::locate`] and to explain its choice.
    pub(crate) fn zone_match(&self, zone: usize, lon: f64, lat: f64) -> ZoneMatch {
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
    pub(crate) fn lineage(&self, zone: usize) -> Vec<usize> {
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
    /// ancestors' (`Values::overlay`), so the most specific zone wins for every key it sets.
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
    pub(crate) fn inference_by_zone(&self) -> Vec<Inference> {
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
}

#[cfg(test)]
mod tests;
