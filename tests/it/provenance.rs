//! Provenance in every output (issue 42): a building's storeys, height and roof say where they
//! came from, in the CityGML, CityJSON, CityJSONSeq, IFC, glTF and 3D Tiles outputs and
//! counted in the report.

use crate::common::*;

use citygen::testkit::pbf_write::PbfWriter;

/// Three 10 × 8 m buildings in Monaco: one with `building:levels`, one with `height` and
/// `roof:shape`, one untagged.
fn three_buildings(path: &std::path::Path) {
    let (lon, lat) = (7.4200_f64, 43.7310_f64);
    let (m_lat, m_lon) = (111_195.0, 111_195.0 * lat.to_radians().cos());
    let mut w = PbfWriter::new(std::fs::File::create(path).unwrap()).unwrap();
    let mut node = 0;
    let mut ways = Vec::new();
    for i in 0..3 {
        let x0 = f64::from(i) * 30.0;
        let mut refs = Vec::new();
        for (dx, dy) in [(0.0, 0.0), (10.0, 0.0), (10.0, 8.0), (0.0, 8.0)] {
            node += 1;
            w.node(node, lon + (x0 + dx) / m_lon, lat + dy / m_lat, &[])
                .unwrap();
            refs.push(node);
        }
        refs.push(refs[0]);
        ways.push(refs);
    }
    let tags: [&[(&str, &str)]; 3] = [
        &[("building", "yes"), ("building:levels", "3")],
        &[
            ("building", "yes"),
            ("height", "12"),
            ("roof:shape", "flat"),
        ],
        &[("building", "yes")],
    ];
    for (i, (refs, t)) in ways.iter().zip(tags).enumerate() {
        w.way(i as i64 + 1, refs, t).unwrap();
    }
    w.finish().unwrap();
}

#[test]
fn every_output_and_the_report_carry_the_provenance() {
    let dir = tempfile::tempdir().unwrap();
    let pbf = dir.path().join("three.osm.pbf");
    three_buildings(&pbf);
    let extra_dir = dir.path().display().to_string();
    let cj = format!("{extra_dir}/out.city.json");
    let tiles = format!("{extra_dir}/tiles");
    let run = run_all(
        "--osm",
        pbf.to_str().unwrap(),
        "2",
        // No values from neighbours: the untagged building's are the knowledge base's.
        &["--cityjson", &cj, "--tiles3d", &tiles, "--infer", "none"],
    );

    // The report counts the sources.
    let report = run.report_json();
    assert_eq!(report["generated"], 3);
    let p = &report["provenance"];
    let counts = |what: &str| {
        ["tag", "neighbours", "fitted", "model", "kb"].map(|s| p[what][s].as_u64().unwrap())
    };
    assert_eq!(counts("storeys"), [2, 0, 0, 0, 1]);
    assert_eq!(counts("height"), [2, 0, 0, 0, 1]);
    assert_eq!(counts("roof"), [1, 0, 0, 0, 2]);

    // CityGML: the sources as strings, the KB's uncertainty as doubles.
    let gml = std::fs::read_to_string(&run.gml).unwrap();
    let building = |id: &str| {
        let start = gml.find(&format!("gml:id=\"B_way_{id}\"")).unwrap();
        let end = start + gml[start..].find("</bldg:Building>").unwrap();
        gml[start..end].to_string()
    };
    let attr = |b: &str, name: &str| -> Option<String> {
        let at = b.find(&format!("name=\"{name}\">"))?;
        let v = &b[at..];
        let v = &v[v.find("<gen:value>")? + 11..];
        Some(v[..v.find('<')?].to_string())
    };
    let tagged = building("1");
    assert_eq!(attr(&tagged, "storeysSource").as_deref(), Some("tag"));
    assert_eq!(attr(&tagged, "heightSource").as_deref(), Some("tag"));
    assert_eq!(attr(&tagged, "roofSource").as_deref(), Some("kb"));
    assert_eq!(attr(&tagged, "storeysError"), None);
    assert!(attr(&tagged, "roofProbability").is_some());
    let untagged = building("3");
    assert_eq!(attr(&untagged, "storeysSource").as_deref(), Some("kb"));
    for k in ["storeysError", "heightError", "roofProbability"] {
        let v: f64 = attr(&untagged, k).unwrap().parse().unwrap();
        assert!((0.0..=100.0).contains(&v), "{k} {v}");
    }

    // CityJSON.
    let doc: serde_json::Value = serde_json::from_slice(&std::fs::read(&cj).unwrap()).unwrap();
    let a = &doc["CityObjects"]["B_way_2"]["attributes"];
    assert_eq!(
        [&a["storeysSource"], &a["heightSource"], &a["roofSource"]],
        ["tag"; 3]
    );
    let a = &doc["CityObjects"]["B_way_3"]["attributes"];
    assert_eq!(a["heightSource"], "kb");
    assert!(a["heightError"].is_number());

    // IFC.
    let ifc = std::fs::read_to_string(&run.ifc).unwrap();
    assert_eq!(ifc.matches("'StoreysSource',$,IFCLABEL('tag')").count(), 2);
    assert_eq!(ifc.matches("'RoofSource',$,IFCLABEL('kb')").count(), 2);
    assert_eq!(ifc.matches("'HeightError',$,IFCLENGTHMEASURE(").count(), 1);

    // glTF extras.
    let (json, _) = glb_json(&run.glb);
    let sources: Vec<&str> = json["nodes"]
        .as_array()
        .unwrap()
        .iter()
        .filter_map(|n| n["extras"]["roof_source"].as_str())
        .collect();
    assert_eq!(sources, ["kb", "tag", "kb"]);

    // 3D Tiles: the schema has the properties.
    let tiles = std::path::Path::new(&tiles);
    let glbs = files_under(tiles, |p| p.ends_with(".glb") && !p.contains("blocks"));
    let full = glbs.keys().next().unwrap();
    let (json, _) = glb_json(&tiles.join(full));
    let props = &json["extensions"]["EXT_structural_metadata"]["schema"]["classes"]["building"]
        ["properties"];
    for k in [
        "storeysSource",
        "storeysError",
        "heightSource",
        "heightError",
        "roofSource",
        "roofProbability",
    ] {
        assert!(props.get(k).is_some(), "{k}");
    }
}
