//! SRTM `.hgt` tiles (NASA's Shuttle Radar Topography Mission, as distributed by NASA/USGS and
//! the viewfinderpanoramas-style mirrors): a headerless square grid of big-endian `i16` heights
//! in metres, 1201 x 1201 (3 arc-seconds, SRTM3) or 3601 x 3601 (1 arc-second, SRTM1), row by
//! row from the north. The tile is named after its south-west corner (`N43E007.hgt` covers
//! 43-44°N, 7-8°E); the grid is pixel-is-point with its outermost samples on the whole-degree
//! edges (shared with the neighbouring tiles). Horizontal datum WGS 84 (EPSG:4326), heights
//! above the EGM96 geoid (EPSG:5773); -32768 is a void (no height).
//!
//! A file is recognised by its `.hgt` extension; its name and size must then agree with the
//! format, else it is refused naming the path as given.

use std::fs::File;
use std::io::{Read, Seek, SeekFrom};
use std::path::Path;

use super::geokeys::Georef;

/// SRTM's void value.
pub(super) const VOID: f64 = -32768.0;
/// EGM96 height (EPSG:5773), the vertical datum of SRTM.
const EGM96: u16 = 5773;
/// Rows decoded at once (one "strip"): 154 KB of an SRTM3 tile.
pub(super) const ROWS: u32 = 64;

/// Whether `path` names an `.hgt` file (extension, any case).
pub(super) fn is_hgt(path: &Path) -> bool {
    path.extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| e.eq_ignore_ascii_case("hgt"))
}

/// The south-west corner (longitude, latitude, whole degrees) of the tile named by `name` (the
/// file name without `.hgt`): `N43E007`, `S12W077`, any case, optionally followed by a
/// `.`-separated suffix (`N43E007.SRTMGL1`).
pub(super) fn tile_corner(name: &str) -> Option<(i32, i32)> {
    let tile = name.split('.').next()?;
    let b = tile.as_bytes();
    if b.len() != 7 || !b[1..3].iter().chain(&b[4..7]).all(u8::is_ascii_digit) {
        return None;
    }
    let lat: i32 = tile[1..3].parse().ok()?;
    let lon: i32 = tile[4..7].parse().ok()?;
    let lat = match b[0].to_ascii_uppercase() {
        b'N' if lat <= 89 => lat,
        b'S' if (1..=90).contains(&lat) => -lat,
        _ => return None,
    };
    let lon = match b[3].to_ascii_uppercase() {
        b'E' if lon <= 179 => lon,
        b'W' if (1..=180).contains(&lon) => -lon,
        _ => return None,
    };
    Some((lon, lat))
}

/// The side of a tile of `bytes` bytes: 1201 (SRTM3) or 3601 (SRTM1).
pub(super) fn side_of(bytes: u64) -> Option<u32> {
    [1201u32, 3601]
        .into_iter()
        .find(|n| u64::from(*n) * u64::from(*n) * 2 == bytes)
}

/// An opened `.hgt` tile: its side and georeferencing.
pub(super) struct Tile {
    /// Samples across and down.
    pub side: u32,
    /// Pixel-is-point, the first sample on (west, north).
    pub georef: Georef,
}

/// Why a `.hgt` file is not a tile (the caller names the path).
#[derive(Debug, thiserror::Error)]
pub(super) enum HgtError {
    /// The name is not a tile's.
    #[error("an SRTM .hgt file is named after its tile's south-west corner, e.g. N43E007.hgt or S12W077.hgt (the name says where it is: the file has no header)")]
    Name,
    /// The size is not a tile's.
    #[error("{0} bytes: an SRTM .hgt tile holds 1201 x 1201 (2884802 bytes, 3 arc-seconds) or 3601 x 3601 (25934402 bytes, 1 arc-second) big-endian 16-bit heights; a truncated or damaged download?")]
    Size(u64),
}

/// Checks the name and size of `path` (`bytes` long) and gives its georeferencing.
pub(super) fn tile(path: &Path, bytes: u64) -> Result<Tile, HgtError> {
    let name = path
        .file_stem()
        .and_then(|s| s.to_str())
        .ok_or(HgtError::Name)?;
    let (lon, lat) = tile_corner(name).ok_or(HgtError::Name)?;
    let side = side_of(bytes).ok_or(HgtError::Size(bytes))?;
    let step = 1.0 / f64::from(side - 1);
    Ok(Tile {
        side,
        georef: Georef {
            affine: [f64::from(lon), step, 0.0, f64::from(lat + 1), 0.0, -step],
            pixel_is_point: true,
            epsg: Some(4326),
            citation: None,
            vertical_epsg: Some(EGM96),
            non_metre: None,
        },
    })
}

/// Reads strip `index` (rows `index * ROWS ..`, at most `ROWS`) of a tile of `side` samples:
/// heights row by row, NaN for voids.
pub(super) fn read_strip(file: &mut File, side: u32, index: u32) -> std::io::Result<Vec<f32>> {
    let first = index * ROWS;
    let rows = ROWS.min(side.saturating_sub(first));
    let row_bytes = 2 * u64::from(side);
    file.seek(SeekFrom::Start(u64::from(first) * row_bytes))?;
    let mut buf = vec![0u8; (u64::from(rows) * row_bytes) as usize];
    file.read_exact(&mut buf)?;
    Ok(buf
        .chunks_exact(2)
        .map(|b| {
            let v = f64::from(i16::from_be_bytes([b[0], b[1]]));
            if v == VOID {
                f32::NAN
            } else {
                v as f32
            }
        })
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tile_names() {
        assert_eq!(tile_corner("N43E007"), Some((7, 43)));
        assert_eq!(tile_corner("s12w077"), Some((-77, -12)));
        assert_eq!(tile_corner("N43E007.SRTMGL1"), Some((7, 43)));
        assert_eq!(tile_corner("N00W180"), Some((-180, 0)));
        assert_eq!(tile_corner("S90E179"), Some((179, -90)));
        for bad in [
            "", "N43E07", "N43E0070", "X43E007", "N43X007", "N4AE007", "N90E000", "S00E000",
            "N43E180", "N43W000", "monaco", "N43E007x",
        ] {
            assert_eq!(tile_corner(bad), None, "{bad}");
        }
    }

    #[test]
    fn sizes() {
        assert_eq!(side_of(2_884_802), Some(1201));
        assert_eq!(side_of(25_934_402), Some(3601));
        assert_eq!(side_of(2_884_800), None);
        assert_eq!(side_of(0), None);
    }

    #[test]
    fn georeferencing_puts_the_corners_on_whole_degrees() {
        let t = tile(Path::new("dir/S12W077.hgt"), 2_884_802).unwrap();
        assert_eq!(t.side, 1201);
        let g = &t.georef;
        assert_eq!(
            g.to_model(glam::DVec2::ZERO),
            glam::DVec2::new(-77.0, -11.0)
        );
        let last = g.to_model(glam::DVec2::splat(1200.0));
        assert!((last - glam::DVec2::new(-76.0, -12.0)).length() < 1e-12);
        assert!(matches!(
            tile(Path::new("N43E007.hgt"), 100),
            Err(HgtError::Size(100))
        ));
        assert!(matches!(
            tile(Path::new("monaco.hgt"), 2_884_802),
            Err(HgtError::Name)
        ));
    }
}
