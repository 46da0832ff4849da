//! The EGM96 geoid: its undulation N (metres, the geoid's height above the WGS84 ellipsoid) at
//! any longitude and latitude, so that an orthometric height H (above the geoid, as DEMs give
//! it) becomes the ellipsoidal height h = H + N that 3D Tiles and ECEF want.
//!
//! The grid is NGA's 15-minute worldwide grid `WW15MGH` (721 × 1440 posts from 90° N to 90° S
//! and 0° E eastwards, centimetres), shipped compressed in `assets/geoid/egm96-15.bin` (690 kB;
//! `scripts/egm96_grid.py` writes it from its source and documents the encoding) and decoded on
//! first use (2 MB held from then on). EGM96 is a work of the US government (NGA/NASA), in the
//! public domain.
//!
//! Interpolation is bilinear between the four posts around the point, as NGA's `INTPT` (bilinear
//! mode), PROJ with `us_nga_egm96_15.tif` and GDAL do, so the values are those tools' to the
//! grid's centimetre rounding. Against the full degree-360 spherical-harmonic EGM96, bilinear on
//! the 15' grid is off by 4 cm RMS and 1.15 m at worst (GeographicLib's measurements of the same
//! grid), the worst in the steepest geoid (the Himalaya, ocean trenches); NGA's published test
//! points are matched within 6 cm (`tests`). Longitudes wrap (any real longitude works; the
//! antimeridian is between columns 719 and 720, no seam); latitudes are clamped to ±90°, and the
//! polar rows, each one value, make N at a pole that value from any longitude.

use std::io::Read;
use std::sync::LazyLock;

/// Rows of the grid: 90° N to 90° S every 15'.
const ROWS: usize = 721;
/// Columns: 0° E to 359.75° E every 15' (360° is column 0 again).
const COLS: usize = 1440;
/// Posts per degree.
const PER_DEGREE: f64 = 4.0;

/// The compressed grid (see the module documentation and `scripts/egm96_grid.py`).
static PACKED: &[u8] = include_bytes!("../../assets/geoid/egm96-15.bin");

/// The decoded grid, centimetres, row-major from the north-west.
static GRID: LazyLock<Vec<i16>> = LazyLock::new(|| {
    // The asset is part of the binary, not an input: the tests decode it and check its posts,
    // so a failure here is a build defect.
    decode(PACKED).expect("the shipped EGM96 grid decodes (checked by crs::geoid's tests)")
});

/// Inflates and un-predicts the packed grid; `None` if it is not ROWS × COLS posts.
fn decode(packed: &[u8]) -> Option<Vec<i16>> {
    let n = ROWS * COLS;
    let mut planes = Vec::with_capacity(2 * n);
    flate2::read::ZlibDecoder::new(packed)
        .take(2 * n as u64 + 1)
        .read_to_end(&mut planes)
        .ok()?;
    if planes.len() != 2 * n {
        return None;
    }
    let (lo, hi) = planes.split_at(n);
    let mut v = vec![0i16; n];
    for r in 0..ROWS {
        for c in 0..COLS {
            let k = r * COLS + c;
            let pred = match (r, c) {
                (0, 0) => 0,
                (0, _) => v[k - 1],
                (_, 0) => v[k - COLS],
                _ => v[k - 1]
                    .wrapping_add(v[k - COLS])
                    .wrapping_sub(v[k - COLS - 1]),
            };
            let residual = i16::from_le_bytes([lo[k], hi[k]]);
            v[k] = pred.wrapping_add(residual);
        }
    }
    Some(v)
}

/// The post at `row` (0 = 90° N), `col` (any, wrapped) in metres.
fn post(grid: &[i16], row: usize, col: usize) -> f64 {
    f64::from(grid[row * COLS + col % COLS]) / 100.0
}

/// The EGM96 geoid undulation N (metres above the WGS84 ellipsoid) at `lon`, `lat` degrees:
/// bilinear on the 15' grid (see the module documentation for its error). Longitudes wrap;
/// latitudes beyond ±90° count as the pole; a non-finite coordinate gives 0.
pub fn undulation(lon: f64, lat: f64) -> f64 {
    if !lon.is_finite() || !lat.is_finite() {
        return 0.0;
    }
    let grid = GRID.as_slice();
    // Grid coordinates: x eastwards from 0° E in [0, COLS), y southwards from 90° N.
    let x = (lon * PER_DEGREE).rem_euclid(COLS as f64);
    let y = ((90.0 - lat.clamp(-90.0, 90.0)) * PER_DEGREE).clamp(0.0, (ROWS - 1) as f64);
    // `x` can round up to COLS itself for a tiny negative longitude.
    let c = (x.floor() as usize).min(COLS - 1);
    let r = (y.floor() as usize).min(ROWS - 2);
    let (fx, fy) = (x - c as f64, y - r as f64);
    let north = post(grid, r, c) * (1.0 - fx) + post(grid, r, c + 1) * fx;
    let south = post(grid, r + 1, c) * (1.0 - fx) + post(grid, r + 1, c + 1) * fx;
    north * (1.0 - fy) + south * fy
}

#[cfg(test)]
mod tests {
    use super::*;

    /// NGA's test points for the 15' grid (`OUTINTPT.DAT` of the EGM96 distribution: latitude,
    /// longitude east 0..360, N in metres).
    const NGA: [(f64, f64, f64); 6] = [
        (38.628_155, 269.779_155, -31.628),
        (-14.621_217, 305.021_114, -2.969),
        (46.874_319, 102.448_729, -43.575),
        (-23.617_446, 133.874_712, 15.871),
        (38.625_473, 359.999_500, 50.066),
        (-0.466_744, 0.002_300, 17.329),
    ];

    #[test]
    fn the_shipped_grid_decodes_to_its_known_posts() {
        let g = decode(PACKED).expect("decodes");
        assert_eq!(g.len(), ROWS * COLS);
        // The poles' rows are one value each: NGA's 13.61 m at 90° N, -29.53 m at 90° S.
        assert!(g[..COLS].iter().all(|&v| v == 1361));
        assert!(g[(ROWS - 1) * COLS..].iter().all(|&v| v == -2953));
        // The extremes of EGM96: -106.99 m south of India, +85.39 m over New Guinea.
        assert_eq!(g.iter().min(), Some(&-10699));
        assert_eq!(g.iter().max(), Some(&8539));
        // A grid cut short or padded is refused.
        let mut short = Vec::new();
        flate2::read::ZlibDecoder::new(PACKED)
            .take(100)
            .read_to_end(&mut short)
            .unwrap();
        let mut z = flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::fast());
        std::io::Write::write_all(&mut z, &short).unwrap();
        assert_eq!(decode(&z.finish().unwrap()), None);
        assert_eq!(decode(b"not zlib"), None);
    }

    #[test]
    fn nga_test_points_within_six_centimetres() {
        for (lat, lon, n) in NGA {
            for lon in [lon, lon - 360.0, lon + 360.0] {
                let got = undulation(lon, lat);
                assert!((got - n).abs() < 0.06, "({lat}, {lon}): {got} vs NGA {n}");
            }
        }
    }

    #[test]
    fn named_places_large_and_small() {
        // N of these places from the same grid by `scripts/egm96_grid.py`'s layout read
        // independently (Python, bilinear), to the centimetre; EGM96 maps give the same within
        // a metre: the eastern US about -33 m, Iceland and New Guinea about +66 and +71 m,
        // Sri Lanka's coast near -98 m, Monaco +49 m.
        for (name, lon, lat, n) in [
            ("Washington", -77.0369, 38.9072, -33.24),
            ("Reykjavik", -21.9426, 64.1466, 66.41),
            ("Lae", 146.9961, -6.7333, 71.34),
            ("Colombo", 79.8612, 6.9271, -97.66),
            ("Monaco", 7.4246, 43.7384, 48.73),
        ] {
            let got = undulation(lon, lat);
            assert!((got - n).abs() < 0.3, "{name}: {got} vs {n}");
        }
    }

    #[test]
    fn posts_are_exact_and_cells_are_bilinear() {
        let g = GRID.as_slice();
        // On a post: the post. Row 200 is 40° N, column 40 is 10° E.
        assert_eq!(undulation(10.0, 40.0), post(g, 200, 40));
        // The middle of a cell: the mean of its four posts.
        let mean =
            (post(g, 200, 40) + post(g, 200, 41) + post(g, 201, 40) + post(g, 201, 41)) / 4.0;
        assert!((undulation(10.125, 39.875) - mean).abs() < 1e-9);
    }

    #[test]
    fn longitudes_wrap_and_poles_are_one_value() {
        // Across the antimeridian and the prime meridian, no seam.
        for lat in [-60.0, -10.0, 0.0, 35.0, 71.0] {
            for lon in [180.0, 0.0] {
                let (a, b) = (undulation(lon - 1e-9, lat), undulation(lon + 1e-9, lat));
                assert!((a - b).abs() < 1e-6, "{lon} {lat}: {a} {b}");
                assert_eq!(undulation(lon, lat), undulation(lon + 720.0, lat));
            }
            assert!((undulation(-180.0, lat) - undulation(180.0, lat)).abs() < 1e-9);
        }
        for lon in [-179.0, -45.5, 0.0, 33.3, 180.0] {
            assert!((undulation(lon, 90.0) - 13.61).abs() < 1e-9);
            assert!((undulation(lon, -90.0) + 29.53).abs() < 1e-9);
            assert!((undulation(lon, 95.0) - 13.61).abs() < 1e-9);
        }
        assert_eq!(undulation(f64::NAN, 10.0), 0.0);
        assert_eq!(undulation(10.0, f64::INFINITY), 0.0);
    }

    #[test]
    fn the_steepest_geoid_moves_under_half_a_millimetre_a_metre() {
        // The largest step between neighbouring posts is 9.74 m (the Himalaya, 30° N), over
        // 15' of latitude (27.8 km) or less of longitude: what bounds the error of taking one
        // N for a whole building (tiles3d: N at each building's anchor).
        let g = GRID.as_slice();
        let mut worst: f64 = 0.0;
        for r in 0..ROWS - 1 {
            let lat = (90.0 - r as f64 / PER_DEGREE).to_radians();
            let dx = 6_371_000.0 * (15.0_f64 / 60.0).to_radians() * lat.cos().max(1e-3);
            let dy = 6_371_000.0 * (15.0_f64 / 60.0).to_radians();
            for c in 0..COLS {
                let v = post(g, r, c);
                if r > 0 && r < ROWS - 1 {
                    worst = worst.max((post(g, r, c + 1) - v).abs() / dx);
                }
                worst = worst.max((post(g, r + 1, c) - v).abs() / dy);
            }
        }
        assert!(worst < 5e-4, "{worst}");
    }
}
