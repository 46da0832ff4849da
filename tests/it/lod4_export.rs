//! LOD4 through the writers on real footprints: the Monaco-Ville buildings derived at LOD4 (the
//! floor plans of `interior`, mapped into the model) written as IFC, CityGML and glTF; the
//! files are well-formed, hold every room, and pass the reference validator with the geometry
//! kernel when it is installed.

use crate::common::*;

use citygen::export::citygml::CityGmlWriter;
use citygen::export::gltf::GltfWriter;
use citygen::export::ifc::IfcWriter;
use citygen::export::{BuildingWriter, OutputContext};
use citygen::model::{Building, Lod};

fn monaco_ville_lod4() -> (OutputContext, Vec<Building>) {
    let mut report = citygen::report::Report::default();
    let read = citygen::input::osm::read_osm(&root().join(MONACO), &mut report).unwrap();
    let mut site = citygen::prepare::prepare(read.footprints, None, None, &mut report);
    citygen::prepare::assign_fronts(&mut site, &read.streets, None);
    citygen::prepare::retain_in_bbox(&mut site, [7.4180, 43.7290, 7.4240, 43.7330], &mut report)
        .expect("Monaco-Ville lies in the sample");
    let (kb, _) = citygen::kb::KnowledgeBase::load(&root().join(KB)).unwrap();
    let caps = citygen::grammar::Caps {
        facades: true,
        ..Default::default()
    };
    let generator =
        citygen::derive::Generator::new(kb, citygen::derive::Rules::Kb, Lod::Lod4, 0, caps);
    let buildings: Vec<Building> = site
        .lots
        .iter()
        .filter_map(|lot| generator.generate(lot).ok().map(|(b, _)| b))
        .collect();
    let ctx = OutputContext {
        crs: site.crs,
        origin: glam::DVec3::new(site.origin.x, site.origin.y, 0.0),
        origin_lonlat: site.origin_lonlat,
        lod: Lod::Lod4,
        source_name: "monaco-ville".into(),
        seed: 0,
        vertical_datum: None,
        terrain: None,
    };
    (ctx, buildings)
}

fn write(w: &mut dyn BuildingWriter, ctx: &OutputContext, buildings: &[Building]) {
    w.begin(ctx).unwrap();
    for b in buildings {
        w.write(b).unwrap();
    }
    w.finish().unwrap();
}

#[test]
fn monaco_ville_interiors_write_and_validate() {
    let (ctx, buildings) = monaco_ville_lod4();
    let rooms: usize = buildings
        .iter()
        .flat_map(|b| &b.parts)
        .flat_map(|p| &p.interior)
        .map(|s| s.rooms.len())
        .sum();
    assert!(rooms > 100, "{rooms} rooms");
    // Every room is simple once cleaned as the writers clean it, so no writer leaves one out
    // (a plan used to join two pieces by a zero-width seam; `interior` now cuts such rooms).
    let refused = buildings
        .iter()
        .flat_map(|b| &b.parts)
        .flat_map(|p| &p.interior)
        .flat_map(|s| &s.rooms)
        .filter(|r| citygen::export::lod4geom::room_ring(r).is_none())
        .count();
    assert_eq!(
        refused, 0,
        "{refused} of {rooms} rooms refused by the writers"
    );
    let dir = tempfile::tempdir().unwrap();
    let keep = std::env::var_os("CITYGEN_LOD4_KEEP").map(std::path::PathBuf::from);
    let out = keep.as_deref().unwrap_or(dir.path());

    let mut ifc = IfcWriter::new(Vec::new()).with_file_name("lod4.ifc");
    write(&mut ifc, &ctx, &buildings);
    let ifc_bytes = ifc.into_inner().unwrap();
    let spaces = String::from_utf8_lossy(&ifc_bytes)
        .matches("=IFCSPACE(")
        .count();
    std::fs::write(out.join("lod4.ifc"), &ifc_bytes).unwrap();

    let mut gml = CityGmlWriter::new(Vec::new());
    write(&mut gml, &ctx, &buildings);
    let gml_bytes = gml.into_inner();
    let gml_rooms = String::from_utf8_lossy(&gml_bytes)
        .matches("<bldg:Room ")
        .count();
    std::fs::write(out.join("lod4.gml"), &gml_bytes).unwrap();

    let scratch = tempfile::tempfile().unwrap();
    let mut glb = GltfWriter::new(Vec::new(), scratch);
    write(&mut glb, &ctx, &buildings);
    std::fs::write(out.join("lod4.glb"), glb.into_inner()).unwrap();

    // Every room of the model is a space and a CityGML room.
    assert_eq!(spaces, rooms);
    assert_eq!(gml_rooms, rooms);

    // The geometry kernel is slow on the whole quarter (hundreds of buildings): validate the
    // first 3 buildings with a multi-storey interior (stairs, upper slabs) in files of their
    // own, and the quarter's glTF (CI's sample step builds a whole LOD4 corner of it).
    let Some(tool) =
        citygen::testkit::validators::validate_outputs("Monaco-Ville LOD4 (geometry kernel)")
    else {
        return;
    };
    let some: Vec<Building> = buildings
        .iter()
        .filter(|b| b.parts.iter().any(|p| p.interior.len() > 1))
        .take(3)
        .cloned()
        .collect();
    assert_eq!(some.len(), 3);
    let mut ifc = IfcWriter::new(Vec::new()).with_file_name("some.ifc");
    write(&mut ifc, &ctx, &some);
    std::fs::write(out.join("some.ifc"), ifc.into_inner().unwrap()).unwrap();
    // The schema validator stops at a million elements: the quarter's CityGML is larger.
    let mut gml = CityGmlWriter::new(Vec::new());
    write(&mut gml, &ctx, &some);
    std::fs::write(out.join("some.gml"), gml.into_inner()).unwrap();
    let res = std::process::Command::new(tool)
        .arg("--geometry")
        .args(["some.ifc", "some.gml", "lod4.glb"].map(|f| out.join(f)))
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&res.stdout);
    assert!(
        res.status.success() && text.contains("3 passed, 0 failed"),
        "{text}"
    );
}
