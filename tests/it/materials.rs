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
    let Some(tool) = citygen::testkit::validators::validate_outputs("textured glTF and 3D Tiles")
    else {
        return;
    };
    let out = std::process::Command::new(tool)
        .arg(&one)
        .arg(tiles_one.join("tileset.json"))
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{text}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(text.contains("2 passed, 0 failed"), "{text}");
}
