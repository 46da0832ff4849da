//! Every writer with a terrain in its context (issue 44): the terrain is there and reads
//! back; without one, nothing of it is written.

use std::sync::Arc;

use glam::{DVec2, DVec3};
use serde_json::Value;

use super::citygml::CityGmlWriter;
use super::cityjson::{CityJsonSeqWriter, CityJsonWriter};
use super::gltf::GltfWriter;
use super::ifc::IfcWriter;
use super::tiles3d::{Detail, Tiles3dWriter};
use super::{fixtures, BuildingWriter, OutputContext};
use crate::crs::Crs;
use crate::geometry::tin::{Heights, Rect, Rtin};
use crate::model::{Building, Lod, Terrain};

/// A hill TIN around the fixtures' buildings (local frame, 2 m samples from (-60, -60)).
fn terrain() -> Terrain {
    let n = 80;
    let z: Vec<f32> = (0..n * n)
        .map(|k| {
            let (x, y) = ((k % n) as f64 * 2.0 - 60.0, (k / n) as f64 * 2.0 - 60.0);
            (12.0 * (-(x * x + y * y) / 3000.0).exp() + 0.05 * x) as f32
        })
        .collect();
    let h = Heights {
        origin: DVec2::splat(-60.0),
        step: 2.0,
        nx: n,
        ny: n,
        z: &z,
        shift: (0, 0),
    };
    let r = Rect {
        min: DVec2::splat(-60.0),
        max: DVec2::splat(98.0),
    };
    let tin = Rtin::new(h).mesh(0.2, r);
    Terrain {
        vertices: tin.vertices,
        triangles: tin.triangles,
        tolerance: 0.2,
    }
}

fn ctx(terrain: Option<Arc<Terrain>>) -> OutputContext {
    OutputContext {
        crs: Crs::Utm {
            zone: 32,
            north: true,
        },
        origin: DVec3::new(355_000.0, 4_840_000.0, 0.0),
        origin_lonlat: (7.2, 43.7),
        lod: Lod::Lod2,
        source_name: "terrain.osm.pbf".into(),
        seed: 1,
        vertical_datum: None,
        terrain,
    }
}

fn buildings() -> Vec<Building> {
    fixtures::lod4_all()
        .into_iter()
        .take(2)
        .map(|mut b| {
            b.lod = Lod::Lod2;
            b
        })
        .collect()
}

/// What `w` writes of the buildings with and without the terrain.
fn both<W: BuildingWriter>(make: impl Fn() -> W, done: impl Fn(W) -> Vec<u8>) -> [Vec<u8>; 2] {
    [Some(Arc::new(terrain())), None].map(|t| {
        let mut w = make();
        w.begin(&ctx(t)).unwrap();
        w.write_all(&buildings()).unwrap();
        w.finish().unwrap();
        done(w)
    })
}

#[test]
fn cityjson_has_a_tin_relief_with_one_surface_a_triangle() {
    let t = terrain();
    assert!(t.triangles.len() > 50);
    let [with, without] = both(|| CityJsonWriter::new(Vec::new()), |w| w.into_inner());
    let doc: Value = serde_json::from_slice(&with).unwrap();
    let objects = doc["CityObjects"].as_object().unwrap();
    let reliefs: Vec<&Value> = objects
        .values()
        .filter(|o| o["type"] == "TINRelief")
        .collect();
    assert_eq!(reliefs.len(), 1);
    let g = &reliefs[0]["geometry"][0];
    assert_eq!(g["type"], "CompositeSurface");
    let surfaces = g["boundaries"].as_array().unwrap();
    assert_eq!(surfaces.len(), t.triangles.len());
    let n = doc["vertices"].as_array().unwrap().len() as u64;
    for s in surfaces {
        let ring = s[0].as_array().unwrap();
        assert_eq!(ring.len(), 3);
        assert!(ring.iter().all(|i| i.as_u64().unwrap() < n));
    }
    let plain: Value = serde_json::from_slice(&without).unwrap();
    assert!(plain["CityObjects"]
        .as_object()
        .unwrap()
        .values()
        .all(|o| o["type"] != "TINRelief"));

    let [with, without] = both(|| CityJsonSeqWriter::new(Vec::new()), |w| w.into_inner());
    let lines: Vec<&[u8]> = with
        .split(|b| *b == b'\n')
        .filter(|l| !l.is_empty())
        .collect();
    let last: Value = serde_json::from_slice(lines[lines.len() - 1]).unwrap();
    assert_eq!(last["type"], "CityJSONFeature");
    let id = last["id"].as_str().unwrap();
    assert!(id.starts_with("TIN_354940_4839940"), "{id}");
    assert_eq!(last["CityObjects"][id]["type"], "TINRelief");
    assert!(!String::from_utf8_lossy(&without).contains("TINRelief"));
}

#[test]
fn citygml_has_a_relief_feature_in_the_relief_namespace() {
    let t = terrain();
    let [with, without] = both(|| CityGmlWriter::new(Vec::new()), |w| w.into_inner());
    let text = String::from_utf8(with).unwrap();
    assert!(text.contains("xmlns:dem=\"http://www.opengis.net/citygml/relief/2.0\""));
    assert!(text.contains("relief/2.0/relief.xsd\">"));
    assert_eq!(text.matches("<dem:ReliefFeature ").count(), 1);
    assert_eq!(text.matches("<gml:Triangle>").count(), t.triangles.len());
    assert!(text.trim_end().ends_with("</core:CityModel>"));
    // Every ring closed: four points.
    let first = text.split("<gml:Triangle>").nth(1).unwrap();
    let pos = first.split("<gml:posList>").nth(1).unwrap();
    let pos = pos.split('<').next().unwrap();
    assert_eq!(pos.split_whitespace().count(), 12);
    let plain = String::from_utf8(without).unwrap();
    assert!(!plain.contains("dem:") && !plain.contains("relief"));
}

#[test]
fn ifc_has_a_terrain_geographic_element_in_the_site() {
    let t = terrain();
    let [with, without] = both(|| IfcWriter::new(Vec::new()), |w| w.into_inner().unwrap());
    let text = String::from_utf8(with).unwrap();
    let count = |k: &str| text.matches(&format!("={k}(")).count();
    assert_eq!(count("IFCGEOGRAPHICELEMENT"), 1);
    assert_eq!(count("IFCTRIANGULATEDFACESET"), 1);
    assert_eq!(count("IFCCARTESIANPOINTLIST3D"), 1);
    assert!(text.contains(".TERRAIN.);"));
    let list = text.split("=IFCCARTESIANPOINTLIST3D((").nth(1).unwrap();
    let list = list.split(";").next().unwrap();
    assert_eq!(list.matches("),(").count() + 1, t.vertices.len());
    let plain = String::from_utf8(without).unwrap();
    assert!(!plain.contains("IFCGEOGRAPHICELEMENT"));
}

/// The JSON chunk of a GLB.
fn glb_json(glb: &[u8]) -> Value {
    let len = u32::from_le_bytes(glb[12..16].try_into().unwrap()) as usize;
    serde_json::from_slice(&glb[20..20 + len]).unwrap()
}

#[test]
fn gltf_has_a_terrain_node_with_its_mesh_and_material() {
    let t = terrain();
    let [with, without] = both(
        || GltfWriter::new(Vec::new(), tempfile::tempfile().unwrap()),
        |w| w.into_inner(),
    );
    let doc = glb_json(&with);
    let nodes = doc["nodes"].as_array().unwrap();
    let roots = doc["scenes"][0]["nodes"].as_array().unwrap();
    let last = roots.last().unwrap().as_u64().unwrap() as usize;
    assert_eq!(nodes[last]["name"], "terrain");
    let mesh = &doc["meshes"][nodes[last]["mesh"].as_u64().unwrap() as usize];
    let prim = &mesh["primitives"][0];
    let pos = &doc["accessors"][prim["attributes"]["POSITION"].as_u64().unwrap() as usize];
    assert_eq!(pos["count"].as_u64().unwrap() as usize, t.vertices.len());
    let idx = &doc["accessors"][prim["indices"].as_u64().unwrap() as usize];
    assert_eq!(
        idx["count"].as_u64().unwrap() as usize,
        3 * t.triangles.len()
    );
    let material = &doc["materials"][prim["material"].as_u64().unwrap() as usize];
    assert!(material["name"].as_str().unwrap().starts_with("terrain"));
    let plain = glb_json(&without);
    assert_eq!(plain["nodes"].as_array().unwrap().len(), nodes.len() - 1);
}

#[test]
fn a_3d_tiles_terrain_content_shares_the_tiles_frame() {
    let t = terrain();
    let run = |detail: Detail, terrain: Option<Arc<Terrain>>| {
        let (mut w, info) = Tiles3dWriter::new(Vec::new(), detail);
        w.begin(&ctx(terrain)).unwrap();
        w.write_all(&buildings()).unwrap();
        w.finish().unwrap();
        (w.into_inner(), info.get().unwrap())
    };
    let (glb, info) = run(Detail::Terrain, Some(Arc::new(terrain())));
    let (_, blocks) = run(Detail::Blocks, Some(Arc::new(terrain())));
    let (_, plain_blocks) = run(Detail::Blocks, None);
    assert_eq!(
        blocks, plain_blocks,
        "the terrain changes nothing of Blocks"
    );
    let doc = glb_json(&glb);
    assert_eq!(doc["nodes"][0]["name"], "terrain");
    assert_eq!(info.triangles as usize, t.triangles.len());
    let (p, b) = (info.placement.unwrap(), blocks.placement.unwrap());
    assert_eq!(p.transform, b.transform);
    // The terrain spans more than the buildings.
    assert!(p.region[0] < b.region[0] && p.region[2] > b.region[2]);
    // Without a terrain the content is an empty scene, placed nowhere.
    let (_, none) = run(Detail::Terrain, None);
    assert!(none.placement.is_none());
}
