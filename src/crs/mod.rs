//! Coordinate reference systems in pure Rust: WGS84 lon/lat, UTM zones (WGS84), Lambert-93
//! (EPSG:2154), British National Grid (EPSG:27700, with the OSGB36 datum shift), and the CRS of
//! a shapefile's `.prj`.

use thiserror::Error;

/// A supported CRS.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Crs {
    /// EPSG:4326, x = lon, y = lat in degrees.
    Wgs84,
    /// WGS84 / UTM, EPSG:326zz (north) or 327zz (south).
    Utm { zone: u8, north: bool },
    /// RGF93 / Lambert-93, EPSG:2154.
    Lambert93,
    /// OSGB36 / British National Grid, EPSG:27700.
    BritishNationalGrid,
    /// ETRS89 / UTM zone N (EPSG:25828-25838): treated as WGS84 UTM (sub-metre difference).
    EtrsUtm { zone: u8 },
}

#[derive(Debug, Error, PartialEq)]
pub enum CrsError {
    #[error("unsupported CRS {0}: citygen knows EPSG:4326, 326xx/327xx (UTM), 258xx (ETRS89 UTM), 2154 (Lambert-93), 27700 (British National Grid), 3857 is not supported")]
    Unsupported(String),
    #[error("cannot understand the .prj: {0}")]
    BadPrj(String),
}

impl Crs {
    /// Parses `EPSG:n` (or just `n`).
    pub fn from_epsg_str(s: &str) -> Result<Crs, CrsError> {
        todo!("{s}")
    }

    /// The EPSG code.
    pub fn epsg(&self) -> u32 {
        todo!()
    }

    /// A human name, e.g. `WGS 84 / UTM zone 32N`.
    pub fn name(&self) -> String {
        todo!()
    }

    /// The UTM zone (WGS84) whose central meridian is nearest `lon`, `lat` (with the Norway and
    /// Svalbard exceptions).
    pub fn utm_for(lon: f64, lat: f64) -> Crs {
        todo!("{lon} {lat}")
    }

    /// Identifies the CRS of an ESRI `.prj` (WKT1): British National Grid, Lambert-93,
    /// WGS84 UTM zones, ETRS89 UTM, WGS84 geographic.
    pub fn from_prj(wkt: &str) -> Result<Crs, CrsError> {
        todo!("{wkt}")
    }

    /// Projects WGS84 lon/lat degrees to this CRS's (x, y).
    pub fn from_lonlat(&self, lon: f64, lat: f64) -> (f64, f64) {
        todo!("{lon} {lat}")
    }

    /// Inverse of [`Crs::from_lonlat`]: this CRS's (x, y) to WGS84 lon/lat degrees.
    pub fn to_lonlat(&self, x: f64, y: f64) -> (f64, f64) {
        todo!("{x} {y}")
    }
}
