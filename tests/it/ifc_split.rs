//! `--ifc-max-mb`: an IFC over the cap is split into complete IFC files, each under the cap
//! (10^6 bytes a MB), named `out-001.ifc`, `out-002.ifc`, ..., together holding every
//! building of the uncapped file exactly once, the same bytes at any thread count; a building
//! larger than the cap gets a file of its own and a report note; the names a previous run
//! left that this run does not write are removed.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use crate::common::*;

/// A part of Monaco-Ville: a few dozen buildings, an IFC of a few hundred kB at LOD2.
const BBOX: &str = "7.4215,43.7295,7.4245,43.7315";

/// Runs citygen on the district at LOD2 writing `ifc` (and the report beside it) with
/// `extra`; panics with stderr on failure.
fn run(ifc: &Path, schema: &str, extra: &[&str]) -> serde_json::Value {
    let report = ifc.with_extension("json");
    let mut args = vec![
        "--osm",
        MONACO,
        "--kb",
        KB,
        "--lod",
        "2",
        "--bbox",
        BBOX,
        "--ifc",
        ifc.to_str().unwrap(),
        "--ifc-schema",
        schema,
        "--report",
        report.to_str().unwrap(),
    ];
    args.extend_from_slice(extra);
    let res = citygen(&args);
    assert!(
        res.status.success(),
        "{args:?}: {}",
        String::from_utf8_lossy(&res.stderr)
    );
    serde_json::from_slice(&std::fs::read(&report).unwrap()).unwrap()
}

/// The `.ifc` files of `dir`, by name.
fn ifc_files(dir: &Path) -> Vec<PathBuf> {
    let mut out: Vec<PathBuf> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "ifc"))
        .collect();
    out.sort();
    out
}

/// Checks that `path` is a complete IFC of `schema` on its own (one project, site, unit
/// assignment and, past IFC2X3, map conversion; every reference resolved; every building and
/// storey with its base quantities; the trailer) and returns the GlobalIds of its
/// `IfcBuilding`s.
fn complete_file(path: &Path, schema: &str) -> Vec<String> {
    let text = std::fs::read_to_string(path).unwrap();
    assert!(
        text.starts_with("ISO-10303-21;\nHEADER;\n"),
        "{}",
        path.display()
    );
    assert!(
        text.ends_with("ENDSEC;\nEND-ISO-10303-21;\n"),
        "{}",
        path.display()
    );
    assert!(
        text.contains(&format!("FILE_SCHEMA(('{schema}'));")),
        "{}",
        path.display()
    );
    let ents = step_entities(path);
    let count = |kw: &str| ents.values().filter(|(k, _)| k == kw).count();
    assert_eq!(count("IFCPROJECT"), 1, "{}", path.display());
    assert_eq!(count("IFCSITE"), 1, "{}", path.display());
    assert_eq!(count("IFCUNITASSIGNMENT"), 1, "{}", path.display());
    let georef = if schema == "IFC2X3" { 0 } else { 1 };
    assert_eq!(count("IFCMAPCONVERSION"), georef, "{}", path.display());
    for (id, (kw, args)) in &ents {
        for r in step_refs(args) {
            assert!(
                ents.contains_key(&r),
                "{}: #{id} {kw} names #{r}, not in the file",
                path.display()
            );
        }
    }
    let qtos = crate::ifc_schemas::quantity_sets(&ents);
    let mut ids = Vec::new();
    for (id, (kw, args)) in &ents {
        let want = match kw.as_str() {
            "IFCBUILDING" => "Qto_BuildingBaseQuantities",
            "IFCBUILDINGSTOREY" => "Qto_BuildingStoreyBaseQuantities",
            _ => continue,
        };
        assert!(
            qtos.get(id).is_some_and(|s| s.contains(want)),
            "{}: #{id} {kw} has no {want}",
            path.display()
        );
        if kw == "IFCBUILDING" {
            ids.push(args.split(',').next().unwrap().to_string());
        }
    }
    ids
}

/// Every `IfcBuilding` GlobalId of `files`, with how many files hold it.
fn union(files: &[PathBuf], schema: &str) -> BTreeMap<String, usize> {
    let mut all = BTreeMap::new();
    for f in files {
        for id in complete_file(f, schema) {
            *all.entry(id).or_insert(0) += 1;
        }
    }
    all
}

#[test]
fn split_files_are_complete_under_the_cap_and_hold_every_building_once() {
    for schema in ["IFC2X3", "IFC4", "IFC4X3_ADD2"] {
        let whole = tempfile::tempdir().unwrap();
        let one = whole.path().join("m.ifc");
        run(&one, schema, &[]);
        let size = std::fs::metadata(&one).unwrap().len();
        let expected = union(std::slice::from_ref(&one), schema);
        assert!(
            expected.len() > 20,
            "{schema}: {} buildings",
            expected.len()
        );

        // A cap of about a third of the whole file, in MB with decimals.
        let cap = size / 3;
        let mb = format!("{:.6}", cap as f64 / 1e6);
        let cap = (cap as f64 / 1e6 * 1e6).round() as u64;
        let mut runs = Vec::new();
        for threads in ["1", "3"] {
            let d = tempfile::tempdir().unwrap();
            let out = d.path().join("m.ifc");
            let report = run(&out, schema, &["--ifc-max-mb", &mb, "--threads", threads]);
            let files = ifc_files(d.path());
            let names: Vec<String> = files
                .iter()
                .map(|f| f.file_name().unwrap().to_string_lossy().into_owned())
                .collect();
            let want: Vec<String> = (1..=files.len()).map(|k| format!("m-{k:03}.ifc")).collect();
            assert_eq!(names, want, "{schema}");
            assert!(files.len() >= 3, "{schema}: {names:?} for {size} bytes");
            for f in &files {
                let n = std::fs::metadata(f).unwrap().len();
                assert!(n <= cap, "{}: {n} bytes over the cap {cap}", f.display());
            }
            // Together every building, each once.
            let got = union(&files, schema);
            assert_eq!(
                got.keys().collect::<Vec<_>>(),
                expected.keys().collect::<Vec<_>>(),
                "{schema}"
            );
            assert!(got.values().all(|&n| n == 1), "{schema}: {got:?}");
            // The report lists every file.
            let notes = report["entries"].to_string();
            for n in &names {
                assert!(notes.contains(n.as_str()), "{schema}: {n} not in {notes}");
            }
            runs.push((d, names));
        }
        // The same files, byte for byte, at any thread count.
        let ((d1, n1), (d3, n3)) = (&runs[0], &runs[1]);
        assert_eq!(n1, n3);
        for n in n1 {
            assert!(
                std::fs::read(d1.path().join(n)).unwrap()
                    == std::fs::read(d3.path().join(n)).unwrap(),
                "{schema}: {n} differs between 1 and 3 threads"
            );
        }
    }
}

#[test]
fn a_building_over_the_cap_gets_a_file_of_its_own_and_a_note() {
    let d = tempfile::tempdir().unwrap();
    let whole = d.path().join("whole.ifc");
    run(&whole, "IFC4", &[]);
    let expected = union(std::slice::from_ref(&whole), "IFC4");
    let split = tempfile::tempdir().unwrap();
    // 1000 bytes: less than any file's project alone.
    let report = run(
        &split.path().join("m.ifc"),
        "IFC4",
        &["--ifc-max-mb", "0.001"],
    );
    let files = ifc_files(split.path());
    assert_eq!(files.len(), expected.len());
    let got = union(&files, "IFC4");
    assert_eq!(
        got.keys().collect::<Vec<_>>(),
        expected.keys().collect::<Vec<_>>()
    );
    let alone = report["entries"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|e| e["reason"].as_str().unwrap().contains("alone takes"))
        .count();
    assert_eq!(alone, files.len());
}

#[test]
fn names_a_previous_run_left_go_and_a_fitting_file_keeps_its_name() {
    let d = tempfile::tempdir().unwrap();
    let out = d.path().join("m.ifc");
    // A leftover of the user's that is not a part name stays.
    std::fs::write(d.path().join("m-01.ifc"), "mine").unwrap();
    run(&out, "IFC4", &["--ifc-max-mb", "0.1"]);
    let parts = ifc_files(d.path());
    assert!(parts.len() >= 3 && !out.exists(), "{parts:?}");
    // It fits now: m.ifc alone, the parts gone.
    run(&out, "IFC4", &["--ifc-max-mb", "256"]);
    let names: Vec<PathBuf> = ifc_files(d.path());
    assert_eq!(names, vec![d.path().join("m-01.ifc"), out.clone()]);
    // Split again: m.ifc gone.
    run(&out, "IFC4", &["--ifc-max-mb", "0.1"]);
    assert!(!out.exists());
    assert_eq!(ifc_files(d.path()), parts);
    // A failed run (an unreadable knowledge base) changes nothing.
    let before: Vec<(PathBuf, Vec<u8>)> = ifc_files(d.path())
        .into_iter()
        .map(|p| (p.clone(), std::fs::read(&p).unwrap()))
        .collect();
    let res = citygen(&[
        "--osm",
        MONACO,
        "--kb",
        "no/such/kb.xml",
        "--bbox",
        BBOX,
        "--ifc",
        out.to_str().unwrap(),
        "--ifc-max-mb",
        "256",
    ]);
    assert!(!res.status.success());
    let after: Vec<(PathBuf, Vec<u8>)> = ifc_files(d.path())
        .into_iter()
        .map(|p| (p.clone(), std::fs::read(&p).unwrap()))
        .collect();
    assert!(before == after);
}

#[test]
fn a_cap_out_of_range_is_refused() {
    for bad in ["0", "-1", "abc", "0.0001", "nan"] {
        let cap = format!("--ifc-max-mb={bad}");
        let res = citygen(&["--osm", MONACO, "--ifc", "unused.ifc", &cap]);
        assert!(!res.status.success(), "{bad}");
        let err = String::from_utf8_lossy(&res.stderr);
        assert!(err.contains("megabytes"), "{bad}: {err}");
    }
}
