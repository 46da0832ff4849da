//! Writes a synthetic DEM (GeoTIFF, f32, deflate) over a lon/lat box in a projected CRS, for
//! timing `--dem` with the bench inputs (README, "Terrain cost"):
//!
//! ```text
//! cargo run --release --example make_dem -- OUT.tif EPSG WEST SOUTH EAST NORTH CELL_M
//! cargo run --release --example make_dem -- target/bench-inputs/dem.tif 32632 7.35 43.68 7.9 44.0 5
//! ```
//!
//! Heights: rolling hills of 40 m over a 150 m plain, rising 2 m a kilometre to the north.

use std::path::PathBuf;

use citygen::crs::Crs;
use citygen::testkit::geotiff::{GeoTiff, Packing};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let a: Vec<String> = std::env::args().skip(1).collect();
    if a.len() != 7 {
        return Err("usage: make_dem OUT.tif EPSG WEST SOUTH EAST NORTH CELL_M".into());
    }
    let out = PathBuf::from(&a[0]);
    let epsg: u16 = a[1].parse()?;
    let [w, s, e, n, cell]: [f64; 5] = [
        a[2].parse()?,
        a[3].parse()?,
        a[4].parse()?,
        a[5].parse()?,
        a[6].parse()?,
    ];
    let crs = Crs::from_epsg_str(&format!("EPSG:{epsg}"))?;
    let corners = [(w, s), (w, n), (e, s), (e, n)].map(|(lon, lat)| crs.from_lonlat(lon, lat));
    let x0 = corners.iter().map(|c| c.0).fold(f64::INFINITY, f64::min);
    let x1 = corners
        .iter()
        .map(|c| c.0)
        .fold(f64::NEG_INFINITY, f64::max);
    let y0 = corners.iter().map(|c| c.1).fold(f64::INFINITY, f64::min);
    let y1 = corners
        .iter()
        .map(|c| c.1)
        .fold(f64::NEG_INFINITY, f64::max);
    let (width, height) = (
        ((x1 - x0) / cell).ceil() as u32,
        ((y1 - y0) / cell).ceil() as u32,
    );
    let mut dem = GeoTiff::projected(epsg, (x0, y1), cell, (width, height), |x, y| {
        150.0 + 20.0 * ((x / 700.0).sin() + (y / 900.0).cos()) + 0.002 * (y - y0)
    });
    dem.packing = Packing::Deflate;
    dem.rows_per_strip = 64;
    dem.write(&out)?;
    println!(
        "{}: {width} x {height} pixels of {cell} m, EPSG:{epsg}, {:.1} MB",
        out.display(),
        std::fs::metadata(&out)?.len() as f64 / 1e6
    );
    Ok(())
}
