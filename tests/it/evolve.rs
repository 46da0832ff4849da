//! `citygen evolve` end to end: the search's files, the same bytes with 1 and 2 threads, and
//! `--into-kb` on a copy of the shipped knowledge base, whose Monaco district then derives its
//! buildings with the evolved rules.

use crate::common;

use std::collections::BTreeMap;
use std::path::Path;

use crate::common::{citygen, KB, MONACO};

fn files(dir: &Path) -> BTreeMap<String, Vec<u8>> {
    common::files_under(dir, |_| true)
}

fn evolve(out: &Path, threads: &str, extra: &[&str]) -> std::process::Output {
    let mut args = vec![
        "evolve",
        "--objectives",
        "vsym,hsym",
        "--population",
        "12",
        "--generations",
        "4",
        "--seed",
        "5",
        "--threads",
        threads,
        "--out",
        out.to_str().unwrap(),
    ];
    args.extend(extra);
    let o = citygen(&args);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    o
}

#[test]
fn evolve_writes_the_front_the_same_with_one_and_two_threads() {
    let tmp = tempfile::tempdir().unwrap();
    let (a, b) = (tmp.path().join("a"), tmp.path().join("b"));
    evolve(&a, "1", &[]);
    evolve(&b, "2", &[]);
    let fa = files(&a);
    assert!(fa == files(&b), "1 and 2 threads wrote different files");
    for name in [
        "evolve.json",
        "front.svg",
        "convergence.svg",
        "best-vsym.cga",
        "best-hsym.svg",
    ] {
        assert!(fa.contains_key(name), "{name} missing: {:?}", fa.keys());
    }
    // Every front ruleset passes `rules check` with no finding.
    for name in fa.keys().filter(|n| n.ends_with(".cga")) {
        let p = a.join(name);
        let o = citygen(&["rules", "check", p.to_str().unwrap()]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(
            o.status.success() && err.contains("0 errors, 0 warnings"),
            "{name}: {err}"
        );
    }
    let report: serde_json::Value = serde_json::from_slice(&fa["evolve.json"]).unwrap();
    assert_eq!(report["objectives"], serde_json::json!(["vsym", "hsym"]));
    assert!(report["history"]["generations"].as_array().unwrap().len() >= 2);
}

#[test]
fn into_kb_gives_a_monaco_district_the_evolved_rules() {
    let tmp = tempfile::tempdir().unwrap();
    let kb_dir = tmp.path().join("kb");
    std::fs::create_dir_all(&kb_dir).unwrap();
    let kb = kb_dir.join("kb.xml");
    std::fs::copy(common::root().join(KB), &kb).unwrap();
    let out = tmp.path().join("evolve");
    evolve(
        &out,
        "2",
        &[
            "--into-kb",
            kb.to_str().unwrap(),
            "--zone",
            "Monaco/Fontvieille",
        ],
    );
    let text = std::fs::read_to_string(&kb).unwrap();
    assert!(
        text.contains("<ruleset file=\"evolved/fontvieille-"),
        "no appearance added"
    );
    let o = citygen(&["kb", "check", kb.to_str().unwrap(), "--strict"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    // The district's buildings: some drew an evolved appearance (#3, after its own two).
    let seq = tmp.path().join("f.city.jsonl");
    let report = tmp.path().join("report.json");
    let o = citygen(&[
        "--osm",
        MONACO,
        "--kb",
        kb.to_str().unwrap(),
        "--lod",
        "3",
        "--bbox",
        "7.4115,43.7255,7.4190,43.7310",
        "--cityjsonseq",
        seq.to_str().unwrap(),
        "--report",
        report.to_str().unwrap(),
        "--quiet",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let lines = std::fs::read_to_string(&seq).unwrap();
    let evolved = lines
        .lines()
        .filter(|l| l.contains("Fontvieille#3"))
        .count();
    assert!(evolved > 0, "no building drew the evolved appearance");
    let r: serde_json::Value = serde_json::from_slice(&std::fs::read(&report).unwrap()).unwrap();
    let notes: Vec<&str> = r["entries"]
        .as_array()
        .unwrap()
        .iter()
        .filter_map(|e| e["reason"].as_str())
        .filter(|s| s.contains("evolved/fontvieille-"))
        .collect();
    assert!(
        notes.iter().any(|n| n.contains("derived with it")),
        "{notes:?}"
    );
}
