//! Memory per building, measured by a counting allocator (issue 46). Its own test binary: the
//! allocator counts every thread of the process, so nothing else may run beside the one test.
//!
//! A synthetic OSM input of 20,000 footprints is read and prepared (projected, cleaned,
//! parts grouped, straightened); the live heap the prepared site holds and the peak of the read
//! are measured a building. The lots' geometry is held once (a lot without parts draws its
//! outline, not a copy of it), and the read holds the file, the needed nodes and the
//! footprints, not more: an input held twice over would pass the bounds below by far.

use citygen::input::osm::pbf_write::PbfWriter;
use citygen::input::read_osm;
use citygen::prepare::prepare;
use citygen::report::Report;
use std::sync::atomic::Ordering;

#[path = "common/counting.rs"]
mod counting;
use counting::{LIVE, PEAK};

/// Buildings in the input, and the vertices of each ring (the first repeated to close it).
const BUILDINGS: i64 = 20_000;
const CORNERS: i64 = 12;

/// Writes `BUILDINGS` twelve-cornered footprints, 40 m apart on a grid near Monaco, each
/// with its own nodes.
fn write_input(path: &std::path::Path) {
    let file = std::io::BufWriter::new(std::fs::File::create(path).expect("create input"));
    let mut w = PbfWriter::new(file).expect("pbf header");
    let side = (BUILDINGS as f64).sqrt().ceil() as i64;
    let (m_lon, m_lat) = (1.0 / 78_000.0, 1.0 / 111_000.0);
    for b in 0..BUILDINGS {
        let (cx, cy) = (
            7.40 + (b % side) as f64 * 40.0 * m_lon,
            43.70 + (b / side) as f64 * 40.0 * m_lat,
        );
        for k in 0..CORNERS {
            // A star of two radii, turned a little per building: no two footprints alike.
            let a = std::f64::consts::TAU * k as f64 / CORNERS as f64 + 0.01 * (b % 17) as f64;
            let r = if k % 2 == 0 { 9.0 } else { 6.0 };
            w.node(
                b * CORNERS + k + 1,
                cx + r * a.cos() * m_lon,
                cy + r * a.sin() * m_lat,
                &[],
            )
            .expect("node");
        }
    }
    for b in 0..BUILDINGS {
        let mut refs: Vec<i64> = (0..CORNERS).map(|k| b * CORNERS + k + 1).collect();
        refs.push(refs[0]);
        w.way(b + 1, &refs, &[("building", "yes")]).expect("way");
    }
    w.finish().expect("finish");
}

#[test]
fn a_prepared_building_holds_its_geometry_once_and_the_read_a_few_hundred_bytes() {
    let dir = tempfile::tempdir().expect("tempdir");
    let path = dir.path().join("grid.osm.pbf");
    write_input(&path);
    let file_bytes = std::fs::metadata(&path).expect("input").len() as usize;

    let base = LIVE.load(Ordering::Relaxed);
    PEAK.store(base, Ordering::Relaxed);
    let mut report = Report::default();
    let read = read_osm(&path, &mut report).expect("read");
    let read_peak = PEAK.load(Ordering::Relaxed) - base;
    assert_eq!(read.footprints.len(), BUILDINGS as usize);
    let site = prepare(read.footprints, read.source_crs, None, &mut report);
    assert_eq!(site.lots.len(), BUILDINGS as usize);
    drop(read.streets);
    drop(read.boundaries);
    drop(report);
    let held = LIVE.load(Ordering::Relaxed) - base;

    let n = BUILDINGS as usize;
    // What the site must hold: its lots (the vector's capacity) and one copy of each lot's
    // geometry (polygons, rings and parts, as allocated). A second copy of each outline (the
    // drawn outline cloned, as before issue 46) adds 240 bytes a building here, over the
    // 64 bytes a building left for the rest (shared tags, the site's own fields).
    let ring = |r: &Vec<glam::DVec2>| r.capacity() * 16;
    let polygons = |ps: &Vec<citygen::geometry::Polygon>| {
        ps.capacity() * std::mem::size_of::<citygen::geometry::Polygon>()
            + ps.iter()
                .map(|p| {
                    ring(&p.outer)
                        + p.holes.capacity() * 24
                        + p.holes.iter().map(ring).sum::<usize>()
                })
                .sum::<usize>()
    };
    let lots = site.lots.capacity() * std::mem::size_of::<citygen::prepare::Lot>();
    let geometry: usize = site
        .lots
        .iter()
        .map(|l| {
            polygons(&l.polygons) + l.parts.iter().map(|p| polygons(&p.polygons)).sum::<usize>()
        })
        .sum();
    let per_building = held / n;
    let bound = (lots + geometry) / n + 64;
    assert!(
        per_building <= bound,
        "a prepared building holds {per_building} bytes; at most {bound} (the lots {}, their \
         geometry once {})",
        lots / n,
        geometry / n
    );
    assert!(
        site.lots.iter().all(|l| l.drawn.is_none()),
        "a lot without parts draws its outline, not a copy"
    );
    // The read: the file, the kept ways' node ids, the needed nodes' locations and the
    // footprints in lon/lat; well under the input twice over plus 1 KB a building.
    let read_per_building = read_peak / n;
    let read_bound = 2 * file_bytes / n + 1024;
    assert!(
        read_per_building <= read_bound,
        "the read's peak is {read_per_building} bytes a building; at most {read_bound}"
    );
    eprintln!(
        "memory: prepared {per_building} B a building (bound {bound}), read peak \
         {read_per_building} B a building (bound {read_bound}), input {file_bytes} B"
    );
}
