//! Unit tests of the OSM XML reader (`xml`): the same result as the PBF of the same data,
//! JOSM's and Overpass's particulars, and hostile files.

use std::io::Write;

use super::xml::{MAX_CHILDREN, MAX_EVENT};
use super::*;
use crate::testkit::osm_xml::pbf_to_xml;

fn monaco() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("data/monaco/monaco.osm.pbf")
}

/// What a read gives, as text: footprints, streets, boundaries and the report.
fn outcome(path: &Path) -> String {
    let mut report = Report::default();
    let r = read_osm(path, &mut report).unwrap();
    format!(
        "{:?}\n{:?}\n{:?}\n{:?}\n{} {} {} {}",
        r.footprints,
        r.streets,
        r.boundaries,
        report.entries,
        report.read,
        report.parts_read,
        report.skipped,
        report.repaired
    )
}

fn write(dir: &Path, name: &str, bytes: &[u8]) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, bytes).unwrap();
    p
}

fn read_err(path: &Path) -> String {
    match read_osm(path, &mut Report::default()) {
        Ok(r) => panic!("{}: read {} footprints", path.display(), r.footprints.len()),
        Err(e) => e.to_string(),
    }
}

fn gzip(b: &[u8]) -> Vec<u8> {
    let mut e = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::fast());
    e.write_all(b).unwrap();
    e.finish().unwrap()
}

fn bzip2(b: &[u8]) -> Vec<u8> {
    let mut e = bzip2::write::BzEncoder::new(Vec::new(), bzip2::Compression::fast());
    e.write_all(b).unwrap();
    e.finish().unwrap()
}

#[test]
fn monaco_as_xml_reads_as_its_pbf() {
    let dir = tempfile::tempdir().unwrap();
    let mut xml = Vec::new();
    pbf_to_xml(&monaco(), &mut xml).unwrap();
    let want = outcome(&monaco());
    assert!(want.len() > 100_000, "{}", want.len());
    for (name, bytes) in [
        ("m.osm", xml.clone()),
        ("m.osm.gz", gzip(&xml)),
        ("m.osm.bz2", bzip2(&xml)),
        // Named as a PBF: the content decides.
        ("m.osm.pbf", gzip(&xml)),
    ] {
        let p = write(dir.path(), name, &bytes);
        assert!(outcome(&p) == want, "{name} differs from the PBF");
    }
}

/// A small extract: a building way with its nodes after it, a multipolygon relation before
/// its ways, JOSM's deleted and new objects, an invisible node, escaped values.
const SMALL: &str = r#"<?xml version="1.0" encoding="UTF-8"?>
<osm version="0.6" generator="JOSM">
  <bounds minlat="43.7" minlon="7.4" maxlat="43.8" maxlon="7.5"/>
  <relation id="-5" action="modify">
    <member type="way" ref="-4" role="outer"/>
    <member type="node" ref="1" role=""/>
    <tag k="type" v="multipolygon"/>
    <tag k="building" v="yes"/>
  </relation>
  <relation id="6" action="delete">
    <member type="way" ref="3" role="outer"/>
    <tag k="type" v="multipolygon"/>
    <tag k="building" v="yes"/>
  </relation>
  <way id="3">
    <nd ref="1"/><nd ref="2"/><nd ref="-3"/><nd ref="1"/>
    <tag k="building" v="yes"/>
    <tag k="name" v="Caf&#233; &quot;A&amp;B&quot; &lt;1&gt;"/>
    <tag k="height" v="12"/>
  </way>
  <way id="-4">
    <nd ref="10"/><nd ref="11"/><nd ref="12"/><nd ref="10"/>
  </way>
  <way id="7" action="delete">
    <nd ref="1"/><nd ref="2"/><nd ref="-3"/><nd ref="1"/>
    <tag k="building" v="yes"/>
  </way>
  <way id="8" visible="false">
    <nd ref="1"/><nd ref="2"/><nd ref="-3"/><nd ref="1"/>
    <tag k="building" v="yes"/>
  </way>
  <way id="9">
    <nd ref="1"/><nd ref="2"/><nd ref="13"/><nd ref="1"/>
    <tag k="building" v="yes"/>
  </way>
  <node id="1" lat="43.7300000" lon="7.4200000"/>
  <node id="2" lat="43.7300000" lon="7.4202000"/>
  <node id="-3" lat="43.7302000" lon="7.4202000" action="modify"><tag k="x" v="y"/></node>
  <node id="10" lat="43.7310000" lon="7.4210000"/>
  <node id="11" lat="43.7310000" lon="7.4212000"/>
  <node id="12" lat="43.7312000" lon="7.4212000"/>
  <node id="13" lat="43.7312000" lon="7.4212000" visible="false"/>
</osm>
"#;

#[test]
fn josm_files_read_in_any_order() {
    let dir = tempfile::tempdir().unwrap();
    let p = write(dir.path(), "josm.osm", SMALL.as_bytes());
    let mut report = Report::default();
    let r = read_osm(&p, &mut report).unwrap();
    let ids: Vec<SourceId> = r.footprints.iter().map(|f| f.id).collect();
    // Way 9 uses an invisible node; ways 7 and 8 and relation 6 are gone.
    assert_eq!(
        ids,
        [SourceId::Way(3), SourceId::Relation(-5)],
        "{report:?}"
    );
    assert!(
        report
            .entries
            .iter()
            .any(|e| e.id == "way/9" && e.reason.contains("1 of 4 nodes missing")),
        "{:?}",
        report.entries
    );
    let name = r.footprints[0].tags.name.clone();
    assert_eq!(name.as_deref(), Some("Café \"A&B\" <1>"));
    assert_eq!(r.footprints[0].polygons[0].outer.len(), 3);
}

#[test]
fn a_node_list_in_a_bad_place_or_form_is_an_error_naming_the_line() {
    let dir = tempfile::tempdir().unwrap();
    let cases: &[(&str, &str, &str)] = &[
        // (file text, words the message has, ...)
        (
            "<osm>\n<node id=\"1\" lat=\"4x\" lon=\"7\"/>\n</osm>",
            "line 2",
            "lat '4x' is not a number",
        ),
        ("<osm>\n<way id=\"q\"/>\n</osm>", "line 2", "id 'q' is not an integer"),
        (
            "<osm>\n<way id=\"5\">\n<nd ref=\"\"/></way>\n</osm>",
            "way/5",
            "<nd> ref '' is not an integer",
        ),
        (
            "<osm>\n<relation id=\"5\"><member type=\"area\" ref=\"1\"/></relation></osm>",
            "relation/5",
            "unknown type 'area'",
        ),
        ("<osm>\n<node id=\"1\" lat=\"1\"/></osm>", "node/1", "no lon attribute"),
        (
            "<osm>\n<way id=\"1\">\n<nd ref=\"1\"/>\n",
            "line 4",
            "truncated",
        ),
        ("<osm>\n<way id=\"1\">\n</node></osm>", "line 3", "way"),
        ("<osmChange version=\"0.6\"><create/></osmChange>", "--osc", "osmChange"),
        ("<gpx></gpx>", "root element is <gpx>", "line 1"),
        ("<osm></osm><osm></osm>", "after the root", "line 1"),
        (
            "<?xml version=\"1.0\"?>\n<!DOCTYPE osm [<!ENTITY a \"aaaaaaaaaa\"><!ENTITY b \"&a;&a;&a;&a;&a;&a;&a;&a;&a;&a;\">]>\n<osm><node id=\"1\" lat=\"1\" lon=\"1\"><tag k=\"n\" v=\"&b;\"/></node></osm>",
            "node/1",
            "attribute 'v'",
        ),
        ("{\"version\": 0.6, \"elements\": []}", "JSON", "[out:xml]"),
    ];
    for (i, (text, a, b)) in cases.iter().enumerate() {
        let p = write(dir.path(), &format!("bad{i}.osm"), text.as_bytes());
        let e = read_err(&p);
        assert!(
            e.contains(a) && e.contains(b) && e.contains(&p.display().to_string()),
            "{text}: {e}"
        );
    }
}

#[test]
fn compressed_hostile_inputs_are_bounded_errors() {
    let dir = tempfile::tempdir().unwrap();
    // A truncated gzip stream of a good file.
    let mut xml = Vec::new();
    pbf_to_xml(&monaco(), &mut xml).unwrap();
    let gz = gzip(&xml);
    let p = write(dir.path(), "cut.osm.gz", &gz[..gz.len() / 2]);
    let e = read_err(&p);
    assert!(e.contains("of the decompressed gzip stream"), "{e}");
    let bz = bzip2(&xml);
    let p = write(dir.path(), "cut.osm.bz2", &bz[..bz.len() / 2]);
    let e = read_err(&p);
    assert!(e.contains("of the decompressed bzip2 stream"), "{e}");
    // A huge attribute: refused past MAX_EVENT bytes, not held.
    let mut huge = b"<osm><node id=\"1\" lat=\"1\" lon=\"1\"><tag k=\"a\" v=\"".to_vec();
    huge.resize(huge.len() + MAX_EVENT as usize * 2, b'x');
    huge.extend_from_slice(b"\"/></node></osm>");
    let p = write(dir.path(), "huge.osm.gz", &gzip(&huge));
    let e = read_err(&p);
    assert!(e.contains("more than") && e.contains("line 1"), "{e}");
    // Too many children of one way.
    let mut many = b"<osm><way id=\"1\">".to_vec();
    for _ in 0..=MAX_CHILDREN {
        many.extend_from_slice(b"<nd ref=\"1\"/>");
    }
    many.extend_from_slice(b"</way></osm>");
    let p = write(dir.path(), "many.osm.bz2", &bzip2(&many));
    let e = read_err(&p);
    assert!(e.contains("children") && e.contains("way/1"), "{e}");
    // A gzip of something else than XML (a gzipped PBF).
    let p = write(
        dir.path(),
        "pbf.gz",
        &gzip(&std::fs::read(monaco()).unwrap()[..1000]),
    );
    let e = read_err(&p);
    assert!(e.contains("not OSM XML inside"), "{e}");
}

#[test]
fn an_osm_change_applies_to_an_xml_extract() {
    let dir = tempfile::tempdir().unwrap();
    let p = write(dir.path(), "josm.osm", SMALL.as_bytes());
    let osc = write(
        dir.path(),
        "c.osc",
        br#"<osmChange version="0.6"><delete><way id="3"/></delete></osmChange>"#,
    );
    let mut report = Report::default();
    let r = read_osm_with_changes(&p, Some(&osc), &mut report).unwrap();
    let ids: Vec<SourceId> = r.footprints.iter().map(|f| f.id).collect();
    assert_eq!(ids, [SourceId::Relation(-5)]);
}
