//! End-to-end tests: the real binary on the real samples in data/.

use std::collections::{BTreeMap, BTreeSet};

use crate::common::*;
use osmpbf::{Element, ElementReader};

/// Building ways and relations of the Monaco extract, counted independently of citygen, with
/// the tags the tests need.
fn monaco_buildings() -> BTreeMap<String, BTreeMap<String, String>> {
    let reader = ElementReader::from_path(root().join(MONACO)).unwrap();
    let mut out = BTreeMap::new();
    reader
        .for_each(|e| {
            let (id, tags): (String, BTreeMap<String, String>) = match &e {
                Element::Way(w) => (
                    format!("way/{}", w.id()),
                    w.tags().map(|(k, v)| (k.into(), v.into())).collect(),
                ),
                Element::Relation(r) => (
                    format!("relation/{}", r.id()),
                    r.tags().map(|(k, v)| (k.into(), v.into())).collect(),
                ),
                _ => return,
            };
            let is_building = tags.get("building").is_some_and(|v| v != "no");
            let is_mp =
                id.starts_with("way") || tags.get("type").is_some_and(|t| t == "multipolygon");
            if is_building && is_mp {
                out.insert(id, tags);
            }
        })
        .unwrap();
    out
}

/// gml:id of the Building elements of a CityGML file, with their element text.
fn citygml_buildings(gml: &str) -> BTreeMap<String, String> {
    let mut out = BTreeMap::new();
    for chunk in gml.split("<bldg:Building gml:id=\"").skip(1) {
        let id = chunk[..chunk.find('"').unwrap()].to_string();
        let end = chunk.find("</bldg:Building>").unwrap_or(chunk.len());
        out.insert(id, chunk[..end].to_string());
    }
    out
}

fn source_key(id: &str) -> String {
    id.replace('/', "_")
}

#[test]
fn monaco_lod2_every_building_is_in_all_outputs_or_reported() {
    let run = run_all("--osm", MONACO, "2", &[]);
    let buildings = monaco_buildings();
    assert!(
        buildings.len() > 1000,
        "independent count found {}",
        buildings.len()
    );
    let gml = std::fs::read_to_string(&run.gml).unwrap();
    let in_gml = citygml_buildings(&gml);
    let report = run.report_json();
    let skipped: BTreeSet<String> = report["entries"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|e| e["outcome"] == "skipped")
        .map(|e| e["id"].as_str().unwrap().to_string())
        .collect();
    let gml_keys: BTreeSet<String> = in_gml
        .keys()
        .map(|k| k.trim_start_matches("B_").to_string())
        .collect();
    for id in buildings.keys() {
        assert!(
            gml_keys.contains(&source_key(id)) || skipped.contains(id),
            "{id} is neither in the CityGML nor reported as skipped"
        );
    }
    // The three formats agree on the number of buildings, and with the report.
    let generated = report["generated"].as_u64().unwrap() as usize;
    assert_eq!(in_gml.len(), generated);
    let (json, _) = glb_json(&run.glb);
    let scene_nodes = json["scenes"][0]["nodes"].as_array().unwrap().len();
    assert_eq!(scene_nodes, generated);
    let ifc = step_entities(&run.ifc);
    let top_level = ifc
        .values()
        .filter(|(t, a)| t == "IFCBUILDING" && !a.contains(".PARTIAL."))
        .count();
    assert_eq!(top_level, generated);
}

#[test]
fn height_tag_gives_measured_height_and_top() {
    let buildings = monaco_buildings();
    // A plain building with a numeric height and no roof shape or parts.
    let (id, h) = buildings
        .iter()
        .filter(|(_, t)| !t.contains_key("roof:shape") && !t.contains_key("min_height"))
        .find_map(|(id, t)| Some((id.clone(), t.get("height")?.trim().parse::<f64>().ok()?)))
        .expect("a Monaco building with height=");
    let run = run_all("--osm", MONACO, "2", &[]);
    let gml = std::fs::read_to_string(&run.gml).unwrap();
    let b = &citygml_buildings(&gml)[&format!("B_{}", source_key(&id))];
    let mh: f64 = b
        .split("<bldg:measuredHeight uom=\"m\">")
        .nth(1)
        .unwrap()
        .split('<')
        .next()
        .unwrap()
        .parse()
        .unwrap();
    assert!(
        (mh - h).abs() < 0.01,
        "{id}: measuredHeight {mh} vs height={h}"
    );
    let zs: Vec<f64> = b
        .split("<gml:posList")
        .skip(1)
        .flat_map(|s| {
            let body = &s[s.find('>').unwrap() + 1..s.find("</gml:posList>").unwrap()];
            body.split_whitespace()
                .map(|v| v.parse::<f64>().unwrap())
                .collect::<Vec<_>>()
                .chunks(3)
                .map(|c| c[2])
                .collect::<Vec<_>>()
        })
        .collect();
    let (lo, hi) = zs
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), z| {
            (a.min(*z), b.max(*z))
        });
    assert!(
        (hi - lo - h).abs() < 0.01,
        "{id}: geometry spans {lo}..{hi}, height={h}"
    );
}

#[test]
fn threads_do_not_change_a_byte() {
    let one = run_all("--osm", MONACO, "2", &["--threads", "1", "--seed", "7"]);
    let two = run_all("--osm", MONACO, "2", &["--threads", "2", "--seed", "7"]);
    for (a, b) in [
        (&one.ifc, &two.ifc),
        (&one.gml, &two.gml),
        (&one.glb, &two.glb),
        (&one.report, &two.report),
    ] {
        assert!(
            std::fs::read(a).unwrap() == std::fs::read(b).unwrap(),
            "{} differs between 1 and 2 threads",
            a.display()
        );
    }
}

#[test]
fn clifton_shapefile_lod1_runs_and_counts_agree() {
    let run = run_all("--shp", CLIFTON, "1", &[]);
    let report = run.report_json();
    let generated = report["generated"].as_u64().unwrap() as usize;
    let skipped = report["skipped"].as_u64().unwrap() as usize;
    assert_eq!(report["read"].as_u64().unwrap() as usize, 2989);
    assert!(
        generated + skipped >= 2989,
        "generated {generated} + skipped {skipped}"
    );
    let gml = std::fs::read_to_string(&run.gml).unwrap();
    assert_eq!(citygml_buildings(&gml).len(), generated);
    // The default output CRS is the input's projected CRS (issue 47): the .prj's British
    // National Grid, no longer the data's UTM zone.
    assert!(
        gml.contains("srsName=\"EPSG:27700\"") && !gml.contains("EPSG:326"),
        "default output CRS is the .prj's British National Grid"
    );
}

#[test]
fn missing_input_is_a_clear_error_naming_the_path() {
    let out = citygen(&[
        "--osm",
        "no/such/file.pbf",
        "--kb",
        KB,
        "--ifc",
        "target/never/never.ifc",
    ]);
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("no/such/file.pbf"), "{err}");
}

#[test]
fn no_output_is_a_usage_error() {
    let out = citygen(&["--osm", MONACO, "--kb", KB]);
    assert_eq!(out.status.code(), Some(2));
}

/// Monaco read and prepared through the library, as the binary does.
fn monaco_site() -> citygen::prepare::Site {
    monaco_site_and_streets().0
}

/// Monaco read and prepared through the library, as the binary does, with its streets as read.
fn monaco_site_and_streets() -> (citygen::prepare::Site, citygen::input::Streets) {
    let mut report = citygen::report::Report::default();
    let read = citygen::input::osm::read_osm(&root().join(MONACO), &mut report).unwrap();
    let mut site = citygen::prepare::prepare(read.footprints, None, None, &mut report);
    citygen::prepare::assign_fronts(&mut site, &read.streets, None);
    (site, read.streets)
}

fn generator(lod: citygen::model::Lod) -> citygen::derive::Generator {
    let (kb, _) = citygen::kb::KnowledgeBase::load(&root().join(KB)).unwrap();
    let caps = citygen::grammar::Caps {
        facades: false,
        ..Default::default()
    };
    citygen::derive::Generator::new(kb, citygen::derive::Rules::Kb, lod, 0, caps)
}

#[test]
fn levels_without_height_give_walls_of_levels_times_the_zone_floor_height() {
    let site = monaco_site();
    let gen = generator(citygen::model::Lod::Lod2);
    let mut checked = 0;
    for lot in site.lots.iter().filter(|l| l.parts.is_empty()) {
        let t = &lot.tags;
        let (Some(levels), None, None, None) = (t.levels, t.height, t.min_height, t.min_level)
        else {
            continue;
        };
        // A roof on pillars has no storeys: its levels say how high it stands (tests/it/s3db.rs).
        if t.is_roof() {
            continue;
        }
        // The floor height the building's zone and appearance give, drawn as the generator does.
        let zone = gen.kb.locate(lot.lonlat.0, lot.lonlat.1);
        let mut rng = citygen::rng::Rng::new(0, lot.id.seed_value());
        let (style, _) = gen.kb.style_for(zone, t, &mut rng);
        let (b, _) = gen.generate(lot).unwrap();
        for part in &b.parts {
            let walls = part.eave_z - part.base_z;
            assert!(
                (walls - levels * style.floor_height).abs() < 0.01,
                "{}: walls {walls} m, building:levels={levels} x floor {} m",
                lot.id,
                style.floor_height
            );
            assert_eq!(
                f64::from(part.storeys),
                levels,
                "{}: storeys of the derived tree vs building:levels",
                lot.id
            );
            if part.roof_shape == citygen::model::RoofShape::Flat {
                assert!((b.measured_height - levels * style.floor_height).abs() < 0.01);
            }
        }
        checked += 1;
    }
    assert!(
        checked > 20,
        "only {checked} Monaco buildings with levels and no height"
    );
}

#[test]
fn courtyards_stay_holes_in_all_three_formats() {
    let site = monaco_site();
    let lot = site
        .lots
        .iter()
        .find(|l| l.id.to_string() == "relation/393226")
        .expect("the courtyard relation");
    assert_eq!(lot.polygons[0].holes.len(), 1);
    let area = lot.polygons[0].area();
    let run = run_all("--osm", MONACO, "2", &[]);

    // CityGML: the building's ground polygon carries the courtyard as an interior ring (its
    // hipped roof runs round the courtyard, so the roof faces need none).
    let gml = std::fs::read_to_string(&run.gml).unwrap();
    let b = &citygml_buildings(&gml)["B_relation_393226"];
    let ground = &b[b.find("<bldg:GroundSurface").unwrap()..];
    let ground = &ground[..ground.find("</bldg:GroundSurface>").unwrap()];
    assert_eq!(
        ground.matches("<gml:interior>").count(),
        1,
        "no interior ring in the CityGML ground"
    );

    // glTF: the ground mesh of the building covers the footprint minus the courtyard.
    let (json, bin) = glb_json(&run.glb);
    let nodes = json["nodes"].as_array().unwrap();
    let building = nodes
        .iter()
        .find(|n| n["name"] == "relation_393226")
        .unwrap();
    let ground = building["children"]
        .as_array()
        .unwrap()
        .iter()
        .map(|c| &nodes[c.as_u64().unwrap() as usize])
        .find(|n| n["name"] == "ground")
        .unwrap();
    let prim = &json["meshes"][ground["mesh"].as_u64().unwrap() as usize]["primitives"][0];
    let read_accessor = |i: u64| -> (Vec<f32>, Vec<u32>) {
        let acc = &json["accessors"][i as usize];
        let view = &json["bufferViews"][acc["bufferView"].as_u64().unwrap() as usize];
        let start = (view["byteOffset"].as_u64().unwrap_or(0)
            + acc["byteOffset"].as_u64().unwrap_or(0)) as usize;
        let count = acc["count"].as_u64().unwrap() as usize;
        let stride = view["byteStride"].as_u64().unwrap_or(0) as usize;
        match acc["componentType"].as_u64().unwrap() {
            5126 => {
                let stride = if stride == 0 { 12 } else { stride };
                let mut v = Vec::new();
                for k in 0..count {
                    for c in 0..3 {
                        let o = start + k * stride + c * 4;
                        v.push(f32::from_le_bytes(bin[o..o + 4].try_into().unwrap()));
                    }
                }
                (v, vec![])
            }
            5123 => {
                let at = |k: usize| {
                    u16::from_le_bytes(bin[start + 2 * k..start + 2 * k + 2].try_into().unwrap())
                };
                (vec![], (0..count).map(|k| u32::from(at(k))).collect())
            }
            _ => {
                let at = |k: usize| {
                    u32::from_le_bytes(bin[start + 4 * k..start + 4 * k + 4].try_into().unwrap())
                };
                (vec![], (0..count).map(at).collect())
            }
        }
    };
    let (pos, _) = read_accessor(prim["attributes"]["POSITION"].as_u64().unwrap());
    let (_, idx) = read_accessor(prim["indices"].as_u64().unwrap());
    let p = |i: u32| (pos[3 * i as usize] as f64, pos[3 * i as usize + 2] as f64);
    let tri_area: f64 = idx
        .chunks(3)
        .map(|t| {
            let (a, b, c) = (p(t[0]), p(t[1]), p(t[2]));
            0.5 * ((b.0 - a.0) * (c.1 - a.1) - (c.0 - a.0) * (b.1 - a.1)).abs()
        })
        .sum();
    assert!(
        (tri_area - area).abs() < 0.01 * area,
        "glTF ground {tri_area} m² vs footprint {area} m²"
    );

    // IFC: one slab profile with voids per derived part whose footprint has holes (the
    // courtyards, and the holes that parts cut in the parts around them).
    let gen = generator(citygen::model::Lod::Lod2);
    let with_holes: usize = site
        .lots
        .iter()
        .filter_map(|l| gen.generate(l).ok())
        .flat_map(|(b, _)| b.parts)
        .filter(|p| !p.footprint.holes.is_empty())
        .count();
    let ifc = step_entities(&run.ifc);
    let voids = ifc
        .values()
        .filter(|(t, _)| t == "IFCARBITRARYPROFILEDEFWITHVOIDS")
        .count();
    assert!(with_holes >= 3);
    assert_eq!(
        voids, with_holes,
        "IFC slab profiles with voids vs footprints with holes"
    );
}

#[test]
fn output_crs_can_be_chosen_and_source_crs_overridden() {
    // Clifton is in British National Grid; asking for EPSG:27700 keeps its coordinates.
    let run = run_all(
        "--shp",
        CLIFTON,
        "1",
        &["--crs", "EPSG:27700", "--src-crs", "EPSG:27700"],
    );
    let gml = std::fs::read_to_string(&run.gml).unwrap();
    assert!(gml.contains("srsName=\"EPSG:27700\""));
    let corner = gml.split("<gml:lowerCorner>").nth(1).unwrap();
    let xy: Vec<f64> = corner
        .split_whitespace()
        .take(2)
        .map(|v| v.parse().unwrap())
        .collect();
    assert!(
        (453_000.0..457_000.0).contains(&xy[0]) && (332_000.0..337_000.0).contains(&xy[1]),
        "{xy:?}"
    );
    let ifc = std::fs::read_to_string(&run.ifc).unwrap();
    assert!(ifc.contains("'EPSG:27700'"));
    let (json, _) = glb_json(&run.glb);
    assert_eq!(json["asset"]["extras"]["crs"], "EPSG:27700");
}

#[test]
fn unknown_crs_is_a_usage_error() {
    let out = citygen(&[
        "--osm",
        MONACO,
        "--kb",
        KB,
        "--ifc",
        "target/never/never.ifc",
        "--crs",
        "EPSG:3857",
    ]);
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("3857"));
}

#[test]
fn outputs_are_not_left_half_written_when_the_run_fails() {
    // A rules file that does not parse fails the run before anything is written.
    let dir = tempfile::tempdir().unwrap();
    let rules = dir.path().join("bad.cga");
    std::fs::write(
        &rules,
        "lot -> extrude(10){building}\nbuilding -> frobnicate(3){x}\n",
    )
    .unwrap();
    let target = dir.path().join("out.gml");
    std::fs::write(&target, "previous").unwrap();
    let out = citygen(&[
        "--osm",
        MONACO,
        "--rules",
        rules.to_str().unwrap(),
        "--citygml",
        target.to_str().unwrap(),
    ]);
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("bad.cga:2:"), "{err}");
    assert_eq!(std::fs::read_to_string(&target).unwrap(), "previous");
    assert_eq!(
        std::fs::read_dir(dir.path()).unwrap().count(),
        2,
        "a temporary file was left behind"
    );
}

#[test]
fn rules_check_reports_unreachable_rules_and_exits_zero_on_warnings() {
    let out = citygen(&[
        "rules",
        "check",
        "knowledge_base/rules/toulouse_downtown.cga",
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(0), "{err}");
    for sym in [
        "floor2",
        "face2",
        "upper_face2",
        "windowarea2",
        "vwindow2",
        "bwindow2",
    ] {
        assert!(
            err.contains(&format!("rule for `{sym}` is never used")),
            "{sym} not reported: {err}"
        );
    }
    let out = citygen(&["rules", "check", "knowledge_base/rules/fig3_19.cga"]);
    assert_eq!(
        out.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

#[test]
fn rules_check_fails_with_file_line_col_on_a_malformed_ruleset() {
    let dir = tempfile::tempdir().unwrap();
    let f = dir.path().join("bad.cga");
    std::fs::write(
        &f,
        "lot -> extrude(10){building}\nbuilding -> split(Q, 1, 2){a | b}\n",
    )
    .unwrap();
    let out = citygen(&["rules", "check", f.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("bad.cga:2:"), "{err}");
    assert!(err.contains('^'), "no caret: {err}");
}

#[test]
fn rules_derive_writes_one_test_lot() {
    let dir = tempfile::tempdir().unwrap();
    // The output folder does not exist yet: citygen creates it.
    let gml = dir.path().join("new/sub/lot.gml");
    let out = citygen(&[
        "rules",
        "derive",
        "knowledge_base/rules/fig3_19.cga",
        "--lot",
        "20x12",
        "--citygml",
        gml.to_str().unwrap(),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = std::fs::read_to_string(&gml).unwrap();
    // Figure 3.19 splits the mass in two halves along Y: two building parts.
    assert_eq!(text.matches("<bldg:BuildingPart ").count(), 2);
    let wkt = citygen(&[
        "rules",
        "derive",
        "knowledge_base/rules/fig3_19.cga",
        "--wkt",
        "POLYGON ((0 0, 30 0, 30 10, 10 10, 10 25, 0 25, 0 0))",
        "--citygml",
        gml.to_str().unwrap(),
    ]);
    assert!(
        wkt.status.success(),
        "{}",
        String::from_utf8_lossy(&wkt.stderr)
    );
}

#[test]
fn a_rule_bomb_ends_in_bounded_time_with_one_report_entry_per_building() {
    let dir = tempfile::tempdir().unwrap();
    let rules = dir.path().join("bomb.cga");
    std::fs::write(&rules, "lot -> extrude(10){a}\na -> repeat(X, 0.0001){a}\n").unwrap();
    let report = dir.path().join("report.json");
    let start = std::time::Instant::now();
    let out = citygen(&[
        "--osm",
        MONACO,
        "--rules",
        rules.to_str().unwrap(),
        "--citygml",
        dir.path().join("out.gml").to_str().unwrap(),
        "--report",
        report.to_str().unwrap(),
        // Every building is skipped: the run is asked to write its (empty) outputs anyway.
        "--allow-empty",
        "--quiet",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(
        start.elapsed().as_secs() < 120,
        "took {:?}",
        start.elapsed()
    );
    let r: serde_json::Value = serde_json::from_slice(&std::fs::read(&report).unwrap()).unwrap();
    assert_eq!(r["generated"], 0);
    let skipped: Vec<&serde_json::Value> = r["entries"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|e| e["outcome"] == "skipped")
        .collect();
    assert_eq!(skipped.len() as u64, r["skipped"].as_u64().unwrap());
    assert!(skipped.len() > 1000);
    assert!(
        skipped
            .iter()
            .all(|e| e["reason"].as_str().unwrap().contains("bomb.cga:2")),
        "{:?}",
        skipped[0]
    );
}

/// Windows and doors per building in a CityGML file (by gml:id).
fn citygml_openings(gml: &str) -> BTreeMap<String, (usize, usize)> {
    citygml_buildings(gml)
        .into_iter()
        .map(|(id, text)| {
            (
                id,
                (
                    text.matches("<bldg:Window ").count(),
                    text.matches("<bldg:Door ").count(),
                ),
            )
        })
        .collect()
}

/// A corner of Monaco (the old town), small enough for LOD3 in a debug test.
const MONACO_VILLE: &str = "7.4180,43.7290,7.4240,43.7330";

#[test]
fn lod3_window_and_door_counts_agree_between_ifc_and_citygml() {
    let run = run_all("--osm", MONACO, "3", &["--bbox", MONACO_VILLE]);
    let gml = citygml_openings(&std::fs::read_to_string(&run.gml).unwrap());
    let ifc = ifc_openings_per_building(&step_entities(&run.ifc));
    let (mut windows, mut doors) = (0, 0);
    for (id, (w, d)) in &gml {
        let source = id.trim_start_matches("B_").replacen('_', "/", 1);
        let (iw, id_) = ifc.get(&source).copied().unwrap_or((0, 0));
        assert_eq!(
            (iw, id_),
            (*w, *d),
            "{source}: IFC windows/doors vs CityGML"
        );
        windows += w;
        doors += d;
    }
    assert!(gml.len() > 20, "{} buildings in the box", gml.len());
    assert!(
        windows > 500 && doors > 20,
        "{windows} windows, {doors} doors"
    );
    // Every IFC opening is filled by exactly one window or door, and voids exactly one wall.
    let ents = step_entities(&run.ifc);
    let count = |t: &str| ents.values().filter(|(k, _)| k == t).count();
    assert_eq!(
        count("IFCOPENINGELEMENT"),
        count("IFCWINDOW") + count("IFCDOOR")
    );
    assert_eq!(count("IFCRELFILLSELEMENT"), count("IFCOPENINGELEMENT"));
    assert_eq!(count("IFCRELVOIDSELEMENT"), count("IFCOPENINGELEMENT"));
}

/// Front doors face the nearest street. For the Monaco buildings (without parts) with a street
/// within 20 m — measured here independently of `prepare`, by sampling the outline — the
/// ground-floor wall whose outward normal is closest to the street direction holds a door.
/// Two street directions are checked: the lot's `front` (the normal of the outline edge that
/// `prepare` found facing the street: this checks the scope, `comp` and the compiled rules put
/// the door there), and, more loosely, the normal of the nearest street segment measured here
/// (buildings between two streets or touching a footway may legitimately differ).
#[test]
fn monaco_front_doors_face_the_nearest_street() {
    use citygen::model::{Building, OpeningKind};
    use glam::DVec2;
    let (site, streets) = monaco_site_and_streets();
    let local = |(lon, lat): (f64, f64)| {
        let (x, y) = site.crs.from_lonlat(lon, lat);
        DVec2::new(x, y) - site.origin
    };
    let segments: Vec<(DVec2, DVec2)> = streets
        .lines()
        .flat_map(|l| l.windows(2).map(|w| (local(w[0]), local(w[1]))))
        .collect();
    let nearest_on = |a: DVec2, b: DVec2, p: DVec2| {
        let d = b - a;
        a + d * ((p - a).dot(d) / d.length_squared().max(1e-12)).clamp(0.0, 1.0)
    };
    // Whether a ground-floor wall among those whose outward normal is closest to `dir` has a door.
    let door_on_closest_wall = |b: &Building, dir: DVec2| {
        let walls: Vec<(f64, bool)> = b
            .parts
            .iter()
            .flat_map(|p| p.walls.iter())
            .filter(|w| w.storey == 0 && w.length() > 1e-6)
            .map(|w| {
                let d = (w.end - w.start).normalize();
                let door = w.openings.iter().any(|o| o.kind == OpeningKind::Door);
                (DVec2::new(d.y, -d.x).dot(dir), door)
            })
            .collect();
        let top = walls.iter().map(|w| w.0).fold(f64::NEG_INFINITY, f64::max);
        walls.iter().any(|w| w.0 >= top - 1e-3 && w.1)
    };
    let mut gen = generator(citygen::model::Lod::Lod3);
    gen.caps.facades = true;
    let (mut checked, mut good, mut measured, mut thesis) = (0usize, 0usize, 0usize, 0usize);
    let mut blocked = 0usize;
    let mut misses = Vec::new();
    // Every third building keeps the debug-mode time small (LOD3 twice per building).
    for lot in site.lots.iter().filter(|l| l.parts.is_empty()).step_by(3) {
        let edges: Vec<(DVec2, DVec2)> = lot
            .polygons
            .iter()
            .flat_map(|p| {
                (0..p.outer.len()).map(|i| (p.outer[i], p.outer[(i + 1) % p.outer.len()]))
            })
            .collect();
        let (lo, hi) = edges.iter().fold(
            (DVec2::splat(f64::INFINITY), DVec2::splat(f64::NEG_INFINITY)),
            |(lo, hi), (a, _)| (lo.min(*a), hi.max(*a)),
        );
        // The nearest street segment and outline point, sampling the outline every 0.5 m.
        let mut best: Option<(f64, DVec2, (DVec2, DVec2))> = None;
        for &(s0, s1) in &segments {
            if s0.max(s1).cmplt(lo - 20.0).any() || s0.min(s1).cmpgt(hi + 20.0).any() {
                continue;
            }
            for &(a, b) in &edges {
                let n = ((a.distance(b) / 0.5).ceil() as usize).max(1);
                for k in 0..=n {
                    let p = a.lerp(b, k as f64 / n as f64);
                    let d = p.distance(nearest_on(s0, s1, p));
                    if best.is_none_or(|b| d < b.0) {
                        best = Some((d, p, (s0, s1)));
                    }
                }
            }
        }
        let Some((dist, p, (s0, s1))) = best else {
            continue;
        };
        if dist > 20.0 {
            continue;
        }
        // Every edge that faces the street may be against another building (a house behind
        // another): then it has no front.
        let Some(front) = lot.front else {
            blocked += 1;
            continue;
        };
        let (b, _) = gen.generate(lot).unwrap();
        checked += 1;
        if door_on_closest_wall(&b, front) {
            good += 1;
        } else {
            misses.push(lot.id.to_string());
        }
        // The nearest segment's normal, from the building towards the street.
        let mut dir = (s1 - s0).normalize().perp();
        if dir.dot(p - s0) > 0.0 {
            dir = -dir;
        }
        if door_on_closest_wall(&b, dir) {
            measured += 1;
        }
        let mut plain = lot.clone();
        plain.front = None;
        if door_on_closest_wall(&gen.generate(&plain).unwrap().0, dir) {
            thesis += 1;
        }
    }
    let pc = |n: usize| 100.0 * n as f64 / checked.max(1) as f64;
    println!(
        "{checked} buildings with a street within 20 m ({blocked} more against another building there); door on the wall facing: the lot's front \
         {good} ({:.1} %), the nearest segment {measured} ({:.1} %), the same with the thesis \
         front {thesis} ({:.1} %); misses: {:?}",
        pc(good),
        pc(measured),
        pc(thesis),
        &misses[..misses.len().min(10)]
    );
    assert!(checked > 250, "{checked} buildings near a street");
    assert!(
        blocked * 20 <= checked,
        "{blocked} of {checked} have every street-facing edge against another building"
    );
    assert!(pc(good) >= 90.0, "{:.1} %", pc(good));
    assert!(pc(measured) >= pc(thesis) + 30.0);
}

#[test]
fn kb_check_repairs_the_thesis_annex_and_strict_mode_refuses_it() {
    let out = citygen(&["kb", "check", "tests/data/thesis_annex.xml"]);
    let text = String::from_utf8_lossy(&out.stdout);
    assert_eq!(
        out.status.code(),
        Some(0),
        "{text}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(text.contains("line"), "repairs carry their line: {text}");
    let strict = citygen(&["kb", "check", "--strict", "tests/data/thesis_annex.xml"]);
    assert_ne!(strict.status.code(), Some(0));
    let shipped = citygen(&["kb", "check", "--strict", KB]);
    assert_eq!(
        shipped.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&shipped.stdout)
    );
}

#[test]
fn a_reader_that_stops_early_is_no_panic() {
    // `citygen kb check BIG.xml | head -1`: half a megabyte of findings, the pipe closed
    // after the first line. The rest goes nowhere; the exit code is the command's own.
    use std::io::{BufRead, BufReader};
    let dir = tempfile::tempdir().unwrap();
    let kb = dir.path().join("big.xml");
    let mut text = String::from("<earth><info color=\"white\"/>\n");
    for i in 0..3000 {
        text.push_str(&format!(
            "<country designation=\"C{i}\"><info lat=\"1\" lon=\"1\" dist=\"1\" \
             color=\"notacolour{i}\"/></country>\n"
        ));
    }
    text.push_str("</earth>\n");
    std::fs::write(&kb, text).unwrap();
    let mut child = std::process::Command::new(env!("CARGO_BIN_EXE_citygen"))
        .args(["kb", "check"])
        .arg(&kb)
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let mut first = String::new();
    BufReader::new(child.stdout.take().unwrap())
        .read_line(&mut first)
        .unwrap();
    assert!(first.contains("3001 zones"), "{first}");
    // The reader is dropped: the pipe is closed.
    let out = child.wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!err.contains("panicked"), "{err}");
    assert_eq!(out.status.code(), Some(0), "{err}");
}

#[test]
fn kb_compile_prints_rules_that_parse() {
    let out = citygen(&[
        "kb",
        "compile",
        KB,
        "--zone",
        "France/Occitanie/Toulouse/Centre-Ville",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = String::from_utf8_lossy(&out.stdout);
    let sections: Vec<&str> = text.split("# ").filter(|s| !s.trim().is_empty()).collect();
    assert!(!sections.is_empty());
    for s in sections {
        let (label, rules) = s.split_once('\n').unwrap();
        citygen::grammar::parse(rules, label).unwrap_or_else(|e| panic!("{e}"));
    }
    let bad = citygen(&["kb", "compile", KB, "--zone", "Atlantis"]);
    assert_eq!(bad.status.code(), Some(1));
}

#[test]
fn kb_explain_tells_the_zone_chain_and_the_chosen_appearance() {
    let out = citygen(&[
        "kb",
        "explain",
        KB,
        "--osm",
        MONACO,
        "--id",
        "relation/393226",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.contains("/Monaco/Monaco-Ville"), "{text}");
    // What explain says is what the generator does: the same appearance as in the CityGML.
    let chosen = text
        .lines()
        .find_map(|l| l.strip_prefix("chosen with this seed: "))
        .unwrap()
        .trim()
        .to_string();
    let run = run_all("--osm", MONACO, "2", &[]);
    let gml = std::fs::read_to_string(&run.gml).unwrap();
    let b = &citygml_buildings(&gml)["B_relation_393226"];
    assert!(
        b.contains(&format!("<gen:value>{chosen}</gen:value>")),
        "explain chose {chosen}"
    );
    let missing = citygen(&["kb", "explain", KB, "--osm", MONACO, "--id", "way/1"]);
    assert_eq!(missing.status.code(), Some(1));
}

#[test]
fn kb_explain_finds_a_feature_by_its_text_id() {
    // The Zürich truth footprints carry GUID text ids (their `ID` column): the outputs name
    // the buildings by them, and so does explain.
    let shp = "tests/data/truth/zurich/footprints.shp";
    let id = "UUID_04153856-c970-4f34-a0cf-ff14691e3841";
    let out = citygen(&["kb", "explain", KB, "--shp", shp, "--id", id]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.contains("Switzerland"), "{text}");
    let missing = citygen(&["kb", "explain", KB, "--shp", shp, "--id", "UUID_nobody"]);
    assert_eq!(missing.status.code(), Some(1));
    let err = String::from_utf8_lossy(&missing.stderr);
    assert!(err.contains("no building UUID_nobody"), "{err}");
}

#[test]
fn tiled_run_puts_every_building_in_exactly_one_tile_with_the_same_bytes() {
    // A whole run and a tiled run of the same input: the tiles hold exactly the buildings of the
    // whole run, each once, with the same geometry (the frame is the site's, not the tile's).
    let whole = run_all("--shp", CLIFTON, "1", &[]);
    let tiled = run_all("--shp", CLIFTON, "1", &["--tile", "250"]);
    assert!(!tiled.gml.exists(), "a tiled run writes no untiled file");
    let whole_gml = std::fs::read_to_string(&whole.gml).unwrap();
    let all = citygml_buildings(&whole_gml);
    let mut seen = BTreeMap::new();
    let mut names = Vec::new();
    for entry in std::fs::read_dir(tiled.dir.path()).unwrap() {
        let name = entry.unwrap().file_name().to_string_lossy().into_owned();
        if !name.ends_with(".gml") {
            continue;
        }
        // out_{easting}_{northing}.gml, corners on the 250 m grid.
        let parts: Vec<&str> = name.trim_end_matches(".gml").split('_').collect();
        assert_eq!(parts.len(), 3, "{name}");
        let (e, n): (i64, i64) = (parts[1].parse().unwrap(), parts[2].parse().unwrap());
        assert!(e % 250 == 0 && n % 250 == 0, "{name} is not on the grid");
        for ext in ["ifc", "glb"] {
            let sibling = tiled
                .dir
                .path()
                .join(name.replace(".gml", &format!(".{ext}")));
            assert!(sibling.exists(), "{} missing", sibling.display());
        }
        let text = std::fs::read_to_string(tiled.dir.path().join(&name)).unwrap();
        for (id, body) in citygml_buildings(&text) {
            assert_eq!(all.get(&id), Some(&body), "{id} differs in tile {name}");
            assert!(
                seen.insert(id.clone(), name.clone()).is_none(),
                "{id} twice"
            );
        }
        names.push(name);
    }
    assert!(
        names.len() >= 4,
        "Clifton spans several 250 m tiles: {names:?}"
    );
    assert_eq!(seen.len(), all.len(), "every building is in one tile");
    assert_eq!(
        whole.report_json()["generated"],
        tiled.report_json()["generated"]
    );
}

#[test]
fn dry_run_writes_no_model_file_and_counts_the_bytes_a_real_run_writes() {
    let real = run_all("--shp", CLIFTON, "2", &["--tile", "250"]);
    // The model files: not the report, nor the tiled run's manifest (a dry run writes neither
    // a manifest nor any file it would list).
    let model_files: Vec<std::fs::DirEntry> = std::fs::read_dir(real.dir.path())
        .unwrap()
        .map(|e| e.unwrap())
        .filter(|e| {
            let n = e.file_name().to_string_lossy().into_owned();
            n != "report.json" && !n.starts_with("citygen-manifest.")
        })
        .collect();
    assert!(real
        .dir
        .path()
        .join("citygen-manifest.0-of-1.json")
        .exists());
    let real_bytes: u64 = model_files
        .iter()
        .map(|e| e.metadata().unwrap().len())
        .sum();
    let real_files = model_files.len();

    let dir = tempfile::tempdir().unwrap();
    let outs = dir.path().join("not-yet");
    let p = |n: &str| outs.join(n).display().to_string();
    let report = dir.path().join("report.json");
    let out = citygen(&[
        "--shp",
        CLIFTON,
        "--kb",
        KB,
        "--lod",
        "2",
        "--tile",
        "250",
        "--ifc",
        &p("out.ifc"),
        "--citygml",
        &p("out.gml"),
        "--gltf",
        &p("out.glb"),
        "--report",
        &report.display().to_string(),
        "--dry-run",
    ]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    assert!(!outs.exists(), "a dry run creates no output folder");
    let names: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(names, ["report.json"], "only the report is written");
    assert!(
        stderr.contains(&format!(
            " bytes in {real_files} file(s)"
        )) && stderr.contains(&format!(", {real_bytes} bytes in ")),
        "the dry run counts the {real_bytes} bytes in {real_files} files of the real run:\n{stderr}"
    );
    assert!(stderr.contains("would write "), "{stderr}");
    let dry: serde_json::Value = serde_json::from_slice(&std::fs::read(&report).unwrap()).unwrap();
    assert_eq!(dry["generated"], real.report_json()["generated"]);
}

/// The south-west corner of the Clifton sample (a few dozen houses), as `--bbox=...` because
/// the value starts with a minus sign.
const CLIFTON_PART: &str = "--bbox=-1.1950,52.9020,-1.1900,52.9050";

#[test]
fn lod4_from_the_command_line_writes_every_room_in_every_format() {
    let run = run_all("--shp", CLIFTON, "4", &[CLIFTON_PART]);
    let report = run.report_json();
    assert_eq!(report["skipped"], 0, "{report}");
    let ents = step_entities(&run.ifc);
    let count = |t: &str| ents.values().filter(|(k, _)| k == t).count();
    let spaces = count("IFCSPACE");
    let buildings = count("IFCBUILDING");
    assert!(buildings > 20, "{buildings} buildings");
    // Houses of two storeys and more: a stair each, rooms on every storey.
    assert!(
        spaces > 4 * buildings,
        "{spaces} spaces in {buildings} buildings"
    );
    assert!(
        count("IFCSTAIR") > buildings / 2,
        "{} stairs",
        count("IFCSTAIR")
    );
    let gml = std::fs::read_to_string(&run.gml).unwrap();
    assert_eq!(gml.matches("<bldg:Room ").count(), spaces);
    assert!(gml.contains("<bldg:lod4Solid>") && gml.contains("<bldg:InteriorWallSurface"));
    let (json, _) = glb_json(&run.glb);
    let names: Vec<&str> = json["nodes"]
        .as_array()
        .unwrap()
        .iter()
        .filter_map(|n| n["name"].as_str())
        .collect();
    // Child nodes per class, interior ones included (named "<building> <class>").
    for class in ["floors", "interior walls", "interior doors", "stairs"] {
        assert!(
            names.iter().any(|n| n.ends_with(class)),
            "no {class:?} node among {} nodes",
            names.len()
        );
    }
}

/// A lot of 50 km: at LOD2 a valid IFC (checked by the reference validator where installed);
/// at LOD3 the facade rules would make millions of windows, and the run ends with the cap's
/// message instead (exit 1, nothing written).
#[test]
fn a_fifty_kilometre_lot_gives_a_valid_ifc_or_a_clear_error() {
    let dir = tempfile::tempdir().unwrap();
    let ifc = dir.path().join("big.ifc");
    let args = |lod: &'static str| {
        vec![
            "rules".to_string(),
            "derive".into(),
            "knowledge_base/rules/fig3_19.cga".into(),
            "--lot".into(),
            "50000x50000".into(),
            "--lod".into(),
            lod.into(),
            "--ifc".into(),
            ifc.to_str().unwrap().into(),
        ]
    };
    let a3 = args("3");
    let out = citygen(&a3.iter().map(String::as_str).collect::<Vec<_>>());
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(
        err.contains("max_pieces") && err.contains("fig3_19.cga:"),
        "{err}"
    );
    assert!(!ifc.exists());
    let a2 = args("2");
    let out = citygen(&a2.iter().map(String::as_str).collect::<Vec<_>>());
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    if let Some(tool) = citygen::testkit::validators::validate_outputs("a 50 km lot at LOD2") {
        let v = std::process::Command::new(tool).arg(&ifc).output().unwrap();
        let text = String::from_utf8_lossy(&v.stdout);
        assert!(
            v.status.success() && text.contains("1 passed, 0 failed"),
            "{text}"
        );
    }
}

#[test]
fn selex_derive_prints_the_tree_and_check_fails_with_a_caret() {
    let dir = tempfile::tempdir().unwrap();
    let good = dir.path().join("facade.slx");
    std::fs::write(
        &good,
        r#"{< descendant() [label == "building_front"] > -> createStoreyGrid("g", 3.0)};
{< descendant() [label == "g"] / [rowIdx == 1] [colIdx == 2] > -> addRoundFacade("door", ["top_left", "top_right"], 0.5, 6, 0.5)};
{< descendant() [label == "g"] / [rowIdx > 1] [pattern("(XA)*", "A")] > -> addFacade("window")};
{< descendant() [label == "nowhere"] > -> coverShape()};
"#,
    )
    .unwrap();
    let good = good.to_str().unwrap();
    let out = citygen(&["selex", "derive", good, "--lot", "12x10x9"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(0), "{err}");
    let tree = String::from_utf8_lossy(&out.stdout);
    // 9 m: three storeys; 12 m: four bays; the pattern picks bays 2 and 4 of the upper rows.
    assert!(tree.contains("g — grid 3 rows x 4 columns"), "{tree}");
    assert_eq!(tree.matches("door — element").count(), 1, "{tree}");
    assert_eq!(tree.matches("window — element").count(), 4, "{tree}");
    // The rule that selects nothing is skipped, with a warning at its place.
    assert!(
        err.contains("facade.slx:4:2: warning: the selection picks no shape"),
        "{err}"
    );
    // Without the lot, nothing has a building_front: every rule is skipped.
    let out = citygen(&["selex", "check", good]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(0), "{err}");
    assert!(err.contains("4 warnings"), "{err}");

    let bad = dir.path().join("bad.slx");
    std::fs::write(&bad, "{< cell() [rowIdz == 1] > -> addFacade(\"door\")};\n").unwrap();
    let out = citygen(&["selex", "check", bad.to_str().unwrap()]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(
        err.contains("bad.slx:1:12: unknown attribute `rowIdz`"),
        "{err}"
    );
    assert!(
        err.contains("did you mean `rowIdx`?") && err.contains('^'),
        "{err}"
    );
    let out = citygen(&["selex", "derive", bad.to_str().unwrap(), "--lot", "0x1x1"]);
    assert_eq!(out.status.code(), Some(2));
}

#[test]
fn selex_derive_writes_the_building_of_a_program_on_its_lot() {
    let dir = tempfile::tempdir().unwrap();
    let program = dir.path().join("bay.slx");
    std::fs::write(
        &program,
        r#"{< descendant() [label == "building_front"] > -> createGrid("g", 3, 5)};
{< descendant() [label == "g"] / [rowIdx == 1] [colIdx in (2, 3, 4)] [::groupRegions] > -> addVolume("bay", "building_front", 2, ["bay_front", "bay_left", "bay_right"])};
{< descendant() [label == "bay"] > -> roundShape("front", "outside", 0.5, 12, "main_front", "vertical")};
{< descendant() [label == "bay_front_grid"] / [colIdx == 2] > -> addRoundFacade("door", ["top_left", "top_right"], 0.5, 6, 0.5)};
{< descendant() [label == "g"] / [rowIdx > 1] > -> addFacadeWithFrame("window", "frame", 0.1, 0.1)};
"#,
    )
    .unwrap();
    let p = program.to_str().unwrap();
    let glb = dir.path().join("bay.glb");
    let out = citygen(&[
        "selex",
        "derive",
        p,
        "--lot",
        "12x10x9",
        "--gltf",
        glb.to_str().unwrap(),
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(0), "{err}");
    // The outputs instead of the tree.
    assert!(
        out.stdout.is_empty(),
        "{}",
        String::from_utf8_lossy(&out.stdout)
    );
    assert!(err.contains("citygen: 1 building(s)"), "{err}");
    let (json, _) = glb_json(&glb);
    assert!(!json["meshes"].as_array().unwrap().is_empty());
    // The default is LOD3: doors and windows have meshes of their own.
    let names: Vec<String> = json["meshes"]
        .as_array()
        .unwrap()
        .iter()
        .filter_map(|m| m["name"].as_str().map(str::to_string))
        .collect();
    assert!(names.iter().any(|n| n.contains("door")), "{names:?}");
    assert!(names.iter().any(|n| n.contains("window")), "{names:?}");

    // LOD2 has none.
    let glb2 = dir.path().join("lod2.glb");
    let out = citygen(&[
        "selex",
        "derive",
        p,
        "--lot",
        "12x10x9",
        "--lod",
        "2",
        "--gltf",
        glb2.to_str().unwrap(),
    ]);
    assert_eq!(out.status.code(), Some(0));
    let (json, _) = glb_json(&glb2);
    let text = json["meshes"].to_string();
    assert!(!text.contains("door") && !text.contains("window"), "{text}");

    // Usage errors before any work: LOD4, an output on the program, a report alone.
    for args in [
        vec!["--lod", "4", "--gltf", glb2.to_str().unwrap()],
        vec!["--ifc", p],
        vec!["--report", "r.json"],
    ] {
        let mut all = vec!["selex", "derive", p, "--lot", "12x10x9"];
        all.extend(args.iter().copied());
        let out = citygen(&all);
        assert_eq!(
            out.status.code(),
            Some(2),
            "{all:?}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
    }
    assert!(std::fs::read_to_string(&program)
        .unwrap()
        .contains("addVolume"));
}
