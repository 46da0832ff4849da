//! Input readers: OSM PBF and ESRI shapefiles, turned into [`Footprint`]s in the source CRS.
//!
//! Readers know nothing of the knowledge base, the grammar or the outputs. Every record they
//! skip or repair is reported through [`crate::report::Report`] with the record's id.

pub mod osm;
pub mod shp;
pub mod tags;

use std::fmt;

pub use tags::BuildingTags;

/// Where a footprint came from. Displayed as `way/123`, `relation/45` or `shp/7`
/// (shapefile record index, 0-based).
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum SourceId {
    Way(i64),
    Relation(i64),
    Shape(u64),
}

impl SourceId {
    /// `way_123`, `relation_45`, `shp_7`: usable in XML ids and file-safe names.
    pub fn key(&self) -> String {
        self.to_string().replace('/', "_")
    }

    /// A stable 64-bit value used to seed the building's random generator.
    pub fn seed_value(&self) -> u64 {
        match *self {
            SourceId::Way(i) => (i as u64).wrapping_mul(4).wrapping_add(1),
            SourceId::Relation(i) => (i as u64).wrapping_mul(4).wrapping_add(2),
            SourceId::Shape(i) => i.wrapping_mul(4).wrapping_add(3),
        }
    }

    /// Parses `way/123`, `w123`, `relation/4`, `r4`, `shp/7`.
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
        }
    }
}

/// One polygon ring in source coordinates: (x, y) = (lon, lat) in degrees for OSM,
/// or the shapefile's native coordinates. Not closed (first point not repeated).
pub type Ring = Vec<(f64, f64)>;

/// One polygon of a footprint in source coordinates.
#[derive(Clone, Debug, PartialEq)]
pub struct SourcePolygon {
    pub outer: Ring,
    pub holes: Vec<Ring>,
}

/// What kind of OSM object a footprint is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FootprintKind {
    /// A building outline (`building=*`, or any shapefile record).
    Building,
    /// A `building:part=*` piece.
    Part,
}

/// A building footprint as read, before projection. A multipolygon with several outer rings
/// gives one footprint with several polygons (one building, several parts of ground).
#[derive(Clone, Debug, PartialEq)]
pub struct Footprint {
    pub id: SourceId,
    pub kind: FootprintKind,
    pub polygons: Vec<SourcePolygon>,
    pub tags: BuildingTags,
}

/// Everything a reader produced.
#[derive(Debug, Default)]
pub struct ReadResult {
    /// Footprints in input order (OSM: ways by id, then relations by id; shapefile: record order).
    pub footprints: Vec<Footprint>,
    /// The source CRS: `None` means WGS84 lon/lat degrees (OSM); shapefiles give the CRS found in
    /// the `.prj` or `--src-crs`.
    pub source_crs: Option<crate::crs::Crs>,
}
