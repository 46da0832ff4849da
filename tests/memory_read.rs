//! The OSM reader holds a blob at a time, not the file (issue 46), measured by a counting
//! allocator. Its own test binary: the allocator counts every thread of the process, so
//! nothing else may run beside the one test.
//!
//! The input is mostly what a building read does not keep: 2,000 buildings and 1.5 million
//! nodes no way uses, at random places (so the file, about 13.5 MB, does not compress away). The
//! read keeps the buildings' ways, their nodes and their footprints, a few MB; a read that
//! holds the whole file (as before issue 46) peaks above the file's size and fails here, and so
//! does one that keeps, per block, room for every node of the block (12 bytes a node: 19 MB).

use citygen::input::osm::pbf_write::PbfWriter;
use citygen::input::read_osm;
use citygen::report::Report;
use std::sync::atomic::Ordering;

#[path = "common/counting.rs"]
mod counting;
use counting::{LIVE, PEAK};

const BUILDINGS: i64 = 2_000;
const CORNERS: i64 = 12;
/// Nodes no way uses, after the buildings' own.
const LOOSE: i64 = 1_500_000;

/// Writes `BUILDINGS` twelve-cornered footprints near Monaco, then `LOOSE` nodes anywhere on
/// Earth (a fixed pseudo-random sequence), then the buildings' ways.
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
    let mut x: u64 = 0x9e37_79b9_7f4a_7c15;
    let mut next = || {
        x ^= x << 13;
        x ^= x >> 7;
        x ^= x << 17;
        x
    };
    for i in 0..LOOSE {
        let lon = (next() % 3_600_000_000) as i64 - 1_800_000_000;
        let lat = (next() % 1_700_000_000) as i64 - 850_000_000;
        w.node_e7(BUILDINGS * CORNERS + 1 + i, lon, lat, &[])
            .expect("node");
    }
    for b in 0..BUILDINGS {
        let mut refs: Vec<i64> = (0..CORNERS).map(|k| b * CORNERS + k + 1).collect();
        refs.push(refs[0]);
        w.way(b + 1, &refs, &[("building", "yes")]).expect("way");
    }
    w.finish().expect("finish");
}

#[test]
fn the_read_holds_a_blob_a_thread_not_the_file() {
    // Two decoding threads, as on the bench machine: each holds its blob and inflated block.
    rayon::ThreadPoolBuilder::new()
        .num_threads(2)
        .build_global()
        .expect("thread pool");
    let dir = tempfile::tempdir().expect("tempdir");
    let path = dir.path().join("loose.osm.pbf");
    write_input(&path);
    let file_bytes = std::fs::metadata(&path).expect("input").len() as usize;
    assert!(file_bytes > 12_000_000, "input of {file_bytes} bytes");

    let base = LIVE.load(Ordering::Relaxed);
    PEAK.store(base, Ordering::Relaxed);
    let mut report = Report::default();
    let read = read_osm(&path, &mut report).expect("read");
    let peak = PEAK.load(Ordering::Relaxed) - base;
    assert_eq!(read.footprints.len(), BUILDINGS as usize);
    assert_eq!(report.skipped, 0);
    // The buildings' share (ways, node index, footprints: well under 2 KB a building) and a
    // blob and its inflated block for each of two threads (under 1 MB each).
    let bound = file_bytes / 4;
    eprintln!("memory: the read's peak {peak} B for a file of {file_bytes} B (bound {bound})");
    assert!(
        peak <= bound,
        "the read's peak is {peak} bytes, at most {bound} (a quarter of the {file_bytes}-byte file)"
    );
}
