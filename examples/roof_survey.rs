//! Roof survey: builds a hipped roof on every footprint polygon of an input and reports the
//! ones the straight skeleton cannot handle (optionally dumping them as JSON for debugging).
//!
//! `cargo run --release --example roof_survey -- data/monaco/monaco.osm.pbf [failures.json]`

use std::path::PathBuf;

use citygen::derive::roof;
use citygen::input::{osm::read_osm, shp::read_shp, shp::ShpOptions};
use citygen::prepare::prepare;
use citygen::report::Report;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let input = PathBuf::from(
        args.next()
            .unwrap_or_else(|| "data/monaco/monaco.osm.pbf".into()),
    );
    let dump = args.next().map(PathBuf::from);
    let mut report = Report::default();
    let read = if input.extension().is_some_and(|e| e == "shp") {
        read_shp(&input, &ShpOptions::default(), &mut report)?
    } else {
        read_osm(&input, &mut report)?
    };
    let site = prepare(read.footprints, read.source_crs, None, &mut report);
    let mut total = 0;
    let mut failures = Vec::new();
    for lot in &site.lots {
        let polys = lot
            .polygons
            .iter()
            .chain(lot.parts.iter().flat_map(|p| p.polygons.iter()));
        for p in polys {
            total += 1;
            if let Err(e) = roof::hipped(p, 30.0) {
                let ring = |r: &Vec<glam::DVec2>| r.iter().map(|v| [v.x, v.y]).collect::<Vec<_>>();
                failures.push(serde_json::json!({
                    "id": lot.id.to_string(),
                    "error": e.to_string(),
                    "outer": ring(&p.outer),
                    "holes": p.holes.iter().map(ring).collect::<Vec<_>>(),
                }));
            }
        }
    }
    println!(
        "{} polygons, {} hipped roofs failed ({:.2} %)",
        total,
        failures.len(),
        100.0 * failures.len() as f64 / total.max(1) as f64
    );
    for f in failures.iter().take(20) {
        println!("  {} {}", f["id"], f["error"]);
    }
    if let Some(path) = dump {
        std::fs::write(&path, serde_json::to_string_pretty(&failures)?)?;
        println!("failures written to {}", path.display());
    }
    Ok(())
}
