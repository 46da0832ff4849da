//! The preview picture on real buildings: Monaco derived at LOD2, drawn by the preview writer
//! and, through the glTF writer's GLB read back by the preview's GLB reader, drawn again. The
//! GLB's triangles are all read, the writer's are the GLB's without the grounds, the two
//! pictures nearly the same, the scene compact, and the picture shows a city (buildings over
//! a plate under the sky, red roofs and light walls in many tones). `CITYGEN_PREVIEW_KEEP=DIR` keeps the picture (docs/images/preview-monaco.png
//! is one).

use crate::common::*;

use citygen::export::gltf::GltfWriter;
use citygen::export::preview::{glb_triangles, PreviewWriter, Scene, View};
use citygen::export::{BuildingWriter, OutputContext};
use citygen::model::{Building, Lod};

fn monaco(lod: Lod) -> (OutputContext, Vec<Building>) {
    let mut report = citygen::report::Report::default();
    let read = citygen::input::osm::read_osm(&root().join(MONACO), &mut report).unwrap();
    let mut site = citygen::prepare::prepare(read.footprints, None, None, &mut report);
    citygen::prepare::assign_fronts(&mut site, &read.streets, None);
    let (kb, _) = citygen::kb::KnowledgeBase::load(&root().join(KB)).unwrap();
    let generator = citygen::derive::Generator::new(
        kb,
        citygen::derive::Rules::Kb,
        lod,
        0,
        citygen::grammar::Caps::default(),
    );
    let buildings: Vec<Building> = site
        .lots
        .iter()
        .filter_map(|lot| generator.generate(lot).ok().map(|(b, _)| b))
        .collect();
    let ctx = OutputContext {
        crs: site.crs,
        origin: glam::DVec3::new(site.origin.x, site.origin.y, 0.0),
        origin_lonlat: site.origin_lonlat,
        lod,
        source_name: "monaco".into(),
        seed: 0,
        vertical_datum: None,
        terrain: None,
    };
    (ctx, buildings)
}

#[test]
fn monaco_lod2_preview_reads_as_a_city() {
    let (ctx, buildings) = monaco(Lod::Lod2);
    assert!(buildings.len() > 1000, "{} buildings", buildings.len());

    // The writer, fed in batches as a run feeds it.
    let mut w = PreviewWriter::new(Vec::new());
    w.begin(&ctx).unwrap();
    for chunk in buildings.chunks(100) {
        w.write_all(chunk).unwrap();
    }
    let scene = w.scene().clone();
    w.finish().unwrap();
    let png = w.into_inner();
    let per_building = scene.heap_bytes() / buildings.len();
    eprintln!(
        "{} buildings: {} triangles, {} vertices, {} bytes a building; PNG {} bytes",
        buildings.len(),
        scene.triangle_count(),
        scene.vertex_count(),
        per_building,
        png.len()
    );
    // Compact: 100,000 LOD2 buildings in a few hundred MB at most.
    assert!(per_building < 3000, "{per_building} bytes a building");

    // The same buildings through the GLB and its reader: the same triangles, the same picture.
    let mut glb = GltfWriter::new(Vec::new(), tempfile::tempfile().unwrap());
    glb.begin(&ctx).unwrap();
    glb.write_all(&buildings).unwrap();
    glb.finish().unwrap();
    let glb = glb.into_inner();
    let meshes = glb_triangles(&glb, &|p| p).unwrap();
    let mut from_glb = Scene::new();
    from_glb.add_glb_meshes(&meshes);
    // Every triangle the GLB's JSON declares is read; the preview leaves out the grounds.
    let (declared, ground) = declared_triangles(&glb);
    let read: usize = meshes.iter().map(|m| m.indices.len() / 3).sum();
    assert_eq!(read, declared);
    assert_eq!(from_glb.triangle_count(), declared);
    assert_eq!(scene.triangle_count(), declared - ground);

    let image = scene.render(&View::default());
    assert_eq!(
        image.to_png(),
        png,
        "the writer's PNG is the scene's render"
    );
    // The GLB's picture, from the same side (the grounds' vertices would turn the automatic
    // view a little): the same but where a ground face shows at a wall's foot.
    let side = View {
        azimuth: Some(300.0),
        ..View::default()
    };
    let (mine, other) = (scene.render(&side), from_glb.render(&side));
    let differ = mine
        .rgb()
        .chunks(3)
        .zip(other.rgb().chunks(3))
        .filter(|(a, b)| a != b)
        .count();
    let pixels = (image.width() * image.height()) as usize;
    assert!(differ * 200 < pixels, "{differ} of {pixels} pixels differ");

    // A city: many pixels are buildings (neither the sky's blue nor the plate's grey-green),
    // in many tones; red roofs and light walls among them.
    let (mut built, mut roofs, mut walls) = (0, 0, 0);
    let mut tones = std::collections::BTreeSet::new();
    let plate = image.rgb()[3 * (pixels - 1)..].to_vec();
    for c in image.rgb().chunks(3) {
        let [r, g, b] = [c[0], c[1], c[2]].map(i32::from);
        let sky = b > r + 20;
        if sky || c == &plate[..] {
            continue;
        }
        built += 1;
        tones.insert([c[0], c[1], c[2]]);
        roofs += usize::from(r > g + 60);
        walls += usize::from((r - g).abs() < 12 && (g - b).abs() < 12 && r > 150);
    }
    eprintln!(
        "{built} building pixels, {} tones, {roofs} roof, {walls} wall",
        tones.len()
    );
    assert!(built * 20 > pixels, "{built} building pixels of {pixels}");
    assert!(tones.len() > 500, "{} tones", tones.len());
    assert!(
        roofs * 5 > built && walls * 5 > built,
        "{roofs} roof, {walls} wall pixels"
    );
    if let Some(dir) = std::env::var_os("CITYGEN_PREVIEW_KEEP") {
        let dir = std::path::PathBuf::from(dir);
        std::fs::write(dir.join("preview-monaco.png"), &png).unwrap();
    }
}

/// The triangles a GLB's JSON declares (index counts / 3), all and those of `ground` nodes.
fn declared_triangles(glb: &[u8]) -> (usize, usize) {
    let (doc, _) = glb_json_bytes(glb);
    let count = |mesh: &serde_json::Value| -> usize {
        let prims = doc["meshes"][mesh.as_u64().unwrap() as usize]["primitives"]
            .as_array()
            .unwrap();
        prims
            .iter()
            .map(|p| {
                let acc = p["indices"].as_u64().unwrap() as usize;
                doc["accessors"][acc]["count"].as_u64().unwrap() as usize / 3
            })
            .sum()
    };
    let nodes = doc["nodes"].as_array().unwrap();
    let with_mesh = nodes.iter().filter(|n| n.get("mesh").is_some());
    let all = with_mesh.clone().map(|n| count(&n["mesh"])).sum();
    let ground = with_mesh
        .filter(|n| n["name"] == "ground")
        .map(|n| count(&n["mesh"]))
        .sum();
    (all, ground)
}

/// A GLB's JSON chunk, parsed, and its length.
fn glb_json_bytes(glb: &[u8]) -> (serde_json::Value, usize) {
    let len = u32::from_le_bytes(glb[12..16].try_into().unwrap()) as usize;
    (serde_json::from_slice(&glb[20..20 + len]).unwrap(), len)
}
