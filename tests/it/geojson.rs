//! GeoJSON footprints through the binary (issue 47, `input::geojson`): a FeatureCollection in
//! the British National Grid (GDAL's `crs` member) with heights under a municipal name
//! (`HAUTEUR`), OSM keys and integer ids: heights honoured within 5 cm, storeys as tagged, ids
//! kept as `feature/<id>`, the same bytes as the same file read with `--src-crs`; broken files
//! refused with the file and line named and nothing written.

use super::common::{citygen, KB};

/// Five 10 × 8 m footprints in Clifton (EPSG:27700); `None` heights carry 3 levels instead.
fn collection(crs_member: bool) -> String {
    let heights = [Some(7.2), Some(9.9), None, Some(12.34), Some(5.0)];
    let features: Vec<String> = heights
        .iter()
        .enumerate()
        .map(|(i, h)| {
            let (x, y) = (455_000.0 + 20.0 * i as f64, 334_000.0);
            let props = match h {
                Some(h) if i == 3 => format!(r#"{{"HAUTEUR": {h}, "roof:shape": "flat"}}"#),
                Some(h) => format!(r#"{{"HAUTEUR": {h}}}"#),
                None => r#"{"building:levels": "3", "building": "house"}"#.to_string(),
            };
            format!(
                r#"{{"type": "Feature", "id": {}, "properties": {props}, "geometry": {{"type": "Polygon", "coordinates": [[[{x}, {y}], [{}, {y}], [{}, {}], [{x}, {}], [{x}, {y}]]]}}}}"#,
                101 + i,
                x + 10.0,
                x + 10.0,
                y + 8.0,
                y + 8.0
            )
        })
        .collect();
    let crs = if crs_member {
        r#""crs": {"type": "name", "properties": {"name": "urn:ogc:def:crs:EPSG::27700"}},"#
    } else {
        ""
    };
    format!(
        "{{\"type\": \"FeatureCollection\", {crs}\n\"features\": [\n{}\n]}}\n",
        features.join(",\n")
    )
}

#[test]
fn a_geojson_collection_keeps_its_heights_levels_and_ids() {
    let dir = tempfile::tempdir().unwrap();
    let gj = dir.path().join("clifton.geojson");
    std::fs::write(&gj, collection(true)).unwrap();
    let seq = dir.path().join("out.city.jsonl");
    let out = citygen(&[
        "--footprints",
        gj.to_str().unwrap(),
        "--kb",
        KB,
        "--lod",
        "2",
        "--cityjsonseq",
        seq.to_str().unwrap(),
        "--quiet",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = std::fs::read_to_string(&seq).unwrap();
    let mut seen = Vec::new();
    for line in text.lines().skip(1) {
        let v: serde_json::Value = serde_json::from_str(line).unwrap();
        for o in v["CityObjects"].as_object().unwrap().values() {
            let a = &o["attributes"];
            let id = a["sourceId"].as_str().unwrap().to_string();
            let h = a["measuredHeight"].as_f64().unwrap();
            match id.as_str() {
                "feature/101" => assert!((h - 7.2).abs() < 0.05, "{h}"),
                "feature/102" => assert!((h - 9.9).abs() < 0.05, "{h}"),
                "feature/103" => assert_eq!(a["storeysAboveGround"], 3),
                "feature/104" => {
                    assert!((h - 12.34).abs() < 0.05, "{h}");
                    assert_eq!(a["roofType"], "1000");
                }
                "feature/105" => assert!((h - 5.0).abs() < 0.05, "{h}"),
                other => panic!("unexpected {other}"),
            }
            assert_eq!(a["heightSource"], "tag", "{id}");
            seen.push(id);
        }
    }
    seen.sort();
    assert_eq!(seen.len(), 5, "{seen:?}");
    // The KB zone of the place, found from the projected coordinates.
    assert!(text.contains("Nottingham/Clifton"));

    // The same file without its crs member, the CRS given on the command line: same bytes.
    let bare = dir.path().join("bare.geojson");
    std::fs::write(&bare, collection(false)).unwrap();
    let seq2 = dir.path().join("bare.city.jsonl");
    let out = citygen(&[
        "--shp",
        bare.to_str().unwrap(),
        "--src-crs",
        "EPSG:27700",
        "--kb",
        KB,
        "--lod",
        "2",
        "--cityjsonseq",
        seq2.to_str().unwrap(),
        "--quiet",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let strip = |t: &str| t.replace("bare.geojson", "clifton.geojson");
    assert_eq!(strip(&std::fs::read_to_string(&seq2).unwrap()), text);
}

#[test]
fn a_broken_geojson_is_named_with_its_line_and_nothing_is_written() {
    let dir = tempfile::tempdir().unwrap();
    let gj = dir.path().join("broken.geojson");
    let mut text = collection(true);
    text.truncate(text.len() / 2);
    std::fs::write(&gj, &text).unwrap();
    let seq = dir.path().join("out.city.jsonl");
    let out = citygen(&[
        "--footprints",
        gj.to_str().unwrap(),
        "--kb",
        KB,
        "--cityjsonseq",
        seq.to_str().unwrap(),
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(
        err.contains("broken.geojson") && err.contains("line "),
        "{err}"
    );
    assert!(!seq.exists());
}
