//! Issue 43, merge and the input/output guard: `citygen merge` reads only regular files inside
//! the shard folders (a manifest path or content URI with `..`, an absolute path, a symlinked
//! tile, a FIFO: refused naming the manifest and the entry, nothing written), refuses outputs
//! over its own inputs before writing anything, the main run refuses an output on `--osc`,
//! and a tileset across the antimeridian keeps its regions within [-π, π]. Inputs are small
//! towns written in code.

use crate::common::*;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

use citygen::testkit::pbf_write::PbfWriter;

/// Writes `n` small tagged houses 30 m apart in a row from (`lon0`, `lat0`) eastwards, as an OSM
/// PBF. Longitudes wrap at ±180°.
fn write_town(path: &Path, lon0: f64, lat0: f64, n: usize) {
    let mut w = PbfWriter::new(std::fs::File::create(path).unwrap()).unwrap();
    let m_lat = 111_132.0;
    let m_lon = m_lat * lat0.to_radians().cos();
    let ll = |x: f64, y: f64| {
        let lon = lon0 + x / m_lon;
        ((lon + 180.0).rem_euclid(360.0) - 180.0, lat0 + y / m_lat)
    };
    for k in 0..n as i64 {
        let x0 = k as f64 * 30.0;
        let corners = [(x0, 0.0), (x0 + 12.0, 0.0), (x0 + 12.0, 10.0), (x0, 10.0)];
        for (c, (x, y)) in corners.iter().enumerate() {
            let (lon, lat) = ll(*x, *y);
            w.node(100 + k * 10 + c as i64, lon, lat, &[]).unwrap();
        }
    }
    for k in 0..n as i64 {
        let refs: Vec<i64> = (0..4).chain([0]).map(|c| 100 + k * 10 + c).collect();
        w.way(
            1000 + k,
            &refs,
            &[
                ("building", "house"),
                ("building:levels", "2"),
                ("roof:shape", "flat"),
            ],
        )
        .unwrap();
    }
    w.finish().unwrap();
}

/// A tiled run of a small town into `dir` (CityJSONSeq and 3D Tiles), its manifest beside them.
fn shard_folder(dir: &Path) {
    let pbf = dir.join("../town.osm.pbf");
    write_town(&pbf, 7.42, 43.73, 4);
    let p = |n: &str| dir.join(n).display().to_string();
    let pbf = pbf.display().to_string();
    let out = citygen(&[
        "--osm",
        &pbf,
        "--kb",
        KB,
        "--lod",
        "1",
        "--tile",
        "100",
        "--quiet",
        "--cityjsonseq",
        &p("t.city.jsonl"),
        "--tiles3d",
        &p("3d"),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

const MANIFEST: &str = "citygen-manifest.0-of-1.json";

fn manifest(dir: &Path) -> serde_json::Value {
    serde_json::from_slice(&std::fs::read(dir.join(MANIFEST)).unwrap()).unwrap()
}

fn save(dir: &Path, m: &serde_json::Value) {
    std::fs::write(dir.join(MANIFEST), serde_json::to_vec_pretty(m).unwrap()).unwrap();
}

/// Every file under `dir`, relative path to bytes (FIFOs and symlinks as their kind).
fn snapshot(dir: &Path) -> BTreeMap<String, Vec<u8>> {
    let mut out = BTreeMap::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap().flatten() {
            let p = e.path();
            let t = e.file_type().unwrap();
            let rel = p.strip_prefix(dir).unwrap().display().to_string();
            if t.is_dir() {
                stack.push(p);
            } else if t.is_symlink() {
                let to = std::fs::read_link(&p).unwrap();
                out.insert(rel, format!("symlink {}", to.display()).into_bytes());
            } else if t.is_file() {
                out.insert(rel, std::fs::read(&p).unwrap());
            } else {
                out.insert(rel, b"special".to_vec());
            }
        }
    }
    out
}

/// `citygen merge` with a deadline (a FIFO must not hang it).
fn merge(args: &[&str]) -> Output {
    let mut child = Command::new(env!("CARGO_BIN_EXE_citygen"))
        .current_dir(root())
        .arg("merge")
        .args(args)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let start = Instant::now();
    while child.try_wait().unwrap().is_none() {
        if start.elapsed() > Duration::from_secs(60) {
            child.kill().unwrap();
            panic!("citygen merge {args:?} hangs");
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    child.wait_with_output().unwrap()
}

/// A shard folder made once, copied into a fresh temporary folder as `root/s` for each case.
fn fresh() -> (tempfile::TempDir, PathBuf) {
    static MADE: std::sync::OnceLock<tempfile::TempDir> = std::sync::OnceLock::new();
    let made = MADE.get_or_init(|| {
        let t = tempfile::tempdir().unwrap();
        std::fs::create_dir(t.path().join("s")).unwrap();
        shard_folder(&t.path().join("s"));
        t
    });
    let tmp = tempfile::tempdir().unwrap();
    let s = tmp.path().join("s");
    copy_tree(&made.path().join("s"), &s);
    (tmp, s)
}

fn copy_tree(from: &Path, to: &Path) {
    std::fs::create_dir_all(to).unwrap();
    for e in std::fs::read_dir(from).unwrap().flatten() {
        let (src, dst) = (e.path(), to.join(e.file_name()));
        if e.file_type().unwrap().is_dir() {
            copy_tree(&src, &dst);
        } else {
            std::fs::copy(&src, &dst).unwrap();
        }
    }
}

/// The manifest's first listed file whose path ends with `suffix`: (tile index, file index,
/// path).
fn listed(m: &serde_json::Value, suffix: &str) -> (usize, usize, String) {
    for (i, t) in m["tiles"].as_array().unwrap().iter().enumerate() {
        for (j, f) in t["files"].as_array().unwrap().iter().enumerate() {
            let p = f["path"].as_str().unwrap();
            if p.ends_with(suffix) {
                return (i, j, p.to_string());
            }
        }
    }
    panic!("no listed file ends with {suffix}");
}

/// Asserts that `out` is a refusal (exit `code`, no panic) whose message holds every needle.
fn refused(out: &Output, code: i32, needles: &[&str]) {
    let e = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(code), "{e}");
    assert!(!e.contains("panicked"), "{e}");
    for n in needles {
        assert!(e.contains(n), "{n:?} not in: {e}");
    }
}

/// `merge s` with every output into `root/out`; asserts that it is refused naming the
/// manifest and `needles`, that nothing was written, and that the shard folder is as it was.
fn merge_refused(root: &Path, s: &Path, needles: &[&str]) {
    let before = snapshot(s);
    let out_dir = root.join("out");
    let o = |n: &str| out_dir.join(n).display().to_string();
    let out = merge(&[
        &s.display().to_string(),
        "--report",
        &o("r.json"),
        "--cityjsonseq",
        &o("region.city.jsonl"),
        "--tiles3d",
        &o("3d"),
        "--preview",
        &o("region.png"),
    ]);
    let manifest = s.join(MANIFEST).display().to_string();
    let mut all = vec![manifest.as_str()];
    all.extend(needles);
    refused(&out, 1, &all);
    assert!(
        !out_dir.exists(),
        "a refused merge wrote {:?}",
        snapshot(&out_dir).keys()
    );
    assert!(
        snapshot(s) == before,
        "a refused merge changed the shard folder"
    );
}

#[test]
fn merge_refuses_a_manifest_path_going_up_or_absolute() {
    for absolute in [false, true] {
        let (tmp, s) = fresh();
        let mut m = manifest(&s);
        let (i, j, tile) = listed(&m, ".city.jsonl");
        // The outside file is the tile's own bytes: its size and SHA-256 match the manifest.
        let outside = tmp.path().join("outside.city.jsonl");
        std::fs::copy(s.join(&tile), &outside).unwrap();
        let given = if absolute {
            outside.display().to_string()
        } else {
            "../outside.city.jsonl".to_string()
        };
        m["tiles"][i]["files"][j]["path"] = serde_json::json!(given);
        save(&s, &m);
        let why = if absolute {
            "is absolute"
        } else {
            "goes up with `..`"
        };
        merge_refused(tmp.path(), &s, &[&format!("{given:?}"), why]);
    }
}

#[test]
fn merge_refuses_a_tile_file_that_is_a_symlink_out_or_under_a_symlinked_folder() {
    let (tmp, s) = fresh();
    let (_, _, tile) = listed(&manifest(&s), ".city.jsonl");
    let outside = tmp.path().join("outside.city.jsonl");
    std::fs::rename(s.join(&tile), &outside).unwrap();
    std::os::unix::fs::symlink(&outside, s.join(&tile)).unwrap();
    merge_refused(tmp.path(), &s, &[&format!("{tile:?}"), "symlink"]);

    // The content folder moved out and symlinked back: every file reads through it.
    let (tmp, s) = fresh();
    let (_, _, glb) = listed(&manifest(&s), ".glb");
    let elsewhere = tmp.path().join("elsewhere");
    std::fs::rename(s.join("3d/content"), &elsewhere).unwrap();
    std::os::unix::fs::symlink(&elsewhere, s.join("3d/content")).unwrap();
    merge_refused(tmp.path(), &s, &[&format!("{glb:?}"), "symlinked folder"]);
}

#[test]
fn merge_refuses_a_tile_that_is_a_fifo_without_hanging() {
    let (tmp, s) = fresh();
    let (_, _, tile) = listed(&manifest(&s), ".city.jsonl");
    std::fs::remove_file(s.join(&tile)).unwrap();
    let made = Command::new("mkfifo").arg(s.join(&tile)).status().unwrap();
    assert!(made.success());
    merge_refused(tmp.path(), &s, &[&format!("{tile:?}"), "named pipe"]);

    // A FIFO named as a manifest: refused, not waited on.
    let (tmp, s) = fresh();
    let fifo = s.join("citygen-manifest.1-of-2.json");
    let made = Command::new("mkfifo").arg(&fifo).status().unwrap();
    assert!(made.success());
    let out_dir = tmp.path().join("out");
    let report = out_dir.join("r.json").display().to_string();
    let out = merge(&[&s.display().to_string(), "--report", &report]);
    refused(&out, 1, &[&fifo.display().to_string(), "named pipe"]);
    assert!(!out_dir.exists());
}

#[test]
fn merge_refuses_a_content_uri_leaving_the_folder() {
    for uri in [
        "../x.glb",
        "/x.glb",
        "file:///etc/passwd",
        "http://example.org/x.glb",
    ] {
        let (tmp, s) = fresh();
        let mut m = manifest(&s);
        let (i, _, glb) = listed(&m, ".glb");
        std::fs::copy(s.join(&glb), tmp.path().join("x.glb")).unwrap();
        m["tiles"][i]["tiles3d"]["full"]["uri"] = serde_json::json!(uri);
        save(&s, &m);
        merge_refused(
            tmp.path(),
            &s,
            &["3D Tiles content uri", &format!("{uri:?}")],
        );
    }
}

#[test]
fn merge_refuses_outputs_over_its_inputs_before_writing() {
    let (tmp, s) = fresh();
    let m = manifest(&s);
    let (_, _, tile) = listed(&m, ".city.jsonl");
    let (_, _, glb) = listed(&m, ".glb");
    let before = snapshot(&s);
    let at = |n: &str| s.join(n).display().to_string();
    let o = |n: &str| tmp.path().join("o").join(n).display().to_string();
    let sd = s.display().to_string();
    let cases: Vec<(Vec<String>, &str)> = vec![
        (vec!["--cityjsonseq".into(), at(&tile)], "which merge reads"),
        (vec!["--report".into(), at(MANIFEST)], "which merge reads"),
        (vec!["--report".into(), at(&glb)], "--report"),
        (vec!["--preview".into(), at(&glb)], "--preview"),
        (
            vec!["--report".into(), at("citygen-manifest.1-of-1.json")],
            "shard manifest",
        ),
        // Two outputs on one path: the region's tileset and the report.
        (
            vec![
                "--report".into(),
                at("3d/tileset.json"),
                "--tiles3d".into(),
                at("3d"),
            ],
            "are the same file",
        ),
    ];
    for (args, needle) in cases {
        let mut all = vec![sd.clone()];
        all.extend(args.iter().cloned());
        // Every other output beside, to see that none is published.
        for (flag, name) in [
            ("--cityjsonseq", "region.city.jsonl"),
            ("--preview", "region.png"),
            ("--report", "r.json"),
        ] {
            if !args.iter().any(|a| a == flag) {
                all.extend([flag.to_string(), o(name)]);
            }
        }
        let a: Vec<&str> = all.iter().map(|s| s.as_str()).collect();
        let out = merge(&a);
        refused(&out, 2, &[needle, &args[1]]);
        assert!(
            !tmp.path().join("o").exists(),
            "{args:?}: an output was published"
        );
        assert!(snapshot(&s) == before, "{args:?}: the shard folder changed");
    }
    // The same merge with its outputs elsewhere (the tileset over the shards' contents) works.
    let out = merge(&[
        &sd,
        "--tiles3d",
        &at("3d"),
        "--report",
        &o("r.json"),
        "--cityjsonseq",
        &o("region.city.jsonl"),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(tmp.path().join("o/region.city.jsonl").is_file());
}

#[test]
fn an_output_on_the_change_file_is_refused_and_the_change_file_kept() {
    let tmp = tempfile::tempdir().unwrap();
    let pbf = tmp.path().join("town.osm.pbf");
    write_town(&pbf, 7.42, 43.73, 2);
    let osc = tmp.path().join("change.osc");
    let text = b"<?xml version='1.0'?>\n<osmChange version='0.6'></osmChange>\n";
    std::fs::write(&osc, text).unwrap();
    let (pbf, osc_s) = (pbf.display().to_string(), osc.display().to_string());
    // (A model output beside the report.)
    let glb = tmp.path().join("t.glb").display().to_string();
    for flag in ["--report", "--ifc", "--cityjsonseq"] {
        let out = citygen(&[
            "--osm",
            &pbf,
            "--osc",
            &osc_s,
            "--kb",
            KB,
            "--force-extension",
            "--gltf",
            &glb,
            flag,
            &osc_s,
        ]);
        refused(
            &out,
            2,
            &[flag, "--osc", &osc_s, "refusing to overwrite an input"],
        );
        assert_eq!(
            std::fs::read(&osc).unwrap(),
            text,
            "{flag}: the change file changed"
        );
    }
}

/// Every `region` of a tileset's JSON, with where it is.
fn regions(v: &serde_json::Value, at: String, out: &mut Vec<(String, Vec<f64>)>) {
    match v {
        serde_json::Value::Object(m) => {
            for (k, x) in m {
                if k == "region" {
                    let r = x.as_array().unwrap().iter().map(|n| n.as_f64().unwrap());
                    out.push((at.clone(), r.collect()));
                } else {
                    regions(x, format!("{at}/{k}"), out);
                }
            }
        }
        serde_json::Value::Array(a) => {
            for (i, x) in a.iter().enumerate() {
                regions(x, format!("{at}/{i}"), out);
            }
        }
        _ => {}
    }
}

/// Asserts that every region of the tileset at `path` lies within the 3D Tiles ranges, and
/// that the root's takes every longitude (its tiles lie on both sides of the antimeridian).
fn regions_in_range(path: &Path) {
    let v: serde_json::Value = serde_json::from_slice(&std::fs::read(path).unwrap()).unwrap();
    let mut all = Vec::new();
    regions(&v, String::new(), &mut all);
    assert!(all.len() >= 3, "{all:?}");
    use std::f64::consts::{FRAC_PI_2, PI};
    for (at, r) in &all {
        assert!(
            (-PI..=PI).contains(&r[0]) && (-PI..=PI).contains(&r[2]),
            "{}: {at}: west/east {r:?} past π",
            path.display()
        );
        assert!(
            (-FRAC_PI_2..=FRAC_PI_2).contains(&r[1]) && (-FRAC_PI_2..=FRAC_PI_2).contains(&r[3]),
            "{at}: {r:?}"
        );
        assert!(r[1] <= r[3] && r[4] <= r[5], "{at}: {r:?}");
    }
    let root = &v["root"]["boundingVolume"]["region"];
    assert!(
        root[0].as_f64().unwrap() < -3.0 && root[2].as_f64().unwrap() > 3.0,
        "{root}"
    );
}

/// Six houses 30 m apart from 60 m west of the antimeridian, the third's west wall on it (the
/// region of its content touched ±π before its margin was added).
const FIJI_LON0: f64 = 180.0 - 60.0 / (111_132.0 * 0.958_819_734_868_193);

#[test]
fn a_tileset_across_the_antimeridian_keeps_its_regions_within_pi() {
    let tmp = tempfile::tempdir().unwrap();
    let pbf = tmp.path().join("fiji.osm.pbf");
    write_town(&pbf, FIJI_LON0, -16.5, 6);
    let pbf = pbf.display().to_string();
    let p = |n: &str| tmp.path().join(n).display().to_string();
    let out = citygen(&[
        "--osm",
        &pbf,
        "--kb",
        KB,
        "--lod",
        "1",
        "--tile",
        "50",
        "--quiet",
        "--tiles3d",
        &p("3d"),
        "--cityjsonseq",
        &p("t.city.jsonl"),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    regions_in_range(&tmp.path().join("3d/tileset.json"));
    // The merge's tileset, from the manifest's facts.
    let out = merge(&[&tmp.path().display().to_string(), "--tiles3d", &p("m3d")]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    regions_in_range(&tmp.path().join("m3d/tileset.json"));
}

#[test]
fn an_output_on_a_kb_appearances_ruleset_is_refused_and_the_ruleset_kept() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    let pbf = d.join("town.osm.pbf");
    write_town(&pbf, 7.42, 43.73, 2);
    let rules = b"lot -> extrude(7.5){building}\n";
    std::fs::write(d.join("r.cga"), rules).unwrap();
    let kb = d.join("kb.xml");
    std::fs::write(
        &kb,
        "<earth>\n  <info nbfloor=\"2\" floorsize=\"3\" rooftype=\"flat\"/>\n  \
         <appearance><values proba=\"1\"/><ruleset file=\"r.cga\"/></appearance>\n</earth>\n",
    )
    .unwrap();
    let at = |n: &str| d.join(n).display().to_string();
    let out = citygen(&[
        "--osm",
        &at("town.osm.pbf"),
        "--kb",
        &at("kb.xml"),
        "--force-extension",
        "--gltf",
        &at("t.glb"),
        "--report",
        &at("r.cga"),
    ]);
    refused(
        &out,
        2,
        &[
            "--report",
            "a --kb appearance",
            "r.cga",
            "refusing to overwrite",
        ],
    );
    assert_eq!(std::fs::read(d.join("r.cga")).unwrap(), rules);
    assert!(
        !d.join("t.glb").exists(),
        "a refused run published its model"
    );
}
