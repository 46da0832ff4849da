//! OSM XML input (issue 47 item 1): Monaco's PBF written as OSM XML, plain, gzip and bzip2,
//! gives the real binary the same CityJSON bytes and the same report as the PBF; hostile XML
//! files are errors naming the file and the line, with no output written.

use std::io::Write;
use std::path::Path;
use std::process::Output;

use crate::common::{citygen, KB, MONACO};
use citygen::testkit::osm_xml::pbf_to_xml;

fn show(out: &Output) -> String {
    format!(
        "exit {:?}\nstderr: {}",
        out.status.code(),
        String::from_utf8_lossy(&out.stderr)
    )
}

/// Runs citygen on `input` at LOD2 into `dir/<tag>.city.json` and `dir/<tag>.json`: the
/// CityJSON's bytes and the report (it holds no path or timing).
fn run(input: &Path, dir: &Path, tag: &str) -> (Vec<u8>, serde_json::Value) {
    let cj = dir.join(format!("{tag}.city.json"));
    let rep = dir.join(format!("{tag}.json"));
    let out = citygen(&[
        "--osm",
        &input.display().to_string(),
        "--kb",
        KB,
        "--lod",
        "2",
        "--source-name",
        "monaco",
        "--cityjson",
        &cj.display().to_string(),
        "--report",
        &rep.display().to_string(),
        "--quiet",
    ]);
    assert!(out.status.success(), "{}: {}", input.display(), show(&out));
    let report: serde_json::Value = serde_json::from_slice(&std::fs::read(&rep).unwrap()).unwrap();
    (std::fs::read(&cj).unwrap(), report)
}

#[test]
fn monaco_as_osm_xml_plain_gz_bz2_gives_the_pbf_outputs() {
    let dir = tempfile::tempdir().unwrap();
    let mut xml = Vec::new();
    pbf_to_xml(&crate::common::root().join(MONACO), &mut xml).unwrap();
    let plain = dir.path().join("monaco.osm");
    std::fs::write(&plain, &xml).unwrap();
    let gz = dir.path().join("monaco.osm.gz");
    let mut e = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::fast());
    e.write_all(&xml).unwrap();
    std::fs::write(&gz, e.finish().unwrap()).unwrap();
    let bz = dir.path().join("monaco.osm.bz2");
    let mut e = bzip2::write::BzEncoder::new(Vec::new(), bzip2::Compression::fast());
    e.write_all(&xml).unwrap();
    std::fs::write(&bz, e.finish().unwrap()).unwrap();

    let (want_cj, want_report) = run(&crate::common::root().join(MONACO), dir.path(), "pbf");
    assert!(want_cj.len() > 1_000_000, "{}", want_cj.len());
    assert!(
        want_report["generated"].as_u64().unwrap_or(0) > 500,
        "{want_report}"
    );
    for (input, tag) in [(&plain, "xml"), (&gz, "gz"), (&bz, "bz2")] {
        let (cj, report) = run(input, dir.path(), tag);
        assert!(cj == want_cj, "{tag}: CityJSON differs from the PBF's");
        assert_eq!(report, want_report, "{tag}: report differs from the PBF's");
    }
}

#[test]
fn hostile_osm_xml_is_an_error_naming_the_file_and_line_and_writes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let cases: &[(&str, &[u8], &str)] = &[
        (
            "truncated.osm",
            b"<?xml version='1.0'?>\n<osm>\n<node id='1' lat='1' lon='1'/>\n<way id='2'>\n<nd ref='1'/>",
            "line 5",
        ),
        (
            "badnum.osm",
            b"<osm>\n<node id='1' lat='43.7' lon='7,4'/>\n</osm>",
            "lon '7,4' is not a number",
        ),
        (
            "laughs.osm",
            b"<?xml version='1.0'?>\n<!DOCTYPE osm [<!ENTITY a 'aaaaaaaaaaaaaaaa'><!ENTITY b '&a;&a;&a;&a;&a;&a;&a;&a;'><!ENTITY c '&b;&b;&b;&b;&b;&b;&b;&b;'>]>\n<osm>\n<way id='3'><tag k='building' v='&c;'/></way>\n</osm>",
            "way/3",
        ),
        (
            "change.osm",
            b"<osmChange version='0.6'><modify/></osmChange>",
            "--osc",
        ),
    ];
    for (name, bytes, needle) in cases {
        let input = dir.path().join(name);
        std::fs::write(&input, bytes).unwrap();
        let cj = dir.path().join("out.city.json");
        let out = citygen(&[
            "--osm",
            &input.display().to_string(),
            "--kb",
            KB,
            "--cityjson",
            &cj.display().to_string(),
            "--quiet",
        ]);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{name}: {}", show(&out));
        assert!(!err.contains("panicked"), "{name}: {err}");
        assert!(
            err.contains(&input.display().to_string()) && err.contains(needle),
            "{name}: {err}"
        );
        assert!(!cj.exists(), "{name}: an output was written");
    }
}
