//! Benchmark: the whole pipeline (read, derive, write IFC + CityGML + glTF) on one input, at
//! LOD1 and LOD2, repeated; prints the best run's buildings/s and output polygons/s.
//!
//! `cargo run --release --example bench -- data/monaco/monaco.osm.pbf 5`

use std::path::PathBuf;
use std::time::Instant;

use citygen::grammar::Caps;
use citygen::model::Lod;
use citygen::pipeline::{run, Options, Source};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let input = PathBuf::from(
        args.next()
            .unwrap_or_else(|| "data/monaco/monaco.osm.pbf".into()),
    );
    let reps: usize = args.next().and_then(|s| s.parse().ok()).unwrap_or(5);
    let kb = PathBuf::from(
        args.next()
            .unwrap_or_else(|| "knowledge_base/kb.xml".into()),
    );
    let dir = std::env::temp_dir().join(format!("citygen-bench-{}", std::process::id()));
    std::fs::create_dir_all(&dir)?;
    let source = if input.extension().is_some_and(|e| e == "shp") {
        Source::Shp {
            path: input.clone(),
            height_field: None,
            levels_field: None,
        }
    } else {
        Source::Osm(input.clone())
    };
    println!(
        "input {} ({} threads, best of {reps})",
        input.display(),
        rayon::current_num_threads()
    );
    for lod in [Lod::Lod1, Lod::Lod2] {
        let opts = Options {
            source: source.clone(),
            kb: Some(kb.clone()),
            rules: None,
            lod,
            ifc: Some(dir.join("b.ifc")),
            citygml: Some(dir.join("b.gml")),
            gltf: Some(dir.join("b.glb")),
            report: None,
            seed: 0,
            crs: None,
            src_crs: None,
            caps: Caps::default(),
            bbox: None,
            tile: None,
        };
        let mut best = f64::INFINITY;
        let mut last = None;
        for _ in 0..reps.max(1) {
            let t = Instant::now();
            let s = run(&opts, &|_, _| {})?;
            best = best.min(t.elapsed().as_secs_f64());
            last = Some(s);
        }
        let s = last.ok_or("no run")?;
        let bytes: u64 = s
            .outputs
            .iter()
            .filter_map(|p| std::fs::metadata(p).ok())
            .map(|m| m.len())
            .sum();
        println!(
            "LOD{}: {} buildings, {} polygons in {:.3} s: {:.0} buildings/s, {:.0} polygons/s, {:.1} MB/s written",
            lod.number(),
            s.report.generated,
            s.polygons,
            best,
            s.report.generated as f64 / best,
            s.polygons as f64 / best,
            bytes as f64 / 1e6 / best
        );
    }
    std::fs::remove_dir_all(&dir)?;
    skeleton_bench(&source, reps)?;
    Ok(())
}

/// Straight skeletons (hipped roofs) per second on the input's footprint polygons, one thread.
fn skeleton_bench(source: &Source, reps: usize) -> Result<(), Box<dyn std::error::Error>> {
    let mut report = citygen::report::Report::default();
    let read = match source {
        Source::Osm(p) => citygen::input::osm::read_osm(p, &mut report)?,
        Source::Shp { path, .. } => {
            citygen::input::shp::read_shp(path, &Default::default(), &mut report)?
        }
    };
    let site = citygen::prepare::prepare(read.footprints, read.source_crs, None, &mut report);
    let polygons: Vec<&citygen::geometry::Polygon> = site
        .lots
        .iter()
        .flat_map(|l| {
            l.polygons
                .iter()
                .chain(l.parts.iter().flat_map(|p| p.polygons.iter()))
        })
        .collect();
    let vertices: usize = polygons
        .iter()
        .map(|p| p.rings().map(Vec::len).sum::<usize>())
        .sum();
    let mut best = f64::INFINITY;
    let mut failed = 0;
    for _ in 0..reps.max(1) {
        let t = Instant::now();
        failed = polygons
            .iter()
            .filter(|p| citygen::geometry::skeleton::straight_skeleton(p).is_err())
            .count();
        best = best.min(t.elapsed().as_secs_f64());
    }
    println!(
        "skeleton: {} footprints ({vertices} vertices), {failed} failed, {:.3} s: {:.0} skeletons/s on one thread",
        polygons.len(),
        best,
        polygons.len() as f64 / best
    );
    Ok(())
}
