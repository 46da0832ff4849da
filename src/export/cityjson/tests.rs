use std::collections::{BTreeMap, HashSet};

use glam::DVec3;
use serde_json::Value;

use super::*;
use crate::crs::Crs;
use crate::export::fixtures;
use crate::export::lod3geom::samples;
use crate::model::{grid_key, Building, Lod};

/// Not a whole metre, so the translate round trip is tested off the grid of the origin too.
const ORIGIN: DVec3 = DVec3::new(574_000.25, 6_279_000.5, 140.0);

fn ctx(lod: Lod) -> OutputContext {
    OutputContext {
        crs: Crs::Lambert93,
        origin: ORIGIN,
        origin_lonlat: (1.44, 43.6),
        lod,
        source_name: "tiny \"town\".osm.pbf".into(),
        seed: 42,
        vertical_datum: None,
        terrain: None,
    }
}

/// The LOD3 samples without openings and balconies: what a LOD1 or LOD2 run gives a writer.
fn plain(mut buildings: Vec<Building>, lod: Lod) -> Vec<Building> {
    for b in &mut buildings {
        b.lod = lod;
        for p in &mut b.parts {
            for w in &mut p.walls {
                w.openings.clear();
                w.balconies.clear();
                w.outline.holes.clear();
            }
        }
    }
    buildings
}

/// The samples of a LOD: LOD1-2 the plain LOD3 samples, LOD3 the samples, LOD4 the fixtures.
fn samples_at(lod: Lod) -> Vec<Building> {
    match lod {
        Lod::Lod1 | Lod::Lod2 => plain(samples::all(), lod),
        Lod::Lod3 => samples::all(),
        Lod::Lod4 => fixtures::lod4_all(),
    }
}

/// The buildings with ids of their own (the LOD4 fixtures reuse the samples' ids).
fn renumbered(mut buildings: Vec<Building>) -> Vec<Building> {
    for (i, b) in buildings.iter_mut().enumerate() {
        b.id = crate::model::SourceId::Way(5000 + i as i64);
    }
    buildings
}

fn write_file(lod: Lod, buildings: &[Building], all: bool) -> Vec<u8> {
    let mut w = CityJsonWriter::new(Vec::new());
    w.begin(&ctx(lod)).unwrap();
    if all {
        w.write_all(buildings).unwrap();
    } else {
        for b in buildings {
            w.write(b).unwrap();
        }
    }
    w.finish().unwrap();
    w.into_inner()
}

fn write_seq(lod: Lod, buildings: &[Building], all: bool) -> Vec<u8> {
    let mut w = CityJsonSeqWriter::new(Vec::new());
    w.begin(&ctx(lod)).unwrap();
    if all {
        w.write_all(buildings).unwrap();
    } else {
        for b in buildings {
            w.write(b).unwrap();
        }
    }
    w.finish().unwrap();
    w.into_inner()
}

fn parse(bytes: &[u8]) -> Value {
    serde_json::from_slice(bytes).unwrap_or_else(|e| {
        panic!("not JSON: {e}\n{}", String::from_utf8_lossy(bytes));
    })
}

/// The file's vertices as output-CRS points (translate + scale * v).
fn points(doc: &Value) -> Vec<DVec3> {
    let t = &doc["transform"];
    let s: Vec<f64> = (0..3).map(|i| t["scale"][i].as_f64().unwrap()).collect();
    let o: Vec<f64> = (0..3)
        .map(|i| t["translate"][i].as_f64().unwrap())
        .collect();
    doc["vertices"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| {
            let c = |i: usize| o[i] + s[i] * v[i].as_i64().unwrap() as f64;
            DVec3::new(c(0), c(1), c(2))
        })
        .collect()
}

/// Every vertex index in a geometry's boundaries.
fn indices(v: &Value, out: &mut Vec<usize>) {
    match v {
        Value::Array(a) => a.iter().for_each(|x| indices(x, out)),
        Value::Number(n) => out.push(n.as_u64().unwrap() as usize),
        _ => {}
    }
}

/// The geometries of every object.
fn geometries(doc: &Value) -> Vec<(&str, &Value)> {
    doc["CityObjects"]
        .as_object()
        .unwrap()
        .iter()
        .flat_map(|(id, o)| {
            o["geometry"]
                .as_array()
                .into_iter()
                .flatten()
                .map(move |g| (id.as_str(), g))
        })
        .collect()
}

#[test]
fn header_has_the_transform_the_crs_and_the_version() {
    let doc = parse(&write_file(Lod::Lod2, &samples_at(Lod::Lod2), true));
    assert_eq!(doc["type"], "CityJSON");
    assert_eq!(doc["version"], "2.0");
    assert_eq!(
        doc["metadata"]["referenceSystem"],
        "https://www.opengis.net/def/crs/EPSG/0/2154"
    );
    assert_eq!(doc["transform"]["scale"][0].as_f64(), Some(0.001));
    assert_eq!(doc["transform"]["translate"][0].as_f64(), Some(ORIGIN.x));
    assert_eq!(doc["transform"]["translate"][1].as_f64(), Some(ORIGIN.y));
    assert!(doc["metadata"]["title"]
        .as_str()
        .unwrap()
        .contains("tiny \"town\""));
}

#[test]
fn vertices_are_written_once_used_and_within_half_a_millimetre() {
    for lod in [Lod::Lod1, Lod::Lod2, Lod::Lod3, Lod::Lod4] {
        let buildings = samples_at(lod);
        let doc = parse(&write_file(lod, &buildings, true));
        let verts = doc["vertices"].as_array().unwrap();
        let distinct: HashSet<String> = verts.iter().map(|v| v.to_string()).collect();
        assert_eq!(distinct.len(), verts.len(), "LOD{lod:?}: a vertex twice");
        let mut used = Vec::new();
        for (_, g) in geometries(&doc) {
            indices(&g["boundaries"], &mut used);
        }
        let used: HashSet<usize> = used.into_iter().collect();
        assert_eq!(
            used.len(),
            verts.len(),
            "{lod:?}: unused or missing vertices"
        );
        assert!(used.iter().all(|&i| i < verts.len()));
        // Every model point of the exterior is a file vertex within 0.5 mm.
        let pts = points(&doc);
        let keys: HashSet<(i64, i64, i64)> = verts
            .iter()
            .map(|v| {
                let c = |i: usize| v[i].as_i64().unwrap();
                (c(0), c(1), c(2))
            })
            .collect();
        let mut n = 0;
        for b in &buildings {
            for p in &b.parts {
                let faces = std::iter::once(&p.ground)
                    .chain(p.walls.iter().map(|w| &w.outline))
                    .chain(&p.roof);
                for q in faces.flat_map(|f| f.outer.iter().chain(f.holes.iter().flatten())) {
                    assert!(keys.contains(&grid_key(*q)), "{lod:?}: {q} not written");
                    let back = ORIGIN
                        + DVec3::new(
                            grid_key(*q).0 as f64,
                            grid_key(*q).1 as f64,
                            grid_key(*q).2 as f64,
                        ) * 0.001;
                    assert!(back.distance(ORIGIN + *q) <= 0.0005 * 3f64.sqrt() + 1e-6);
                    n += 1;
                }
            }
        }
        assert!(n > 50);
        // And every file vertex, read back, is within 0.5 mm of some model point's grid.
        assert!(pts.iter().all(|p| p.is_finite()));
    }
}

#[test]
fn a_vertex_two_buildings_share_is_written_once() {
    let a = samples::house();
    let mut b = samples::house();
    b.id = crate::model::SourceId::Way(99);
    let one = parse(&write_file(Lod::Lod3, std::slice::from_ref(&a), true));
    let two = parse(&write_file(Lod::Lod3, &[a, b], true));
    assert_eq!(
        one["vertices"].as_array().unwrap().len(),
        two["vertices"].as_array().unwrap().len()
    );
    let buildings = |d: &Value| {
        d["CityObjects"]
            .as_object()
            .unwrap()
            .values()
            .filter(|o| o["type"] == "Building")
            .count()
    };
    assert_eq!(buildings(&two), 2);
}

/// (type of each surface of a geometry, by its semantic value).
fn surface_types(g: &Value) -> Vec<String> {
    let objs = g["semantics"]["surfaces"].as_array().unwrap();
    let mut v = Vec::new();
    indices(&g["semantics"]["values"], &mut v);
    v.iter()
        .map(|&i| objs[i]["type"].as_str().unwrap().to_string())
        .collect()
}

#[test]
fn semantics_count_every_wall_roof_ground_window_and_door() {
    for b in samples::all() {
        let doc = parse(&write_file(Lod::Lod3, std::slice::from_ref(&b), true));
        let mut count: BTreeMap<String, usize> = BTreeMap::new();
        for (_, g) in geometries(&doc) {
            if g["type"] == "Solid" {
                assert_eq!(g["lod"], "3");
                for t in surface_types(g) {
                    *count.entry(t).or_default() += 1;
                }
                // Every Window and Door names its wall as parent, which lists it as a child.
                let objs = g["semantics"]["surfaces"].as_array().unwrap();
                for (i, o) in objs.iter().enumerate() {
                    if o["type"] == "Window" || o["type"] == "Door" {
                        let p = o["parent"].as_u64().unwrap() as usize;
                        assert_eq!(objs[p]["type"], "WallSurface");
                        let kids = objs[p]["children"].as_array().unwrap();
                        assert!(kids.iter().any(|k| k.as_u64() == Some(i as u64)));
                    }
                }
            }
        }
        let (windows, doors) = samples::counts(&b);
        let walls: usize = b.parts.iter().map(|p| p.walls.len()).sum();
        let roofs: usize = b.parts.iter().map(|p| p.roof.len()).sum();
        let get = |k: &str| count.get(k).copied().unwrap_or(0);
        assert_eq!(get("Window"), windows, "{}", b.id);
        assert_eq!(get("Door"), doors, "{}", b.id);
        assert_eq!(get("WallSurface"), walls, "{}", b.id);
        assert_eq!(get("RoofSurface"), roofs, "{}", b.id);
        assert_eq!(get("GroundSurface"), b.parts.len(), "{}", b.id);
        let balconies: usize = b
            .parts
            .iter()
            .flat_map(|p| &p.walls)
            .map(|w| w.balconies.len())
            .sum();
        let installations = doc["CityObjects"]
            .as_object()
            .unwrap()
            .values()
            .filter(|o| o["type"] == "BuildingInstallation")
            .count();
        // A wall's window sills are one installation.
        let sills = b
            .parts
            .iter()
            .flat_map(|p| &p.walls)
            .filter(|w| !crate::export::lod3geom::sills(w).is_empty())
            .count();
        assert_eq!(installations, balconies + sills, "{}", b.id);
        // Balconies and sills carry a material on every face, as in CityGML and glTF.
        let materials = doc["appearance"]["materials"]
            .as_array()
            .map_or(0, Vec::len);
        for o in doc["CityObjects"].as_object().unwrap().values() {
            let function = o["attributes"]["function"].as_str().unwrap_or("");
            if o["type"] != "BuildingInstallation"
                || !["balcony", "window sills"].contains(&function)
            {
                continue;
            }
            for g in o["geometry"].as_array().unwrap() {
                let faces = g["boundaries"].as_array().unwrap().len();
                let values = g["material"]["citygen"]["values"].as_array();
                let values =
                    values.unwrap_or_else(|| panic!("{}: a {function} without material", b.id));
                assert_eq!(values.len(), faces, "{}: {function}", b.id);
                assert!(
                    values
                        .iter()
                        .all(|v| v.as_u64().is_some_and(|i| (i as usize) < materials)),
                    "{}: {function}: {values:?}",
                    b.id
                );
            }
        }
    }
    // LOD2: three semantic objects, one value per surface.
    let b = plain(vec![samples::house()], Lod::Lod2);
    let doc = parse(&write_file(Lod::Lod2, &b, true));
    let (_, g) = geometries(&doc)[0];
    assert_eq!(g["lod"], "2.2");
    let t = surface_types(g);
    let walls = b[0].parts[0].walls.len();
    assert!(walls >= 4);
    assert_eq!(t.iter().filter(|t| *t == "WallSurface").count(), walls);
    assert_eq!(t.iter().filter(|t| *t == "GroundSurface").count(), 1);
}

/// Newell normal of a ring of file points.
fn newell(ring: &[DVec3]) -> DVec3 {
    let mut n = DVec3::ZERO;
    for i in 0..ring.len() {
        let (a, b) = (ring[i], ring[(i + 1) % ring.len()]);
        n += DVec3::new(
            (a.y - b.y) * (a.z + b.z),
            (a.z - b.z) * (a.x + b.x),
            (a.x - b.x) * (a.y + b.y),
        );
    }
    n.normalize_or_zero()
}

#[test]
fn a_wall_ring_runs_counter_clockwise_round_its_outward_normal_and_its_holes_the_other_way() {
    let b = samples::house();
    let doc = parse(&write_file(Lod::Lod3, std::slice::from_ref(&b), true));
    let pts = points(&doc);
    let (_, g) = geometries(&doc)[0];
    let shell = g["boundaries"][0].as_array().unwrap();
    let types = surface_types(g);
    let part = &b.parts[0];
    let ring = |r: &Value| -> Vec<DVec3> {
        r.as_array()
            .unwrap()
            .iter()
            .map(|i| pts[i.as_u64().unwrap() as usize] - ORIGIN)
            .collect()
    };
    // The shell: ground, then the walls in the model's order.
    let mut checked = 0;
    for (k, wall) in part.walls.iter().enumerate() {
        let surface = &shell[1 + k];
        assert_eq!(types[1 + k], "WallSurface");
        let outward = (wall.end - wall.start).perp().extend(0.0) * -1.0;
        let n = newell(&ring(&surface[0]));
        assert!(
            n.dot(outward.normalize()) > 0.999,
            "wall {k}: {n} vs {outward}"
        );
        for hole in surface.as_array().unwrap().iter().skip(1) {
            assert!(newell(&ring(hole)).dot(outward.normalize()) < -0.999);
            checked += 1;
        }
    }
    assert_eq!(checked, samples::counts(&b).0 + samples::counts(&b).1);
    // Ground faces down, roof up.
    assert!(newell(&ring(&shell[0][0])).z < -0.999);
}

#[test]
fn parts_rooms_and_installations_are_linked_both_ways() {
    let mut buildings = renumbered(samples::all());
    buildings.extend(fixtures::lod4_all());
    let doc = parse(&write_file(Lod::Lod4, &buildings, true));
    let objs = doc["CityObjects"].as_object().unwrap();
    let mut kinds: BTreeMap<&str, usize> = BTreeMap::new();
    for (id, o) in objs {
        *kinds.entry(o["type"].as_str().unwrap()).or_default() += 1;
        for c in o["children"].as_array().into_iter().flatten() {
            let child = &objs[c.as_str().unwrap()];
            assert!(child["parents"][0] == *id, "{c} does not name {id}");
        }
        for p in o["parents"].as_array().into_iter().flatten() {
            let parent = &objs[p.as_str().unwrap()];
            let kids = parent["children"].as_array().unwrap();
            assert!(kids.iter().any(|k| k.as_str() == Some(id)));
        }
    }
    let rooms: usize = fixtures::lod4_all()
        .iter()
        .flat_map(|b| &b.parts)
        .flat_map(|p| &p.interior)
        .map(|s| s.rooms.len())
        .sum();
    assert_eq!(kinds["BuildingRoom"], rooms);
    assert!(kinds["BuildingPart"] >= 2);
    assert!(kinds["BuildingConstructiveElement"] > 0);
    // No lod "4": CityJSON 2.0 has none.
    for (_, g) in geometries(&doc) {
        assert!(g["lod"].as_str().unwrap().starts_with(['1', '2', '3']));
    }
}

#[test]
fn write_all_gives_the_bytes_of_one_write_per_building() {
    for lod in [Lod::Lod2, Lod::Lod3, Lod::Lod4] {
        let mut many = Vec::new();
        for i in 0..2 * crate::export::PARALLEL_BATCH + 3 {
            for mut b in samples_at(lod) {
                b.id = crate::model::SourceId::Way(1000 + i as i64 * 10 + many.len() as i64);
                many.push(b);
            }
        }
        let (one, all) = (write_file(lod, &many, false), write_file(lod, &many, true));
        assert!(one == all, "{lod:?}: CityJSON write_all differs");
        let (one, all) = (write_seq(lod, &many, false), write_seq(lod, &many, true));
        assert!(one == all, "{lod:?}: CityJSONSeq write_all differs");
    }
}

#[test]
fn seq_is_a_header_line_then_one_feature_per_building_with_its_own_vertices() {
    let buildings = samples_at(Lod::Lod3);
    let text = String::from_utf8(write_seq(Lod::Lod3, &buildings, true)).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    assert_eq!(lines.len(), 1 + buildings.len());
    let head = parse(lines[0].as_bytes());
    assert_eq!(head["type"], "CityJSON");
    assert!(head["CityObjects"].as_object().unwrap().is_empty());
    assert!(head["vertices"].as_array().unwrap().is_empty());
    let file = parse(&write_file(Lod::Lod3, &buildings, true));
    for (line, b) in lines[1..].iter().zip(&buildings) {
        let f = parse(line.as_bytes());
        assert_eq!(f["type"], "CityJSONFeature");
        let id = f["id"].as_str().unwrap();
        assert_eq!(id, format!("B_{}", b.key()));
        let n = f["vertices"].as_array().unwrap().len();
        let mut used = Vec::new();
        for o in f["CityObjects"].as_object().unwrap().values() {
            for g in o["geometry"].as_array().into_iter().flatten() {
                indices(&g["boundaries"], &mut used);
            }
        }
        let used: HashSet<usize> = used.into_iter().collect();
        assert_eq!(used.len(), n);
        // The same objects as in the file.
        for k in f["CityObjects"].as_object().unwrap().keys() {
            assert!(file["CityObjects"].get(k).is_some(), "{k}");
        }
    }
}

#[test]
fn a_non_finite_building_is_refused_and_nothing_of_it_is_written() {
    let mut bad = samples::house();
    bad.parts[0].walls[1].outline.outer[0].z = f64::NAN;
    let good = samples::gable();
    let mut w = CityJsonWriter::new(Vec::new());
    w.begin(&ctx(Lod::Lod3)).unwrap();
    let e = w.write_all(&[good.clone(), bad.clone()]).unwrap_err();
    assert!(e.to_string().contains("not finite"), "{e}");
    let mut s = CityJsonSeqWriter::new(Vec::new());
    s.begin(&ctx(Lod::Lod3)).unwrap();
    assert!(s.write_all(&[good, bad]).is_err());
    let text = String::from_utf8(s.into_inner()).unwrap();
    assert_eq!(text.lines().count(), 2, "header and the good building only");
}

/// Runs cjval (through `validate-outputs`) on LOD1-4 samples of both formats, when installed.
#[test]
fn validates_with_cjval() {
    let Some(validator) = crate::testkit::validators::validate_outputs("CityJSON LOD1-4 (cjval)")
    else {
        return;
    };
    let has_cjval = crate::testkit::validators::validate_home()
        .is_some_and(|h| h.join("cargo/bin/cjval").exists());
    if !has_cjval && !crate::testkit::validators::under_ci() {
        eprintln!("cjval is not built yet: skipped (validate-outputs builds it on first use)");
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let mut files = Vec::new();
    for lod in [Lod::Lod1, Lod::Lod2, Lod::Lod3, Lod::Lod4] {
        let mut buildings = samples_at(lod);
        if lod == Lod::Lod4 {
            buildings.extend(renumbered(samples::all()));
        }
        let n = lod.number();
        let path = dir.path().join(format!("lod{n}.city.json"));
        std::fs::write(&path, write_file(lod, &buildings, true)).unwrap();
        files.push(path);
        let path = dir.path().join(format!("lod{n}.city.jsonl"));
        std::fs::write(&path, write_seq(lod, &buildings, true)).unwrap();
        files.push(path);
    }
    let out = std::process::Command::new(validator)
        .args(&files)
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success() && text.contains("8 passed, 0 failed") && !text.contains("warning:"),
        "{text}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

/// Provenance is in the building's attributes, in the file and in the sequence: sources as
/// strings, uncertainties as numbers, an unknown uncertainty left out.
#[test]
fn provenance_is_written_in_the_buildings_attributes() {
    let mut buildings = samples_at(Lod::Lod2);
    buildings[0].provenance = fixtures::model_provenance();
    buildings[1].provenance = crate::model::Provenance {
        storeys: crate::model::ValueSource::Neighbours,
        ..Default::default()
    };
    let check = |objects: &Value| {
        let a = &objects[format!("B_{}", buildings[0].key())]["attributes"];
        assert_eq!(a["storeysSource"], "model");
        assert_eq!(a["heightSource"], "model");
        assert_eq!(a["roofSource"], "kb");
        assert_eq!(a["storeysError"].as_f64(), Some(0.75));
        assert_eq!(a["heightError"].as_f64(), Some(2.25));
        assert_eq!(a["roofProbability"].as_f64(), Some(0.8));
        let a = &objects[format!("B_{}", buildings[1].key())]["attributes"];
        assert_eq!(a["storeysSource"], "neighbours");
        assert_eq!(a["roofSource"], "kb");
        for k in ["storeysError", "heightError", "roofProbability"] {
            assert!(a.get(k).is_none(), "{k}");
        }
    };
    check(&parse(&write_file(Lod::Lod2, &buildings, true))["CityObjects"]);
    let text = String::from_utf8(write_seq(Lod::Lod2, &buildings, false)).unwrap();
    let mut objects = serde_json::Map::new();
    for line in text.lines().skip(1) {
        if let Some(o) = parse(line.as_bytes())["CityObjects"].as_object() {
            objects.extend(o.clone());
        }
    }
    check(&Value::Object(objects));
}

/// The colours of a solid's surfaces as its materials give them (`None` for `null`).
fn surface_colours(g: &Value, materials: &[Value]) -> Vec<Option<String>> {
    g["material"]["citygen"]["values"][0]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| {
            v.as_u64()
                .map(|i| materials[i as usize]["name"].as_str().unwrap().to_string())
        })
        .collect()
}

#[test]
fn colours_are_materials_per_surface_and_the_extent_bounds_every_vertex() {
    let hex = |c: crate::color::Color| {
        let q = |x: f32| (x * 255.0).round() as u8;
        format!("#{:02x}{:02x}{:02x}", q(c.r), q(c.g), q(c.b))
    };
    for lod in [Lod::Lod1, Lod::Lod2, Lod::Lod3] {
        let buildings = renumbered(samples_at(lod));
        let doc = parse(&write_file(lod, &buildings, true));
        let materials = doc["appearance"]["materials"].as_array().unwrap().clone();
        // One material per distinct colour.
        let names: HashSet<&str> = materials
            .iter()
            .map(|m| m["name"].as_str().unwrap())
            .collect();
        assert_eq!(names.len(), materials.len());
        let mut walls = 0;
        for b in &buildings {
            let id = render::building_id(b);
            let obj = &doc["CityObjects"][&id];
            let part = &b.parts[0];
            let g = if b.parts.len() == 1 {
                &obj["geometry"][0]
            } else {
                &doc["CityObjects"][obj["children"][0].as_str().unwrap()]["geometry"][0]
            };
            let colours = surface_colours(g, &materials);
            let n = g["boundaries"][0].as_array().unwrap().len();
            assert_eq!(colours.len(), n, "{id}: a value per surface");
            // Ground first (no material), then the walls in the part's colour.
            assert_eq!(colours[0], None);
            let wall = hex(part.wall_color);
            let wall_faces = part
                .walls
                .iter()
                .filter(|w| render::ring(&w.outline.outer).is_some());
            for (c, _) in colours[1..].iter().zip(wall_faces) {
                assert_eq!(
                    c.as_deref(),
                    Some(wall.as_str()),
                    "{id} at LOD{}",
                    lod.number()
                );
                walls += 1;
            }
            if lod == Lod::Lod3 {
                let glazed = part
                    .walls
                    .iter()
                    .flat_map(|w| &w.openings)
                    .any(|o| o.glazed);
                let clear = materials
                    .iter()
                    .any(|m| m["transparency"].as_f64() == Some(0.6));
                assert!(!glazed || clear, "{id}: glazed windows are transparent");
            }
        }
        assert!(walls > 0);
        // The extent holds every vertex (in the output CRS, to the millimetre).
        let e: Vec<f64> = doc["metadata"]["geographicalExtent"]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_f64().unwrap())
            .collect();
        let (s, t) = (&doc["transform"]["scale"], &doc["transform"]["translate"]);
        for v in doc["vertices"].as_array().unwrap() {
            for k in 0..3 {
                let c = t[k].as_f64().unwrap() + v[k].as_f64().unwrap() * s[k].as_f64().unwrap();
                assert!(
                    c >= e[k] - 1e-3 && c <= e[k + 3] + 1e-3,
                    "{c} outside {e:?}"
                );
            }
        }
    }
    // Each CityJSONSeq feature carries its own materials, indexed from 0.
    let buildings = renumbered(samples_at(Lod::Lod2));
    let seq = write_seq(Lod::Lod2, &buildings, true);
    for line in String::from_utf8(seq).unwrap().lines().skip(1) {
        let f: Value = serde_json::from_str(line).unwrap();
        let mats = f["appearance"]["materials"].as_array().unwrap();
        for o in f["CityObjects"].as_object().unwrap().values() {
            for g in o["geometry"].as_array().into_iter().flatten() {
                for v in g["material"]["citygen"]["values"][0].as_array().unwrap() {
                    assert!(v.is_null() || (v.as_u64().unwrap() as usize) < mats.len());
                }
            }
        }
    }
}
