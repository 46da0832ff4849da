//! Helpers shared by the end-to-end tests: running the real binary, reading its outputs.
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

pub const MONACO: &str = "data/monaco/monaco.osm.pbf";
pub const CLIFTON: &str = "data/clifton/clifton_test.shp";
pub const KB: &str = "knowledge_base/kb.xml";

pub fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// Runs citygen from the repository root.
pub fn citygen(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_citygen"))
        .current_dir(root())
        .args(args)
        .output()
        .expect("run citygen")
}

/// Paths of the three outputs and the report of one run.
pub struct Run {
    pub dir: tempfile::TempDir,
    pub ifc: PathBuf,
    pub gml: PathBuf,
    pub glb: PathBuf,
    pub report: PathBuf,
}

impl Run {
    pub fn report_json(&self) -> serde_json::Value {
        serde_json::from_slice(&std::fs::read(&self.report).unwrap()).unwrap()
    }
}

/// Runs citygen with all outputs into a fresh temporary folder; panics with stderr on failure.
pub fn run_all(input_flag: &str, input: &str, lod: &str, extra: &[&str]) -> Run {
    let dir = tempfile::tempdir().unwrap();
    let p = |n: &str| dir.path().join(n);
    let (ifc, gml, glb, report) = (p("out.ifc"), p("out.gml"), p("out.glb"), p("report.json"));
    let mut args: Vec<String> = vec![
        input_flag.into(),
        input.into(),
        "--kb".into(),
        KB.into(),
        "--lod".into(),
        lod.into(),
        "--ifc".into(),
        ifc.display().to_string(),
        "--citygml".into(),
        gml.display().to_string(),
        "--gltf".into(),
        glb.display().to_string(),
        "--report".into(),
        report.display().to_string(),
        "--quiet".into(),
    ];
    args.extend(extra.iter().map(|s| s.to_string()));
    let refs: Vec<&str> = args.iter().map(String::as_str).collect();
    let out = citygen(&refs);
    assert!(
        out.status.success(),
        "citygen failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    Run {
        dir,
        ifc,
        gml,
        glb,
        report,
    }
}

/// The JSON chunk of a GLB file.
pub fn glb_json(path: &Path) -> (serde_json::Value, Vec<u8>) {
    let bytes = std::fs::read(path).unwrap();
    assert_eq!(&bytes[0..4], b"glTF");
    let json_len = u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize;
    let json: serde_json::Value = serde_json::from_slice(&bytes[20..20 + json_len]).unwrap();
    let bin_start = 20 + json_len + 8;
    let bin = bytes
        .get(bin_start..)
        .map(<[u8]>::to_vec)
        .unwrap_or_default();
    (json, bin)
}

/// A minimal STEP reader: entity id -> (TYPE, raw argument text).
pub fn step_entities(path: &Path) -> std::collections::BTreeMap<u64, (String, String)> {
    let text = std::fs::read_to_string(path).unwrap();
    let data = &text[text.find("DATA;").unwrap() + 5..];
    let mut out = std::collections::BTreeMap::new();
    for stmt in data.split(";\n") {
        let stmt = stmt.trim();
        let Some(rest) = stmt.strip_prefix('#') else {
            continue;
        };
        let Some((id, body)) = rest.split_once('=') else {
            continue;
        };
        let body = body.trim();
        let Some(paren) = body.find('(') else {
            continue;
        };
        out.insert(
            id.trim().parse().unwrap(),
            (
                body[..paren].to_string(),
                body[paren + 1..body.len() - 1].to_string(),
            ),
        );
    }
    out
}
