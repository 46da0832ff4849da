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

/// The `#n` references in a STEP argument text, in order.
pub fn step_refs(args: &str) -> Vec<u64> {
    let mut out = Vec::new();
    let b = args.as_bytes();
    let mut i = 0;
    let mut in_str = false;
    while i < b.len() {
        match b[i] {
            b'\'' => in_str = !in_str,
            b'#' if !in_str => {
                let j = i + 1 + b[i + 1..].iter().take_while(|c| c.is_ascii_digit()).count();
                if let Ok(n) = args[i + 1..j].parse() {
                    out.push(n);
                }
                i = j;
                continue;
            }
            _ => {}
        }
        i += 1;
    }
    out
}

/// Windows and doors per top-level IfcBuilding, keyed by the building's `SourceId` property:
/// window/door <- IfcRelFillsElement <- opening <- IfcRelVoidsElement <- wall <- storey
/// (IfcRelContainedInSpatialStructure) <- building(s) (IfcRelAggregates).
pub fn ifc_openings_per_building(
    ents: &std::collections::BTreeMap<u64, (String, String)>,
) -> std::collections::BTreeMap<String, (usize, usize)> {
    use std::collections::BTreeMap;
    let mut parent: BTreeMap<u64, u64> = BTreeMap::new(); // child -> container
    let mut filled_by: BTreeMap<u64, u64> = BTreeMap::new(); // window/door -> opening
    let mut voids: BTreeMap<u64, u64> = BTreeMap::new(); // opening -> wall
    let mut source: BTreeMap<u64, String> = BTreeMap::new(); // building -> SourceId
    for (id, (t, a)) in ents {
        let refs = step_refs(a);
        match t.as_str() {
            "IFCRELAGGREGATES" | "IFCRELCONTAINEDINSPATIALSTRUCTURE" => {
                // (GlobalId, OwnerHistory, Name, Description, RelatingObject, (RelatedObjects))
                // or (..., (RelatedElements), RelatingStructure)
                if t == "IFCRELAGGREGATES" {
                    let (whole, parts) = refs.split_first().unwrap();
                    for p in parts {
                        parent.insert(*p, *whole);
                    }
                } else {
                    let (structure, elems) = refs.split_last().unwrap();
                    for e in elems {
                        parent.insert(*e, *structure);
                    }
                }
            }
            "IFCRELFILLSELEMENT" => {
                filled_by.insert(refs[1], refs[0]);
            }
            "IFCRELVOIDSELEMENT" => {
                voids.insert(refs[1], refs[0]);
            }
            "IFCPROPERTYSINGLEVALUE" if a.starts_with("'SourceId'") => {
                let v = a
                    .split("IFCIDENTIFIER('")
                    .nth(1)
                    .and_then(|r| r.split('\'').next())
                    .unwrap_or("");
                source.insert(*id, v.to_string());
            }
            _ => {}
        }
    }
    // Map pset id -> SourceId, then building -> SourceId through IfcRelDefinesByProperties.
    let mut pset_ids: BTreeMap<u64, String> = BTreeMap::new();
    for (id, (t, a)) in ents {
        if t == "IFCPROPERTYSET" {
            if let Some(v) = step_refs(a).iter().find_map(|r| source.get(r)) {
                pset_ids.insert(*id, v.clone());
            }
        }
    }
    let mut building_source: BTreeMap<u64, String> = BTreeMap::new();
    for (t, a) in ents.values() {
        if t == "IFCRELDEFINESBYPROPERTIES" {
            let refs = step_refs(a);
            let (pset, objs) = refs.split_last().unwrap();
            if let Some(v) = pset_ids.get(pset) {
                for o in objs {
                    building_source.insert(*o, v.clone());
                }
            }
        }
    }
    let top_building = |mut e: u64| -> Option<u64> {
        let mut found = None;
        for _ in 0..16 {
            if ents.get(&e).is_some_and(|(t, _)| t == "IFCBUILDING") {
                found = Some(e);
            }
            match parent.get(&e) {
                Some(p) => e = *p,
                None => break,
            }
        }
        found
    };
    let mut out: BTreeMap<String, (usize, usize)> = BTreeMap::new();
    for (id, (t, _)) in ents {
        let is_window = t == "IFCWINDOW";
        if !is_window && t != "IFCDOOR" {
            continue;
        }
        let wall = filled_by
            .get(id)
            .and_then(|o| voids.get(o))
            .copied()
            .expect("window or door fills a voided opening");
        let b = top_building(wall).expect("the wall is in a building");
        let key = building_source
            .get(&b)
            .cloned()
            .unwrap_or_else(|| format!("#{b}"));
        let e = out.entry(key).or_default();
        if is_window {
            e.0 += 1;
        } else {
            e.1 += 1;
        }
    }
    out
}

/// Every file under `dir`, by path relative to it, with its bytes, but those `keep` refuses.
pub fn files_under(
    dir: &Path,
    keep: impl Fn(&str) -> bool,
) -> std::collections::BTreeMap<String, Vec<u8>> {
    fn walk(
        base: &Path,
        dir: &Path,
        keep: &dyn Fn(&str) -> bool,
        out: &mut std::collections::BTreeMap<String, Vec<u8>>,
    ) {
        for e in std::fs::read_dir(dir).unwrap().flatten() {
            let p = e.path();
            if p.is_dir() {
                walk(base, &p, keep, out);
            } else {
                let rel = p.strip_prefix(base).unwrap().display().to_string();
                if keep(&rel) {
                    out.insert(rel, std::fs::read(&p).unwrap());
                }
            }
        }
    }
    let mut out = std::collections::BTreeMap::new();
    walk(dir, dir, &keep, &mut out);
    out
}
