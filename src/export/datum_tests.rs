//! The heights' datum in every writer (issue 44): what each states when the run states a
//! vertical datum, that nothing else changes (the file without the statement is the file
//! without a datum, byte for byte), and the reference validators on files written with one.

use glam::DVec3;

use super::citygml::CityGmlWriter;
use super::cityjson::{CityJsonSeqWriter, CityJsonWriter};
use super::gltf::GltfWriter;
use super::ifc::IfcWriter;
use super::*;
use crate::crs::Crs;
use crate::export::fixtures;
use crate::model::{Lod, VerticalDatum};

fn ctx(datum: Option<VerticalDatum>) -> OutputContext {
    OutputContext {
        crs: Crs::Utm {
            zone: 32,
            north: true,
        },
        origin: DVec3::new(512_000.0, 5_150_000.0, 450.0),
        origin_lonlat: (9.155, 46.5),
        lod: Lod::Lod4,
        source_name: "valley <&> \"floor\".osm.pbf".into(),
        seed: 11,
        vertical_datum: datum,
        terrain: None,
    }
}

fn egm96() -> Option<VerticalDatum> {
    Some(VerticalDatum::Orthometric {
        epsg: Some(5773),
        name: "EGM96 height".into(),
    })
}

/// A datum without a code: only its name can be stated.
fn unnamed() -> Option<VerticalDatum> {
    Some(VerticalDatum::Orthometric {
        epsg: None,
        name: "DEM heights <local>".into(),
    })
}

fn run(w: &mut dyn BuildingWriter, ctx: &OutputContext) {
    w.begin(ctx).unwrap();
    w.write_all(&fixtures::lod4_all()).unwrap();
    w.finish().unwrap();
}

fn citygml(datum: Option<VerticalDatum>) -> String {
    let mut w = CityGmlWriter::new(Vec::new());
    run(&mut w, &ctx(datum));
    String::from_utf8(w.into_inner()).unwrap()
}

fn cityjson(datum: Option<VerticalDatum>) -> String {
    let mut w = CityJsonWriter::new(Vec::new());
    run(&mut w, &ctx(datum));
    String::from_utf8(w.into_inner()).unwrap()
}

fn cityjsonseq(datum: Option<VerticalDatum>) -> String {
    let mut w = CityJsonSeqWriter::new(Vec::new());
    run(&mut w, &ctx(datum));
    String::from_utf8(w.into_inner()).unwrap()
}

fn ifc(datum: Option<VerticalDatum>) -> String {
    let mut w = IfcWriter::new(Vec::new());
    run(&mut w, &ctx(datum));
    String::from_utf8(w.into_inner().unwrap()).unwrap()
}

fn glb(datum: Option<VerticalDatum>) -> Vec<u8> {
    let mut out = Vec::new();
    let mut w = GltfWriter::new(&mut out, tempfile::tempfile().unwrap());
    run(&mut w, &ctx(datum));
    drop(w);
    out
}

/// A GLB's JSON chunk (trailing padding removed) and its binary chunk.
fn glb_chunks(glb: &[u8]) -> (String, Vec<u8>) {
    let u = |at: usize| u32::from_le_bytes(glb[at..at + 4].try_into().unwrap()) as usize;
    let jlen = u(12);
    let json = String::from_utf8(glb[20..20 + jlen].to_vec()).unwrap();
    (json.trim_end().to_string(), glb[20 + jlen..].to_vec())
}

#[test]
fn citygml_names_the_compound_crs_and_the_datum() {
    let none = citygml(None);
    let some = citygml(egm96());
    let compound = "urn:ogc:def:crs,crs:EPSG::32632,crs:EPSG::5773";
    assert!(!none.contains("5773") && none.contains("srsName=\"EPSG:32632\""));
    assert!(some.contains(&format!("srsName=\"{compound}\"")));
    assert!(
        !some.contains("srsName=\"EPSG:32632\""),
        "every srsName is the compound"
    );
    assert!(some.contains("geometry; heights: EGM96 height (EPSG:5773)</gml:description>"));
    let back = some
        .replace(compound, "EPSG:32632")
        .replace("; heights: EGM96 height (EPSG:5773)", "");
    assert!(back == none, "nothing else changes");
    // Without a code: the horizontal CRS alone, the datum by name (escaped).
    let unnamed = citygml(unnamed());
    assert!(unnamed.contains("; heights: DEM heights &lt;local&gt;</gml:description>"));
    assert_eq!(
        unnamed.replace("; heights: DEM heights &lt;local&gt;", ""),
        none
    );
}

#[test]
fn cityjson_states_the_vertical_crs_beside_the_horizontal_one() {
    for (some, none, unnamed) in [
        (cityjson(egm96()), cityjson(None), cityjson(unnamed())),
        (
            cityjsonseq(egm96()),
            cityjsonseq(None),
            cityjsonseq(unnamed()),
        ),
    ] {
        let header: serde_json::Value =
            serde_json::from_str(some.lines().next().unwrap_or_default())
                .or_else(|_| serde_json::from_str(&some))
                .unwrap();
        let m = &header["metadata"];
        assert_eq!(
            m["referenceSystem"],
            "https://www.opengis.net/def/crs/EPSG/0/32632"
        );
        assert_eq!(
            m["verticalReferenceSystem"],
            "https://www.opengis.net/def/crs/EPSG/0/5773"
        );
        assert!(m["title"]
            .as_str()
            .unwrap()
            .ends_with("LOD4 geometry; heights: EGM96 height (EPSG:5773)"));
        let back = some
            .replace(
                "\"verticalReferenceSystem\":\"https://www.opengis.net/def/crs/EPSG/0/5773\",",
                "",
            )
            .replace("; heights: EGM96 height (EPSG:5773)", "");
        assert!(back == none, "nothing else changes");
        assert!(!unnamed.contains("verticalReferenceSystem"));
        assert_eq!(unnamed.replace("; heights: DEM heights <local>", ""), none);
    }
}

#[test]
fn ifc_sets_the_projected_crs_vertical_datum() {
    let none = ifc(None);
    let some = ifc(egm96());
    let plain = "IFCPROJECTEDCRS('EPSG:32632','WGS 84 / UTM zone 32N',$,$,$,$,";
    assert!(none.contains(plain), "{none}");
    let with =
        "IFCPROJECTEDCRS('EPSG:32632','WGS 84 / UTM zone 32N + EGM96 height',$,'EPSG:5773',$,$,";
    assert!(some.contains(with));
    // The map conversion's OrthogonalHeight is the origin's height, now in that datum.
    assert!(some.contains(",512000.,5150000.,450.,"), "OrthogonalHeight");
    assert!(some.replace(with, plain) == none, "nothing else changes");
    let unnamed = ifc(unnamed());
    assert!(unnamed.contains(
        "IFCPROJECTEDCRS('EPSG:32632','WGS 84 / UTM zone 32N + DEM heights <local>',$,'DEM heights <local>',$,$,"
    ));
}

#[test]
fn gltf_asset_extras_name_the_datum() {
    let (none_json, none_bin) = glb_chunks(&glb(None));
    let (json, bin) = glb_chunks(&glb(egm96()));
    assert_eq!(bin, none_bin, "the geometry is the same");
    let doc: serde_json::Value = serde_json::from_str(&json).unwrap();
    let extras = &doc["asset"]["extras"];
    assert_eq!(extras["crs"], "EPSG:32632");
    assert_eq!(extras["verticalCrs"], "EPSG:5773");
    assert_eq!(extras["verticalDatum"], "EGM96 height");
    let back = json.replace(
        "\"verticalCrs\":\"EPSG:5773\",\"verticalDatum\":\"EGM96 height\",",
        "",
    );
    assert!(back == none_json, "nothing else changes");
    let (json, _) = glb_chunks(&glb(unnamed()));
    let doc: serde_json::Value = serde_json::from_str(&json).unwrap();
    assert!(doc["asset"]["extras"].get("verticalCrs").is_none());
    assert_eq!(
        doc["asset"]["extras"]["verticalDatum"],
        "DEM heights <local>"
    );
}

/// Every format written with a vertical datum (with and without its code) passes the
/// reference validators. `CITYGEN_DATUM_KEEP=DIR` keeps the files in DIR.
#[test]
fn files_with_a_datum_pass_the_reference_validators() {
    let Some(validator) = fixtures::validator("datum statements (CityGML, CityJSON, IFC, glTF)")
    else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let keep = std::env::var_os("CITYGEN_DATUM_KEEP").map(std::path::PathBuf::from);
    let out = keep.as_deref().unwrap_or(dir.path());
    std::fs::create_dir_all(out).unwrap();
    let mut files = Vec::new();
    for (tag, datum) in [("egm96", egm96()), ("unnamed", unnamed())] {
        let mut put = |name: String, bytes: &[u8]| {
            let path = out.join(name);
            std::fs::write(&path, bytes).unwrap();
            files.push(path);
        };
        put(format!("{tag}.gml"), citygml(datum.clone()).as_bytes());
        put(
            format!("{tag}.city.json"),
            cityjson(datum.clone()).as_bytes(),
        );
        put(
            format!("{tag}.city.jsonl"),
            cityjsonseq(datum.clone()).as_bytes(),
        );
        put(format!("{tag}.ifc"), ifc(datum.clone()).as_bytes());
        put(format!("{tag}.glb"), &glb(datum));
    }
    let run = std::process::Command::new(&validator)
        .args(&files)
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&run.stdout);
    eprintln!("{text}");
    assert!(
        run.status.success() && text.contains(&format!("{} passed, 0 failed", files.len())),
        "{text}\n{}",
        String::from_utf8_lossy(&run.stderr)
    );
}
