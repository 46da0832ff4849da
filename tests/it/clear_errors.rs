//! Issue 43's unclear errors: what a user gives by mistake is named with what to do, and a dry
//! run neither needs nor creates output folders.

use std::path::Path;
use std::process::Output;

use crate::common::{citygen, KB, MONACO};

fn text(out: &Output) -> String {
    format!(
        "exit {:?}\nstderr: {}",
        out.status.code(),
        String::from_utf8_lossy(&out.stderr)
    )
}

/// Runs citygen on `input` (as `--osm`) with a glTF output in `dir`.
fn run_osm(dir: &Path, input: &Path, extra: &[&str]) -> Output {
    let glb = dir.join("out.glb");
    let mut args = vec![
        "--osm",
        input.to_str().unwrap_or_default(),
        "--kb",
        KB,
        "--lod",
        "1",
        "--gltf",
        glb.to_str().unwrap_or_default(),
        "-q",
    ];
    args.extend_from_slice(extra);
    citygen(&args)
}

#[test]
fn broken_gzip_bzip2_and_o5m_given_as_osm_are_named_with_what_to_do() {
    // OSM XML itself is read (tests/it/osm_xml.rs); broken compressed streams and other
    // formats are named.
    let dir = tempfile::tempdir().unwrap();
    let cases: [(&str, &[u8], &str); 4] = [
        ("region.osm.gz", &[0x1f, 0x8b, 8, 0, 0, 0, 0, 0], "gzip"),
        ("region.osm.bz2", b"BZh91AY&SY", "bzip2"),
        ("region.pbf.gz", &[0x1f, 0x8b, 8, 0, 1, 2, 3, 4], "gzip"),
        (
            "region.o5m",
            &[0xff, 0xe0, 0x04, b'o', b'5', b'm', b'2', 0xff],
            "o5m",
        ),
    ];
    for (name, bytes, word) in cases {
        let sub = dir.path().join(name.replace('.', "_"));
        std::fs::create_dir(&sub).unwrap();
        let input = sub.join(name);
        std::fs::write(&input, bytes).unwrap();
        let out = run_osm(&sub, &input, &[]);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{name}: {}", text(&out));
        assert!(
            err.contains(input.to_str().unwrap_or_default()),
            "{name}: the path as given: {}",
            text(&out)
        );
        assert!(err.contains(word), "{name}: {}", text(&out));
        assert!(
            err.contains("osmium") || err.contains("decompress"),
            "{name}: what to do: {}",
            text(&out)
        );
        assert!(!sub.join("out.glb").exists(), "{name}: nothing written");
        assert_eq!(
            std::fs::read(&input).unwrap(),
            bytes,
            "{name}: input intact"
        );
    }
}

#[test]
fn src_crs_with_an_osm_input_is_refused_naming_both() {
    let dir = tempfile::tempdir().unwrap();
    let out = run_osm(dir.path(), Path::new(MONACO), &["--src-crs", "EPSG:2154"]);
    assert_eq!(out.status.code(), Some(2), "{}", text(&out));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("--src-crs") && err.contains("monaco.osm.pbf") && err.contains("4326"),
        "{}",
        text(&out)
    );
    // Saying what OSM is anyway is fine.
    let ok = run_osm(dir.path(), Path::new(MONACO), &["--src-crs", "EPSG:4326"]);
    assert_eq!(ok.status.code(), Some(0), "{}", text(&ok));
}

#[test]
fn an_unsupported_crs_is_refused_with_how_to_reproject() {
    let dir = tempfile::tempdir().unwrap();
    let glb = dir.path().join("x.glb");
    let run = |crs: &str| {
        citygen(&[
            "--osm",
            MONACO,
            "--kb",
            KB,
            "--gltf",
            glb.to_str().unwrap_or_default(),
            "--crs",
            crs,
            "-q",
        ])
    };
    // No such EPSG code.
    let out = run("EPSG:9999");
    assert_eq!(out.status.code(), Some(2), "{}", text(&out));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("9999") && err.contains("reproject") && err.contains("ogr2ogr"),
        "{}",
        text(&out)
    );
    // EPSG:2263 is New York Long Island in US survey feet: outputs are in metres, and the
    // message names the metre edition (issue 47).
    let out = run("EPSG:2263");
    assert_eq!(out.status.code(), Some(2), "{}", text(&out));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("2263") && err.contains("US survey foot") && err.contains("EPSG:32118"),
        "{}",
        text(&out)
    );
    assert!(!glb.exists());
}

#[test]
fn a_dry_run_into_folders_that_do_not_exist_writes_and_creates_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let missing = dir.path().join("not").join("there");
    let path = |name: &str| missing.join(name).to_str().unwrap_or_default().to_string();
    let (json, seq, gml, ifc, glb, tiles) = (
        path("a.city.json"),
        path("a.city.jsonl"),
        path("a.gml"),
        path("a.ifc"),
        path("a.glb"),
        path("3d"),
    );
    let out = citygen(&[
        "--osm",
        MONACO,
        "--kb",
        KB,
        "--lod",
        "2",
        "--bbox",
        "7.4180,43.7290,7.4240,43.7330",
        "--cityjson",
        &json,
        "--cityjsonseq",
        &seq,
        "--citygml",
        &gml,
        "--ifc",
        &ifc,
        "--gltf",
        &glb,
        "--tiles3d",
        &tiles,
        "--dry-run",
        "-q",
    ]);
    assert_eq!(out.status.code(), Some(0), "{}", text(&out));
    assert!(
        !dir.path().join("not").exists(),
        "a dry run creates nothing"
    );
}

#[test]
fn rules_that_make_no_mass_are_named_and_the_input_by_the_path_given() {
    let dir = tempfile::tempdir().unwrap();
    let rules = dir.path().join("nothing.cga");
    std::fs::write(&rules, "lot -> nothing\n").unwrap();
    let glb = dir.path().join("x.glb");
    let out = citygen(&[
        "--osm",
        MONACO,
        "--rules",
        rules.to_str().unwrap_or_default(),
        "--gltf",
        glb.to_str().unwrap_or_default(),
        "-q",
    ]);
    assert_eq!(out.status.code(), Some(1), "{}", text(&out));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains(MONACO),
        "the input's path as given: {}",
        text(&out)
    );
    assert!(
        err.contains(rules.to_str().unwrap_or_default()),
        "the rules file: {}",
        text(&out)
    );
    assert!(!glb.exists());
}
