//! OSGB36 / British National Grid (EPSG:27700) from WGS84, via the Ordnance Survey's published
//! ETRS89 -> OSGB36 seven-parameter Helmert transformation.
//!
//! Accuracy: the Helmert transformation is a single best fit over the whole of Great Britain,
//! while OSGB36 itself is warped by its 1930s triangulation. The OS states its error against
//! the definitive OSTN15 grid transformation as "up to 3.5 metres (95%)" horizontally, i.e.
//! typically 2 m and up to about 5 m in the worst places. WGS84 is taken as equal to ETRS89
//! (the OS calls the difference negligible at this level). Buildings keep their shape exactly
//! (the error is a smooth offset over kilometres), but absolute positions against OS
//! MasterMap may be a few metres off; OSTN15 would need its grid file. The
//! projection step itself (Airy 1830 Transverse Mercator) is exact to well below 1 mm.

use super::ellipsoid::Ellipsoid;
use super::tmerc::TransverseMercator;
use std::sync::LazyLock;

/// The National Grid projection on Airy 1830 (OS guide, Annex A / EPSG:27700).
static GRID: LazyLock<TransverseMercator> = LazyLock::new(|| {
    TransverseMercator::new(
        Ellipsoid::AIRY1830,
        -2.0,
        49.0,
        0.999_601_271_7,
        400_000.0,
        -100_000.0,
    )
});

/// ETRS89 -> OSGB36 Helmert parameters, OS "A guide to coordinate systems in Great Britain"
/// §6.6: translations in metres, scale in ppm, rotations in arc-seconds (position-vector
/// convention, as the OS writes the matrix).
const TX: f64 = -446.448;
const TY: f64 = 125.157;
const TZ: f64 = -542.060;
const S_PPM: f64 = 20.4894;
const RX_SEC: f64 = -0.1502;
const RY_SEC: f64 = -0.2470;
const RZ_SEC: f64 = -0.8421;

/// The Helmert matrix `(1+s) I + [r]×` of the OS formula `X_B = T + M X_A`.
fn helmert_matrix() -> [[f64; 3]; 3] {
    let sec = std::f64::consts::PI / (180.0 * 3600.0);
    let (rx, ry, rz) = (RX_SEC * sec, RY_SEC * sec, RZ_SEC * sec);
    let s1 = 1.0 + S_PPM * 1e-6;
    [[s1, -rz, ry], [rz, s1, -rx], [-ry, rx, s1]]
}

/// WGS84 geocentric to OSGB36 geocentric.
fn wgs84_to_osgb36_xyz(p: [f64; 3]) -> [f64; 3] {
    let m = helmert_matrix();
    let t = [TX, TY, TZ];
    let mut out = [0.0; 3];
    for (i, row) in m.iter().enumerate() {
        out[i] = t[i] + row[0] * p[0] + row[1] * p[1] + row[2] * p[2];
    }
    out
}

/// OSGB36 geocentric to WGS84 geocentric: the exact inverse of [`wgs84_to_osgb36_xyz`]
/// (solving the 3x3 system rather than negating the parameters, which would be off by ~1 cm).
fn osgb36_to_wgs84_xyz(p: [f64; 3]) -> [f64; 3] {
    let m = helmert_matrix();
    let d = [p[0] - TX, p[1] - TY, p[2] - TZ];
    let det = m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
        - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
        + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]);
    // Cramer's rule; det is 1 + 3s + O(s²) ≈ 1, never near zero.
    let col = |c: usize| -> f64 {
        let mut mm = m;
        for r in 0..3 {
            mm[r][c] = d[r];
        }
        mm[0][0] * (mm[1][1] * mm[2][2] - mm[1][2] * mm[2][1])
            - mm[0][1] * (mm[1][0] * mm[2][2] - mm[1][2] * mm[2][0])
            + mm[0][2] * (mm[1][0] * mm[2][1] - mm[1][1] * mm[2][0])
    };
    [col(0) / det, col(1) / det, col(2) / det]
}

/// WGS84 (lon, lat) degrees at ellipsoidal height 0 to OSGB36 (lon, lat) degrees.
pub(crate) fn wgs84_to_osgb36(lon: f64, lat: f64) -> (f64, f64) {
    let p = Ellipsoid::WGS84.geodetic_to_geocentric(lon.to_radians(), lat.to_radians(), 0.0);
    let q = wgs84_to_osgb36_xyz(p);
    let (lo, la, _) = Ellipsoid::AIRY1830.geocentric_to_geodetic(q);
    (lo.to_degrees(), la.to_degrees())
}

/// OSGB36 (lon, lat) degrees at height 0 to WGS84 (lon, lat) degrees. An approximate inverse of
/// [`wgs84_to_osgb36`]: heights are dropped on both sides, so the two are not exact mutual
/// inverses (mm-level); [`grid_to_wgs84`] corrects for that.
fn osgb36_to_wgs84(lon: f64, lat: f64) -> (f64, f64) {
    let p = Ellipsoid::AIRY1830.geodetic_to_geocentric(lon.to_radians(), lat.to_radians(), 0.0);
    let q = osgb36_to_wgs84_xyz(p);
    let (lo, la, _) = Ellipsoid::WGS84.geocentric_to_geodetic(q);
    (lo.to_degrees(), la.to_degrees())
}

/// OSGB36 geodetic degrees to National Grid (easting, northing): the projection step alone,
/// which is what the OS worked example (Annex C) checks.
pub(crate) fn osgb36_to_grid(lon: f64, lat: f64) -> (f64, f64) {
    GRID.project(lon, lat)
}

/// National Grid (easting, northing) to OSGB36 geodetic degrees.
pub(crate) fn grid_to_osgb36(e: f64, n: f64) -> (f64, f64) {
    GRID.unproject(e, n)
}

/// WGS84 (lon, lat) degrees to National Grid (easting, northing) metres.
pub(crate) fn wgs84_to_grid(lon: f64, lat: f64) -> (f64, f64) {
    let (lo, la) = wgs84_to_osgb36(lon, lat);
    osgb36_to_grid(lo, la)
}

/// National Grid (easting, northing) metres to WGS84 (lon, lat) degrees: the WGS84 point at
/// height 0 that [`wgs84_to_grid`] maps onto (e, n).
///
/// The plain reverse chain would assume OSGB36 height 0 where the forward chain produced a
/// height of tens of metres, leaving a few millimetres of round-trip error. A fixed-point
/// correction `p += inv(target) - inv(forward(p))` removes it; the map is so close to a
/// translation that each pass gains several digits.
pub(crate) fn grid_to_wgs84(e: f64, n: f64) -> (f64, f64) {
    let approx_inverse = |e: f64, n: f64| {
        let (lo, la) = grid_to_osgb36(e, n);
        osgb36_to_wgs84(lo, la)
    };
    let first = approx_inverse(e, n);
    let (mut lon, mut lat) = first;
    for _ in 0..4 {
        let (fe, fnn) = wgs84_to_grid(lon, lat);
        if !((fe - e).abs() > 1e-7 || (fnn - n).abs() > 1e-7) {
            break;
        }
        let back = approx_inverse(fe, fnn);
        lon += first.0 - back.0;
        lat += first.1 - back.1;
    }
    (lon, lat)
}
