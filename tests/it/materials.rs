//! Surface materials (issue 49 item 1) through the real binary: a building tagged
//! `building:material=brick` and `roof:material=slate` is written at LOD3 to glTF, CityGML,
//! CityJSON and IFC, and each file, read back, gives its walls brick and its roof slate with the
//! one table's parameters (`citygen::color::material`), and glazed windows glass.
//! `--textures` (items 2-3): the house at LOD2 carries its brick bay and slate pictures, the same
//! bytes at any thread count, validator-clean.

use std::path::Path;

use citygen::color::material::Material;

use crate::common::{citygen, glb_json, step_entities, KB};

/// One gabled house with tagged materials, a street in front (so the facade rules place
/// windows and a door), in Toulouse.
const OSM: &str = r#"<?xml version="1.0" encoding="UTF-8"?>
<osm version="0.6">
  <node id="1" lat="43.60000" lon="1.44000"/>
  <node id="2" lat="43.60000" lon="1.44020"/>
  <node id="3" lat="43.60012" lon="1.44020"/>
  <node id="4" lat="43.60012" lon="1.44000"/>
  <node id="5" lat="43.59995" lon="1.43980"/>
  <node id="6" lat="43.59995" lon="1.44040"/>
  <way id="10">
    <nd ref="1"/><nd ref="2"/><nd ref="3"/><nd ref="4"/><nd ref="1"/>
    <tag k="building" v="house"/>
    <tag k="building:levels" v="3"/>
    <tag k="building:material" v="brick"/>
    <tag k="roof:material" v="slate"/>
    <tag k="roof:shape" v="gabled"/>
  </way>
  <way id="20">
    <nd ref="5"/><nd ref="6"/>
    <tag k="highway" v="residential"/>
  </way>
</osm>
"#;

/// `#rrggbb` of a material's usual colour.
fn hex(m: Material) -> String {
    let c = m.color();
    let b = |v: f32| (v * 255.0).round() as u8;
    format!("#{:02x}{:02x}{:02x}", b(c.r), b(c.g), b(c.b))
}

fn run(dir: &Path) -> [std::path::PathBuf; 4] {
    let input = dir.join("house.osm");
    std::fs::write(&input, OSM).unwrap();
    let p = |n: &str| dir.join(n);
    let files = [p("out.glb"), p("out.gml"), p("out.city.json"), p("out.ifc")];
    let s = |f: &std::path::PathBuf| f.display().to_string();
    let out = citygen(&[
        "--osm",
        &s(&input),
        "--kb",
        KB,
        "--lod",
        "3",
        "--gltf",
        &s(&files[0]),
        "--citygml",
        &s(&files[1]),
        "--cityjson",
        &s(&files[2]),
        "--ifc",
        &s(&files[3]),
        "--quiet",
    ]);
    assert!(
        out.status.success(),
        "citygen failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    files
}

#[test]
fn brick_walls_and_slate_roof_in_every_format() {
    let dir = tempfile::tempdir().unwrap();
    let [glb, gml, cj, ifc] = run(dir.path());
    let (brick, slate, glass) = (Material::Brick, Material::Slate, Material::Glass);
    let close = |a: f64, b: f32| (a - f64::from(b)).abs() < 1e-4;

    // glTF: the walls' and roof's materials by name, with the table's factors.
    let (json, _) = glb_json(&glb);
    let mats = json["materials"].as_array().unwrap();
    let by_name = |name: &str| {
        mats.iter()
            .find(|m| m["name"] == name)
            .unwrap_or_else(|| panic!("no glTF material {name} in {mats:?}"))
    };
    for (name, m) in [
        (format!("walls {} brick", hex(brick)), brick),
        (format!("roof {} slate", hex(slate)), slate),
    ] {
        let pbr = &by_name(&name)["pbrMetallicRoughness"];
        assert!(
            close(pbr["roughnessFactor"].as_f64().unwrap(), m.roughness()),
            "{name}"
        );
        assert!(
            close(pbr["metallicFactor"].as_f64().unwrap(), m.metallic()),
            "{name}"
        );
    }
    let panes: Vec<_> = mats
        .iter()
        .filter(|m| {
            m["name"].as_str().unwrap().starts_with("windows")
                && m["name"].as_str().unwrap().ends_with(" glass")
        })
        .collect();
    assert!(!panes.is_empty(), "glazed windows are glass: {mats:?}");
    for p in panes {
        let pbr = &p["pbrMetallicRoughness"];
        assert!(close(
            pbr["roughnessFactor"].as_f64().unwrap(),
            glass.roughness()
        ));
    }

    // CityGML: an X3DMaterial of brick's colour and shininess targeting the walls, one of
    // slate's targeting the roof.
    let text = std::fs::read_to_string(&gml).unwrap();
    let x3d: Vec<&str> = text
        .split("<app:X3DMaterial ")
        .skip(1)
        .map(|s| &s[..s.find("</app:X3DMaterial>").unwrap()])
        .collect();
    let shininess = |m: Material| format!("<app:shininess>{:.4}</app:shininess>", m.shininess());
    let of = |m: Material| {
        x3d.iter()
            .filter(|x| x.contains(&shininess(m)))
            .copied()
            .collect::<Vec<&str>>()
    };
    let walls = of(brick);
    assert_eq!(walls.len(), 1, "one brick X3DMaterial: {x3d:?}");
    assert!(walls[0].contains("<app:diffuseColor>0.6275 0.3216 0.1765</app:diffuseColor>"));
    assert!(
        walls[0].contains("_wall_") || walls[0].contains("_w"),
        "{}",
        walls[0]
    );
    let roofs = of(slate);
    assert_eq!(roofs.len(), 1, "one slate X3DMaterial: {x3d:?}");
    assert!(roofs[0].contains("<app:diffuseColor>0.2902 0.3216 0.3490</app:diffuseColor>"));
    let glazed = of(glass);
    assert!(!glazed.is_empty() && glazed.iter().all(|x| x.contains("<app:transparency>")));
    // Every material of a known kind has its shininess; the rest none.
    let known = x3d.iter().filter(|x| x.contains("<app:shininess>")).count();
    assert_eq!(known, walls.len() + roofs.len() + glazed.len());

    // CityJSON: the materials named after colour and material, with the shininess, and the
    // surfaces of the walls and the roof pointing at them.
    let doc: serde_json::Value = serde_json::from_slice(&std::fs::read(&cj).unwrap()).unwrap();
    let cmats = doc["appearance"]["materials"].as_array().unwrap();
    let index = |name: String, m: Material| {
        let i = cmats
            .iter()
            .position(|x| x["name"] == name.as_str())
            .unwrap_or_else(|| panic!("no CityJSON material {name}: {cmats:?}"));
        assert!(close(
            cmats[i]["shininess"].as_f64().unwrap(),
            m.shininess()
        ));
        i as u64
    };
    let (wi, ri) = (
        index(format!("{} brick", hex(brick)), brick),
        index(format!("{} slate", hex(slate)), slate),
    );
    let mut seen = (false, false);
    for obj in doc["CityObjects"].as_object().unwrap().values() {
        for g in obj["geometry"].as_array().into_iter().flatten() {
            let (Some(sem), Some(mat)) = (
                g["semantics"].as_object(),
                g["material"]["citygen"]["values"][0].as_array(),
            ) else {
                continue;
            };
            let values = sem["values"][0].as_array().unwrap();
            for (v, m) in values.iter().zip(mat) {
                let kind = &sem["surfaces"][v.as_u64().unwrap() as usize]["type"];
                if kind == "WallSurface" {
                    assert_eq!(m.as_u64(), Some(wi));
                    seen.0 = true;
                } else if kind == "RoofSurface" {
                    assert_eq!(m.as_u64(), Some(ri));
                    seen.1 = true;
                }
            }
        }
    }
    assert_eq!(seen, (true, true), "walls and roof carry their materials");

    // IFC: the walls' and roof's styles are renderings with the material's roughness and
    // reflectance method, named after colour and material.
    let ents = step_entities(&ifc);
    let style = |name: String, m: Material| {
        let (_, (_, args)) = ents
            .iter()
            .find(|(_, (t, a))| t == "IFCSURFACESTYLE" && a.starts_with(&format!("'{name}'")))
            .unwrap_or_else(|| panic!("no IfcSurfaceStyle {name}"));
        let r: u64 = args[args.rfind('#').unwrap() + 1..args.rfind(')').unwrap()]
            .parse()
            .unwrap();
        let (t, a) = &ents[&r];
        assert_eq!(t, "IFCSURFACESTYLERENDERING", "{name}");
        let want = format!("IFCSPECULARROUGHNESS({})", m.specular_roughness());
        assert!(a.contains(&want), "{name}: {a}");
        assert!(a.ends_with(m.reflectance_method().ifc()), "{name}: {a}");
    };
    style(format!("{} brick", hex(brick)), brick);
    style(format!("{} slate", hex(slate)), slate);
    let glass_style = ents
        .values()
        .any(|(t, a)| t == "IFCSURFACESTYLE" && a.contains(" glass'"));
    assert!(glass_style, "glazed panes styled as glass");
}

/// `--textures` (issue 49 items 2-3) through the binary on the house: the LOD2 GLB and 3D
/// Tiles carry the brick bay picture and the slate one, the same bytes at 1 and 2 threads; a
/// run without the flag has no picture; the files pass the reference validators.
#[test]
fn textures_through_the_binary_deterministic_and_valid() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("house.osm");
    std::fs::write(&input, OSM).unwrap();
    let s = |f: &Path| f.display().to_string();
    let write = |name: &str, extra: &[&str]| {
        let glb = dir.path().join(format!("{name}.glb"));
        let tiles = dir.path().join(format!("{name}-tiles"));
        let (g, t) = (s(&glb), s(&tiles));
        let mut args = vec!["--osm", &s(&input), "--kb", KB, "--lod", "2", "--quiet"]
            .into_iter()
            .map(String::from)
            .collect::<Vec<_>>();
        args.extend(["--gltf", &g, "--tiles3d", &t].map(String::from));
        args.extend(extra.iter().map(|a| a.to_string()));
        let refs: Vec<&str> = args.iter().map(String::as_str).collect();
        let out = citygen(&refs);
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        (glb, tiles)
    };
    let (plain, _) = write("plain", &[]);
    let (one, tiles_one) = write("one", &["--textures", "--threads", "1"]);
    let (two, tiles_two) = write("two", &["--textures", "--threads", "2"]);
    assert!(glb_json(&plain).0.get("images").is_none());
    assert_eq!(std::fs::read(&one).unwrap(), std::fs::read(&two).unwrap());
    let content = |d: &Path| std::fs::read(d.join("content/all.glb")).unwrap();
    assert_eq!(content(&tiles_one), content(&tiles_two));
    let (json, _) = glb_json(&one);
    let names: Vec<&str> = json["images"]
        .as_array()
        .unwrap()
        .iter()
        .map(|i| i["name"].as_str().unwrap())
        .collect();
    assert!(
        names.iter().any(|n| n.starts_with("bay brick")),
        "{names:?}"
    );
    assert!(names.contains(&"slate"), "{names:?}");
    validate(
        "textured glTF and 3D Tiles",
        &[one, tiles_one.join("tileset.json")],
    );
}

/// The reference validators pass on every file (when they are installed).
fn validate(what: &str, files: &[std::path::PathBuf]) {
    let Some(tool) = citygen::testkit::validators::validate_outputs(what) else {
        return;
    };
    let out = std::process::Command::new(tool)
        .args(files)
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{text}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let all = format!("{} passed, 0 failed", files.len());
    assert!(text.contains(&all), "{text}");
}

/// The text between `start` (after it) and the next `end`, from `at`: (text, where it ends).
fn between<'a>(s: &'a str, at: usize, start: &str, end: &str) -> Option<(&'a str, usize)> {
    let a = s[at..].find(start)? + at + start.len();
    let b = s[a..].find(end)? + a;
    Some((&s[a..b], b))
}

/// A picture URI of a file: relative, inside `out_textures/`, naming a PNG that was written.
fn check_uri(dir: &Path, uri: &str) {
    assert!(uri.starts_with("out_textures/"), "{uri}");
    assert!(!uri.contains("..") && !uri.starts_with('/'), "{uri}");
    let png = std::fs::read(dir.join(uri)).unwrap_or_else(|e| panic!("{uri}: {e}"));
    assert_eq!(&png[1..4], b"PNG", "{uri}");
}

/// Every textured CityJSON solid of `objects`: per ring, its picture's index and one texture
/// vertex per ring vertex, every index in range. Returns the rings textured.
fn check_cityjson_textures(objects: &serde_json::Value, textures: usize, sts: usize) -> usize {
    let mut rings = 0;
    for (id, o) in objects.as_object().unwrap() {
        for g in o["geometry"].as_array().into_iter().flatten() {
            let Some(values) = g.pointer("/texture/citygen/values") else {
                continue;
            };
            let shells = g["boundaries"].as_array().unwrap();
            for (shell, tshell) in shells.iter().zip(values.as_array().unwrap()) {
                let (shell, tshell) = (shell.as_array().unwrap(), tshell.as_array().unwrap());
                assert_eq!(shell.len(), tshell.len(), "{id}");
                for (surface, tsurface) in shell.iter().zip(tshell) {
                    let tsurface = tsurface.as_array().unwrap();
                    if tsurface[0][0].is_null() {
                        continue;
                    }
                    let surface = surface.as_array().unwrap();
                    assert_eq!(surface.len(), tsurface.len(), "{id}: one list a ring");
                    for (ring, tring) in surface.iter().zip(tsurface) {
                        let (ring, tring) = (ring.as_array().unwrap(), tring.as_array().unwrap());
                        assert_eq!(tring.len(), ring.len() + 1, "{id}: a vertex, a coordinate");
                        assert!(tring[0].as_u64().unwrap() < textures as u64, "{id}");
                        assert!(tring[1..].iter().all(|i| i.as_u64().unwrap() < sts as u64));
                        rings += 1;
                    }
                }
            }
        }
    }
    rings
}

/// `--textures` in CityGML, CityJSON and CityJSONSeq (issue 49): the house at LOD2 and LOD3
/// (holes: one texture coordinate list per ring) writes its pictures into `out_textures/`
/// beside the outputs, every URI relative and resolving there; each CityGML ring a texture
/// names exists with as many coordinates as points, each CityJSON ring as many texture
/// vertices as vertices; the same bytes at 1 and 2 threads; the bay picture at LOD2; the
/// files pass the reference validators.
#[test]
fn textures_in_citygml_and_cityjson() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("house.osm");
    std::fs::write(&input, OSM).unwrap();
    let s = |f: &Path| f.display().to_string();
    let write = |name: &str, lod: &str, threads: &str| {
        let d = dir.path().join(name);
        std::fs::create_dir_all(&d).unwrap();
        let [g, j, l] = ["out.gml", "out.city.json", "out.city.jsonl"].map(|f| s(&d.join(f)));
        let out = citygen(&[
            "--osm",
            &s(&input),
            "--kb",
            KB,
            "--lod",
            lod,
            "--quiet",
            "--textures",
            "--threads",
            threads,
            "--citygml",
            &g,
            "--cityjson",
            &j,
            "--cityjsonseq",
            &l,
        ]);
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        d
    };
    for lod in ["2", "3"] {
        let one = write(&format!("one{lod}"), lod, "1");
        let two = write(&format!("two{lod}"), lod, "2");
        let files = crate::common::files_under(&one, |_| true);
        assert!(
            files.keys().any(|f| f.starts_with("out_textures/")),
            "{:?}",
            files.keys()
        );
        assert!(
            files == crate::common::files_under(&two, |_| true),
            "the same bytes"
        );
        // CityGML: each texture's rings have ids and as many coordinates as points.
        let gml = std::fs::read_to_string(one.join("out.gml")).unwrap();
        let mut at = 0;
        let mut uris = Vec::new();
        while let Some((uri, end)) = between(&gml, at, "<app:imageURI>", "</app:imageURI>") {
            uris.push(uri.to_string());
            at = end;
        }
        assert!(!uris.is_empty());
        uris.iter().for_each(|u| check_uri(&one, u));
        if lod == "2" {
            assert!(uris.iter().any(|u| u.contains("bay_brick")), "{uris:?}");
        }
        let (mut at, mut rings) = (0, 0);
        while let Some((ring, end)) = between(&gml, at, "<app:textureCoordinates ring=\"#", "\"") {
            let (coords, end) = between(&gml, end, ">", "<").unwrap();
            let n = coords.split_whitespace().count();
            let tag = format!("<gml:LinearRing gml:id=\"{ring}\"><gml:posList srsDimension=\"3\">");
            let (pos, _) = between(&gml, 0, &tag, "<").unwrap_or_else(|| panic!("{ring}"));
            assert_eq!(n / 2, pos.split_whitespace().count() / 3, "{ring}");
            assert_eq!(n % 2, 0);
            rings += 1;
            at = end;
        }
        assert!(rings > 4, "{rings}");
        if lod == "3" {
            assert!(gml.contains("_h0\">"), "a textured hole at LOD3");
        }
        // CityJSON: textures, texture vertices and per-ring values.
        let cj: serde_json::Value =
            serde_json::from_slice(&std::fs::read(one.join("out.city.json")).unwrap()).unwrap();
        let app = &cj["appearance"];
        let textures = app["textures"].as_array().unwrap();
        for t in textures {
            assert_eq!(t["type"], "PNG");
            check_uri(&one, t["image"].as_str().unwrap());
        }
        let sts = app["vertices-texture"].as_array().unwrap().len();
        assert!(check_cityjson_textures(&cj["CityObjects"], textures.len(), sts) > 4);
        // CityJSONSeq: each feature its own appearance.
        let seq = std::fs::read_to_string(one.join("out.city.jsonl")).unwrap();
        let mut features = 0;
        for line in seq.lines().skip(1) {
            let f: serde_json::Value = serde_json::from_str(line).unwrap();
            let Some(app) = f.get("appearance").filter(|a| a.get("textures").is_some()) else {
                continue;
            };
            let textures = app["textures"].as_array().unwrap();
            textures
                .iter()
                .for_each(|t| check_uri(&one, t["image"].as_str().unwrap()));
            let sts = app["vertices-texture"].as_array().unwrap().len();
            assert!(check_cityjson_textures(&f["CityObjects"], textures.len(), sts) > 4);
            features += 1;
        }
        assert_eq!(features, 1);
        let files = ["out.gml", "out.city.json", "out.city.jsonl"].map(|f| one.join(f));
        validate("textured CityGML and CityJSON", &files);
    }
}

/// `--textures` in a sharded tiled run (issue 49): the tile's pictures are in its manifest's
/// files, and `citygen merge --cityjsonseq` into another folder names them by a relative path
/// that resolves from the region's file.
#[test]
fn textures_in_a_sharded_run_and_its_merge() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("house.osm");
    std::fs::write(&input, OSM).unwrap();
    let s = |f: &Path| f.display().to_string();
    let out = dir.path().join("out");
    let seq = s(&out.join("h.city.jsonl"));
    let run = citygen(&[
        "--osm",
        &s(&input),
        "--kb",
        KB,
        "--lod",
        "2",
        "--quiet",
        "--textures",
        "--tile",
        "100",
        "--shard",
        "0/1",
        "--cityjsonseq",
        &seq,
    ]);
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let manifest = std::fs::read_to_string(out.join("citygen-manifest.0-of-1.json")).unwrap();
    assert!(manifest.contains("_textures/bay_brick"), "{manifest}");
    let region = dir.path().join("region/all.city.jsonl");
    let merged = citygen(&["merge", &s(&out), "--cityjsonseq", &s(&region), "--quiet"]);
    assert!(
        merged.status.success(),
        "{}",
        String::from_utf8_lossy(&merged.stderr)
    );
    let text = std::fs::read_to_string(&region).unwrap();
    let mut n = 0;
    for line in text.lines().skip(1) {
        let f: serde_json::Value = serde_json::from_str(line).unwrap();
        for t in f["appearance"]["textures"].as_array().into_iter().flatten() {
            let uri = t["image"].as_str().unwrap();
            assert!(uri.starts_with("../out/") && !uri.starts_with('/'), "{uri}");
            let png = std::fs::read(region.parent().unwrap().join(uri)).unwrap();
            assert_eq!(&png[1..4], b"PNG");
            n += 1;
        }
    }
    assert!(n >= 2, "{n}");
}
