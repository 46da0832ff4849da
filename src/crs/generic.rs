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

/// The semi-axes (a, b) in metres of the ellipsoid of EPSG CRS `code`, when the table has it.
pub(crate) fn ellipsoid_of(code: u16) -> Option<(f64, f64)> {
    get(code).map(|g| g.proj.ellipse_parameters())
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

/// A projected CRS as a `.prj` without an EPSG code describes it: PROJ's projection name
/// (`tmerc`, `lcc`, `sterea`, `somerc`, `laea`, `aea`, `cass`), its parameters under PROJ's
/// keys (`lat_0`, `lon_0`, `lat_1`, `lat_2`, `k_0`, `x_0`, `y_0`; false origin in metres),
/// the ellipsoid's semi-axes and the metres in one unit.
#[derive(Clone, Debug)]
pub(crate) struct Definition {
    pub(crate) proj: &'static str,
    pub(crate) params: Vec<(&'static str, f64)>,
    pub(crate) a: f64,
    pub(crate) b: f64,
    pub(crate) to_meter: f64,
    /// The WKT's CRS and datum names, normalised.
    pub(crate) names: String,
}

/// The parameters compared, with the value PROJ takes when a string leaves one out.
const SHAPE_KEYS: [(&str, f64); 7] = [
    ("lat_0", 0.0),
    ("lon_0", 0.0),
    ("lat_1", f64::NAN),
    ("lat_2", f64::NAN),
    ("k_0", 1.0),
    ("x_0", 0.0),
    ("y_0", 0.0),
];

/// The EPSG codes of the table whose PROJ.4 string is `def` (same projection, parameters
/// within 1e-7° and 1 cm, ellipsoid within 1 mm, same unit), ascending. Several entries share
/// one definition (NAD83 and NAD83(HARN) State Planes; a CRS and its compound with heights):
/// the caller ranks them.
pub(crate) fn find_definition(def: &Definition) -> Vec<u16> {
    let mut found = Vec::new();
    for code in 1024..=u16::MAX {
        let Some(entry) = crs_definitions::from_code(code) else {
            continue;
        };
        let p = parse_proj4(entry.proj4);
        let Some(params) = canonical(&p) else {
            continue;
        };
        if params.0 != def.proj || !same_shape(&params.1, &def.params) {
            continue;
        }
        let Some(g) = get(code) else { continue };
        if g.geographic || (g.unit.metres - def.to_meter).abs() > 1e-12 * def.to_meter {
            continue;
        }
        let (a, b) = g.proj.ellipse_parameters();
        if (a - def.a).abs() > 1e-3 || (b - def.b).abs() > 1e-3 {
            continue;
        }
        found.push(code);
    }
    found
}

/// 2 when the entry's datum realisation (`NAD83(HARN)`: `harn`) appears in `names`, 1 when
/// the entry names none, 0 when it names one the text does not.
pub(crate) fn realisation_score(code: u16, names: &str) -> u8 {
    let Some(g) = get(code) else { return 0 };
    let datum = g.name.split(" / ").next().unwrap_or("");
    match datum.split_once('(') {
        Some((_, rest)) => {
            let token: String = rest
                .chars()
                .take_while(|c| *c != ')')
                .filter(|c| c.is_alphanumeric())
                .flat_map(char::to_lowercase)
                .collect();
            let squeezed: String = names.chars().filter(|c| c.is_alphanumeric()).collect();
            if !token.is_empty() && squeezed.contains(&token) {
                2
            } else {
                0
            }
        }
        None => 1,
    }
}

/// A PROJ.4 string's projection and shape parameters (UTM as the Transverse Mercator it is;
/// `k` as `k_0`); `None` for strings without a projection.
fn canonical(p: &HashMap<&str, &str>) -> Option<(&'static str, Vec<(&'static str, f64)>)> {
    let num = |k: &str| p.get(k).and_then(|v| v.parse::<f64>().ok());
    let proj: &'static str = match *p.get("proj")? {
        "utm" => {
            let zone = num("zone")?;
            let south = p.contains_key("south");
            return Some((
                "tmerc",
                vec![
                    ("lat_0", 0.0),
                    ("lon_0", zone * 6.0 - 183.0),
                    ("k_0", 0.9996),
                    ("x_0", 500_000.0),
                    ("y_0", if south { 10_000_000.0 } else { 0.0 }),
                ],
            ));
        }
        "tmerc" => "tmerc",
        "lcc" => "lcc",
        "sterea" => "sterea",
        "somerc" => "somerc",
        "laea" => "laea",
        "aea" => "aea",
        "cass" => "cass",
        _ => return None,
    };
    let mut out = Vec::new();
    for (k, _) in SHAPE_KEYS {
        let v = if k == "k_0" {
            num("k_0").or_else(|| num("k"))
        } else {
            num(k)
        };
        if let Some(v) = v {
            out.push((k, v));
        }
    }
    Some((proj, out))
}

/// The same shape parameters, each missing one at PROJ's default; the standard parallels as
/// a pair in either order (one parallel: both the same).
fn same_shape(a: &[(&str, f64)], b: &[(&str, f64)]) -> bool {
    let get = |ps: &[(&str, f64)], k: &str| {
        ps.iter()
            .find(|(key, _)| *key == k)
            .map(|(_, v)| *v)
            .unwrap_or_else(|| {
                SHAPE_KEYS
                    .iter()
                    .find(|(key, _)| *key == k)
                    .map_or(0.0, |d| d.1)
            })
    };
    let parallels = |ps: &[(&str, f64)]| {
        let (p1, p2) = (get(ps, "lat_1"), get(ps, "lat_2"));
        let p2 = if p2.is_nan() { p1 } else { p2 };
        (p1.min(p2), p1.max(p2))
    };
    let ang = 1e-7;
    let (pa, pb) = (parallels(a), parallels(b));
    let parallels_ok = (pa.0.is_nan() && pb.0.is_nan())
        || ((pa.0 - pb.0).abs() <= ang && (pa.1 - pb.1).abs() <= ang);
    parallels_ok
        && ["lat_0", "lon_0"]
            .iter()
            .all(|k| (get(a, k) - get(b, k)).abs() <= ang)
        && (get(a, "k_0") - get(b, "k_0")).abs() <= 1e-9
        && ["x_0", "y_0"]
            .iter()
            .all(|k| (get(a, k) - get(b, k)).abs() <= 0.01)
}
