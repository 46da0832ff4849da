//! Any EPSG CRS that the `crs-definitions` table (EPSG code -> PROJ.4 string, 6,000-odd
//! codes) defines and `proj4rs` (a pure-Rust port of PROJ.4's projections) can project:
//! State Plane in US survey feet, RD New (oblique stereographic), LV95 (oblique Mercator),
//! Gauss-Krüger, LAEA Europe, national Transverse Mercators, Krovak...
//!
//! Coordinates given to and taken from [`Generic::project`] / [`Generic::unproject`] are
//! the CRS's grid in **metres** (a foot grid's values times 0.3048006096 or 0.3048), so that
//! citygen's model stays in metres whatever the CRS's unit; [`Generic::unit`] says what one
//! unit of the CRS is, and the readers and writers convert at the file's edge.
//!
//! Datums: like PROJ.4, the shift to WGS84 is the string's `+towgs84` (3 or 7 Helmert
//! parameters, or `+datum=` of a known datum); a CRS without one (`+ellps=GRS80` for NAD83,
//! say) is taken as WGS84 itself. No grid shift (NTv2, NADCON) is applied: see the accuracy
//! table in docs/crs.md.

use proj4rs::proj::Proj;
use proj4rs::transform::transform;
use std::collections::HashMap;
use std::sync::{LazyLock, RwLock};

/// A length unit of a CRS.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Unit {
    /// Its name as EPSG spells it: `metre`, `US survey foot`, `foot`, or a made-up name.
    pub name: &'static str,
    /// Metres in one unit: 1, 0.3048006096012192 (1200/3937), 0.3048.
    pub metres: f64,
    /// Its EPSG unit code (9001 metre, 9003 US survey foot, 9002 foot), if it has one.
    pub epsg: Option<u32>,
}

impl Unit {
    /// The metre (EPSG:9001).
    pub const METRE: Unit = Unit {
        name: "metre",
        metres: 1.0,
        epsg: Some(9001),
    };

    /// True for the metre.
    pub fn is_metre(&self) -> bool {
        self.metres == 1.0
    }

    fn of(to_meter: f64) -> Unit {
        if (to_meter - 1.0).abs() < 1e-12 {
            Unit::METRE
        } else if (to_meter - 1200.0 / 3937.0).abs() < 1e-12 {
            Unit {
                name: "US survey foot",
                metres: 1200.0 / 3937.0,
                epsg: Some(9003),
            }
        } else if (to_meter - 0.3048).abs() < 1e-12 {
            Unit {
                name: "foot",
                metres: 0.3048,
                epsg: Some(9002),
            }
        } else {
            Unit {
                name: "unit",
                metres: to_meter,
                epsg: None,
            }
        }
    }
}

/// One EPSG CRS, ready to project.
pub(crate) struct Generic {
    proj: Proj,
    /// The CRS's name from the table's WKT (`NAD83 / New York Long Island (ftUS)`).
    pub(crate) name: String,
    pub(crate) unit: Unit,
    pub(crate) geographic: bool,
}

/// WGS 84 longitude/latitude, the pivot of every transformation.
static WGS84: LazyLock<Proj> = LazyLock::new(|| {
    Proj::from_proj_string("+proj=longlat +datum=WGS84 +no_defs").expect("a valid PROJ string")
});

/// Every code asked for so far: built once, kept for the run (at most the table's 6,000-odd).
static CACHE: LazyLock<RwLock<HashMap<u16, Option<&'static Generic>>>> =
    LazyLock::new(|| RwLock::new(HashMap::new()));

/// The CRS with EPSG code `code`, or `None` when the table lacks it or proj4rs cannot build it
/// (an unknown projection, a grid file it would need).
pub(crate) fn get(code: u16) -> Option<&'static Generic> {
    if let Some(found) = CACHE.read().ok().and_then(|c| c.get(&code).copied()) {
        return found;
    }
    let built = build(code).map(|g| &*Box::leak(Box::new(g)));
    match CACHE.write() {
        Ok(mut c) => *c.entry(code).or_insert(built),
        Err(_) => built,
    }
}

fn build(code: u16) -> Option<Generic> {
    let def = crs_definitions::from_code(code)?;
    // A grid shift proj4rs would look for on disk (`+nadgrids=...`): refused rather than
    // silently off by metres. (EPSG:3857's `@null` grid is no shift at all.)
    if def.proj4.contains("+nadgrids=") && !def.proj4.contains("+nadgrids=@null") {
        return None;
    }
    let proj = Proj::from_proj_string(def.proj4).ok()?;
    let geographic = proj.is_latlong();
    let invertible = proj.has_forward() && proj.has_inverse();
    if proj.is_geocent() || !(geographic || invertible) {
        return None;
    }
    let unit = if geographic {
        Unit::METRE
    } else {
        Unit::of(proj.to_meter())
    };
    let name = wkt_name(def.wkt).unwrap_or_else(|| format!("EPSG:{code}"));
    Some(Generic {
        proj,
        name,
        unit,
        geographic,
    })
}

/// The metre CRS of the same projection, datum and false origin as foot CRS `code` (EPSG:2263
/// NAD83 / New York Long Island (ftUS) -> EPSG:32118, its metre edition), the lowest such code
/// of the table; `None` for a metre CRS or when the table has no twin.
pub(crate) fn metre_twin(code: u16) -> Option<u16> {
    let own = parse_proj4(crs_definitions::from_code(code)?.proj4);
    get(code).filter(|g| !g.geographic && !g.unit.is_metre())?;
    (1024..=u16::MAX).filter(|&c| c != code).find(|&c| {
        crs_definitions::from_code(c).is_some_and(|d| {
            let other = parse_proj4(d.proj4);
            other.get("units").is_none_or(|u| *u == "m")
                && same_definition(&own, &other)
                && get(c).is_some_and(|g| g.unit.is_metre())
        })
    })
}

/// A PROJ.4 string's `+key=value` (or `+flag`, value "") pairs.
fn parse_proj4(s: &str) -> HashMap<&str, &str> {
    s.split_whitespace()
        .filter_map(|t| t.strip_prefix('+'))
        .map(|t| t.split_once('=').unwrap_or((t, "")))
        .collect()
}

/// The same definition but for the unit: every other key present in both with equal values
/// (numbers within 1e-9, the false origin's metres within 1 mm).
fn same_definition(a: &HashMap<&str, &str>, b: &HashMap<&str, &str>) -> bool {
    let ignored = |k: &str| matches!(k, "units" | "to_meter" | "no_defs" | "wktext" | "type");
    fn keys<'a>(m: &HashMap<&'a str, &str>, ignored: impl Fn(&str) -> bool) -> Vec<&'a str> {
        let mut k: Vec<&str> = m.keys().copied().filter(|k| !ignored(k)).collect();
        k.sort_unstable();
        k
    }
    keys(a, ignored) == keys(b, ignored)
        && keys(a, ignored).into_iter().all(|k| {
            let (x, y) = (a[k], b[k]);
            match (x.parse::<f64>(), y.parse::<f64>()) {
                (Ok(x), Ok(y)) => {
                    let tol = if matches!(k, "x_0" | "y_0") {
                        1e-3
                    } else {
                        1e-9
                    };
                    (x - y).abs() <= tol
                }
                _ => x == y,
            }
        })
}

/// The name of the WKT's root, `PROJCS["name",...`.
fn wkt_name(wkt: &str) -> Option<String> {
    let start = wkt.find("[\"")? + 2;
    let len = wkt[start..].find('"')?;
    Some(wkt[start..start + len].to_owned())
}

impl Generic {
    /// WGS84 lon/lat degrees to the CRS: grid metres, or degrees for a geographic CRS. NaN
    /// where the projection fails (outside its domain), never a panic.
    pub(crate) fn project(&self, lon: f64, lat: f64) -> (f64, f64) {
        let mut p = (lon.to_radians(), lat.to_radians(), 0.0);
        if !(lon.is_finite() && lat.is_finite()) || transform(&WGS84, &self.proj, &mut p).is_err() {
            return (f64::NAN, f64::NAN);
        }
        if self.geographic {
            (p.0.to_degrees(), p.1.to_degrees())
        } else {
            (p.0 * self.unit.metres, p.1 * self.unit.metres)
        }
    }

    /// Inverse of [`Generic::project`].
    pub(crate) fn unproject(&self, x: f64, y: f64) -> (f64, f64) {
        let mut p = if self.geographic {
            (x.to_radians(), y.to_radians(), 0.0)
        } else {
            (x / self.unit.metres, y / self.unit.metres, 0.0)
        };
        if !(x.is_finite() && y.is_finite()) || transform(&self.proj, &WGS84, &mut p).is_err() {
            return (f64::NAN, f64::NAN);
        }
        (p.0.to_degrees(), p.1.to_degrees())
    }
}
