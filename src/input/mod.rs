//! Input readers: OSM (PBF or XML), ESRI shapefiles, GeoJSON, GeoPackage and FlatGeobuf, turned into
//! [`Footprint`]s in the source CRS.
//!
//! Readers know nothing of the knowledge base, the grammar or the outputs. Every record they
//! skip or repair is reported through [`crate::report::Report`] with the record's id.

pub mod dem;
pub(crate) mod features;
pub mod fgb;
pub mod geojson;
pub mod gpkg;
pub mod osm;
pub(crate) mod rings;
pub mod shp;
pub(crate) mod tags;
pub mod wkt;

use std::path::PathBuf;

use thiserror::Error;

pub use osm::{read_osm, read_osm_with_changes};
pub use shp::{read_shp, ShpOptions};
pub use tags::{BuildingTags, SharedTags, TagInterner};

/// The `admin_level`s read as boundaries: a country (2) down to a neighbourhood (10).
pub(crate) const ADMIN_LEVELS: std::ops::RangeInclusive<u8> = 2..=10;

/// A file-level failure of a reader: the file cannot be read at all, or is corrupt in a way that
/// makes the rest of it untrustworthy. Record-level problems are report entries instead. Every
/// message names the file, and the place (blob, record) where one is known.
#[derive(Debug, Error)]
pub enum InputError {
    /// The file (or a companion file such as `.shx`/`.dbf`) cannot be opened or read.
    #[error("{}: cannot read the file: {source}", .path.display())]
    Io {
        /// The file that failed: the `--osm` or `--shp` file, or a companion (`.shx`, `.dbf`,
        /// `.prj`) beside it.
        path: PathBuf,
        /// The underlying I/O error.
        #[source]
        source: std::io::Error,
    },
    /// The file is not an OSM PBF file at all (empty, text, no OSMHeader block).
    #[error("{}: not an OSM PBF file: {reason}", .path.display())]
    NotPbf {
        /// The `--osm` file.
        path: PathBuf,
        /// What gave it away, e.g. `the file is empty`, `it is a directory`, `no PBF blocks
        /// found`.
        reason: String,
    },
    /// A PBF block cannot be framed or decoded (truncated or corrupt file).
    #[error("{}: corrupt or truncated PBF at block {block}{}: {reason}", .path.display(),
        .offset.map(|o| format!(" (byte offset {o})")).unwrap_or_default())]
    CorruptPbf {
        /// The `.osm.pbf` file.
        path: PathBuf,
        /// 0-based index of the blob in the file.
        block: usize,
        /// Byte offset of the blob's start, when known.
        offset: Option<u64>,
        /// What is wrong with the block, e.g. `the block cannot be decoded` or the decoder's error.
        reason: String,
    },
    /// A shapefile component is missing, not a shapefile, or of an unsupported shape type.
    #[error("{}: {reason}", .path.display())]
    Shapefile {
        /// The component at fault: the `.shp`, or its `.shx` or `.dbf`.
        path: PathBuf,
        /// What is wrong, e.g. `has 12 rows but the .shx indexes 13 shapes`.
        reason: String,
    },
    /// One shapefile record (or its attribute row) cannot be decoded; records after it cannot
    /// be trusted either.
    #[error("{}: record {record}: {reason}", .path.display())]
    ShapeRecord {
        /// The `.shp` when the geometry record is bad, the `.dbf` when its attribute row is.
        path: PathBuf,
        /// 0-based record index.
        record: usize,
        /// What is wrong, e.g. `undecodable record` or `no attribute row (deleted or missing rows in
        /// the .dbf)`.
        reason: String,
    },
    /// An OSM change file (osmChange XML, plain or gzip) cannot be decompressed or parsed, or
    /// names an element with an invalid id, coordinate, node reference, member or tag.
    #[error("{}: osmChange {place}: {reason}", .path.display())]
    OsmChange {
        /// The change file.
        path: PathBuf,
        /// Where: `line 12, node/34` (the element when one is known), or `gzip stream, after N
        /// decompressed bytes`.
        place: String,
        /// What is wrong, e.g. `lat 91.5 is outside -90..90`.
        reason: String,
    },
    /// An OSM XML file (`.osm`, plain, gzip or bzip2) cannot be decompressed or parsed, or
    /// names an element with an invalid id, coordinate, node reference, member or tag.
    #[error("{}: OSM XML {place}: {reason}", .path.display())]
    OsmXml {
        /// The `--osm` file.
        path: PathBuf,
        /// Where: `line 12 (byte 345), way/7` (the element when one is known; the byte offset
        /// is in the decompressed XML for a compressed file).
        place: String,
        /// What is wrong, e.g. `lat 'x' is not a number`.
        reason: String,
    },
    /// The `.prj` names a CRS citygen cannot use, or there is no CRS at all.
    #[error("{}: {reason}", .path.display())]
    Crs {
        /// The `.prj` beside the `.shp` (also when it is missing).
        path: PathBuf,
        /// Why no CRS could be used, ending with the advice to give one with `--src-crs`.
        reason: String,
    },
}

pub use crate::model::SourceId;

/// One polygon ring in source coordinates: (x, y) = (lon, lat) in degrees for OSM,
/// or the shapefile's native coordinates. Not closed (first point not repeated).
pub(crate) type Ring = Vec<(f64, f64)>;

/// One polygon of a footprint in source coordinates. Readers hand them out with the outer ring
/// counter-clockwise and the holes clockwise (x east, y north), at least 3 distinct points and
/// non-zero area per ring.
#[derive(Clone, Debug, PartialEq)]
pub struct SourcePolygon {
    /// Outer ring, counter-clockwise.
    pub outer: Ring,
    /// Hole rings, clockwise.
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
    /// Where the footprint came from: `way/123`, `relation/45` or `shp/7`.
    pub id: SourceId,
    /// Whether it is a building outline or a `building:part`.
    pub kind: FootprintKind,
    /// The footprint's polygons: one per outer ring with its holes.
    pub polygons: Vec<SourcePolygon>,
    /// Boxed: the parsed tags are large and most footprints move through the pipeline several
    /// times (reader, projection, lot), so only the pointer moves and memory stays compact.
    pub tags: tags::SharedTags,
}

/// Everything a reader produced.
#[derive(Debug, Default)]
pub struct ReadResult {
    /// Footprints in input order (OSM: ways by id, then relations by id; shapefile: record order).
    pub footprints: Vec<Footprint>,
    /// The source CRS: `None` means WGS84 lon/lat degrees (OSM); shapefiles give the CRS found in
    /// the `.prj` or `--src-crs`.
    pub source_crs: Option<crate::crs::Crs>,
    /// Street centre lines in the same coordinates as the footprints, used to turn each
    /// building's front door towards its street. OSM gives them (`osm::STREET_KINDS`);
    /// shapefiles of building footprints carry none, so their buildings keep the thesis front.
    pub streets: Streets,
    /// Administrative boundaries (`boundary=administrative`, `admin_level` 2..=10) in the same
    /// coordinates as the footprints, sorted by id: what the knowledge base's zone lookup tries
    /// before its own, simplified shapes. OSM gives those the extract holds whole (relations and
    /// closed ways); shapefiles carry none.
    pub boundaries: Vec<AdminBoundary>,
    /// The GIS feature readers' other attributes (issue 47): the columns citygen does not read
    /// itself, by footprint id; empty for OSM input and for a file without such columns.
    pub attributes: std::collections::HashMap<SourceId, crate::model::Attributes>,
}

/// An administrative boundary of the input: its polygons and the tags that name it.
#[derive(Clone, Debug, PartialEq)]
pub struct AdminBoundary {
    /// `relation/45` or `way/123`.
    pub id: SourceId,
    /// `admin_level`, 2 (a country) to 10.
    pub admin_level: u8,
    /// Its names, each once, in this order: `name`, `name:en`, `int_name` (those present).
    pub names: Vec<String>,
    /// `ISO3166-1` or `ISO3166-1:alpha2` (a country's two-letter code), as tagged.
    pub iso3166_1: Option<String>,
    /// `ISO3166-2` (a subdivision's code, `FR-OCC`), as tagged.
    pub iso3166_2: Option<String>,
    /// Its polygons: outer rings counter-clockwise, holes clockwise, as a footprint's.
    pub polygons: Vec<SourcePolygon>,
}

/// What kind of way a street is, for the front door (issue 45): a building faces a road
/// rather than the service lane or footpath behind it.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum StreetKind {
    /// A road with frontage (trunk down to residential, living streets, pedestrian streets).
    #[default]
    Road,
    /// A `highway=service` other than an alley or driveway (an access road in a compound).
    Service,
    /// A footway or steps (a sidewalk in front, a path or a stepped lane).
    Foot,
    /// `service=alley` or `service=driveway`: a back lane or a drive, what a row of houses
    /// backs onto.
    Lane,
}

/// Street centre lines, stored flat to stay small on a whole country: every vertex of every
/// polyline in one vector, and where each polyline ends. Polyline `i` is
/// `points[ends[i - 1]..ends[i]]` (from 0 for the first); each has at least 2 vertices.
/// Each polyline has its [`StreetKind`] and its name, if any (issue 45: a building's
/// `addr:street` names the street its door faces), and the buildings' `addr:street`s are
/// kept beside them ([`Streets::address`]).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Streets {
    /// All vertices, polyline after polyline, in source coordinates (lon, lat for OSM).
    pub points: Vec<(f64, f64)>,
    /// The exclusive end of each polyline in `points`, ascending.
    pub ends: Vec<u32>,
    /// The kind of each polyline.
    pub kinds: Vec<StreetKind>,
    /// The name of each polyline: an index into `names`, [`Streets::NO_NAME`] for none.
    pub line_names: Vec<u32>,
    /// The distinct street names (of polylines and addresses), each once.
    pub names: Vec<String>,
    /// The buildings' `addr:street` (an index into `names`), sorted by id.
    pub addresses: Vec<(SourceId, u32)>,
    /// Nodes with an `addr:street` (address and entrance nodes, issue 45): (x, y) in source
    /// coordinates and the name's index into `names`; a building without its own
    /// `addr:street` takes that of the address nodes inside or on its outline
    /// ([`crate::prepare::assign_fronts`]).
    pub address_points: Vec<(f64, f64, u32)>,
}

impl Streets {
    /// The name index of a polyline without a name.
    pub const NO_NAME: u32 = u32::MAX;

    /// Appends one polyline, a [`StreetKind::Road`] without a name; ignored when it has fewer
    /// than 2 vertices (no segment), or when the vertex count no longer fits the `u32` index.
    pub fn push(&mut self, line: &[(f64, f64)]) {
        self.push_street(line, StreetKind::Road, Self::NO_NAME);
    }

    /// Appends one polyline of `kind` named `name` (an index from [`Streets::name_index`], or
    /// [`Streets::NO_NAME`]); ignored as [`Streets::push`].
    pub fn push_street(&mut self, line: &[(f64, f64)], kind: StreetKind, name: u32) {
        let end = self.points.len() + line.len();
        if line.len() < 2 || u32::try_from(end).is_err() {
            return;
        }
        self.points.extend_from_slice(line);
        self.ends.push(end as u32);
        self.kinds.push(kind);
        self.line_names.push(name);
    }

    /// The index of `name` in [`Streets::names`], added when new; `index` maps the names
    /// already there to theirs (the caller keeps it while it adds).
    pub fn name_index(
        &mut self,
        name: &str,
        index: &mut std::collections::HashMap<String, u32>,
    ) -> u32 {
        if let Some(&i) = index.get(name) {
            return i;
        }
        let i = u32::try_from(self.names.len()).unwrap_or(Self::NO_NAME);
        if i != Self::NO_NAME {
            self.names.push(name.to_string());
            index.insert(name.to_string(), i);
        }
        i
    }

    /// The `addr:street` name index of building `id`, if it has one.
    pub fn address(&self, id: SourceId) -> Option<u32> {
        self.addresses
            .binary_search_by(|(a, _)| a.cmp(&id))
            .ok()
            .map(|i| self.addresses[i].1)
    }

    /// The kind and name index of each polyline, in the order of [`Streets::lines`] (a
    /// polyline pushed before the kinds were kept is a nameless road).
    pub fn line_info(&self, i: usize) -> (StreetKind, u32) {
        (
            self.kinds.get(i).copied().unwrap_or_default(),
            self.line_names.get(i).copied().unwrap_or(Self::NO_NAME),
        )
    }

    /// The polylines, in the order they were pushed.
    pub fn lines(&self) -> impl Iterator<Item = &[(f64, f64)]> {
        let starts = std::iter::once(0).chain(self.ends.iter().map(|&e| e as usize));
        starts
            .zip(self.ends.iter())
            .map(|(s, &e)| &self.points[s..e as usize])
    }

    /// Number of polylines.
    pub fn len(&self) -> usize {
        self.ends.len()
    }

    /// Whether there is no polyline.
    pub fn is_empty(&self) -> bool {
        self.ends.is_empty()
    }
}
