//! The working set of what a run infers from the neighbours (colours, then the height and roof
//! estimator), measured by a counting allocator (issue 46): before the run is read and derived
//! by block, this holds every lot at once and was the run's peak (1M bench input). Its own test
//! binary: the allocator counts every thread of the process, so nothing else may run beside the
//! one test.
//!
//! 20,000 footprints (a quarter tagged with storeys, a roof shape and a wall colour, the rest
//! bare) are read and prepared, then colours and estimates are inferred with the shipped
//! knowledge base; the peak of the live heap above what the prepared lots hold is bounded a
//! building. A tag set copied for every lot whose colour was inferred (about 0.5 KB each, as
//! before issue 46's estimator work) or the estimator's per-lot arrays held all at once as
//! they were (the regional mixes twice, every lot's point and a residual slot for every lot
//! through the estimates) pass the bound.

use citygen::input::osm::pbf_write::PbfWriter;
use citygen::input::read_osm;
use citygen::prepare::prepare;
use citygen::report::Report;
use std::sync::atomic::Ordering;

#[path = "common/counting.rs"]
mod counting;
use counting::{LIVE, PEAK};

const BUILDINGS: i64 = 20_000;
const CORNERS: i64 = 6;

/// Footprints 20 m apart in rows near Monaco, each with its own nodes; every fourth tagged.
fn write_input(path: &std::path::Path) {
    let file = std::io::BufWriter::new(std::fs::File::create(path).expect("create input"));
    let mut w = PbfWriter::new(file).expect("pbf header");
    let side = (BUILDINGS as f64).sqrt().ceil() as i64;
    let (m_lon, m_lat) = (1.0 / 80_800.0, 1.0 / 111_000.0);
    for b in 0..BUILDINGS {
        let (cx, cy) = (
            7.41 + (b % side) as f64 * 20.0 * m_lon,
            43.72 + (b / side) as f64 * 20.0 * m_lat,
        );
        // An L of 8 by 6 m, scaled a little per building: no two footprints alike.
        let s = 1.0 + 0.002 * (b % 97) as f64;
        let corners = [
            (0.0, 0.0),
            (8.0, 0.0),
            (8.0, 3.0),
            (4.0, 3.0),
            (4.0, 6.0),
            (0.0, 6.0),
        ];
        for (k, (x, y)) in corners.iter().enumerate() {
            w.node(
                b * CORNERS + k as i64 + 1,
                cx + s * x * m_lon,
                cy + s * y * m_lat,
                &[],
            )
            .expect("node");
        }
    }
    let side = (BUILDINGS as f64).sqrt().ceil() as i64;
    let colours = ["white", "beige", "#c08060"];
    let shapes = ["gabled", "flat", "hipped"];
    for b in 0..BUILDINGS {
        let mut refs: Vec<i64> = (0..CORNERS).map(|k| b * CORNERS + k + 1).collect();
        refs.push(refs[0]);
        let levels = (2 + b % 4).to_string();
        // Bands of 10 rows of one colour and roof: the neighbours agree.
        let k = (b / side / 10) as usize % 3;
        let tags: Vec<(&str, &str)> = if b % 4 == 0 {
            vec![
                ("building", "house"),
                ("building:levels", &levels),
                ("roof:shape", shapes[k]),
                ("building:colour", colours[k]),
            ]
        } else {
            vec![("building", "house")]
        };
        w.way(b + 1, &refs, &tags).expect("way");
    }
    w.finish().expect("finish");
}

#[test]
fn inferring_from_the_neighbours_holds_about_half_a_kilobyte_a_building() {
    let dir = tempfile::tempdir().expect("tempdir");
    let path = dir.path().join("rows.osm.pbf");
    write_input(&path);
    let kb_path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("knowledge_base/kb.xml");
    let (kb, _) = citygen::kb::KnowledgeBase::load(&kb_path).expect("kb");

    let mut report = Report::default();
    let read = read_osm(&path, &mut report).expect("read");
    let mut site = prepare(read.footprints, read.source_crs, None, &mut report);
    drop(read.streets);
    drop(read.boundaries);
    let n = site.lots.len();
    assert_eq!(n, BUILDINGS as usize);

    let base = LIVE.load(Ordering::Relaxed);
    PEAK.store(base, Ordering::Relaxed);
    let with_height = citygen::pipeline::infer_all(&kb, &mut site.lots);
    let peak = PEAK.load(Ordering::Relaxed) - base;
    let after = LIVE.load(Ordering::Relaxed).saturating_sub(base);
    assert_eq!(with_height, n, "every lot tagged or estimated");
    let coloured = site.lots.iter().filter(|l| l.tags.colour.is_some()).count();
    assert!(10 * coloured >= 9 * n, "{coloured} of {n} lots coloured");

    let per_building = peak / n;
    // Measured: 521 bytes a building now, 973 before (a tag set copied for each lot whose
    // colour was inferred, about 340 bytes a building here, and the estimator's arrays as they
    // were, about 110). The notes of the lots the neighbours changed (a phrase or two of about
    // 100 bytes each, in a hash map) are part of it.
    const BOUND: usize = 600;
    eprintln!(
        "memory: inferring holds {per_building} B a building at its peak (bound {BOUND}), \
         {} B a building after",
        after / n
    );
    assert!(
        per_building <= BOUND,
        "inferring from the neighbours peaks at {per_building} bytes a building; at most {BOUND}"
    );
}
