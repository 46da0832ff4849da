//! The zone lookup with the input's admin boundaries, through the binary: a synthetic extract
//! whose country boundary differs from the knowledge base's polygons.

use std::collections::BTreeMap;
use std::path::Path;

use citygen::testkit::pbf_write::{MemberKind, PbfWriter};

use crate::common::citygen;

/// Two countries split at lon 10 (A west, B east), each with an appearance of its own, and a
/// town circle (150 m) in A just east of the split, inside the input's A.
const KB: &str = r#"<earth>
  <info nbfloor="2" floorsize="3" rooftype="flat"/>
  <country designation="Aland">
    <polygon points="9.9 46.9, 10.0 46.9, 10.0 47.1, 9.9 47.1"/>
    <appearance><values proba="1" color="white"/></appearance>
    <town designation="Atown">
      <info lat="47.0" lon="10.0044" dist="0.15"/>
      <appearance><values proba="1" color="red"/></appearance>
    </town>
  </country>
  <country designation="Bland">
    <polygon points="10.0 46.9, 10.1 46.9, 10.1 47.1, 10.0 47.1"/>
    <appearance><values proba="1" color="blue"/></appearance>
  </country>
</earth>"#;

/// One kilometre of longitude at lat 47, degrees.
const KM: f64 = 1.0 / (111.195 * 0.682);

/// Buildings (way id, lon offset from 10 in km): west of the split, in the input's A east of
/// the split, in Atown's circle, beyond the input's A.
const HOUSES: [(i64, f64); 4] = [(1, -0.5), (2, 0.8), (3, 0.3), (4, 1.5)];

/// The extract: the houses; A's boundary relation (admin_level 2, named in the local
/// language, `name:en` the KB's) reaching 1 km east of the split; B's relation with one
/// member way missing from the file (an extract cut by a box); a level 4 boundary named like
/// no zone over everything.
fn write_extract(path: &Path) {
    let mut w = PbfWriter::new(std::fs::File::create(path).unwrap()).unwrap();
    let mut node = 100;
    let mut square = |w: &mut PbfWriter<std::fs::File>, lo: (f64, f64), hi: (f64, f64)| {
        let mut refs = Vec::new();
        for (x, y) in [lo, (hi.0, lo.1), hi, (lo.0, hi.1)] {
            node += 1;
            w.node(node, x, y, &[]).unwrap();
            refs.push(node);
        }
        refs.push(refs[0]);
        refs
    };
    type Way = (i64, Vec<i64>, Vec<(&'static str, &'static str)>);
    let mut ways: Vec<Way> = Vec::new();
    for (id, km) in HOUSES {
        let x = 10.0 + km * KM;
        let refs = square(
            &mut w,
            (x - 0.0001, 47.0 - 0.0001),
            (x + 0.0001, 47.0 + 0.0001),
        );
        ways.push((id, refs, vec![("building", "yes")]));
    }
    let a = square(&mut w, (9.9, 46.9), (10.0 + KM, 47.1));
    ways.push((10, a, Vec::new()));
    let b = square(&mut w, (10.0 + KM, 46.9), (10.1, 47.1));
    // B's ring in two halves; the second (way 12) is not in the file.
    ways.push((11, b[..3].to_vec(), Vec::new()));
    let all = square(&mut w, (9.0, 46.0), (11.0, 48.0));
    ways.push((13, all, Vec::new()));
    for (id, refs, tags) in &ways {
        w.way(*id, refs, tags).unwrap();
    }
    let admin = |level: &'static str, name: &'static str| {
        vec![
            ("type", "boundary"),
            ("boundary", "administrative"),
            ("admin_level", level),
            ("name", name),
        ]
    };
    let mut a_tags = admin("2", "Ålandia");
    a_tags.push(("name:en", "ALAND"));
    let outer = |way| (MemberKind::Way, way, "outer");
    w.relation(
        50,
        &[outer(10), (MemberKind::Node, 101, "admin_centre")],
        &a_tags,
    )
    .unwrap();
    w.relation(51, &[outer(11), outer(12)], &admin("2", "Bland"))
        .unwrap();
    w.relation(52, &[outer(13)], &admin("4", "Nowhere"))
        .unwrap();
    w.finish().unwrap();
}

/// The zone of each building in the CityGML (its first generic value), by way id.
fn zones_of(gml: &str) -> BTreeMap<i64, String> {
    let mut out = BTreeMap::new();
    for chunk in gml.split("<bldg:Building gml:id=\"B_way_").skip(1) {
        let id: i64 = chunk[..chunk.find('"').unwrap()].parse().unwrap();
        let label = chunk
            .split("<gen:value>earth/")
            .nth(1)
            .and_then(|s| s.split(['#', '<']).next())
            .unwrap_or("?");
        out.insert(id, label.to_string());
    }
    out
}

#[test]
fn an_input_country_boundary_wins_over_the_kb_polygons() {
    let dir = tempfile::tempdir().unwrap();
    let (pbf, kb, gml, report) = (
        dir.path().join("in.osm.pbf"),
        dir.path().join("kb.xml"),
        dir.path().join("out.gml"),
        dir.path().join("report.json"),
    );
    write_extract(&pbf);
    std::fs::write(&kb, KB).unwrap();
    let s = |p: &Path| p.display().to_string();
    let out = citygen(&[
        "--osm",
        &s(&pbf),
        "--kb",
        &s(&kb),
        "--lod",
        "1",
        "--citygml",
        &s(&gml),
        "--report",
        &s(&report),
        "--quiet",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let zones = zones_of(&std::fs::read_to_string(&gml).unwrap());
    let want: BTreeMap<i64, String> =
        [(1, "Aland"), (2, "Aland"), (3, "Aland/Atown"), (4, "Bland")]
            .into_iter()
            .map(|(i, z)| (i, z.to_string()))
            .collect();
    assert_eq!(zones, want);
    let report: serde_json::Value =
        serde_json::from_slice(&std::fs::read(&report).unwrap()).unwrap();
    let b = &report["boundaries"];
    assert_eq!(b["read"], 2, "{b}");
    assert_eq!(b["incomplete"], serde_json::json!(["relation/51"]));
    let z = b["zones"].as_array().unwrap();
    assert_eq!(z.len(), 1, "{b}");
    assert_eq!(z[0]["boundary"], "relation/50");
    assert_eq!(z[0]["name"], "Ålandia");
    assert_eq!(z[0]["zone"], "earth/Aland");
    assert_eq!(z[0]["buildings"], 3);
    // kb explain says where the zone came from.
    let explain = citygen(&["kb", "explain", &s(&kb), "--osm", &s(&pbf), "--id", "way/2"]);
    let text = String::from_utf8_lossy(&explain.stdout);
    assert!(
        text.contains("from the input's admin boundary relation/50 \"Ålandia\" (admin_level 2)"),
        "{text}"
    );
    let west = citygen(&["kb", "explain", &s(&kb), "--osm", &s(&pbf), "--id", "way/4"]);
    assert!(!String::from_utf8_lossy(&west.stdout).contains("admin boundary"));
}
