//! `citygen kb learn` on the Monaco sample: the learned knowledge base passes `kb check
//! --strict` (and schemas/kb.xsd where the validators' environment is installed), is
//! byte-identical across runs, and reproduces what it learned: the generator, run with the
//! learned KB on the Monaco buildings whose learned tags are removed (so the KB decides),
//! draws storeys and roof shapes whose distribution is close to the tagged one (total
//! variation distance, overall and per cell). The buildings keep their `building=*` kind, so
//! the generator draws each among the per-kind group that names its kind, where one is learned.

use crate::common::*;

use std::collections::BTreeMap;

use citygen::derive::{Generator, Rules};
use citygen::input::osm::read_osm;
use citygen::input::BuildingTags;
use citygen::kb::learn::{learn, Grouping, LearnOptions, Sample};
use citygen::kb::{KnowledgeBase, ReadMode};
use citygen::model::Lod;
use citygen::prepare::prepare;

/// Seeds pooled on the generated side, so that the figure measures the encoding, not the draw.
const SEEDS: u64 = 10;

/// Total variation distance between two count maps (each normalised).
fn tvd<K: Ord + Clone>(a: &BTreeMap<K, f64>, b: &BTreeMap<K, f64>) -> f64 {
    let (sa, sb): (f64, f64) = (a.values().sum(), b.values().sum());
    let mut keys: Vec<K> = a.keys().cloned().collect();
    keys.extend(b.keys().cloned());
    keys.sort();
    keys.dedup();
    0.5 * keys
        .iter()
        .map(|k| {
            (a.get(k).copied().unwrap_or(0.0) / sa.max(1e-300)
                - b.get(k).copied().unwrap_or(0.0) / sb.max(1e-300))
            .abs()
        })
        .sum::<f64>()
}

/// The tags a learned KB decides: every one `Sample::from_tags` reads but the kind.
fn without_learned_tags(t: &BuildingTags) -> BuildingTags {
    BuildingTags {
        levels: None,
        min_level: None,
        height: None,
        min_height: None,
        roof_shape: None,
        invalid_roof_shape: None,
        roof_height: None,
        roof_levels: None,
        roof_angle: None,
        colour: None,
        roof_colour: None,
        material: None,
        roof_material: None,
        ..t.clone()
    }
}

/// The figures of one learning: (storeys TVD, roof TVD) overall, and weighted per cell.
struct Figures {
    storeys: f64,
    roof: f64,
    roof_learned: bool,
}

/// Learns Monaco on a 500 m grid with `min_samples`, generates the tagged buildings without
/// parts with their learned tags removed ([`SEEDS`] seeds), and compares.
fn measure(min_samples: usize) -> Figures {
    let mut report = citygen::report::Report::default();
    let read = read_osm(&root().join(MONACO), &mut report).unwrap();
    let mut site = prepare(read.footprints, None, None, &mut report);
    let samples: Vec<Sample> = site
        .lots
        .iter()
        .filter_map(|l| Sample::from_tags(l.lonlat, &l.tags))
        .collect();
    let o = LearnOptions {
        grouping: Grouping::Grid { metres: 500.0 },
        min_samples,
        max_appearances: 12,
        name: "monaco".into(),
        source: MONACO.into(),
    };
    let learned = learn(&samples, &o).unwrap();
    let (kb, _) =
        KnowledgeBase::parse_str_with(&learned.text, "learned.xml", ReadMode::Strict).unwrap();
    eprintln!(
        "learned from {} buildings: {} bytes, {} zones ({} with data of their own), {} appearances, \
         {} per-kind groups",
        learned.samples,
        learned.text.len(),
        learned.zones,
        learned.zones_with_own_data,
        learned.appearances,
        learned.kind_groups
    );
    // Every building lies in the cell it was learned in (binning = the KB's polygons).
    let town = kb.find("earth/monaco").unwrap();
    for l in &site.lots {
        let z = kb.locate(l.lonlat.0, l.lonlat.1);
        assert_eq!(kb.zone(z).unwrap().parent, Some(town), "{}", l.id);
    }

    // Buildings without parts (their storeys and roof are their own piece's), tags hidden.
    let test: Vec<usize> = (0..site.lots.len())
        .filter(|&i| {
            let l = &site.lots[i];
            l.parts.is_empty() && !l.drawn_outline().is_empty() && !l.tags.is_roof()
        })
        .collect();
    let truth: Vec<(Option<u32>, Option<&'static str>, usize)> = test
        .iter()
        .map(|&i| {
            let l = &site.lots[i];
            let s = Sample::from_tags(l.lonlat, &l.tags).unwrap();
            (
                s.storeys,
                s.roof.map(|r| r.osm_name()),
                kb.locate(l.lonlat.0, l.lonlat.1),
            )
        })
        .collect();
    for &i in &test {
        let t = without_learned_tags(&site.lots[i].tags);
        site.lots[i].tags = std::sync::Arc::new(t);
    }
    // (zone, value) counts: tagged vs generated (pooled over the seeds).
    type Counts<K> = BTreeMap<usize, BTreeMap<K, f64>>;
    let (mut st_tag, mut st_gen): (Counts<u32>, Counts<u32>) = Default::default();
    let (mut rf_tag, mut rf_gen): (Counts<&str>, Counts<&str>) = Default::default();
    for (s, r, z) in &truth {
        if let Some(n) = s {
            *st_tag.entry(*z).or_default().entry(*n).or_default() += 1.0;
        }
        if let Some(r) = r {
            *rf_tag.entry(*z).or_default().entry(*r).or_default() += 1.0;
        }
    }
    let mut failed = 0;
    for seed in 0..SEEDS {
        let (kb, _) = KnowledgeBase::parse_str(&learned.text, "learned.xml").unwrap();
        let gen = Generator::new(kb, Rules::Kb, Lod::Lod1, seed, Default::default());
        for (&i, (s, r, z)) in test.iter().zip(&truth) {
            if s.is_none() && r.is_none() {
                continue;
            }
            let Ok((b, _)) = gen.generate(&site.lots[i]) else {
                failed += 1;
                continue;
            };
            if s.is_some() {
                *st_gen
                    .entry(*z)
                    .or_default()
                    .entry(b.storeys_above_ground)
                    .or_default() += 1.0;
            }
            if r.is_some() {
                *rf_gen
                    .entry(*z)
                    .or_default()
                    .entry(b.roof_shape.osm_name())
                    .or_default() += 1.0;
            }
        }
    }
    fn overall<K: Ord + Clone>(c: &Counts<K>) -> BTreeMap<K, f64> {
        let mut m = BTreeMap::new();
        for v in c.values() {
            for (k, n) in v {
                *m.entry(k.clone()).or_default() += n;
            }
        }
        m
    }
    /// Per cell with at least `min` tagged values: the TVD weighted by the tagged counts.
    fn per_cell<K: Ord + Clone>(tag: &Counts<K>, gen: &Counts<K>, min: f64) -> (f64, usize) {
        let (mut sum, mut weight, mut cells) = (0.0, 0.0, 0);
        for (z, t) in tag {
            let n: f64 = t.values().sum();
            if n < min {
                continue;
            }
            let g = gen.get(z).cloned().unwrap_or_default();
            sum += n * tvd(t, &g);
            weight += n;
            cells += 1;
        }
        (sum / weight.max(1.0), cells)
    }
    let n_st: f64 = overall(&st_tag).values().sum();
    let n_rf: f64 = overall(&rf_tag).values().sum();
    let st = tvd(&overall(&st_tag), &overall(&st_gen));
    let rf = tvd(&overall(&rf_tag), &overall(&rf_gen));
    let m = min_samples as f64;
    let (st_cell, st_cells) = per_cell(&st_tag, &st_gen, m);
    let (rf_cell, rf_cells) = per_cell(&rf_tag, &rf_gen, m);
    eprintln!(
        "{} buildings without parts, {n_st} with storeys, {n_rf} with a roof shape; {SEEDS} \
         seeds, {failed} derivations failed",
        test.len()
    );
    eprintln!("min samples {min_samples}: TVD overall: storeys {st:.3}, roof shape {rf:.3}");
    let shown = |v: f64, n: usize| {
        if n == 0 {
            "n/a (0 cells)".to_string()
        } else {
            format!("{v:.3} ({n} cells)")
        }
    };
    eprintln!(
        "min samples {min_samples}: TVD per cell (weighted, cells with {min_samples}+ tagged): \
         storeys {}, roof shape {}",
        shown(st_cell, st_cells),
        shown(rf_cell, rf_cells)
    );
    assert_eq!(failed, 0);
    assert!(n_st >= 50.0, "{n_st}");
    Figures {
        storeys: st,
        roof: rf,
        roof_learned: learned.text.contains("bdRooftype"),
    }
}

#[test]
fn monaco_learned_kb_reproduces_the_tag_distributions() {
    // Default settings: Monaco has 71 outlines tagged with building:levels and 6 with
    // roof:shape, so only the storeys are learned (extract-wide, and in the cells with 20+).
    let d = measure(20);
    assert!(!d.roof_learned);
    assert!(d.storeys <= 0.10, "storeys TVD {}", d.storeys);
    // --min-samples 5: the roof shape is learned too (from 6 buildings, extract-wide).
    let f = measure(5);
    assert!(f.roof_learned);
    assert!(f.storeys <= 0.10, "storeys TVD {}", f.storeys);
    assert!(f.roof <= 0.10, "roof TVD {}", f.roof);
}

/// The binary: writes a KB that `kb check --strict` accepts (and schemas/kb.xsd where the
/// validators' environment is installed), the same bytes twice, and refuses bad inputs with
/// the file's name.
#[test]
fn kb_learn_cli_writes_a_strict_kb_deterministically() {
    let dir = tempfile::tempdir().unwrap();
    let a = dir.path().join("a.xml");
    let b = dir.path().join("b.xml");
    for out in [&a, &b] {
        let o = citygen(&[
            "kb",
            "learn",
            "--osm",
            MONACO,
            "--out",
            out.to_str().unwrap(),
        ]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    }
    let text = std::fs::read(&a).unwrap();
    assert_eq!(text, std::fs::read(&b).unwrap(), "not deterministic");
    let check = citygen(&["kb", "check", "--strict", a.to_str().unwrap()]);
    let said = String::from_utf8_lossy(&check.stdout);
    assert!(check.status.success(), "{said}");
    assert!(said.contains("0 repairs, 0 errors, 0 warnings"), "{said}");
    eprintln!("{}", said.lines().next().unwrap_or(""));
    // The schema, where the validators' environment is.
    let home = std::env::var_os("CITYGEN_VALIDATE_HOME")
        .map(std::path::PathBuf::from)
        .or_else(|| {
            std::env::var_os("HOME")
                .map(|h| std::path::Path::new(&h).join(".cache/citygen-validate"))
        });
    let py = home.map(|h| h.join("venv/bin/python"));
    if py.as_ref().is_some_and(|p| p.exists()) {
        let o = std::process::Command::new(root().join("scripts/validate-kb"))
            .arg(&a)
            .output()
            .unwrap();
        assert!(
            o.status.success(),
            "{}{}",
            String::from_utf8_lossy(&o.stdout),
            String::from_utf8_lossy(&o.stderr)
        );
    } else {
        eprintln!("note: no validators' environment: schemas/kb.xsd not checked");
    }
    // By the zones of the shipped KB: strict too.
    let z = dir.path().join("z.xml");
    let o = citygen(&[
        "kb",
        "learn",
        "--osm",
        MONACO,
        "--zones",
        KB,
        "--out",
        z.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let check = citygen(&["kb", "check", "--strict", z.to_str().unwrap()]);
    assert!(
        check.status.success(),
        "{}",
        String::from_utf8_lossy(&check.stdout)
    );
    // Errors name the file; the output may not be the input.
    let empty = dir.path().join("empty.osm.pbf");
    std::fs::write(&empty, b"").unwrap();
    let o = citygen(&[
        "kb",
        "learn",
        "--osm",
        empty.to_str().unwrap(),
        "--out",
        dir.path().join("x.xml").to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&o.stderr).contains("empty.osm.pbf"));
    assert!(!dir.path().join("x.xml").exists());
    let o = citygen(&["kb", "learn", "--osm", MONACO, "--out", MONACO]);
    assert_eq!(o.status.code(), Some(2));
}
