use glam::{DVec2, DVec3};

use super::*;
use crate::color::srgb_to_linear;
use crate::export::lod3geom::{self, balcony_faces, samples};
use crate::export::lod4geom;
use crate::geometry::Polygon;
use crate::model::{Face, Lod, Part, PartRole, RoofShape, SourceId, Wall};
use serde_json::Value;

// ---- synthetic buildings ----

/// A wall on footprint edge start->end, its outer face CCW seen from outside.
fn wall(start: DVec2, end: DVec2, base: f64, top: f64) -> Wall {
    let outline = Face::new(vec![
        start.extend(base),
        end.extend(base),
        end.extend(top),
        start.extend(top),
    ]);
    Wall {
        start,
        end,
        base_z: base,
        top_z: top,
        thickness: 0.3,
        outline,
        storey: 0,
        openings: Vec::new(),
        balconies: Vec::new(),
        party: 0.0,
    }
}

/// A part extruded from `footprint` from `base` to `eave`, with the given roof faces (a flat
/// roof at `eave` when `roof` is empty).
fn part(
    key: &str,
    footprint: Polygon,
    base: f64,
    eave: f64,
    roof: Vec<Face>,
    wall_color: Color,
) -> Part {
    let mut walls = Vec::new();
    for ring in footprint.rings() {
        for i in 0..ring.len() {
            walls.push(wall(ring[i], ring[(i + 1) % ring.len()], base, eave));
        }
    }
    let lift = |r: &Vec<DVec2>, z: f64| r.iter().map(|p| p.extend(z)).collect::<Vec<_>>();
    let (roof, shape, top) = if roof.is_empty() {
        let flat = Face {
            outer: lift(&footprint.outer, eave),
            holes: footprint.holes.iter().map(|h| lift(h, eave)).collect(),
        };
        (vec![flat], RoofShape::Flat, eave)
    } else {
        let top = roof
            .iter()
            .flat_map(|f| f.outer.iter())
            .map(|p| p.z)
            .fold(eave, f64::max);
        (roof, RoofShape::Hipped, top)
    };
    let rev = |r: &Vec<DVec2>| {
        let mut v = lift(r, base);
        v.reverse();
        v
    };
    let ground = Face {
        outer: rev(&footprint.outer),
        holes: footprint.holes.iter().map(rev).collect(),
    };
    Part {
        key: key.into(),
        footprint,
        base_z: base,
        eave_z: eave,
        top_z: top,
        storeys: 2,
        levels: vec![base, (base + eave) / 2.0],
        wall_color,
        roof_color: Color::rgb(0.7, 0.2, 0.1),
        wall_material: Default::default(),
        roof_material: Default::default(),
        roof_shape: shape,
        walls,
        roof,
        ground,
        interior: Vec::new(),
        source: None,
        role: PartRole::Own,
        structure: None,
        rhythm: None,
        cornice: None,
        eaves: None,
    }
}

fn rect(x0: f64, y0: f64, x1: f64, y1: f64) -> Vec<DVec2> {
    vec![
        DVec2::new(x0, y0),
        DVec2::new(x1, y0),
        DVec2::new(x1, y1),
        DVec2::new(x0, y1),
    ]
}

fn building(id: i64, parts: Vec<Part>) -> Building {
    let base = parts.iter().map(|p| p.base_z).fold(f64::INFINITY, f64::min);
    let top = parts
        .iter()
        .map(|p| p.top_z)
        .fold(f64::NEG_INFINITY, f64::max);
    Building {
        id: SourceId::Way(id),
        name: Some(format!("Building {id}")),
        zone: "earth/France/Occitanie/Toulouse".into(),
        appearance: "Toulouse#1".into(),
        base_z: base,
        ground_z: base,
        measured_height: top - base,
        storeys_above_ground: 2,
        roof_shape: parts[0].roof_shape,
        parts,
        lod: Lod::Lod2,
        facade: Default::default(),
        provenance: Default::default(),
        attributes: None,
    }
}

/// 10 x 6 m box, 3 m high, flat roof.
fn box_building() -> Building {
    building(
        1,
        vec![part(
            "p0",
            Polygon::new(rect(0.0, 0.0, 10.0, 6.0), vec![]),
            0.0,
            3.0,
            vec![],
            Color::WHITE,
        )],
    )
}

/// 20 x 20 m block with an 8 x 8 m courtyard, 9 m high.
fn courtyard_building() -> Building {
    let fp = Polygon::new(
        rect(30.0, 0.0, 50.0, 20.0),
        vec![rect(36.0, 6.0, 44.0, 14.0)],
    );
    building(
        2,
        vec![part("p0", fp, 0.0, 9.0, vec![], Color::rgb(0.9, 0.8, 0.6))],
    )
}

/// Hip roof on a 10 x 6 m footprint at (x0, 0): eave 3 m, ridge 5 m from x0+3 to x0+7.
fn hip_roof(x0: f64) -> Vec<Face> {
    let p = |x: f64, y: f64, z: f64| DVec3::new(x0 + x, y, z);
    vec![
        Face::new(vec![
            p(0.0, 0.0, 3.0),
            p(10.0, 0.0, 3.0),
            p(7.0, 3.0, 5.0),
            p(3.0, 3.0, 5.0),
        ]),
        Face::new(vec![p(10.0, 0.0, 3.0), p(10.0, 6.0, 3.0), p(7.0, 3.0, 5.0)]),
        Face::new(vec![
            p(10.0, 6.0, 3.0),
            p(0.0, 6.0, 3.0),
            p(3.0, 3.0, 5.0),
            p(7.0, 3.0, 5.0),
        ]),
        Face::new(vec![p(0.0, 6.0, 3.0), p(0.0, 0.0, 3.0), p(3.0, 3.0, 5.0)]),
    ]
}

/// A flat 6 m part and a hip-roofed part in another wall colour, plus a degenerate roof face.
fn two_part_building() -> Building {
    let a = part(
        "p0",
        Polygon::new(rect(60.0, 0.0, 70.0, 6.0), vec![]),
        0.0,
        6.0,
        vec![],
        Color::WHITE,
    );
    let mut roof = hip_roof(70.0);
    roof.push(Face::new(vec![
        DVec3::new(70.0, 0.0, 3.0),
        DVec3::new(71.0, 0.0, 3.0),
    ]));
    let b = part(
        "p1",
        Polygon::new(rect(70.0, 0.0, 80.0, 6.0), vec![]),
        0.0,
        3.0,
        roof,
        Color::rgb(1.0, 1.0, 0.5),
    );
    building(3, vec![a, b])
}

/// A hip-roofed house whose glazing-like roof colour is translucent.
fn translucent_building() -> Building {
    let mut p = part(
        "p0",
        Polygon::new(rect(90.0, 0.0, 100.0, 6.0), vec![]),
        2.0,
        5.0,
        vec![],
        Color::WHITE,
    );
    p.roof = hip_roof(90.0)
        .into_iter()
        .map(|f| Face::new(f.outer.iter().map(|q| *q + DVec3::Z * 2.0).collect()))
        .collect();
    p.roof_color = Color {
        r: 0.5,
        g: 0.7,
        b: 0.9,
        a: 0.4,
    };
    building(4, vec![p])
}

fn all_buildings() -> Vec<Building> {
    vec![
        box_building(),
        courtyard_building(),
        two_part_building(),
        translucent_building(),
    ]
}

fn ctx() -> OutputContext {
    OutputContext {
        crs: Crs::Lambert93,
        origin: DVec3::new(574_000.25, 6_279_000.5, 140.0),
        origin_lonlat: (1.44, 43.6),
        lod: Lod::Lod2,
        source_name: "toulouse.osm.pbf".into(),
        seed: 7,
        vertical_datum: None,
        terrain: None,
    }
}

/// Writes `buildings` to a GLB in memory (without asking the CRS for its EPSG code, which
/// another module provides).
fn write_glb(buildings: &[Building]) -> Vec<u8> {
    write_glb_at(Lod::Lod2, buildings)
}

/// [`write_glb`] for a run at `lod`.
fn write_glb_at(lod: Lod, buildings: &[Building]) -> Vec<u8> {
    let mut out = Vec::new();
    let mut w = GltfWriter::new(&mut out, tempfile::tempfile().unwrap());
    w.start(&OutputContext { lod, ..ctx() }, "EPSG:2154".into())
        .unwrap();
    for b in buildings {
        w.write(b).unwrap();
    }
    w.finish().unwrap();
    out
}

// ---- a GLB reader for the checks ----

fn u32_at(b: &[u8], at: usize) -> u32 {
    u32::from_le_bytes(b[at..at + 4].try_into().unwrap())
}

fn f32_at(b: &[u8], at: usize) -> f32 {
    f32::from_le_bytes(b[at..at + 4].try_into().unwrap())
}

/// Checks the container and returns (JSON, BIN chunk data).
fn parse_glb(glb: &[u8]) -> (Value, &[u8]) {
    assert_eq!(&glb[0..4], b"glTF");
    assert_eq!(u32_at(glb, 4), 2);
    assert_eq!(u32_at(glb, 8) as usize, glb.len());
    assert_eq!(glb.len() % 4, 0);
    let json_len = u32_at(glb, 12) as usize;
    assert_eq!(json_len % 4, 0);
    assert_eq!(&glb[16..20], b"JSON");
    let json_bytes = &glb[20..20 + json_len];
    let json: Value = serde_json::from_slice(json_bytes).expect("JSON chunk parses");
    let rest = &glb[20 + json_len..];
    if rest.is_empty() {
        return (json, rest);
    }
    let bin_len = u32_at(rest, 0) as usize;
    assert_eq!(bin_len % 4, 0);
    assert_eq!(&rest[4..8], b"BIN\0");
    assert_eq!(rest.len(), 8 + bin_len);
    (json, &rest[8..])
}

/// Reads accessor `i` as f32 vec3s or as indices, after checking it lies in its view and the
/// view in the buffer.
fn accessor_data(json: &Value, bin: &[u8], i: u64) -> (Vec<[f32; 3]>, Vec<u32>) {
    let a = &json["accessors"][i as usize];
    let view = &json["bufferViews"][a["bufferView"].as_u64().unwrap() as usize];
    let buffer_len = json["buffers"][0]["byteLength"].as_u64().unwrap() as usize;
    assert!(buffer_len <= bin.len() && bin.len() - buffer_len < 4);
    let v_off = view["byteOffset"].as_u64().unwrap_or(0) as usize;
    let v_len = view["byteLength"].as_u64().unwrap() as usize;
    assert_eq!(v_off % 4, 0, "bufferView offsets are 4-aligned");
    assert!(v_off + v_len <= buffer_len, "bufferView inside the buffer");
    if view["target"] == ARRAY_BUFFER {
        assert_eq!(view["byteStride"], 12);
    } else {
        assert!(view.get("byteStride").is_none());
    }
    let a_off = a["byteOffset"].as_u64().unwrap_or(0) as usize;
    let count = a["count"].as_u64().unwrap() as usize;
    assert!(count > 0);
    let start = v_off + a_off;
    match (
        a["type"].as_str().unwrap(),
        a["componentType"].as_u64().unwrap() as u32,
    ) {
        ("VEC3", FLOAT) => {
            assert_eq!(start % 4, 0);
            assert!(a_off + count * 12 <= v_len);
            let v = (0..count)
                .map(|k| std::array::from_fn(|c| f32_at(bin, start + k * 12 + c * 4)))
                .collect();
            (v, Vec::new())
        }
        ("SCALAR", UNSIGNED_SHORT) => {
            assert_eq!(start % 2, 0);
            assert!(a_off + count * 2 <= v_len);
            let v = (0..count)
                .map(|k| u16::from_le_bytes([bin[start + 2 * k], bin[start + 2 * k + 1]]) as u32)
                .collect();
            (Vec::new(), v)
        }
        ("SCALAR", UNSIGNED_INT) => {
            assert_eq!(start % 4, 0);
            assert!(a_off + count * 4 <= v_len);
            (
                Vec::new(),
                (0..count).map(|k| u32_at(bin, start + 4 * k)).collect(),
            )
        }
        other => panic!("unexpected accessor {other:?}"),
    }
}

/// Every primitive of mesh `m`: checks min/max, normals, index range, and that every
/// triangle faces the way its normal does. Returns the total triangle area.
fn check_mesh(json: &Value, bin: &[u8], m: u64) -> f64 {
    let mut area = 0.0;
    for prim in json["meshes"][m as usize]["primitives"].as_array().unwrap() {
        let pos_i = prim["attributes"]["POSITION"].as_u64().unwrap();
        let (pos, _) = accessor_data(json, bin, pos_i);
        let (nrm, _) = accessor_data(json, bin, prim["attributes"]["NORMAL"].as_u64().unwrap());
        let (_, idx) = accessor_data(json, bin, prim["indices"].as_u64().unwrap());
        assert_eq!(pos.len(), nrm.len());
        let acc = &json["accessors"][pos_i as usize];
        for c in 0..3 {
            let lo = pos.iter().map(|p| p[c]).fold(f32::INFINITY, f32::min);
            let hi = pos.iter().map(|p| p[c]).fold(f32::NEG_INFINITY, f32::max);
            assert_eq!(acc["min"][c].as_f64().unwrap() as f32, lo);
            assert_eq!(acc["max"][c].as_f64().unwrap() as f32, hi);
        }
        assert!(nrm
            .iter()
            .all(|n| (DVec3::from(n.map(f64::from)).length() - 1.0).abs() < 1e-6));
        assert_eq!(idx.len() % 3, 0);
        assert!(
            idx.iter().all(|&i| (i as usize) < pos.len()),
            "indices in range"
        );
        for t in idx.chunks_exact(3) {
            let p = |k: usize| DVec3::from(pos[t[k] as usize].map(f64::from));
            let cross = (p(1) - p(0)).cross(p(2) - p(0));
            let n = DVec3::from(nrm[t[0] as usize].map(f64::from));
            assert!(
                cross.dot(n) > 0.0,
                "triangle winding agrees with its normal"
            );
            area += 0.5 * cross.length();
        }
        let mat = prim["material"].as_u64().unwrap() as usize;
        assert!(mat < json["materials"].as_array().unwrap().len());
    }
    area
}

/// The child mesh of building node `node` named `class`.
fn class_mesh(json: &Value, node: &Value, class: &str) -> Option<u64> {
    node["children"].as_array()?.iter().find_map(|c| {
        let child = &json["nodes"][c.as_u64().unwrap() as usize];
        (child["name"] == class).then(|| child["mesh"].as_u64().unwrap())
    })
}

// ---- tests ----

#[test]
fn a_binary_chunk_over_the_limit_fails_at_that_building_not_at_the_end() {
    let buildings = all_buildings();
    let mut out = Vec::new();
    let mut w = GltfWriter::new(&mut out, tempfile::tempfile().unwrap());
    w.max_bin = 1; // any building's vertex data is over it
    w.start(&OutputContext { ..ctx() }, "EPSG:2154".into())
        .unwrap();
    let e = w.write(&buildings[0]).unwrap_err().to_string();
    assert!(
        e.contains("over the GLB limit") && e.contains("--tile"),
        "{e}"
    );
    assert!(e.contains(&buildings[0].id.to_string()), "{e}");
    assert!(w.write(&buildings[1]).is_err() && w.finish().is_err());
    drop(w);
    assert!(out.is_empty(), "nothing is written to the target");
}

#[test]
fn glb_container_and_asset() {
    let glb = write_glb(&all_buildings());
    let (json, bin) = parse_glb(&glb);
    assert_eq!(json["asset"]["version"], "2.0");
    assert_eq!(
        json["asset"]["generator"],
        format!("citygen {}", env!("CARGO_PKG_VERSION"))
    );
    assert_eq!(json["asset"]["extras"]["crs"], "EPSG:2154");
    assert_eq!(
        json["asset"]["extras"]["origin"],
        serde_json::json!([574000.25, 6279000.5, 140.0])
    );
    assert_eq!(json["scene"], 0);
    assert_eq!(json["buffers"].as_array().unwrap().len(), 1);
    assert!(json["buffers"][0].get("uri").is_none());
    // Every accessor is readable and consistent.
    for i in 0..json["accessors"].as_array().unwrap().len() {
        accessor_data(&json, bin, i as u64);
    }
}

#[test]
fn one_node_per_building_with_extras() {
    let buildings = all_buildings();
    let glb = write_glb(&buildings);
    let (json, _) = parse_glb(&glb);
    let roots = json["scenes"][0]["nodes"].as_array().unwrap();
    assert_eq!(roots.len(), buildings.len());
    for (r, b) in roots.iter().zip(&buildings) {
        let node = &json["nodes"][r.as_u64().unwrap() as usize];
        assert_eq!(node["name"], b.key());
        let x = &node["extras"];
        assert_eq!(x["id"], b.id.to_string());
        assert_eq!(x["zone"], "earth/France/Occitanie/Toulouse");
        assert_eq!(x["appearance"], "Toulouse#1");
        assert_eq!(x["height"].as_f64().unwrap(), b.measured_height);
        assert_eq!(x["base"].as_f64().unwrap(), b.base_z);
        let names: Vec<&str> = node["children"]
            .as_array()
            .unwrap()
            .iter()
            .map(|c| {
                json["nodes"][c.as_u64().unwrap() as usize]["name"]
                    .as_str()
                    .unwrap()
            })
            .collect();
        assert_eq!(names, ["walls", "roof", "ground"]);
    }
}

#[test]
fn box_areas_and_coordinates() {
    let glb = write_glb(&[box_building()]);
    let (json, bin) = parse_glb(&glb);
    let node = &json["nodes"][0];
    let walls = check_mesh(&json, bin, class_mesh(&json, node, "walls").unwrap());
    let roof = check_mesh(&json, bin, class_mesh(&json, node, "roof").unwrap());
    let ground = check_mesh(&json, bin, class_mesh(&json, node, "ground").unwrap());
    assert!((walls - 96.0).abs() < 1e-4);
    assert!((roof - 60.0).abs() < 1e-4);
    assert!((ground - 60.0).abs() < 1e-4);
    // Y up, north = -Z: the box spans x 0..10, y 0..3, z -6..0.
    let roof_mesh = class_mesh(&json, node, "roof").unwrap() as usize;
    let pos = json["meshes"][roof_mesh]["primitives"][0]["attributes"]["POSITION"]
        .as_u64()
        .unwrap() as usize;
    assert_eq!(
        json["accessors"][pos]["min"],
        serde_json::json!([0.0, 3.0, -6.0])
    );
    assert_eq!(
        json["accessors"][pos]["max"],
        serde_json::json!([10.0, 3.0, 0.0])
    );
    // Roof normals point up (+Y) in glTF.
    let nrm = json["meshes"][roof_mesh]["primitives"][0]["attributes"]["NORMAL"]
        .as_u64()
        .unwrap();
    let (n, _) = accessor_data(&json, bin, nrm);
    assert!(n.iter().all(|n| *n == [0.0, 1.0, 0.0]));
    // Flat shading: 4 walls x 4 + 4 + 4 vertices.
    let count = |m: u64| {
        let a = json["meshes"][m as usize]["primitives"][0]["attributes"]["POSITION"]
            .as_u64()
            .unwrap();
        json["accessors"][a as usize]["count"].as_u64().unwrap()
    };
    assert_eq!(count(class_mesh(&json, node, "walls").unwrap()), 16);
}

#[test]
fn courtyard_hole_is_kept() {
    let glb = write_glb(&[courtyard_building()]);
    let (json, bin) = parse_glb(&glb);
    let node = &json["nodes"][0];
    let roof = check_mesh(&json, bin, class_mesh(&json, node, "roof").unwrap());
    let ground = check_mesh(&json, bin, class_mesh(&json, node, "ground").unwrap());
    let walls = check_mesh(&json, bin, class_mesh(&json, node, "walls").unwrap());
    assert!((roof - 336.0).abs() < 1e-3, "{roof}");
    assert!((ground - 336.0).abs() < 1e-3, "{ground}");
    assert!((walls - (80.0 + 32.0) * 9.0).abs() < 1e-3, "{walls}");
}

#[test]
fn two_parts_two_wall_materials_and_hip_roof() {
    let glb = write_glb(&[two_part_building()]);
    let (json, bin) = parse_glb(&glb);
    let node = &json["nodes"][0];
    let walls_mesh = class_mesh(&json, node, "walls").unwrap();
    assert_eq!(
        json["meshes"][walls_mesh as usize]["primitives"]
            .as_array()
            .unwrap()
            .len(),
        2
    );
    let walls = check_mesh(&json, bin, walls_mesh);
    // Less the shared wall at x = 70 up to the lower part's 3 m, on both sides: inside.
    assert!((walls - (32.0 * 6.0 + 32.0 * 3.0 - 2.0 * 6.0 * 3.0)).abs() < 1e-3);
    let roof = check_mesh(&json, bin, class_mesh(&json, node, "roof").unwrap());
    // Flat 60 m2 plus the hip roof (trapezoids 2 x 19.80, triangles 2 x 10.82).
    let s = (9.0f64 + 4.0).sqrt();
    let expected = 60.0 + 2.0 * (10.0 + 4.0) / 2.0 * s + 2.0 * 0.5 * 6.0 * (9.0f64 + 4.0).sqrt();
    assert!((roof - expected).abs() < 1e-3, "{roof} vs {expected}");
}

#[test]
fn materials_cached_linear_and_blended() {
    let glb = write_glb(&all_buildings());
    let (json, _) = parse_glb(&glb);
    let mats = json["materials"].as_array().unwrap();
    // walls white, roof, ground, courtyard walls, yellow walls, translucent roof.
    let names: Vec<&str> = mats.iter().map(|m| m["name"].as_str().unwrap()).collect();
    assert_eq!(
        names,
        [
            "walls #ffffff",
            "roof #b3331a",
            "ground #808080",
            "walls #e6cc99",
            "walls #ffff80",
            "roof #80b3e6 alpha 0.4"
        ]
    );
    for m in mats {
        let pbr = &m["pbrMetallicRoughness"];
        assert_eq!(pbr["metallicFactor"], 0.0);
        assert!((pbr["roughnessFactor"].as_f64().unwrap() - 0.9).abs() < 1e-6);
    }
    // sRGB 0.5 -> linear 0.2140.
    let grey = mats[2]["pbrMetallicRoughness"]["baseColorFactor"][0]
        .as_f64()
        .unwrap();
    assert!((grey - 0.2140).abs() < 1e-3, "{grey}");
    assert_eq!(mats[5]["alphaMode"], "BLEND");
    assert!(mats[0].get("alphaMode").is_none());
}

#[test]
#[ignore = "writes x.glb in the temporary folder for manual validation"]
fn dump_sample() {
    std::fs::write(
        std::env::temp_dir().join("x.glb"),
        write_glb(&all_buildings()),
    )
    .unwrap();
}

/// FNV-1a 64: a dependency-free fingerprint of an output.
fn fnv1a(bytes: &[u8]) -> u64 {
    bytes.iter().fold(0xcbf2_9ce4_8422_2325, |h, &b| {
        (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3)
    })
}

/// The GLB with the extras of a default provenance (every source `kb`, no uncertainty, which
/// every building has carried since issue 42) taken out of its JSON chunk.
fn without_kb_provenance(glb: &[u8]) -> Vec<u8> {
    let json_len = u32_at(glb, 12) as usize;
    let json = std::str::from_utf8(&glb[20..20 + json_len]).unwrap();
    let mut json = json
        .replace(
            r#","storeys_source":"kb","height_source":"kb","roof_source":"kb""#,
            "",
        )
        .trim_end()
        .to_string();
    while json.len() % 4 != 0 {
        json.push(' ');
    }
    let bin = &glb[20 + json_len..];
    let mut out = Vec::new();
    out.extend_from_slice(&glb[..8]);
    out.extend_from_slice(&((20 + json.len() + bin.len()) as u32).to_le_bytes());
    out.extend_from_slice(&(json.len() as u32).to_le_bytes());
    out.extend_from_slice(&glb[16..20]);
    out.extend_from_slice(json.as_bytes());
    out.extend_from_slice(bin);
    out
}

/// LOD2 output is byte-identical to the writer before LOD3 support (fingerprint taken from
/// that writer on the same samples, then once more when the walls between two parts of a
/// building were left out: only `two_part_building` changed, by its shared wall), but for the
/// provenance extras added since.
#[test]
fn lod2_output_unchanged_by_lod3_support() {
    assert_eq!(
        fnv1a(&without_kb_provenance(&write_glb(&all_buildings()))),
        6_307_124_370_317_660_226
    );
}

#[test]
fn deterministic() {
    assert_eq!(write_glb(&all_buildings()), write_glb(&all_buildings()));
}

#[test]
fn empty_and_degenerate_inputs() {
    let glb = write_glb(&[]);
    let (json, bin) = parse_glb(&glb);
    assert!(bin.is_empty());
    assert!(json.get("buffers").is_none() && json.get("nodes").is_none());
    // A building whose every face is degenerate still gets its node, without children.
    let mut b = box_building();
    for p in &mut b.parts {
        p.roof = vec![Face::new(vec![DVec3::ZERO, DVec3::X])];
        p.ground = Face::new(vec![DVec3::new(1.0, 0.0, 0.0); 3]);
        p.walls.clear();
    }
    let glb = write_glb(std::slice::from_ref(&b));
    let (json, _) = parse_glb(&glb);
    assert_eq!(json["nodes"].as_array().unwrap().len(), 1);
    assert!(json["nodes"][0].get("children").is_none());
    // A non-finite coordinate or height refuses the building (Building::check_finite).
    for bad in [f64::NAN, f64::INFINITY] {
        let mut nan = b.clone();
        nan.parts[0].ground = Face::new(vec![DVec3::new(bad, 0.0, 0.0); 3]);
        let mut w = GltfWriter::new(Vec::new(), tempfile::tempfile().unwrap());
        w.start(&ctx(), "EPSG:2154".into()).unwrap();
        let err = w.write(&nan).unwrap_err().to_string();
        assert!(
            err.contains("glTF writer") && err.contains("not finite"),
            "{err}"
        );
        nan.parts[0].ground = b.parts[0].ground.clone();
        nan.measured_height = bad;
        assert!(w.write(&nan).is_err());
        w.write(&b).unwrap();
        w.finish().unwrap();
        let (json, _) = parse_glb(&w.into_inner());
        assert_eq!(
            json["nodes"].as_array().unwrap().len(),
            1,
            "only the good building"
        );
    }
}

#[test]
fn scratch_beside_target_is_removed() {
    let dir = tempfile::tempdir().unwrap();
    let target = dir.path().join("out.glb");
    let file = File::create(&target).unwrap();
    let mut w = GltfWriter::beside(file, &target).unwrap();
    w.start(&ctx(), "EPSG:2154".into()).unwrap();
    w.write(&box_building()).unwrap();
    w.finish().unwrap();
    drop(w);
    let names: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(names, ["out.glb"]);
    let glb = std::fs::read(&target).unwrap();
    let (json, bin) = parse_glb(&glb);
    check_mesh(&json, bin, 0);
}

#[test]
fn call_order_is_enforced() {
    let mut out = Vec::new();
    let mut w = GltfWriter::new(&mut out, tempfile::tempfile().unwrap());
    assert!(w.write(&box_building()).is_err());
    assert!(w.finish().is_err());
    w.start(&ctx(), "EPSG:2154".into()).unwrap();
    assert!(w.start(&ctx(), "EPSG:2154".into()).is_err());
    w.finish().unwrap();
    assert!(w.finish().is_err());
    assert!(w.write(&box_building()).is_err());
}

#[test]
fn large_primitive_uses_u32_indices() {
    // 17 000 small wall quads: 68 000 vertices in one primitive, more than u16 can index.
    let mut b = box_building();
    b.parts[0].walls = (0..17_000)
        .map(|k| {
            let x = k as f64 * 0.01;
            wall(DVec2::new(x, 0.0), DVec2::new(x + 0.01, 0.0), 0.0, 3.0)
        })
        .collect();
    let glb = write_glb(&[b]);
    let (json, bin) = parse_glb(&glb);
    let walls = class_mesh(&json, &json["nodes"][0], "walls").unwrap();
    let idx = json["meshes"][walls as usize]["primitives"][0]["indices"]
        .as_u64()
        .unwrap();
    assert_eq!(
        json["accessors"][idx as usize]["componentType"],
        UNSIGNED_INT
    );
    check_mesh(&json, bin, walls);
}

/// Runs the Khronos glTF validator through the shared script when it is installed.
#[test]
fn khronos_validator_accepts_output() {
    let Some(tool) = crate::testkit::validators::validate_outputs("glTF LOD1-3 (Khronos)") else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("citygen-test.glb");
    std::fs::write(&path, write_glb(&all_buildings())).unwrap();
    let path3 = dir.path().join("citygen-test-lod3.glb");
    std::fs::write(&path3, write_glb_at(Lod::Lod3, &samples::all())).unwrap();
    let out = std::process::Command::new(tool)
        .arg(&path)
        .arg(&path3)
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "validator failed:\n{text}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(text.contains("2 passed, 0 failed"), "{text}");
    assert_eq!(text.matches("warnings=0").count(), 2, "{text}");
}

// ---- LOD4 ----

#[test]
fn lod4_interior_nodes_and_areas() {
    let house = crate::export::fixtures::lod4_house();
    let glb = write_glb_at(Lod::Lod4, std::slice::from_ref(&house));
    let (json, bin) = parse_glb(&glb);
    let root = &json["nodes"][json["scenes"][0]["nodes"][0].as_u64().unwrap() as usize];
    assert_eq!(
        child_names(&json, root),
        [
            "walls",
            "roof",
            "ground",
            "windows",
            "doors",
            "floors",
            "interior walls",
            "interior doors",
            "stairs",
            "slabs"
        ]
    );
    let area = |class: &str| check_mesh(&json, bin, class_mesh(&json, root, class).unwrap());
    // Floors: the usable area on each storey.
    let usable = 11.4 * 7.4;
    assert!(
        (area("floors") - 2.0 * usable).abs() < 1e-3,
        "{}",
        area("floors")
    );
    // Door leaves: two faces per door, 4 doors of 0.9 m x (2.1 - sill).
    let leaf = 0.9 * (2.1 - lod4geom::DOOR_SILL);
    assert!((area("interior doors") - 8.0 * leaf).abs() < 1e-3);
    // Interior walls: both long faces minus the door holes dominate; at least that much.
    let walls = 2.0 * 2.8 * (3.7 + 3.7 + 7.4) * 2.0 - 2.0 * 4.0 * leaf;
    assert!(area("interior walls") > walls);
    // Slabs: only the upper storey has one: its underside is the rooms minus the well.
    let well = 1.0 * 4.5;
    assert!(area("slabs") > usable - well);
    assert!(area("stairs") > 0.0);
    // Below LOD4 a model without interiors writes none of these nodes.
    let glb = write_glb_at(Lod::Lod3, &samples::all());
    let (json, _) = parse_glb(&glb);
    for r in json["scenes"][0]["nodes"].as_array().unwrap() {
        let node = &json["nodes"][r.as_u64().unwrap() as usize];
        assert!(!child_names(&json, node).iter().any(|n| n == "floors"));
    }
}

#[test]
fn lod4_validates_with_khronos() {
    let Some(tool) = crate::export::fixtures::validator("glTF LOD4 (Khronos)") else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("lod4.glb");
    let bytes = write_glb_at(Lod::Lod4, &crate::export::fixtures::lod4_all());
    if let Some(keep) = std::env::var_os("CITYGEN_GLB_LOD4_SAMPLE") {
        std::fs::write(keep, &bytes).unwrap();
    }
    std::fs::write(&path, bytes).unwrap();
    let out = std::process::Command::new(tool)
        .arg(&path)
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success() && text.contains(" 0 failed"), "{text}");
    assert!(text.contains("warnings=0"), "{text}");
}

// ---- LOD3 ----

fn child_names(json: &Value, node: &Value) -> Vec<String> {
    node["children"]
        .as_array()
        .map(|c| {
            c.iter()
                .map(|i| json["nodes"][i.as_u64().unwrap() as usize]["name"].to_string())
                .map(|n| n.trim_matches('"').to_string())
                .collect()
        })
        .unwrap_or_default()
}

/// Positions of the primitives of mesh `m` whose material satisfies `pred`.
fn positions_where(
    json: &Value,
    bin: &[u8],
    m: u64,
    pred: impl Fn(&Value) -> bool,
) -> Vec<[f32; 3]> {
    json["meshes"][m as usize]["primitives"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|p| pred(&json["materials"][p["material"].as_u64().unwrap() as usize]))
        .flat_map(|p| accessor_data(json, bin, p["attributes"]["POSITION"].as_u64().unwrap()).0)
        .collect()
}

#[test]
fn lod3_nodes_per_class() {
    let buildings = samples::all();
    let glb = write_glb_at(Lod::Lod3, &buildings);
    let (json, _) = parse_glb(&glb);
    let roots: Vec<&Value> = json["scenes"][0]["nodes"]
        .as_array()
        .unwrap()
        .iter()
        .map(|r| &json["nodes"][r.as_u64().unwrap() as usize])
        .collect();
    let names = |i: usize| child_names(&json, roots[i]);
    assert_eq!(names(0), ["walls", "roof", "ground", "windows", "doors"]);
    assert_eq!(names(1), ["walls", "roof", "ground", "windows"]);
    assert_eq!(
        names(2),
        ["walls", "roof", "ground", "windows", "doors", "balconies"]
    );
    assert_eq!(names(3), ["walls", "roof", "ground", "windows"]);
    assert_eq!(roots[0]["extras"]["lod"], 3);
    // Below LOD3 the details are not written (the model has none there anyway).
    let glb = write_glb_at(Lod::Lod2, &buildings);
    let (json, _) = parse_glb(&glb);
    let first = &json["nodes"][json["scenes"][0]["nodes"][0].as_u64().unwrap() as usize];
    assert_eq!(child_names(&json, first), ["walls", "roof", "ground"]);
}

#[test]
fn lod3_wall_area_is_wall_minus_openings() {
    for b in samples::all() {
        let glb = write_glb_at(Lod::Lod3, std::slice::from_ref(&b));
        let (json, bin) = parse_glb(&glb);
        let node = &json["nodes"][0];
        let walls = check_mesh(&json, bin, class_mesh(&json, node, "walls").unwrap());
        // Less the walls between the two parts of way/303 (x = 70, 6 m wide, up to the
        // annex's 3 m, on both sides): inside the building, not drawn.
        let between = if b.id == SourceId::Way(303) {
            36.0
        } else {
            0.0
        };
        let expected = samples::net_wall_area(&b) - between;
        assert!(
            (walls - expected).abs() < 1e-3,
            "{}: {walls} vs {expected}",
            b.id
        );
        // Panes (or frame and pane: w*h, less nothing) and reveals (2(w+h)*0.1) per opening,
        // the frame's inner band, and the sills less their faces against the wall.
        let area = |f: &Face| {
            let a = |r: &[DVec3]| crate::geometry::newell_normal(r).length() / 2.0;
            a(&f.outer) - f.holes.iter().map(|h| a(h)).sum::<f64>()
        };
        let mut expected_openings = 0.0;
        for w in b.parts.iter().flat_map(|p| &p.walls) {
            for o in &w.openings {
                expected_openings += 2.0 * (o.width() + o.height()) * 0.1;
                match lod3geom::opening_frame(w, o, 0.1) {
                    Some(f) => {
                        expected_openings += area(&f.pane) + f.frame.iter().map(area).sum::<f64>()
                    }
                    None => expected_openings += o.width() * o.height(),
                }
            }
            for s in lod3geom::sills(w) {
                let faces = lod3geom::sill_faces(w, &s).unwrap();
                expected_openings += faces.iter().skip(1).map(area).sum::<f64>();
            }
        }
        let mut got = 0.0;
        for class in ["windows", "doors"] {
            if let Some(m) = class_mesh(&json, node, class) {
                got += check_mesh(&json, bin, m);
            }
        }
        assert!(
            (got - expected_openings).abs() < 1e-3,
            "{got} vs {expected_openings}"
        );
        for class in ["roof", "ground", "balconies"] {
            if let Some(m) = class_mesh(&json, node, class) {
                check_mesh(&json, bin, m);
            }
        }
    }
}

#[test]
fn lod3_panes_are_recessed_and_glass_is_opaque() {
    let glb = write_glb_at(Lod::Lod3, &[samples::house()]);
    let (json, bin) = parse_glb(&glb);
    let node = &json["nodes"][0];
    let windows = class_mesh(&json, node, "windows").unwrap();
    let doors = class_mesh(&json, node, "doors").unwrap();
    let is_glass = |m: &Value| m["name"].as_str().unwrap().ends_with(" glass");
    // The front wall is y = 0, the inside +y: glTF z = -y, so panes sit at z = -0.1.
    let glass = positions_where(&json, bin, windows, is_glass);
    assert_eq!(glass.len(), 4 * 4);
    assert!(glass.iter().all(|p| (p[2] + 0.1).abs() < 1e-6), "{glass:?}");
    let door_pane = positions_where(&json, bin, doors, |m| {
        m["name"].as_str().unwrap().starts_with("doors #66401a")
    });
    assert_eq!(door_pane.len(), 4);
    assert!(door_pane.iter().all(|p| (p[2] + 0.1).abs() < 1e-6));
    let mats = json["materials"].as_array().unwrap();
    // A hollow LOD3 shell: nothing is see-through, nothing double-sided.
    for m in mats {
        let name = m["name"].as_str().unwrap();
        assert!(m.get("alphaMode").is_none(), "{name}");
        assert!(m.get("doubleSided").is_none(), "{name}");
        assert_eq!(
            m["pbrMetallicRoughness"]["baseColorFactor"][3], 1.0,
            "{name}"
        );
    }
    // Glass: the window colour darkened, smooth and a little metallic.
    let glass_mat = mats.iter().find(|m| is_glass(m)).unwrap();
    assert_eq!(glass_mat["name"], "windows #8cb3cc glass");
    let pbr = &glass_mat["pbrMetallicRoughness"];
    let rgb: Vec<f64> = (0..3)
        .map(|k| pbr["baseColorFactor"][k].as_f64().unwrap())
        .collect();
    let glass = samples::GLASS;
    for (got, c) in rgb.iter().zip([glass.r, glass.g, glass.b]) {
        assert!((got - f64::from(srgb_to_linear(c * GLASS_SHADE))).abs() < 1e-6);
    }
    assert!((pbr["roughnessFactor"].as_f64().unwrap() - 0.1).abs() < 1e-6);
    assert!((pbr["metallicFactor"].as_f64().unwrap() - 0.2).abs() < 1e-6);
    // Doors opaque in their colour, matte.
    let door = mats
        .iter()
        .find(|m| m["name"] == "doors #66401a")
        .expect("door material");
    let r = door["pbrMetallicRoughness"]["baseColorFactor"][0]
        .as_f64()
        .unwrap();
    assert!((r - f64::from(srgb_to_linear(0.4))).abs() < 1e-6);
    assert_eq!(door["pbrMetallicRoughness"]["metallicFactor"], 0.0);
}

#[test]
fn lod4_glass_stays_transparent() {
    // A part with rooms keeps see-through glass, in the window colour.
    let house = crate::export::fixtures::lod4_house();
    let glb = write_glb_at(Lod::Lod4, std::slice::from_ref(&house));
    let (json, _) = parse_glb(&glb);
    let mats = json["materials"].as_array().unwrap();
    let glass: Vec<&Value> = mats
        .iter()
        .filter(|m| m["name"].as_str().unwrap().ends_with(" glass"))
        .collect();
    assert_eq!(glass.len(), 1);
    assert_eq!(glass[0]["name"], "windows #8cb3cc alpha 0.35 glass");
    assert_eq!(glass[0]["alphaMode"], "BLEND");
    let c = &glass[0]["pbrMetallicRoughness"]["baseColorFactor"];
    assert!((c[3].as_f64().unwrap() - 0.35).abs() < 1e-6);
    let r = c[0].as_f64().unwrap();
    assert!((r - f64::from(srgb_to_linear(samples::GLASS.r))).abs() < 1e-6);
    // The same house without its rooms is a hollow shell: its glass is opaque.
    let mut hollow = house.clone();
    hollow.parts.iter_mut().for_each(|p| p.interior.clear());
    let glb = write_glb_at(Lod::Lod4, std::slice::from_ref(&hollow));
    let (json, _) = parse_glb(&glb);
    for m in json["materials"].as_array().unwrap() {
        assert!(m.get("alphaMode").is_none(), "{}", m["name"]);
    }
}

#[test]
fn lod3_balcony_slab_and_railing() {
    let b = samples::with_balcony();
    let glb = write_glb_at(Lod::Lod3, std::slice::from_ref(&b));
    let (json, bin) = parse_glb(&glb);
    let m = class_mesh(&json, &json["nodes"][0], "balconies").unwrap();
    let area = check_mesh(&json, bin, m);
    // The model's faces less those in the wall's plane (the slab's back, the handrail's and
    // the infill's ends), which would fight the wall.
    let wall = &b.parts[0].walls[4];
    let faces = balcony_faces(wall, &wall.balconies[0]).unwrap();
    let expected: f64 = faces
        .all()
        .filter(|f| !faces.against_wall(f))
        .map(|f| crate::geometry::newell_normal(&f.outer).length() / 2.0)
        .sum();
    let against: f64 = faces
        .all()
        .filter(|f| faces.against_wall(f))
        .map(|f| crate::geometry::newell_normal(&f.outer).length() / 2.0)
        .sum();
    // Slab back 4 x 0.2, handrail ends 2 x 0.06 x 0.05, infill ends 2 x 0.015 x 0.8.
    assert!((against - (0.8 + 0.006 + 0.024)).abs() < 1e-9, "{against}");
    assert!((area - expected).abs() < 1e-3, "{area} vs {expected}");
    // Three materials: the slab in the balcony colour, the dark railing, the tinted infill.
    let prims = json["meshes"][m as usize]["primitives"].as_array().unwrap();
    let names: Vec<&str> = prims
        .iter()
        .map(|p| {
            json["materials"][p["material"].as_u64().unwrap() as usize]["name"]
                .as_str()
                .unwrap()
        })
        .collect();
    assert_eq!(
        names,
        [
            "balconies #999999",
            "balconies #33363b",
            "balconies #8ca6a6 alpha 0.5"
        ]
    );
    let infill = &json["materials"][prims[2]["material"].as_u64().unwrap() as usize];
    assert_eq!(infill["alphaMode"], "BLEND");
    // Out in front of the wall (y from 0 to -1.2 is glTF z 0 to 1.2), up to the handrail.
    let pos = positions_where(&json, bin, m, |_| true);
    let max_z = pos.iter().map(|p| p[2]).fold(f32::NEG_INFINITY, f32::max);
    assert!((max_z - 1.2).abs() < 1e-5, "{max_z}");
    let max_y = pos.iter().map(|p| p[1]).fold(f32::NEG_INFINITY, f32::max);
    assert!((max_y - 4.0).abs() < 1e-5, "{max_y}");
    // No material is double-sided: every face is the outside of a body.
    for mat in json["materials"].as_array().unwrap() {
        assert!(mat.get("doubleSided").is_none());
    }
}

#[test]
fn lod3_deterministic() {
    let b = samples::all();
    assert_eq!(write_glb_at(Lod::Lod3, &b), write_glb_at(Lod::Lod3, &b));
}

#[test]
#[ignore = "writes c3.glb in the temporary folder for manual validation"]
fn dump_lod3_sample() {
    std::fs::write(
        std::env::temp_dir().join("c3.glb"),
        write_glb_at(Lod::Lod3, &samples::all()),
    )
    .unwrap();
}

/// Provenance is in the building node's extras, an unknown uncertainty left out.
#[test]
fn provenance_is_in_the_building_extras() {
    let mut buildings = vec![box_building(), courtyard_building()];
    buildings[0].provenance = crate::export::fixtures::model_provenance();
    let (json, _) = parse_glb(&write_glb(&buildings));
    let roots = json["scenes"][0]["nodes"].as_array().unwrap();
    let extras = |i: usize| &json["nodes"][roots[i].as_u64().unwrap() as usize]["extras"];
    let x = extras(0);
    assert_eq!(x["storeys_source"], "model");
    assert_eq!(x["storeys_error"].as_f64(), Some(0.75));
    assert_eq!(x["height_source"], "model");
    assert_eq!(x["height_error"].as_f64(), Some(2.25));
    assert_eq!(x["roof_source"], "kb");
    assert_eq!(x["roof_probability"].as_f64(), Some(0.8));
    let x = extras(1);
    assert_eq!(x["storeys_source"], "kb");
    assert!(x.get("storeys_error").is_none() && x.get("roof_probability").is_none());
}

// ---- textures (issue 49, `--textures`) ----

/// [`write_glb_at`] with `--textures`.
fn write_glb_textured(lod: Lod, buildings: &[Building]) -> Vec<u8> {
    let mut out = Vec::new();
    let mut w = GltfWriter::new(&mut out, tempfile::tempfile().unwrap()).with_textures(true);
    w.start(&OutputContext { lod, ..ctx() }, "EPSG:2154".into())
        .unwrap();
    for b in buildings {
        w.write(b).unwrap();
    }
    w.finish().unwrap();
    out
}

/// The 10 x 6 m box of brick walls and slate roof, two storeys of 1.5 m, bays of 3 m with
/// 1.2 m windows.
fn textured_box() -> Building {
    let mut b = box_building();
    for p in &mut b.parts {
        p.wall_material = Material::Brick;
        p.roof_material = Material::Slate;
        p.rhythm = Some(crate::model::Rhythm {
            bay: 3.0,
            window: 1.2,
            sill: 0.25,
            height: 0.6,
        });
    }
    b
}

/// Every (position, uv) of the primitives of `class` in the first building.
fn class_uvs(json: &Value, bin: &[u8], class: &str) -> Vec<([f32; 3], [f32; 2])> {
    let node = &json["nodes"][0];
    let m = class_mesh(json, node, class).expect("the class is drawn");
    let mut out = Vec::new();
    for prim in json["meshes"][m as usize]["primitives"].as_array().unwrap() {
        let (pos, _) = accessor_data(json, bin, prim["attributes"]["POSITION"].as_u64().unwrap());
        let t = &json["accessors"][prim["attributes"]["TEXCOORD_0"].as_u64().unwrap() as usize];
        assert_eq!(
            (t["type"].as_str(), t["count"].as_u64()),
            (Some("VEC2"), Some(pos.len() as u64))
        );
        let view = &json["bufferViews"][t["bufferView"].as_u64().unwrap() as usize];
        assert_eq!(view["byteStride"], 8);
        let at = (view["byteOffset"].as_u64().unwrap_or(0) + t["byteOffset"].as_u64().unwrap_or(0))
            as usize;
        for (k, p) in pos.iter().enumerate() {
            out.push((*p, [f32_at(bin, at + 8 * k), f32_at(bin, at + 8 * k + 4)]));
        }
    }
    out
}

/// The box's walls (start, end, bays at 3 m) in ring order.
const BOX_WALLS: [([f64; 2], [f64; 2], f64); 4] = [
    ([0.0, 0.0], [10.0, 0.0], 3.0),
    ([10.0, 0.0], [10.0, 6.0], 2.0),
    ([10.0, 6.0], [0.0, 6.0], 3.0),
    ([0.0, 6.0], [0.0, 0.0], 2.0),
];

/// The distances along each box wall through glTF point `p` (x east, z south) from its start.
fn along_box(p: [f32; 3]) -> Vec<f64> {
    let q = DVec2::new(p[0] as f64, -p[2] as f64);
    BOX_WALLS
        .iter()
        .filter_map(|(a, b, _)| {
            let (a, b) = (DVec2::from(*a), DVec2::from(*b));
            let t = (q - a).dot(b - a) / (b - a).length_squared();
            ((a + (b - a) * t).distance(q) < 1e-4 && (-1e-6..=1.0 + 1e-6).contains(&t))
                .then(|| t * a.distance(b))
        })
        .collect()
}

/// The (length, bays) of each box wall through `p`, in [`along_box`]'s order.
fn box_lengths(p: [f32; 3]) -> Vec<(f64, f64)> {
    let q = DVec2::new(p[0] as f64, -p[2] as f64);
    BOX_WALLS
        .iter()
        .filter_map(|(a, b, n)| {
            let (a, b) = (DVec2::from(*a), DVec2::from(*b));
            let t = (q - a).dot(b - a) / (b - a).length_squared();
            ((a + (b - a) * t).distance(q) < 1e-4 && (-1e-6..=1.0 + 1e-6).contains(&t))
                .then(|| (a.distance(b), *n))
        })
        .collect()
}

#[test]
fn textures_are_off_by_default_and_shared_when_on() {
    let plain = write_glb(&[textured_box()]);
    let (json, _) = parse_glb(&plain);
    assert!(json.get("textures").is_none() && json.get("images").is_none());
    assert!(!String::from_utf8_lossy(&plain).contains("TEXCOORD_0"));

    // Three buildings: one picture per kind of surface, not one per building.
    let three = [textured_box(), textured_box(), textured_box()];
    let glb = write_glb_textured(Lod::Lod2, &three);
    assert_eq!(glb, write_glb_textured(Lod::Lod2, &three), "deterministic");
    let (json, bin) = parse_glb(&glb);
    let names: Vec<&str> = json["images"]
        .as_array()
        .unwrap()
        .iter()
        .map(|i| i["name"].as_str().unwrap())
        .collect();
    assert_eq!(names, ["bay brick w40 s25 h60", "slate"]);
    assert_eq!(json["textures"].as_array().unwrap().len(), 2);
    assert_eq!(json["samplers"][0]["wrapS"], 10497);
    assert_eq!(json["samplers"][0]["wrapT"], 10497);
    for i in json["images"].as_array().unwrap() {
        assert_eq!(i["mimeType"], "image/png");
        let v = &json["bufferViews"][i["bufferView"].as_u64().unwrap() as usize];
        let at = v["byteOffset"].as_u64().unwrap() as usize;
        assert_eq!(&bin[at..at + 8], &crate::export::png::SIGNATURE);
    }
    // The colour still comes from the surface: the texture multiplies the white wall.
    let walls = json["materials"]
        .as_array()
        .unwrap()
        .iter()
        .find(|m| m["name"].as_str().unwrap().starts_with("walls"))
        .unwrap();
    assert_eq!(walls["pbrMetallicRoughness"]["baseColorFactor"][0], 1.0);
    assert_eq!(
        walls["pbrMetallicRoughness"]["baseColorTexture"]["index"],
        0
    );
}

#[test]
fn texture_coordinates_are_in_metres_and_bays() {
    // LOD1: the brick's picture covers 1 m by 0.6 m: u counts metres along a wall, v up it.
    let glb = write_glb_textured(Lod::Lod1, &[textured_box()]);
    let (json, bin) = parse_glb(&glb);
    for (p, [u, v]) in class_uvs(&json, bin, "walls") {
        assert!(
            along_box(p).iter().any(|a| (u as f64 - a).abs() < 1e-5),
            "{p:?} {u}"
        );
        assert!((v + p[1] / 0.6).abs() < 1e-5, "{p:?} {v}");
    }
    // Roof: slate's picture is 1.2 m by 1 m; the flat roof is mapped east and north.
    for (p, [u, v]) in class_uvs(&json, bin, "roof") {
        assert!(
            (u - p[0] / 1.2).abs() < 1e-5 && (v - p[2]).abs() < 1e-5,
            "{p:?} {u} {v}"
        );
    }
    // LOD2: a bay picture a bay wide, as many bays as the grammar's repeat fits (10 m / 3 m
    // -> 3 bays, 6 m / 3 m -> 2) and a storey (1.5 m) high.
    let glb = write_glb_textured(Lod::Lod2, &[textured_box()]);
    let (json, bin) = parse_glb(&glb);
    let uvs = class_uvs(&json, bin, "walls");
    let max_u = uvs.iter().map(|(_, uv)| uv[0]).fold(0.0f32, f32::max);
    assert!((max_u - 3.0).abs() < 1e-5, "{max_u}");
    for (p, [u, v]) in uvs {
        // Bays: metres along times the bays over the wall's length (3 / 10 m, 2 / 6 m).
        let bays = along_box(p)
            .iter()
            .zip(box_lengths(p))
            .any(|(a, (len, n))| (u as f64 - a * n / len).abs() < 1e-5);
        assert!(bays, "{p:?} {u}");
        assert!((v + p[1] / 1.5).abs() < 1e-5, "{p:?} {v}");
    }
}

#[test]
fn a_gable_above_the_eaves_has_no_windows() {
    // A gabled wall: the piece above the eaves gets the plain pattern, below it the bays.
    let mut b = textured_box();
    let p = &mut b.parts[0];
    let w = &mut p.walls[1];
    w.outline.outer.insert(3, DVec3::new(10.0, 3.0, 5.0));
    let (below, above) = super::mesh::split_at(&w.outline, 3.0);
    let (below, above) = (below.unwrap(), above.unwrap());
    assert!(below.outer.iter().all(|q| q.z <= 3.0 + 1e-9), "{below:?}");
    assert!(above.outer.iter().all(|q| q.z >= 3.0 - 1e-9), "{above:?}");
    assert_eq!(above.outer.len(), 3);
    let (whole, none) = super::mesh::split_at(&p.walls[0].outline, 3.0);
    assert!(whole.is_some() && none.is_none());
}

#[test]
fn khronos_validator_accepts_textured_output() {
    let Some(tool) = crate::testkit::validators::validate_outputs("glTF LOD1-3 (Khronos)") else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let mut buildings = all_buildings();
    buildings.push(textured_box());
    let mut paths = Vec::new();
    for lod in [Lod::Lod1, Lod::Lod2, Lod::Lod3] {
        let path = dir
            .path()
            .join(format!("citygen-textured-lod{}.glb", lod.number()));
        let sample = if lod == Lod::Lod3 {
            samples::all()
        } else {
            buildings.clone()
        };
        std::fs::write(&path, write_glb_textured(lod, &sample)).unwrap();
        paths.push(path);
    }
    let out = std::process::Command::new(tool)
        .args(&paths)
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "validator failed:\n{text}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(text.contains("3 passed, 0 failed"), "{text}");
    assert_eq!(text.matches("warnings=0").count(), 3, "{text}");
}
