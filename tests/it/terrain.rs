//! The terrain written beside the buildings (issue 44), through the library's run: a run
//! given an elevation grid (`Options::ground_fn`: there is no `--dem` yet) writes a terrain in
//! every format, per tile when tiled (and through shards and `merge`), the same bytes at 1 and
//! 2 threads (the files through the reference validators: .ci/run's samples on the SRTM crop,
//! and the merged tileset here); `--no-terrain` writes the files of
//! a run without a grid.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use crate::common::*;
use citygen::pipeline::terrain::GroundFn;
use citygen::pipeline::{self, Options, Source};

/// Monaco's slope in UTM 32N metres: a rise inland, waves, a 6 m cliff every 700 m of
/// easting, and holes without data (20 m discs) on a 900 m lattice.
fn monaco_ground(e: f64, n: f64) -> f64 {
    let (de, dn) = ((e % 900.0) - 450.0, (n % 900.0) - 450.0);
    if de * de + dn * dn < 400.0 {
        return f64::NAN;
    }
    let rise = 0.04 * (n - 4_843_000.0);
    let waves = 12.0 * (e / 250.0).sin() * (n / 310.0).cos();
    let cliff = if e % 700.0 > 350.0 { 6.0 } else { 0.0 };
    40.0 + rise + waves + cliff
}

fn ground() -> GroundFn {
    GroundFn {
        step: 2.0,
        height: Arc::new(monaco_ground),
    }
}

/// A Monaco run at LOD2 into `dir`, every format.
fn opts(dir: &Path, tile: Option<u32>, ground: Option<GroundFn>) -> Options {
    let p = |n: &str| Some(dir.join(n));
    Options {
        source: Source::Osm(root().join(MONACO)),
        kb: Some(root().join(KB)),
        rules: None,
        lod: citygen::model::Lod::Lod2,
        ifc: p("m.ifc"),
        ifc_schema: Default::default(),
        ifc_max_bytes: None,
        citygml: p("m.gml"),
        gltf: p("m.glb"),
        cityjson: p("m.city.json"),
        cityjsonseq: p("m.city.jsonl"),
        report: None,
        preview: None,
        tiles3d: p("tiles"),
        seed: 0,
        crs: None,
        src_crs: None,
        caps: Default::default(),
        bbox: None,
        tile,
        dry_run: false,
        textures: false,
        force_extension: false,
        allow_empty: false,
        infer: None,
        shard: None,
        previous: None,
        link_previous: false,
        osc: None,
        source_name: Some("monaco".into()),
        terrain_tolerance: 0.5,
        no_terrain: false,
        ground_fn: ground,
        split_part: None,
        dem: Vec::new(),
        ground_height: None,
    }
}

/// Every file below `dir`, by relative path, with its bytes.
fn files(dir: &Path) -> Vec<(PathBuf, Vec<u8>)> {
    let mut out = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                stack.push(p);
            } else {
                let rel = p.strip_prefix(dir).unwrap().to_path_buf();
                out.push((rel, std::fs::read(&p).unwrap()));
            }
        }
    }
    out.sort();
    out
}

fn run_in(threads: usize, o: &Options) {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap();
    pool.install(|| pipeline::run(o, &|_, _| {})).unwrap();
}

#[test]
fn tiles_carry_their_terrain_in_every_format_the_same_at_one_and_two_threads() {
    let (a, b) = (tempfile::tempdir().unwrap(), tempfile::tempdir().unwrap());
    run_in(1, &opts(a.path(), Some(500), Some(ground())));
    run_in(2, &opts(b.path(), Some(500), Some(ground())));
    let (fa, fb) = (files(a.path()), files(b.path()));
    assert_eq!(
        fa.iter().map(|f| &f.0).collect::<Vec<_>>(),
        fb.iter().map(|f| &f.0).collect::<Vec<_>>()
    );
    for ((p, x), (_, y)) in fa.iter().zip(&fb) {
        assert!(x == y, "{} differs between 1 and 2 threads", p.display());
    }
    let name = |f: &(PathBuf, Vec<u8>)| f.0.to_string_lossy().into_owned();
    let jsons: Vec<_> = fa
        .iter()
        .filter(|f| name(f).ends_with(".city.json"))
        .collect();
    assert!(jsons.len() >= 4, "{} tiles", jsons.len());
    for f in &jsons {
        let doc: serde_json::Value = serde_json::from_slice(&f.1).unwrap();
        let reliefs = doc["CityObjects"]
            .as_object()
            .unwrap()
            .values()
            .filter(|o| o["type"] == "TINRelief")
            .count();
        assert_eq!(reliefs, 1, "{}", name(f));
    }
    let terrain_contents = fa
        .iter()
        .filter(|f| name(f).ends_with("-terrain.glb"))
        .count();
    assert_eq!(terrain_contents, jsons.len());
    let tileset = String::from_utf8(
        fa.iter()
            .find(|f| name(f).ends_with("tileset.json"))
            .unwrap()
            .1
            .clone(),
    )
    .unwrap();
    assert_eq!(
        tileset.matches("-terrain.glb").count(),
        2 * terrain_contents,
        "each tile's terrain beside its Blocks and its Full"
    );
    for f in fa.iter().filter(|f| name(f).ends_with(".gml")) {
        let t = String::from_utf8_lossy(&f.1);
        assert_eq!(t.matches("<dem:ReliefFeature ").count(), 1);
    }
    for f in fa.iter().filter(|f| name(f).ends_with(".ifc")) {
        let t = String::from_utf8_lossy(&f.1);
        assert_eq!(t.matches("=IFCGEOGRAPHICELEMENT(").count(), 1);
    }
}

#[test]
fn without_terrain_the_files_are_those_of_a_run_without_a_grid() {
    let (a, b) = (tempfile::tempdir().unwrap(), tempfile::tempdir().unwrap());
    let mut off = opts(a.path(), Some(500), Some(ground()));
    off.no_terrain = true;
    run_in(2, &off);
    run_in(2, &opts(b.path(), Some(500), None));
    let (fa, fb) = (files(a.path()), files(b.path()));
    assert_eq!(fa.len(), fb.len());
    for ((p, x), (_, y)) in fa.iter().zip(&fb) {
        assert!(x == y, "{} differs", p.display());
    }
    assert!(fa
        .iter()
        .all(|f| !f.0.to_string_lossy().contains("terrain")));
}

/// Fontvieille and Monaco-Ville (lon, lat).
const SOUTH_WEST: [f64; 4] = [7.4120, 43.7265, 7.4240, 43.7330];

#[test]
fn shards_merge_with_their_terrain() {
    let dir = tempfile::tempdir().unwrap();
    for i in 0..2 {
        let mut o = opts(dir.path(), Some(500), Some(ground()));
        // Fontvieille and Monaco-Ville, on six tiles of 500 m: the whole city's merged
        // CityJSONSeq, a terrain per tile, took cjval eight minutes.
        o.bbox = Some(SOUTH_WEST);
        o.shard = Some((
            citygen::pipeline::shard::Shard { index: i, count: 2 },
            format!("--shard {}/2", i + 1),
        ));
        run_in(2, &o);
    }
    let merged = dir.path().join("merged");
    pipeline::merge::merge(&pipeline::merge::MergeOptions {
        dirs: vec![dir.path().to_path_buf()],
        report: None,
        cityjsonseq: Some(merged.join("all.city.jsonl")),
        tiles3d: Some(merged.clone()),
        preview: None,
        verify: true,
    })
    .unwrap();
    let tileset = std::fs::read_to_string(merged.join("tileset.json")).unwrap();
    let terrains = std::fs::read_dir(dir.path().join("tiles/content"))
        .unwrap()
        .filter(|e| {
            e.as_ref()
                .unwrap()
                .file_name()
                .to_string_lossy()
                .ends_with("-terrain.glb")
        })
        .count();
    assert!(terrains >= 4);
    assert_eq!(tileset.matches("-terrain.glb").count(), 2 * terrains);
    let seq = std::fs::read_to_string(merged.join("all.city.jsonl")).unwrap();
    assert_eq!(seq.matches("\"type\":\"TINRelief\"").count(), terrains);
    if let Some(tool) = citygen::testkit::validators::validate_outputs("merged terrain tileset") {
        let out = std::process::Command::new(tool)
            .arg(merged.join("tileset.json"))
            .arg(merged.join("all.city.jsonl"))
            .output()
            .unwrap();
        let text = String::from_utf8_lossy(&out.stdout);
        assert!(
            out.status.success(),
            "{text}{}",
            String::from_utf8_lossy(&out.stderr)
        );
    }
}

// An untiled run with terrain through every validator (IFC with --geometry, CityGML, glTF,
// CityJSON, CityJSONSeq, 3D Tiles) is .ci/run's `monaco-ville-lod3` sample and its
// `region-ville-lod3` shards, both drawn on the SRTM crop; here it cost minutes of `cargo test`.
