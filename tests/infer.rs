//! Storeys inferred from tagged neighbours (`prepare::infer`), cross-validated on the Monaco
//! sample: 30 % of the buildings tagged with `building:levels` (and no `height`) lose their tag,
//! and their storeys are predicted by the knowledge base alone and by the inference (the
//! knowledge base where it infers nothing). Mean absolute errors in storeys.

mod common;
use common::*;

use citygen::derive::{Generator, Rules};
use citygen::input::osm::read_osm;
use citygen::model::Lod;
use citygen::prepare::infer::{infer_levels, InferOptions};
use citygen::prepare::{assign_fronts, prepare};

#[test]
fn monaco_storeys_from_neighbours_beat_the_knowledge_base_alone() {
    let mut report = citygen::report::Report::default();
    let read = read_osm(&root().join(MONACO), &mut report).unwrap();
    let mut site = prepare(read.footprints, None, None, &mut report);
    assign_fronts(&mut site, &read.streets, None);
    let (kb, _) = citygen::kb::KnowledgeBase::load(&root().join(KB)).unwrap();
    let gen = Generator::new(kb, Rules::Kb, Lod::Lod1, 0, Default::default());
    // The hidden: a fixed 30 % of the level-tagged lots without a height.
    let hidden: Vec<usize> = site
        .lots
        .iter()
        .enumerate()
        .filter(|(_, l)| l.tags.levels.is_some_and(|v| v >= 1.0) && l.tags.height.is_none())
        .filter(|(_, l)| (l.id.seed_value().wrapping_mul(0x9e37_79b9_7f4a_7c15) >> 32) % 10 < 3)
        .map(|(i, _)| i)
        .collect();
    let truth: Vec<f64> = hidden
        .iter()
        .map(|&i| site.lots[i].tags.levels.unwrap())
        .collect();
    for &i in &hidden {
        let mut t = (*site.lots[i].tags).clone();
        t.levels = None;
        site.lots[i].tags = std::sync::Arc::new(t);
    }
    let kb: Vec<f64> = hidden
        .iter()
        .map(|&i| f64::from(gen.generate(&site.lots[i]).unwrap().0.storeys_above_ground))
        .collect();
    let kb_err: f64 = kb.iter().zip(&truth).map(|(k, t)| (k - t).abs()).sum();
    // The inference where it infers, else the knowledge base.
    let mae = |o: InferOptions| {
        let inf = infer_levels(&site.lots, o);
        let mut used = 0;
        let err: f64 = hidden
            .iter()
            .zip(kb.iter().zip(&truth))
            .map(|(&i, (&k, &t))| match inf[i] {
                Some(x) => {
                    used += 1;
                    (x.levels - t).abs()
                }
                None => (k - t).abs(),
            })
            .sum();
        (err / hidden.len() as f64, used)
    };
    // Other settings, for the record (printed, not asserted).
    for (k, radius, min) in [(8, 150.0, 3), (8, 150.0, 2), (8, 300.0, 2), (16, 500.0, 3)] {
        let o = InferOptions {
            k,
            radius,
            min_neighbours: min,
        };
        let (m, used) = mae(o);
        eprintln!("k {k}, {radius} m, at least {min}: MAE {m:.2} ({used} inferred)");
    }
    let (inf_mae, from_neighbours) = mae(InferOptions::default());
    let kb_mae = kb_err / hidden.len() as f64;
    eprintln!(
        "{} hidden of {} level-tagged; storeys MAE: knowledge base {kb_mae:.2}, inference \
         {inf_mae:.2} ({from_neighbours} from neighbours), {:.0} % lower",
        hidden.len(),
        site.lots.iter().filter(|l| l.tags.levels.is_some()).count() + hidden.len(),
        100.0 * (1.0 - inf_mae / kb_mae)
    );
    assert!(hidden.len() >= 15, "{} hidden", hidden.len());
    // Measured: 5.07 -> 3.57 storeys (30 % lower). Issue 21 asks for 40 %: not reached yet.
    assert!(inf_mae <= 0.8 * kb_mae, "{inf_mae} vs {kb_mae}");
}

/// The binary's `--infer-levels`: a report note for every building given storeys, none
/// without the flag, and taller buildings where the neighbours are.
#[test]
fn infer_levels_is_a_flag_with_a_note_per_building() {
    let notes = |r: &Run| {
        r.report_json()["entries"]
            .as_array()
            .unwrap()
            .iter()
            .filter(|e| e["reason"].as_str().unwrap().contains("inferred from"))
            .count()
    };
    let plain = run_all(
        "--osm",
        MONACO,
        "1",
        &["--bbox", "7.4180,43.7290,7.4240,43.7330"],
    );
    let with = run_all(
        "--osm",
        MONACO,
        "1",
        &["--bbox", "7.4180,43.7290,7.4240,43.7330", "--infer-levels"],
    );
    assert_eq!(notes(&plain), 0);
    let n = notes(&with);
    assert!(n > 0 && n <= 70, "{n} notes for 70 buildings");
    assert_ne!(
        std::fs::read(&plain.gml).unwrap(),
        std::fs::read(&with.gml).unwrap()
    );
}
