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
    citygen::testkit::tiled::make_tiled(1200, &osm).unwrap();
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

/// The attributes of building `key` in the CityJSONSeq tiles of `files`, if one holds it.
fn attributes_of(files: &BTreeMap<String, Vec<u8>>, key: &str) -> Option<serde_json::Value> {
    files
        .iter()
        .filter(|(name, _)| name.ends_with(".city.jsonl"))
        .flat_map(|(_, bytes)| {
            String::from_utf8_lossy(bytes)
                .lines()
                .map(str::to_string)
                .collect::<Vec<_>>()
        })
        .filter_map(|line| serde_json::from_str::<serde_json::Value>(&line).ok())
        .find_map(|f| f["CityObjects"].get(key).map(|o| o["attributes"].clone()))
}

/// A square building: its way id, how far east of the meridian it starts (metres), its tags.
type Square = (i64, f64, Vec<(&'static str, &'static str)>);

#[test]
fn a_buildings_storeys_from_tagged_neighbours_across_the_shard_border_are_the_whole_inputs() {
    // UTM 32's central meridian (longitude 9) is the easting 500,000: a border of the
    // 500 m tile grid. West of it, in one tile, building 1 (untagged) 20 m from the border and
    // building 2 (untagged) 300 m from it; east of it, in the next tile, eight buildings
    // tagged with 9 storeys: building 1's only tagged neighbours, in another shard's tile.
    let dir = tempfile::tempdir().unwrap();
    let osm = dir.path().join("border.osm.pbf");
    let utm = citygen::crs::Crs::from_epsg_str("EPSG:32632").unwrap();
    let (_, y0) = utm.from_lonlat(9.0, 45.0);
    let tile = 500.0;
    // The middle of the tile row, so that every building lies in one row of tiles.
    let lat = 45.0 + ((y0 / tile).floor() * tile + tile / 2.0 - y0) / 111_132.0;
    let lon = |east_m: f64| 9.0 + east_m / (111_320.0 * 45f64.to_radians().cos());
    let squares: Vec<Square> = [(1, -30.0, vec![]), (2, -310.0, vec![])]
        .into_iter()
        .chain((0..8).map(|k| {
            (
                3 + k,
                15.0 + 25.0 * k as f64,
                vec![("building:levels", "9")],
            )
        }))
        .collect();
    let mut w =
        citygen::input::osm::pbf_write::PbfWriter::new(std::fs::File::create(&osm).unwrap())
            .unwrap();
    let corners = |x0: f64| {
        [(0.0, 0.0), (12.0, 0.0), (12.0, 12.0), (0.0, 12.0)]
            .map(|(dx, dy)| (lon(x0 + dx), lat + dy / 111_132.0))
    };
    for (id, x0, _) in &squares {
        for (k, (lo, la)) in corners(*x0).into_iter().enumerate() {
            w.node(id * 10 + k as i64, lo, la, &[]).unwrap();
        }
    }
    for (id, _, tags) in &squares {
        let refs: Vec<i64> = (0..4).chain([0]).map(|k| id * 10 + k).collect();
        let mut t = vec![("building", "yes")];
        t.extend(tags.iter().copied());
        w.way(*id, &refs, &t).unwrap();
    }
    w.finish().unwrap();

    let n = 2;
    let [whole, near, bare] = [(); 3].map(|_| tempfile::tempdir().unwrap());
    let cut = [tempfile::tempdir().unwrap(), tempfile::tempdir().unwrap()];
    ok(&split(
        &osm,
        cut[0].path(),
        "500",
        n,
        &citygen::pipeline::split::DEFAULT_HALO_M.to_string(),
    ));
    ok(&split(&osm, cut[1].path(), "500", n, "0"));
    let mut shard_of_1 = None;
    for i in 0..n {
        let s = format!("{i}/{n}");
        let w_dir = whole.path().join(i.to_string());
        ok(&shard_run(&osm, &w_dir, "500", &s, &[]));
        for (out, c) in [(&near, &cut[0]), (&bare, &cut[1])] {
            let part = c.path().join(format!("part-{i}-of-{n}.osm.pbf"));
            let head = c.path().join(format!("part-{i}-of-{n}.split.json"));
            let h = head.display().to_string();
            ok(&shard_run(
                &part,
                &out.path().join(i.to_string()),
                "500",
                &s,
                &["--split-part", &h],
            ));
        }
        if attributes_of(&files_under(&w_dir, |_| true), "B_way_1").is_some() {
            shard_of_1 = Some(i);
        }
    }
    let i = shard_of_1.expect("building 1 is written by a shard");
    let files = |d: &Path| files_under(&d.join(i.to_string()), |_| true);
    let (whole, near, bare) = (files(whole.path()), files(near.path()), files(bare.path()));
    assert!(
        attributes_of(&whole, "B_way_3").is_none(),
        "the tagged buildings are another shard's"
    );
    let a = attributes_of(&whole, "B_way_1").unwrap();
    assert_eq!(a["storeysSource"], "neighbours", "{a}");
    let storeys = a["storeysAboveGround"].as_f64().unwrap();
    assert!(
        storeys >= 5.0,
        "building 1 takes its tagged neighbours' storeys: {a}"
    );
    // On its part (with the halo) the shard writes the whole input's bytes; without a halo
    // building 1 has no tagged neighbour and other storeys.
    assert_eq!(
        whole.keys().collect::<Vec<_>>(),
        near.keys().collect::<Vec<_>>()
    );
    let differ: Vec<&String> = whole.keys().filter(|k| whole[*k] != near[*k]).collect();
    assert!(differ.is_empty(), "files that differ: {differ:?}");
    let b = attributes_of(&bare, "B_way_1").unwrap();
    assert_ne!(b["storeysAboveGround"], a["storeysAboveGround"], "{b}");
}
