//! A region on several machines (issue 24): shards of a tiled run with local processes, their
//! index from the job variables of Kubernetes and Slurm, `citygen merge`, its refusals, and a
//! shard killed with SIGKILL and run again. The 100k-building version of the same checks is
//! `scripts/shard-check` (a CI step).

use crate::common::*;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::time::{Duration, Instant};

const TILE: &str = "400";

fn run_in(dir: &Path, extra: &[&str], env: &[(&str, &str)]) -> Output {
    let p = |n: &str| dir.join(n).display().to_string();
    let mut args: Vec<String> = [
        "--osm", MONACO, "--kb", KB, "--lod", "2", "--tile", TILE, "--quiet",
    ]
    .iter()
    .map(|s| s.to_string())
    .collect();
    args.extend([
        "--tiles3d".into(),
        p("3dtiles"),
        "--cityjsonseq".into(),
        p("m.city.jsonl"),
        "--gltf".into(),
        p("m.glb"),
        "--report".into(),
        p("report.json"),
    ]);
    args.extend(extra.iter().map(|s| s.to_string()));
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_citygen"));
    cmd.current_dir(root()).args(&args);
    for k in [
        "JOB_COMPLETION_INDEX",
        "SLURM_ARRAY_TASK_ID",
        "SLURM_ARRAY_TASK_MIN",
        "SLURM_ARRAY_TASK_MAX",
        "SLURM_ARRAY_TASK_COUNT",
    ] {
        cmd.env_remove(k);
    }
    cmd.envs(env.iter().copied());
    cmd.output().unwrap()
}

fn ok(out: &Output) {
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

/// The files of a folder (not the temporaries), by name.
fn files(dir: &Path) -> BTreeMap<String, Vec<u8>> {
    std::fs::read_dir(dir)
        .unwrap()
        .flatten()
        .map(|e| e.path())
        .filter(|p| p.is_file())
        .map(|p| {
            (
                p.file_name().unwrap().to_string_lossy().into_owned(),
                std::fs::read(&p).unwrap(),
            )
        })
        .collect()
}

/// Every building's digest over the manifests of a folder.
fn digests(dir: &Path) -> BTreeMap<String, String> {
    let mut all = BTreeMap::new();
    for (name, bytes) in files(dir) {
        if !name.starts_with("citygen-manifest.") {
            continue;
        }
        let m: serde_json::Value = serde_json::from_slice(&bytes).unwrap();
        for t in m["tiles"].as_array().unwrap() {
            for b in t["buildings"].as_array().unwrap() {
                let id = b["id"].as_str().unwrap().to_string();
                let d = b["digest"].as_str().unwrap().to_string();
                assert!(all.insert(id.clone(), d).is_none(), "{id} twice");
            }
        }
    }
    all
}

fn merge(dirs: &[&Path], extra: &[&str]) -> Output {
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_citygen"));
    cmd.current_dir(root()).arg("merge").args(dirs).args(extra);
    cmd.output().unwrap()
}

#[test]
fn three_shards_and_merge_give_the_single_run() {
    let single = tempfile::tempdir().unwrap();
    ok(&run_in(single.path(), &[], &[]));
    let sharded = tempfile::tempdir().unwrap();
    let s = sharded.path();
    // Shard 0 as a Kubernetes Indexed Job's pod, shard 1 as a Slurm array task (--array=0-2),
    // shard 2 by hand.
    let k8s = run_in(
        s,
        &["--shard", "auto", "--shards", "3"],
        &[("JOB_COMPLETION_INDEX", "0")],
    );
    ok(&k8s);
    let slurm = run_in(
        s,
        &["--shard", "auto"],
        &[
            ("SLURM_ARRAY_TASK_ID", "1"),
            ("SLURM_ARRAY_TASK_MIN", "0"),
            ("SLURM_ARRAY_TASK_MAX", "2"),
            ("SLURM_ARRAY_TASK_COUNT", "3"),
        ],
    );
    ok(&slurm);
    ok(&run_in(s, &["--shard", "2/3"], &[]));
    let m1: serde_json::Value =
        serde_json::from_slice(&std::fs::read(s.join("citygen-manifest.1-of-3.json")).unwrap())
            .unwrap();
    assert!(
        m1["shard_from"]
            .as_str()
            .unwrap()
            .contains("SLURM_ARRAY_TASK_ID=1")
            && m1["shard_from"]
                .as_str()
                .unwrap()
                .contains("SLURM_ARRAY_TASK_COUNT=3"),
        "{}",
        m1["shard_from"]
    );

    // Every tile file is the single run's, byte for byte, and every building's digest too.
    let one = files(single.path());
    let many = files(s);
    let tiles: Vec<&String> = one
        .keys()
        .filter(|n| n.starts_with("m_") && (n.ends_with(".glb") || n.ends_with(".jsonl")))
        .collect();
    assert!(tiles.len() > 10, "{} tile files", tiles.len());
    for n in &tiles {
        assert!(
            many.get(*n) == one.get(*n),
            "{n} differs from the single run's"
        );
    }
    let tile_files_sharded = many
        .keys()
        .filter(|n| n.starts_with("m_") && (n.ends_with(".glb") || n.ends_with(".jsonl")))
        .count();
    assert_eq!(tile_files_sharded, tiles.len());
    let (d1, dn) = (digests(single.path()), digests(s));
    assert!(d1.len() > 1000, "{} buildings", d1.len());
    assert_eq!(d1, dn);

    // Shards share the work: no shard holds more than half of it.
    for i in 0..3 {
        let m: serde_json::Value = serde_json::from_slice(
            &std::fs::read(s.join(format!("citygen-manifest.{i}-of-3.json"))).unwrap(),
        )
        .unwrap();
        let n: usize = m["tiles"]
            .as_array()
            .unwrap()
            .iter()
            .map(|t| t["buildings"].as_array().unwrap().len())
            .sum();
        assert!(n > 0 && n < d1.len() / 2, "shard {i}: {n} of {}", d1.len());
    }

    // The merge: the single run's report, and its buildings in one CityJSONSeq.
    let out = merge(
        &[s],
        &[
            "--report",
            &s.join("merged.json").display().to_string(),
            "--cityjsonseq",
            &s.join("region.city.jsonl").display().to_string(),
            "--tiles3d",
            &s.join("3dtiles").display().to_string(),
            "--preview",
            &s.join("region.png").display().to_string(),
        ],
    );
    ok(&out);
    // The region's tileset is the single run's, and so are its contents.
    let tileset = |d: &Path| std::fs::read(d.join("3dtiles/tileset.json")).unwrap();
    assert!(tileset(s) == tileset(single.path()));
    assert_eq!(
        files(&s.join("3dtiles/content")),
        files(&single.path().join("3dtiles/content"))
    );
    let png = std::fs::read(s.join("region.png")).unwrap();
    assert!(
        png.starts_with(b"\x89PNG") && png.len() > 50_000,
        "{} bytes",
        png.len()
    );
    let report = |p: PathBuf| -> serde_json::Value {
        serde_json::from_slice(&std::fs::read(p).unwrap()).unwrap()
    };
    assert_eq!(
        report(s.join("merged.json")),
        report(single.path().join("report.json"))
    );
    let region = std::fs::read_to_string(s.join("region.city.jsonl")).unwrap();
    let mut lines = region.lines();
    let header = lines.next().unwrap();
    assert!(header.contains("\"type\":\"CityJSON\"") && !header.contains(" tile "));
    let mut features: Vec<&str> = lines.collect();
    let mut single_features: Vec<String> = one
        .iter()
        .filter(|(n, _)| n.ends_with(".city.jsonl"))
        .flat_map(|(_, b)| {
            String::from_utf8(b.clone())
                .unwrap()
                .lines()
                .skip(1)
                .map(str::to_string)
                .collect::<Vec<_>>()
        })
        .collect();
    features.sort_unstable();
    single_features.sort_unstable();
    assert_eq!(features.len(), single_features.len());
    assert!(features.iter().zip(&single_features).all(|(a, b)| a == b));
}

#[test]
fn merge_refuses_a_set_that_does_not_add_up_and_names_why() {
    let a = tempfile::tempdir().unwrap();
    for i in 0..3 {
        ok(&run_in(a.path(), &["--shard", &format!("{i}/3")], &[]));
    }
    let err = |out: Output| {
        assert!(!out.status.success(), "the merge should have been refused");
        String::from_utf8_lossy(&out.stderr).into_owned()
    };
    // One shard missing.
    let b = tempfile::tempdir().unwrap();
    for i in [0, 2] {
        let n = format!("citygen-manifest.{i}-of-3.json");
        std::fs::copy(a.path().join(&n), b.path().join(&n)).unwrap();
    }
    let e = err(merge(&[b.path()], &[]));
    assert!(
        e.contains("shard 1 of 3 is missing") && e.contains("citygen-manifest.1-of-3.json"),
        "{e}"
    );
    // One shard twice (two folders with shard 2).
    let c = tempfile::tempdir().unwrap();
    let n2 = "citygen-manifest.2-of-3.json";
    std::fs::copy(a.path().join(n2), c.path().join(n2)).unwrap();
    let e = err(merge(&[a.path(), c.path()], &[]));
    assert!(e.contains("shard 2 of 3 is there twice"), "{e}");
    // One shard made with another seed.
    let d = tempfile::tempdir().unwrap();
    ok(&run_in(d.path(), &["--shard", "1/3", "--seed", "7"], &[]));
    let e = err(merge(&[b.path(), d.path()], &[]));
    assert!(e.contains("seed 7") && e.contains("seed 0"), "{e}");
    // A file changed after the shard wrote it.
    let tile = files(a.path())
        .into_keys()
        .find(|n| n.ends_with(".glb"))
        .unwrap();
    let mut bytes = std::fs::read(a.path().join(&tile)).unwrap();
    let last = bytes.len() - 1;
    bytes[last] ^= 1;
    std::fs::write(a.path().join(&tile), bytes).unwrap();
    let e = err(merge(&[a.path()], &[]));
    assert!(e.contains(&tile) && e.contains("SHA-256"), "{e}");
    // A damaged manifest (its grid gives a tile to a shard that does not exist): refused, no
    // panic.
    let e2 = tempfile::tempdir().unwrap();
    for i in 0..3 {
        let n = format!("citygen-manifest.{i}-of-3.json");
        let mut m: serde_json::Value =
            serde_json::from_slice(&std::fs::read(a.path().join(&n)).unwrap()).unwrap();
        m["grid"]["tiles"][0]["shard"] = serde_json::json!(99);
        std::fs::write(e2.path().join(&n), serde_json::to_vec(&m).unwrap()).unwrap();
    }
    let e = err(merge(&[e2.path()], &[]));
    assert!(e.contains("to shard 99") && e.contains("damaged"), "{e}");
    // Sharding needs tiles.
    let glb = d.path().join("x.glb").display().to_string();
    let out = citygen(&[
        "--osm", MONACO, "--kb", KB, "--shard", "0/2", "--gltf", &glb,
    ]);
    assert_eq!(out.status.code(), Some(2));
    let e = String::from_utf8_lossy(&out.stderr);
    assert!(e.contains("--shard needs --tile"), "{e}");
}

#[test]
fn a_shard_killed_mid_write_and_run_again_writes_the_same_bytes() {
    let dir = tempfile::tempdir().unwrap();
    let p = |n: &str| dir.path().join(n).display().to_string();
    // LOD3, so that the shard writes long enough to be caught writing; Monaco-Ville in 150 m
    // tiles (the whole city at LOD3 made this a minute and a half of the debug suite).
    let args = [
        "--osm",
        MONACO,
        "--kb",
        KB,
        "--lod",
        "3",
        "--bbox",
        "7.4180,43.7290,7.4240,43.7330",
        "--tile",
        "150",
        "--shard",
        "1/2",
        "--quiet",
        "--citygml",
        &p("k.gml"),
    ];
    let mut child = Command::new(env!("CARGO_BIN_EXE_citygen"))
        .current_dir(root())
        .args(args)
        .spawn()
        .unwrap();
    let start = Instant::now();
    loop {
        let writing = std::fs::read_dir(dir.path())
            .unwrap()
            .flatten()
            .any(|e| e.file_name().to_string_lossy().ends_with(".tmp"));
        if writing {
            break;
        }
        assert!(
            child.try_wait().unwrap().is_none(),
            "the shard ended before it could be killed"
        );
        assert!(start.elapsed() < Duration::from_secs(300));
        std::thread::sleep(Duration::from_millis(10));
    }
    child.kill().unwrap(); // SIGKILL
    child.wait().unwrap();
    let left = files(dir.path());
    assert!(
        left.keys()
            .all(|n| n.starts_with('.') && n.ends_with(".tmp")),
        "a killed shard published {:?}",
        left.keys().collect::<Vec<_>>()
    );
    // Run again, twice: the same bytes, and no temporary left.
    let out = Command::new(env!("CARGO_BIN_EXE_citygen"))
        .current_dir(root())
        .args(args)
        .output()
        .unwrap();
    ok(&out);
    let first = files(dir.path());
    assert!(
        first.keys().all(|n| !n.ends_with(".tmp")),
        "{:?}",
        first.keys()
    );
    assert!(first.contains_key("citygen-manifest.1-of-2.json"));
    let again = tempfile::tempdir().unwrap();
    let p2 = |n: &str| again.path().join(n).display().to_string();
    let mut args2: Vec<String> = args.iter().map(|s| s.to_string()).collect();
    let last = args2.len() - 1;
    args2[last] = p2("k.gml");
    ok(&Command::new(env!("CARGO_BIN_EXE_citygen"))
        .current_dir(root())
        .args(&args2)
        .output()
        .unwrap());
    let names = |m: &BTreeMap<String, Vec<u8>>| m.keys().cloned().collect::<Vec<_>>();
    let second = files(again.path());
    assert_eq!(names(&first), names(&second));
    for (n, b) in &first {
        assert!(second[n] == *b, "{n} differs between two runs of the shard");
    }
}
