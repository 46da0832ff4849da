//! Load time of knowledge bases and the cost of `KnowledgeBase::locate` (see the README's
//! "World knowledge base" section).
//!
//! ```text
//! cargo run --release --example kb_bench -- knowledge_base/kb.xml [OLD.xml ...] [--reps 5]
//!     [--pbf target/bench-inputs/tiled-1000000.osm.pbf]
//! ```
//!
//! For each KB file: the best of `--reps` loads (`KnowledgeBase::load`, lenient, as a run
//! loads it), then `locate` on 1,000,000 pseudo-random points over the inhabited latitudes
//! (fixed seed), and with `--pbf` on the centre (mean of the outer ring's vertices) of every
//! footprint of that OSM file, as the generator locates each building: total and per point,
//! best of the repetitions.

use std::path::{Path, PathBuf};
use std::time::Instant;

use citygen::kb::KnowledgeBase;

type Error = Box<dyn std::error::Error>;

fn main() -> Result<(), Error> {
    let mut kbs: Vec<PathBuf> = Vec::new();
    let mut reps = 5usize;
    let mut pbf: Option<PathBuf> = None;
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        match a.as_str() {
            "--reps" => reps = args.next().ok_or("--reps N")?.parse()?,
            "--pbf" => pbf = Some(args.next().ok_or("--pbf FILE")?.into()),
            _ => kbs.push(a.into()),
        }
    }
    if kbs.is_empty() {
        kbs.push("knowledge_base/kb.xml".into());
    }
    let reps = reps.max(1);

    let mut state = 0x9e37_79b9_7f4a_7c15u64;
    let mut next = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 11) as f64 / (1u64 << 53) as f64
    };
    let random: Vec<(f64, f64)> = (0..1_000_000)
        .map(|_| (next() * 360.0 - 180.0, next() * 130.0 - 60.0))
        .collect();
    let centres = match &pbf {
        Some(p) => Some(building_centres(p)?),
        None => None,
    };

    for path in &kbs {
        let mut load = f64::INFINITY;
        let mut kb = None;
        for _ in 0..reps {
            let t = Instant::now();
            let (k, _) = KnowledgeBase::load(path)?;
            load = load.min(t.elapsed().as_secs_f64());
            kb = Some(k);
        }
        let kb = kb.ok_or("no load")?;
        let (polygons, points) = kb.polygon_counts();
        println!(
            "{}: {} bytes, {} zones, {polygons} polygons, {points} points; load best of {reps}: {:.1} ms",
            path.display(),
            std::fs::metadata(path)?.len(),
            kb.zones().len(),
            load * 1e3
        );
        let (secs, hits) = time_locate(&kb, &random, reps);
        println!(
            "  locate, 1,000,000 random points: {:.3} s, {:.0} ns a point ({hits} not earth)",
            secs,
            secs * 1e9 / random.len() as f64
        );
        if let Some(c) = &centres {
            let (secs, hits) = time_locate(&kb, c, reps);
            println!(
                "  locate, {} building centres: {:.3} s, {:.0} ns a building ({hits} not earth)",
                c.len(),
                secs,
                secs * 1e9 / c.len().max(1) as f64
            );
        }
    }
    Ok(())
}

/// Best time of `reps` passes of `locate` over `points`, and how many fell in a zone.
fn time_locate(kb: &KnowledgeBase, points: &[(f64, f64)], reps: usize) -> (f64, usize) {
    let mut best = f64::INFINITY;
    let mut hits = 0;
    for _ in 0..reps {
        let t = Instant::now();
        hits = points
            .iter()
            .filter(|&&(lon, lat)| kb.locate(lon, lat) != 0)
            .count();
        best = best.min(t.elapsed().as_secs_f64());
    }
    (best, hits)
}

fn building_centres(path: &Path) -> Result<Vec<(f64, f64)>, Error> {
    let mut report = citygen::report::Report::default();
    let t = Instant::now();
    let r = citygen::input::osm::read_osm(path, &mut report)?;
    let out: Vec<(f64, f64)> = r
        .footprints
        .iter()
        .filter_map(|f| {
            let ring = &f.polygons.first()?.outer;
            let n = ring.len().max(1) as f64;
            let (x, y) = ring.iter().fold((0.0, 0.0), |(x, y), p| (x + p.0, y + p.1));
            Some((x / n, y / n))
        })
        .collect();
    println!(
        "{}: {} footprint centres read in {:.1} s",
        path.display(),
        out.len(),
        t.elapsed().as_secs_f64()
    );
    Ok(out)
}
