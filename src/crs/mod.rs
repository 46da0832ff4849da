//! Coordinate reference systems in pure Rust: WGS84 lon/lat, UTM zones (WGS84), Lambert-93
//! (EPSG:2154), British National Grid (EPSG:27700, with the OSGB36 datum shift), and the CRS of
//! a shapefile's `.prj`; and, read only (`--dem` rasters, never an output), WGS 84 /
//! Pseudo-Mercator (EPSG:3857, `webmerc`).
//!
//! Every projected CRS converts to and from WGS84 longitude/latitude in degrees:
//!
//! ```
//! use citygen::crs::Crs;
//! let l93 = Crs::from_epsg_str("EPSG:2154").unwrap();
//! let (x, y) = l93.from_lonlat(1.4442, 43.6045); // Toulouse, Capitole
//! assert!((x - 574_357.38).abs() < 0.02 && (y - 6_279_620.75).abs() < 0.02);
//! let (lon, lat) = l93.to_lonlat(x, y);
//! assert!((lon - 1.4442).abs() < 1e-9 && (lat - 43.6045).abs() < 1e-9);
//! ```
//!
//! Datums: ETRS89 and RGF93 are taken as equal to WGS84 (they drift apart by a few cm a year;
//! under 1 m today), which is far below what building footprints need. OSGB36 is a genuinely
//! different datum (~100 m away) and goes through the OS Helmert transformation, which is good
//! to about 2-5 m against OSTN15 (see the notes in `osgb.rs`).
//!
//! Projection formulas: Transverse Mercator by the 6th-order Krüger series (Karney 2011; nm
//! accuracy over a UTM zone), Lambert Conic Conformal 2SP in closed form (IOGP GN 7-2).

mod ellipsoid;
mod generic;
pub mod geoid;
mod lcc;
mod osgb;
mod tmerc;
pub(crate) mod webmerc;
mod wkt;

#[cfg(test)]
mod tests;

use ellipsoid::Ellipsoid;
pub use generic::Unit;
use lcc::LambertConic2Sp;
use std::fmt;
use std::sync::LazyLock;
use thiserror::Error;
use tmerc::TransverseMercator;

/// A supported CRS.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Crs {
    /// EPSG:4326, x = lon, y = lat in degrees.
    Wgs84,
    /// WGS84 / UTM, EPSG:326zz (north) or 327zz (south). `zone` is 1..=60.
    Utm {
        /// UTM zone number, 1..=60: 6° wide, central meridian at 6 × zone − 183 degrees.
        zone: u8,
        /// `true` for the northern hemisphere (EPSG:326zz, northings from the equator),
        /// `false` for the southern (EPSG:327zz, 10 000 km false northing).
        north: bool,
    },
    /// RGF93 / Lambert-93, EPSG:2154.
    Lambert93,
    /// OSGB36 / British National Grid, EPSG:27700. The OSGB36 <-> WGS84 datum shift is the
    /// OS 7-parameter Helmert transformation: 2-5 m from OSTN15 (OS: up to 3.5 m, 95%).
    BritishNationalGrid,
    /// ETRS89 / UTM zone N (EPSG:25828-25838): projected on GRS80 with ETRS89 taken as WGS84
    /// (sub-metre difference). `zone` is 28..=38, northern hemisphere.
    EtrsUtm {
        /// UTM zone number, 28..=38 (EPSG:25828-25838).
        zone: u8,
    },
    /// Any other EPSG CRS of the `crs-definitions` table that `proj4rs` projects (State
    /// Plane, RD New, LV95, Gauss-Krüger, LAEA...): see `generic.rs`. Its coordinates, as
    /// [`Crs::from_lonlat`] gives them, are metres even when the CRS's unit is the foot
    /// ([`Crs::unit`]).
    Epsg(u16),
}

/// Why a CRS could not be identified.
#[derive(Debug, Error, PartialEq)]
pub enum CrsError {
    /// A well-formed CRS that citygen does not implement; the text names it.
    #[error("unsupported CRS {0}: citygen reads EPSG:4326 (longitude/latitude) and the EPSG CRSs that proj4rs projects without a grid file (UTM, State Plane, national grids...); reproject the data to one of them first, e.g. `ogr2ogr -t_srs EPSG:4326 out.shp in.shp`")]
    Unsupported(String),
    /// A `.prj` that is not valid WKT; the text says where.
    #[error("cannot understand the .prj: {0} (give the data's CRS with --src-crs EPSG:n, or reproject it, e.g. `ogr2ogr -t_srs EPSG:4326 out.shp in.shp`)")]
    BadPrj(String),
}

/// Lambert-93: LCC 2SP on GRS80, false origin (3°E, 46.5°N), parallels 49° and 44°.
static LAMBERT93: LazyLock<LambertConic2Sp> = LazyLock::new(|| {
    LambertConic2Sp::new(
        Ellipsoid::GRS80,
        3.0,
        46.5,
        49.0,
        44.0,
        700_000.0,
        6_600_000.0,
    )
});

impl Crs {
    /// Parses `EPSG:n`, `epsg:n`, `EPSG::n`, `urn:ogc:def:crs:EPSG::n` or just `n` (surrounding
    /// whitespace ignored). Any other code or text is [`CrsError::Unsupported`] naming it.
    pub fn from_epsg_str(s: &str) -> Result<Crs, CrsError> {
        let t = s.trim();
        let lower = t.to_ascii_lowercase();
        let rest = lower
            .strip_prefix("urn:ogc:def:crs:")
            .unwrap_or(&lower)
            .strip_prefix("epsg:")
            .map(|r| r.trim_start_matches(':'))
            .unwrap_or(&lower);
        match rest.trim().parse::<u32>() {
            Ok(code) => Crs::from_epsg(code),
            Err(_) => Err(CrsError::Unsupported(format!(
                "{t:?} (expected EPSG:n, e.g. EPSG:2154)"
            ))),
        }
    }

    /// The CRS with EPSG code `code`, or [`CrsError::Unsupported`] naming `EPSG:code`.
    pub(crate) fn from_epsg(code: u32) -> Result<Crs, CrsError> {
        match code {
            4326 => Ok(Crs::Wgs84),
            2154 => Ok(Crs::Lambert93),
            27700 => Ok(Crs::BritishNationalGrid),
            32601..=32660 => Ok(Crs::Utm {
                zone: (code - 32600) as u8,
                north: true,
            }),
            32701..=32760 => Ok(Crs::Utm {
                zone: (code - 32700) as u8,
                north: false,
            }),
            25828..=25838 => Ok(Crs::EtrsUtm {
                zone: (code - 25800) as u8,
            }),
            // Pseudo-Mercator is no CRS to read or write buildings in (its metres are 1/cos φ
            // ground metres); DEMs in it go through `webmerc`.
            3857 => Err(CrsError::Unsupported(
                "EPSG:3857 (WGS 84 / Pseudo-Mercator)".to_owned(),
            )),
            _ => u16::try_from(code)
                .ok()
                .filter(|&c| generic::get(c).is_some())
                .map(Crs::Epsg)
                .ok_or_else(|| CrsError::Unsupported(format!("EPSG:{code}"))),
        }
    }

    /// The EPSG code.
    pub(crate) fn epsg(&self) -> u32 {
        match *self {
            Crs::Wgs84 => 4326,
            Crs::Utm { zone, north: true } => 32600 + u32::from(zone),
            Crs::Utm { zone, north: false } => 32700 + u32::from(zone),
            Crs::Lambert93 => 2154,
            Crs::BritishNationalGrid => 27700,
            Crs::EtrsUtm { zone } => 25800 + u32::from(zone),
            Crs::Epsg(code) => u32::from(code),
        }
    }

    /// The EPSG name, e.g. `WGS 84 / UTM zone 32N`, `RGF93 v1 / Lambert-93`.
    pub fn name(&self) -> String {
        match *self {
            Crs::Wgs84 => "WGS 84".to_owned(),
            Crs::Utm { zone, north } => {
                format!("WGS 84 / UTM zone {zone}{}", if north { 'N' } else { 'S' })
            }
            Crs::Lambert93 => "RGF93 v1 / Lambert-93".to_owned(),
            Crs::BritishNationalGrid => "OSGB36 / British National Grid".to_owned(),
            Crs::EtrsUtm { zone } => format!("ETRS89 / UTM zone {zone}N"),
            Crs::Epsg(code) => {
                generic::get(code).map_or_else(|| format!("EPSG:{code}"), |g| g.name.clone())
            }
        }
    }

    /// The unit of the CRS's coordinates in its files: the metre, except for the CRSs in feet
    /// (State Plane `ftUS`, ...). [`Crs::from_lonlat`] and [`Crs::to_lonlat`] work in metres
    /// whatever this is; [`Crs::file_to_lonlat`] takes the file's own unit.
    pub fn unit(&self) -> Unit {
        match *self {
            Crs::Epsg(code) => generic::get(code).map_or(Unit::METRE, |g| g.unit),
            _ => Unit::METRE,
        }
    }

    /// The metre CRS of the same projection, datum and false origin, for a CRS in feet
    /// (EPSG:2263 NAD83 / New York Long Island (ftUS) -> EPSG:32118 NAD83 / New York Long
    /// Island): what citygen writes in for it. Itself for a CRS in metres; `None` when the
    /// EPSG table has no such twin.
    pub fn in_metres(&self) -> Option<Crs> {
        match *self {
            Crs::Epsg(code) if !self.unit().is_metre() => generic::metre_twin(code).map(Crs::Epsg),
            c => Some(c),
        }
    }

    /// A file's coordinates in this CRS (its own unit: feet for a State Plane `ftUS` file) to
    /// WGS84 lon/lat degrees.
    pub fn file_to_lonlat(&self, x: f64, y: f64) -> (f64, f64) {
        let m = self.unit().metres;
        self.to_lonlat(x * m, y * m)
    }

    /// The largest |k − 1| at (`lon`, `lat`) degrees: how much the CRS stretches or shrinks
    /// lengths there, north-south or east-west, measured by projecting 1e-6 rad steps and
    /// comparing with the ellipsoid's arcs (WGS84). `None` for a geographic CRS or where the
    /// projection fails.
    pub(crate) fn scale_error(&self, lon: f64, lat: f64) -> Option<f64> {
        if self.is_geographic() {
            return None;
        }
        if let Some(e) = self.utm_scale_error(lon, lat) {
            return Some(e);
        }
        let e = Ellipsoid::WGS84;
        let phi = lat.to_radians();
        let w = (1.0 - e.e2() * phi.sin().powi(2)).sqrt();
        let n = e.a / w;
        let m = e.a * (1.0 - e.e2()) / (w * w * w);
        let d = 1e-6_f64;
        let p0 = self.from_lonlat(lon, lat);
        let pn = self.from_lonlat(lon, lat + d.to_degrees());
        let pe = self.from_lonlat(lon + d.to_degrees(), lat);
        let kn = (pn.0 - p0.0).hypot(pn.1 - p0.1) / (m * d);
        let ke = (pe.0 - p0.0).hypot(pe.1 - p0.1) / (n * phi.cos() * d);
        let k = (kn - 1.0).abs().max((ke - 1.0).abs());
        k.is_finite().then_some(k)
    }

    /// True for the geographic CRS (coordinates in degrees); false for the projected ones
    /// (metres, easting then northing).
    pub(crate) fn is_geographic(&self) -> bool {
        match *self {
            Crs::Wgs84 => true,
            Crs::Epsg(code) => generic::get(code).is_some_and(|g| g.geographic),
            _ => false,
        }
    }

    /// The WGS84 UTM zone for (`lon`, `lat`) degrees: the standard 6° zone of `lon` (wrapped
    /// into [-180, 180)), with the exceptions of zone 32V (Norway, 56-64°N, 3-12°E) and zones
    /// 31X/33X/35X/37X (Svalbard, 72-84°N). North is `lat >= 0`. Never panics; a non-finite
    /// input gives zone 1 or 31 rather than an error.
    pub(crate) fn utm_for(lon: f64, lat: f64) -> Crs {
        let lon = if lon.is_finite() {
            (lon + 180.0).rem_euclid(360.0) - 180.0
        } else {
            0.0
        };
        // `as` saturates, and the clamp keeps 180° (rounded into range) in zone 60.
        let mut zone = (((lon + 180.0) / 6.0).floor() as i64 + 1).clamp(1, 60) as u8;
        if (56.0..64.0).contains(&lat) && (3.0..12.0).contains(&lon) {
            zone = 32;
        }
        if (72.0..=84.0).contains(&lat) && (0.0..42.0).contains(&lon) {
            zone = match lon {
                l if l < 9.0 => 31,
                l if l < 21.0 => 33,
                l if l < 33.0 => 35,
                _ => 37,
            };
        }
        Crs::Utm {
            zone,
            north: lat >= 0.0,
        }
    }

    /// The scale error |k − 1| of a UTM zone (WGS84 or ETRS89) at (`lon`, `lat`) degrees: how
    /// much lengths there are stretched or shrunk by the projection (0.001 is 1 mm per metre).
    /// Spherical formula, k = 0.9996 / √(1 − (cos φ sin Δλ)²), Δλ from the zone's central
    /// meridian: within 1e-5 of the ellipsoid's over a zone, which is all a bound needs. `None`
    /// for the other CRSs.
    pub(crate) fn utm_scale_error(&self, lon: f64, lat: f64) -> Option<f64> {
        let zone = match *self {
            Crs::Utm { zone, .. } | Crs::EtrsUtm { zone } => zone,
            _ => return None,
        };
        let central = 6.0 * f64::from(zone) - 183.0;
        let b = lat.to_radians().cos() * (lon - central).to_radians().sin();
        let k = 0.9996 / (1.0 - b * b).max(1e-12).sqrt();
        Some((k - 1.0).abs())
    }

    /// Identifies the CRS of an ESRI or OGC WKT1 `.prj` (WKT2 `PROJCRS`/`GEOGCRS` is accepted
    /// too): British National Grid, Lambert-93, WGS84 UTM zones, ETRS89 UTM, WGS84 geographic.
    ///
    /// A top-level `AUTHORITY["EPSG","n"]` (or WKT2 `ID["EPSG",n]`) for a supported code wins;
    /// otherwise the projection method and parameters on the datum decide, and failing that the
    /// CRS name. Malformed text is [`CrsError::BadPrj`] with the byte offset; a well-formed but
    /// unknown CRS is [`CrsError::Unsupported`] naming what was found.
    pub(crate) fn from_prj(wkt: &str) -> Result<Crs, CrsError> {
        wkt::identify(wkt)
    }

    /// Projects WGS84 lon/lat degrees to this CRS's (x, y): metres (easting, northing) for the
    /// projected CRSs, also for those whose unit is the foot (a foot grid's value times
    /// [`Crs::unit`]'s metres), (lon, lat) unchanged for [`Crs::Wgs84`]. Non-finite input, or a
    /// point outside a projection's domain, gives non-finite output, never a panic.
    pub fn from_lonlat(&self, lon: f64, lat: f64) -> (f64, f64) {
        match *self {
            Crs::Wgs84 => (lon, lat),
            Crs::Utm { zone, north } => {
                TransverseMercator::utm(&tmerc::WGS84_SERIES, zone, north).project(lon, lat)
            }
            Crs::EtrsUtm { zone } => {
                TransverseMercator::utm(&tmerc::GRS80_SERIES, zone, true).project(lon, lat)
            }
            Crs::Lambert93 => LAMBERT93.project(lon, lat),
            Crs::BritishNationalGrid => osgb::wgs84_to_grid(lon, lat),
            Crs::Epsg(code) => {
                generic::get(code).map_or((f64::NAN, f64::NAN), |g| g.project(lon, lat))
            }
        }
    }

    /// Inverse of [`Crs::from_lonlat`]: this CRS's (x, y) to WGS84 lon/lat degrees. Round trips
    /// agree to better than 1e-9° within each CRS's area of use.
    pub fn to_lonlat(&self, x: f64, y: f64) -> (f64, f64) {
        match *self {
            Crs::Wgs84 => (x, y),
            Crs::Utm { zone, north } => {
                TransverseMercator::utm(&tmerc::WGS84_SERIES, zone, north).unproject(x, y)
            }
            Crs::EtrsUtm { zone } => {
                TransverseMercator::utm(&tmerc::GRS80_SERIES, zone, true).unproject(x, y)
            }
            Crs::Lambert93 => LAMBERT93.unproject(x, y),
            Crs::BritishNationalGrid => osgb::grid_to_wgs84(x, y),
            Crs::Epsg(code) => {
                generic::get(code).map_or((f64::NAN, f64::NAN), |g| g.unproject(x, y))
            }
        }
    }
}

/// WGS84 longitude and latitude (degrees) and ellipsoidal height (metres) to geocentric
/// cartesian coordinates (EPSG:4978, ECEF: X towards (0°, 0°), Z towards the north pole,
/// metres), as 3D Tiles places its contents.
///
/// ```
/// let [x, y, z] = citygen::crs::wgs84_to_ecef(0.0, 0.0, 0.0);
/// assert!((x - 6_378_137.0).abs() < 1e-9 && y.abs() < 1e-9 && z.abs() < 1e-9);
/// ```
pub fn wgs84_to_ecef(lon: f64, lat: f64, h: f64) -> [f64; 3] {
    Ellipsoid::WGS84.geodetic_to_geocentric(lon.to_radians(), lat.to_radians(), h)
}

/// Inverse of [`wgs84_to_ecef`]: ECEF metres to WGS84 (longitude, latitude) degrees and
/// ellipsoidal height in metres (exact near the surface, see the ellipsoid's iteration).
pub(crate) fn ecef_to_wgs84(xyz: [f64; 3]) -> (f64, f64, f64) {
    let (lon, lat, h) = Ellipsoid::WGS84.geocentric_to_geodetic(xyz);
    (lon.to_degrees(), lat.to_degrees(), h)
}

/// `EPSG:n (name)`, e.g. `EPSG:2154 (RGF93 v1 / Lambert-93)`.
impl fmt::Display for Crs {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "EPSG:{} ({})", self.epsg(), self.name())
    }
}
