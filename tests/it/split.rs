//! `citygen split` (issue 46): a shard run on its part of a split input writes the files and
//! manifest the same shard writes from the whole input, byte for byte, and the merge of the
//! parts' shards is the merge of the whole input's shards.

use crate::common::*;

use std::collections::BTreeMap;
use std::path::Path;
use std::process::{Command, Output};

fn ok(out: &Output) {
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

/// A shard of a tiled LOD2 run of `osm` writing into `dir`, with `extra` arguments.
fn shard_run(osm: &Path, dir: &Path, tile: &str, shard: &str, extra: &[&str]) -> Output {
    let p = |n: &str| dir.join(n).display().to_string();
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_citygen"));
    cmd.current_dir(root())
        .args([
            "--osm",
            &osm.display().to_string(),
            "--kb",
            KB,
            "--lod",
            "2",
        ])
        .args(["--tile", tile, "--shard", shard, "--quiet"])
        .args([
            "--tiles3d",
            &p("3dtiles"),
            "--cityjsonseq",
            &p("m.city.jsonl"),
        ])
        .args(["--gltf", &p("m.glb"), "--report", &p("report.json")])
        .args(extra);
    cmd.output().unwrap()
}

fn split(osm: &Path, out: &Path, tile: &str, n: usize, halo: &str) -> Output {
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_citygen"));
    cmd.current_dir(root())
        .args(["split", "--osm", &osm.display().to_string(), "--kb", KB])
        .args(["--tile", tile, "--shards", &n.to_string(), "--halo", halo])
        .args(["--out", &out.display().to_string()]);
    cmd.output().unwrap()
}

fn merge(dir: &Path, out: &Path) -> Output {
    let p = |n: &str| out.join(n).display().to_string();
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_citygen"));
    cmd.current_dir(root())
        .arg("merge")
        .arg(dir)
        .args([
            "--cityjsonseq",
            &p("region.city.jsonl"),
            "--report",
            &p("report.json"),
        ])
        .args(["--tiles3d", &dir.join("3dtiles").display().to_string()]);
    cmd.output().unwrap()
}

/// Shards `n` of `osm` from the whole input and from its parts (split with `halo`): the
/// files of the two folders (every tile, manifest, report, tileset), and of their merges.
fn whole_and_split(
    osm: &Path,
    tile: &str,
    n: usize,
    halo: &str,
    smaller: bool,
) -> [BTreeMap<String, Vec<u8>>; 2] {
    let whole = tempfile::tempdir().unwrap();
    let parts = tempfile::tempdir().unwrap();
    let cut = tempfile::tempdir().unwrap();
    ok(&split(osm, cut.path(), tile, n, halo));
    for i in 0..n {
        let s = format!("{i}/{n}");
        ok(&shard_run(osm, whole.path(), tile, &s, &[]));
        let part = cut.path().join(format!("part-{i}-of-{n}.osm.pbf"));
        let head = cut.path().join(format!("part-{i}-of-{n}.split.json"));
        if smaller {
            assert!(
                std::fs::metadata(&part).unwrap().len() < std::fs::metadata(osm).unwrap().len(),
                "part {i} is not smaller than the input"
            );
        }
        let h = head.display().to_string();
        ok(&shard_run(
            &part,
            parts.path(),
            tile,
            &s,
            &["--split-part", &h],
        ));
    }
    let merged = [tempfile::tempdir().unwrap(), tempfile::tempdir().unwrap()];
    ok(&merge(whole.path(), merged[0].path()));
    ok(&merge(parts.path(), merged[1].path()));
    let all = |d: &Path, m: &Path| {
        let mut f = files_under(d, |_| true);
        for (k, v) in files_under(m, |_| true) {
            f.insert(format!("merged/{k}"), v);
        }
        f
    };
    [
        all(whole.path(), merged[0].path()),
        all(parts.path(), merged[1].path()),
    ]
}

fn assert_same(a: &BTreeMap<String, Vec<u8>>, b: &BTreeMap<String, Vec<u8>>) {
    assert_eq!(
        a.keys().collect::<Vec<_>>(),
        b.keys().collect::<Vec<_>>(),
        "the same files"
    );
    let differ: Vec<&String> = a.keys().filter(|k| a[*k] != b[*k]).collect();
    assert!(differ.is_empty(), "files that differ: {differ:?}");
    assert!(a.keys().any(|k| k.starts_with("citygen-manifest.")));
    assert!(a.keys().any(|k| k.starts_with("merged/")));
}

#[test]
fn monaco_shards_on_their_parts_write_the_whole_inputs_bytes() {
    // Real data: streets (fronts), parts, multipolygons, admin boundaries (zones).
    let osm = root().join(MONACO);
    let [whole, parts] = whole_and_split(&osm, "250", 3, "1000", true);
    assert_same(&whole, &parts);
}

#[test]
fn synthetic_shards_on_their_parts_write_the_whole_inputs_bytes_and_need_the_halo() {
    let dir = tempfile::tempdir().unwrap();
    let osm = dir.path().join("tiled.osm.pbf");
    citygen::testkit::tiled::make_tiled(2500, &osm).unwrap();
    let [whole, parts] = whole_and_split(&osm, "300", 4, "1000", false);
    assert_same(&whole, &parts);
    // Without a halo the buildings at a tile's edge lose the neighbours they take heights
    // and rows from: some file differs.
    let [whole, bare] = whole_and_split(&osm, "300", 4, "0", true);
    assert!(
        whole.keys().any(|k| bare.get(k) != whole.get(k)),
        "a split without a halo should change some building"
    );
}
