//! Nightly, incremental runs (issue 25) on synthetic towns written in code: a building's bytes
//! do not depend on the buildings around it that it does not touch, and `--previous` gives the
//! bytes of a full run while copying every tile without an edit, with the exact list of
//! buildings added, removed and changed. The 100k-building version is `scripts/nightly-check`.

use crate::common;
use crate::common::*;

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

use citygen::testkit::pbf_write::PbfWriter;

/// One building of a synthetic town: way id, centre (metres east and north of the town's
/// corner), size (metres), tags.
#[derive(Clone)]
struct B {
    id: i64,
    at: (f64, f64),
    size: (f64, f64),
    tags: Vec<(&'static str, String)>,
}

const LON0: f64 = 7.4200;
const LAT0: f64 = 43.7300;

fn lonlat(x: f64, y: f64) -> (f64, f64) {
    let m_lat = 111_132.0;
    let m_lon = m_lat * LAT0.to_radians().cos();
    (LON0 + x / m_lon, LAT0 + y / m_lat)
}

/// A town of `n` × `n` fully tagged buildings (so that `--infer` lends them nothing), 24 m
/// apart; ids 1000 + k.
fn town(n: usize) -> Vec<B> {
    let mut out = Vec::new();
    for j in 0..n {
        for i in 0..n {
            let k = (j * n + i) as i64;
            out.push(B {
                id: 1000 + k,
                at: (i as f64 * 24.0 + 12.0, j as f64 * 24.0 + 12.0),
                size: (10.0 + (k % 5) as f64, 8.0 + (k % 3) as f64),
                tags: vec![
                    ("building", "house".into()),
                    ("building:levels", (2 + k % 4).to_string()),
                    (
                        "roof:shape",
                        ["gabled", "hipped", "flat"][k as usize % 3].into(),
                    ),
                    ("building:colour", "#d8c8a8".into()),
                    ("roof:colour", "#a05030".into()),
                ],
            });
        }
    }
    out
}

/// Writes `town` as an OSM PBF (nodes 4 per building, ids from the way id).
fn write_pbf(path: &Path, town: &[B]) {
    std::fs::create_dir_all(path.parent().unwrap()).unwrap();
    let mut w = PbfWriter::new(std::fs::File::create(path).unwrap()).unwrap();
    let mut bs = town.to_vec();
    bs.sort_by_key(|b| b.id);
    for b in &bs {
        let (hx, hy) = (b.size.0 / 2.0, b.size.1 / 2.0);
        let corners = [(-hx, -hy), (hx, -hy), (hx, hy), (-hx, hy)];
        for (c, (dx, dy)) in corners.iter().enumerate() {
            let (lon, lat) = lonlat(b.at.0 + dx, b.at.1 + dy);
            w.node(b.id * 10 + c as i64, lon, lat, &[]).unwrap();
        }
    }
    for b in &bs {
        let refs: Vec<i64> = (0..4).chain([0]).map(|c| b.id * 10 + c).collect();
        let tags: Vec<(&str, &str)> = b.tags.iter().map(|(k, v)| (*k, v.as_str())).collect();
        w.way(b.id, &refs, &tags).unwrap();
    }
    w.finish().unwrap();
}

fn run(input: &Path, out: &Path, lod: &str, tile: &str, extra: &[&str]) {
    run_kb(input, out, lod, tile, KB, extra)
}

/// [`run`] with knowledge base `kb`.
fn run_kb(input: &Path, out: &Path, lod: &str, tile: &str, kb: &str, extra: &[&str]) {
    let o = citygen_timed(&args(input, out, (lod, tile, kb), "report.json", extra));
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}

/// The arguments of a run of `input` into folder `out` (CityJSONSeq, IFC, glTF, 3D Tiles, the
/// report `report`) at (LOD, tile size, knowledge base), then `extra`.
fn args(
    input: &Path,
    out: &Path,
    (lod, tile, kb): (&str, &str, &str),
    report: &str,
    extra: &[&str],
) -> Vec<String> {
    let p = |n: &str| out.join(n).display().to_string();
    let mut args: Vec<String> = [
        "--osm",
        &input.display().to_string(),
        "--kb",
        kb,
        "--lod",
        lod,
        "--tile",
        tile,
        "--quiet",
    ]
    .iter()
    .map(|s| s.to_string())
    .collect();
    args.extend(
        [
            "--cityjsonseq",
            &p("t.city.jsonl"),
            "--ifc",
            &p("t.ifc"),
            "--gltf",
            &p("t.glb"),
            "--tiles3d",
            &p("3d"),
            "--report",
            &p(report),
        ]
        .iter()
        .map(|s| s.to_string()),
    );
    args.extend(extra.iter().map(|s| s.to_string()));
    args
}

/// Runs citygen with `args` from the repository root, killed and failed after 300 s: a run
/// that hangs (on a named pipe) fails the test instead of blocking it.
fn citygen_timed(args: &[String]) -> std::process::Output {
    use std::io::Read as _;
    let tmp = tempfile::tempdir().unwrap();
    let (out, err) = (tmp.path().join("out"), tmp.path().join("err"));
    let mut child = std::process::Command::new(env!("CARGO_BIN_EXE_citygen"))
        .current_dir(common::root())
        .args(args)
        .stdin(std::process::Stdio::null())
        .stdout(std::fs::File::create(&out).unwrap())
        .stderr(std::fs::File::create(&err).unwrap())
        .spawn()
        .unwrap();
    let start = std::time::Instant::now();
    let status = loop {
        if let Some(s) = child.try_wait().unwrap() {
            break s;
        }
        if start.elapsed() > std::time::Duration::from_secs(300) {
            let _ = child.kill();
            let _ = child.wait();
            panic!("citygen {args:?} did not finish in 300 s (a hang)");
        }
        std::thread::sleep(std::time::Duration::from_millis(50));
    };
    let read = |p: &Path| {
        let mut v = Vec::new();
        std::fs::File::open(p).unwrap().read_to_end(&mut v).unwrap();
        v
    };
    std::process::Output {
        status,
        stdout: read(&out),
        stderr: read(&err),
    }
}

/// Every file under `dir` (relative path → bytes), the report and manifests left out.
fn files(dir: &Path) -> BTreeMap<String, Vec<u8>> {
    common::files_under(dir, |rel| {
        rel != "report.json" && !rel.starts_with("citygen-manifest.")
    })
}

fn manifest(dir: &Path) -> serde_json::Value {
    serde_json::from_slice(&std::fs::read(dir.join("citygen-manifest.0-of-1.json")).unwrap())
        .unwrap()
}

/// A building's CityJSONSeq feature line (its own vertices: no other building's bytes in it),
/// its digest and its keys, from a run's folder.
fn building(dir: &Path, id: &str) -> (String, String, String, String) {
    let m = manifest(dir);
    let mut found = None;
    for t in m["tiles"].as_array().unwrap() {
        let digest = t["buildings"]
            .as_array()
            .unwrap()
            .iter()
            .find(|b| b["id"] == id)
            .map(|b| b["digest"].as_str().unwrap().to_string());
        let Some(digest) = digest else { continue };
        let lot = t["lots"]
            .as_array()
            .unwrap()
            .iter()
            .find(|l| l["id"] == id)
            .unwrap()
            .clone();
        let file = dir.join(format!("t_{}.city.jsonl", t["suffix"].as_str().unwrap()));
        let text = std::fs::read_to_string(file).unwrap();
        let line = text
            .lines()
            .find(|l| l.contains(&format!("\"sourceId\":\"{id}\"")))
            .unwrap_or_else(|| panic!("{id} not in its tile's CityJSONSeq"))
            .to_string();
        found = Some((
            line,
            digest,
            lot["own"].as_str().unwrap().to_string(),
            lot["key"].as_str().unwrap().to_string(),
        ));
    }
    found.unwrap_or_else(|| panic!("{id} is in no tile"))
}

fn changes(dir: &Path) -> serde_json::Value {
    let r: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.join("report.json")).unwrap()).unwrap();
    r["changes"].clone()
}

fn ids(v: &serde_json::Value) -> BTreeSet<String> {
    v.as_array()
        .unwrap()
        .iter()
        .map(|s| s.as_str().unwrap().to_string())
        .collect()
}

#[test]
fn a_buildings_bytes_do_not_depend_on_the_buildings_it_does_not_touch() {
    let tmp = tempfile::tempdir().unwrap();
    let t = tmp.path();
    let day1 = town(6);
    // Building 1014 (row 2, column 2); a new one 4 m east of it (not touching), and one far
    // away removed (before it in the file, so that its place in the file moves too).
    let target = day1.iter().find(|b| b.id == 1014).unwrap().clone();
    let mut day2: Vec<B> = day1.iter().filter(|b| b.id != 1003).cloned().collect();
    day2.push(B {
        id: 5000,
        at: (target.at.0 + target.size.0 / 2.0 + 4.0 + 2.0, target.at.1),
        size: (4.0, 6.0),
        tags: vec![("building", "shed".into()), ("building:levels", "1".into())],
    });
    for lod in ["2", "3"] {
        let (a, b) = (t.join(format!("a{lod}")), t.join(format!("b{lod}")));
        // The same file name both days: the input's name is written into the files.
        write_pbf(&a.join("in/town.osm.pbf"), &day1);
        write_pbf(&b.join("in/town.osm.pbf"), &day2);
        // Tiles of 1 km: everything in one tile, so the tile's files change and only the
        // building's own bytes can be compared.
        run(&a.join("in/town.osm.pbf"), &a.join("out"), lod, "1000", &[]);
        run(&b.join("in/town.osm.pbf"), &b.join("out"), lod, "1000", &[]);
        let (x, y) = (
            building(&a.join("out"), "way/1014"),
            building(&b.join("out"), "way/1014"),
        );
        assert_eq!(x.0, y.0, "LOD{lod}: way/1014's CityJSONSeq feature changed");
        assert_eq!(x.1, y.1, "LOD{lod}: way/1014's geometry digest changed");
        assert_eq!(x.2, y.2, "LOD{lod}: way/1014's own key changed");
        assert_eq!(x.3, y.3, "LOD{lod}: way/1014's content key changed");
        let c = changes_between(&a.join("out"), &b.join("out"));
        assert_eq!(c, (vec!["way/5000".into()], vec!["way/1003".into()]));
    }
    // At LOD3 a building that touches it does count (its party wall): the key says so.
    let mut day3 = day1.clone();
    day3.push(B {
        id: 6000,
        at: (target.at.0 + target.size.0 / 2.0 + 2.0, target.at.1),
        size: (4.0, 6.0),
        tags: vec![
            ("building", "house".into()),
            ("building:levels", "3".into()),
        ],
    });
    let c = t.join("c3");
    write_pbf(&c.join("in/town.osm.pbf"), &day3);
    run(&c.join("in/town.osm.pbf"), &c.join("out"), "3", "1000", &[]);
    let (x, z) = (
        building(&t.join("a3/out"), "way/1014"),
        building(&c.join("out"), "way/1014"),
    );
    assert_eq!(x.2, z.2, "the own key is the building's alone");
    assert_ne!(
        x.3, z.3,
        "a touching neighbour is in the content key at LOD3"
    );
}

/// The suffix of the tile holding lot `id` in a run's manifest.
fn tile_of(dir: &Path, id: &str) -> String {
    manifest(dir)["tiles"]
        .as_array()
        .unwrap()
        .iter()
        .find(|t| t["lots"].as_array().unwrap().iter().any(|l| l["id"] == id))
        .map(|t| t["suffix"].as_str().unwrap().to_string())
        .unwrap()
}

/// Added and removed ids between two runs' manifests.
fn changes_between(a: &Path, b: &Path) -> (Vec<String>, Vec<String>) {
    let lots = |d: &Path| -> BTreeSet<String> {
        manifest(d)["tiles"]
            .as_array()
            .unwrap()
            .iter()
            .flat_map(|t| t["lots"].as_array().unwrap().clone())
            .map(|l| l["id"].as_str().unwrap().to_string())
            .collect()
    };
    let (x, y) = (lots(a), lots(b));
    (
        y.difference(&x).cloned().collect(),
        x.difference(&y).cloned().collect(),
    )
}

/// Day 1 and day 2 of a town of 100 buildings in 50 m tiles; day 2 edits: tags of way/1011,
/// geometry and tags of way/1047 (moved 0.6 m), way/1090 removed, way/7000 added in a gap.
fn two_days(t: &Path) -> (PathBuf, PathBuf, PathBuf) {
    let day1 = town(10);
    let mut day2: Vec<B> = day1.iter().filter(|b| b.id != 1090).cloned().collect();
    for b in &mut day2 {
        if b.id == 1011 {
            b.tags[1].1 = "7".into();
        }
        if b.id == 1047 {
            b.at.0 += 0.6;
            b.tags[2].1 = "pyramidal".into();
        }
    }
    day2.push(B {
        id: 7000,
        at: (24.0 * 5.0, 24.0 * 5.0),
        size: (5.0, 5.0),
        tags: vec![
            ("building", "kiosk".into()),
            ("building:levels", "1".into()),
        ],
    });
    let (d1, d2) = (t.join("day1/town.osm.pbf"), t.join("day2/town.osm.pbf"));
    write_pbf(&d1, &day1);
    write_pbf(&d2, &day2);
    let osc = t.join("day2/changes.osc.gz");
    write_osc(&osc, &day1, &day2);
    (d1, d2, osc)
}

/// The osmChange (gzipped) that turns `day1` into `day2` as [`write_pbf`] writes them.
fn write_osc(path: &Path, day1: &[B], day2: &[B]) {
    use std::fmt::Write as _;
    let esc = |v: &str| {
        v.replace('&', "&amp;")
            .replace('<', "&lt;")
            .replace('"', "&quot;")
    };
    let element = |out: &mut String, b: &B, nodes_too: bool| {
        if nodes_too {
            let (hx, hy) = (b.size.0 / 2.0, b.size.1 / 2.0);
            for (c, (dx, dy)) in [(-hx, -hy), (hx, -hy), (hx, hy), (-hx, hy)]
                .iter()
                .enumerate()
            {
                let (lon, lat) = lonlat(b.at.0 + dx, b.at.1 + dy);
                let _ = writeln!(
                    out,
                    r#"  <node id="{}" version="2" lat="{lat:.7}" lon="{lon:.7}"/>"#,
                    b.id * 10 + c as i64
                );
            }
        }
        let _ = writeln!(out, r#"  <way id="{}" version="2">"#, b.id);
        for c in (0..4).chain([0]) {
            let _ = writeln!(out, r#"   <nd ref="{}"/>"#, b.id * 10 + c);
        }
        for (k, v) in &b.tags {
            let _ = writeln!(out, r#"   <tag k="{k}" v="{}"/>"#, esc(v));
        }
        out.push_str("  </way>\n");
    };
    let old: BTreeMap<i64, &B> = day1.iter().map(|b| (b.id, b)).collect();
    let new: BTreeMap<i64, &B> = day2.iter().map(|b| (b.id, b)).collect();
    let mut x = String::from(
        "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<osmChange version=\"0.6\" generator=\"citygen tests\">\n",
    );
    x.push_str(" <create>\n");
    for b in new.values().filter(|b| !old.contains_key(&b.id)) {
        element(&mut x, b, true);
    }
    x.push_str(" </create>\n <modify>\n");
    for b in new.values() {
        if let Some(a) = old.get(&b.id) {
            let moved = a.at != b.at || a.size != b.size;
            if moved || a.tags != b.tags {
                element(&mut x, b, moved);
            }
        }
    }
    x.push_str(" </modify>\n <delete>\n");
    for a in old.values().filter(|a| !new.contains_key(&a.id)) {
        let _ = writeln!(x, r#"  <way id="{}" version="2"/>"#, a.id);
        for c in 0..4 {
            let _ = writeln!(x, r#"  <node id="{}" version="2"/>"#, a.id * 10 + c);
        }
    }
    x.push_str(" </delete>\n</osmChange>\n");
    let mut gz = flate2::write::GzEncoder::new(
        std::fs::File::create(path).unwrap(),
        flate2::Compression::default(),
    );
    std::io::Write::write_all(&mut gz, x.as_bytes()).unwrap();
    gz.finish().unwrap();
}

#[test]
fn previous_reuses_the_unchanged_tiles_and_gives_the_full_runs_bytes() {
    let tmp = tempfile::tempdir().unwrap();
    let t = tmp.path();
    let (d1, d2, osc) = two_days(t);
    let (o1, full, inc) = (t.join("o1"), t.join("full2"), t.join("inc2"));
    run(&d1, &o1, "2", "50", &[]);
    run(&d2, &full, "2", "50", &[]);
    run(&d2, &inc, "2", "50", &["--previous", o1.to_str().unwrap()]);
    let (f1, ff, fi) = (files(&o1), files(&full), files(&inc));
    assert_eq!(
        ff.keys().collect::<Vec<_>>(),
        fi.keys().collect::<Vec<_>>(),
        "the same files"
    );
    for (name, bytes) in &ff {
        assert!(
            fi[name] == *bytes,
            "{name}: the incremental run's bytes differ"
        );
    }
    // The report is the full run's, but for the changes.
    let report = |d: &Path| {
        let mut r: serde_json::Value =
            serde_json::from_slice(&std::fs::read(d.join("report.json")).unwrap()).unwrap();
        r.as_object_mut().unwrap().remove("changes");
        r
    };
    assert_eq!(report(&full), report(&inc));
    let c = changes(&inc);
    assert_eq!(ids(&c["added"]), ["way/7000".to_string()].into());
    assert_eq!(ids(&c["removed"]), ["way/1090".to_string()].into());
    assert_eq!(
        ids(&c["changed"]),
        ["way/1011".to_string(), "way/1047".to_string()].into()
    );
    assert_eq!(ids(&c["affected"]), BTreeSet::new());
    // The tiles rewritten are those of the edited buildings; every other tile kept its bytes.
    let edited: BTreeSet<String> = [
        tile_of(&inc, "way/1011"),
        tile_of(&inc, "way/1047"),
        tile_of(&o1, "way/1090"),
        tile_of(&inc, "way/7000"),
    ]
    .into();
    assert_eq!(ids(&c["tiles_rewritten"]), edited);
    let tiles = manifest(&inc)["tiles"].as_array().unwrap().len();
    assert_eq!(
        c["tiles_reused"].as_u64().unwrap() as usize,
        tiles - edited.len()
    );
    let mut kept = 0;
    for (name, bytes) in &fi {
        if name.ends_with("tileset.json") {
            continue;
        }
        if edited.iter().any(|s| of_tile(name, s)) {
            assert!(
                f1.get(name) != Some(bytes),
                "{name}: an edited tile kept its bytes"
            );
        } else {
            assert!(
                f1.get(name) == Some(bytes),
                "{name}: an unchanged tile changed"
            );
            kept += 1;
        }
    }
    assert!(kept >= 4 * (tiles - edited.len()), "{kept} files kept");
    // Day 1's extract with the change file on top: the same run.
    let with_osc = t.join("osc2");
    run(
        &d1,
        &with_osc,
        "2",
        "50",
        &[
            "--osc",
            osc.to_str().unwrap(),
            "--previous",
            o1.to_str().unwrap(),
        ],
    );
    assert!(
        files(&with_osc) == ff,
        "--osc: the files differ from the full run's"
    );
    assert_eq!(changes(&with_osc)["changed"], c["changed"]);
    assert_eq!(changes(&with_osc)["added"], c["added"]);
    assert_eq!(changes(&with_osc)["removed"], c["removed"]);
    // The region's merge is the full run's too.
    let merged = |d: &Path| {
        let seq = d.join("region.city.jsonl");
        let o = citygen(&[
            "merge",
            d.to_str().unwrap(),
            "--cityjsonseq",
            seq.to_str().unwrap(),
            "--quiet",
        ]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        std::fs::read(seq).unwrap()
    };
    assert!(
        merged(&full) == merged(&inc),
        "the merged CityJSONSeq differs"
    );
    // A previous file damaged: its tile is derived again, still the full run's bytes.
    let victim = o1.join(
        fi.keys()
            .find(|n| n.ends_with(".ifc") && !edited.iter().any(|s| of_tile(n, s)))
            .unwrap(),
    );
    let mut bytes = std::fs::read(&victim).unwrap();
    bytes[100] ^= 1;
    std::fs::write(&victim, bytes).unwrap();
    let inc3 = t.join("inc3");
    run(&d2, &inc3, "2", "50", &["--previous", o1.to_str().unwrap()]);
    assert!(files(&inc3) == ff, "after a damaged previous file");
    assert_eq!(
        changes(&inc3)["tiles_rewritten"].as_array().unwrap().len(),
        edited.len() + 1
    );
    // --link-previous: the same bytes; unchanged tiles' files are day 1's inodes, and the
    // damaged file's tile is derived again, not linked.
    let inc4 = t.join("inc4");
    run(
        &d2,
        &inc4,
        "2",
        "50",
        &["--previous", o1.to_str().unwrap(), "--link-previous"],
    );
    assert!(files(&inc4) == ff, "--link-previous: the files differ");
    #[cfg(unix)]
    {
        use std::os::unix::fs::MetadataExt;
        let ino = |p: &Path| std::fs::metadata(p).unwrap().ino();
        let victim_name = victim.strip_prefix(&o1).unwrap();
        let victim_tile = edited_or_damaged(&changes(&inc4), victim_name);
        let mut linked = 0;
        for name in fi.keys().filter(|n| !n.ends_with("tileset.json")) {
            let rewritten = edited.iter().any(|s| of_tile(name, s)) || of_tile(name, &victim_tile);
            let same = o1.join(name).exists() && ino(&o1.join(name)) == ino(&inc4.join(name));
            assert_eq!(
                same, !rewritten,
                "{name}: linked {same}, rewritten {rewritten}"
            );
            linked += usize::from(same);
        }
        assert!(linked >= 4, "{linked} files linked");
    }
}

/// The one tile of `changes`' rewritten tiles that holds file `name`.
#[cfg(unix)]
fn edited_or_damaged(changes: &serde_json::Value, name: &Path) -> String {
    let name = name.to_string_lossy();
    changes["tiles_rewritten"]
        .as_array()
        .unwrap()
        .iter()
        .map(|s| s.as_str().unwrap().to_string())
        .find(|s| of_tile(&name, s))
        .unwrap()
}

/// Whether file `name` (`t_{suffix}.ifc`, `3d/content/{suffix}-blocks.glb`...) is tile
/// `suffix`'s.
fn of_tile(name: &str, suffix: &str) -> bool {
    ["_", "/"].iter().any(|a| {
        [".", "-"]
            .iter()
            .any(|b| name.contains(&format!("{a}{suffix}{b}")))
    })
}

#[test]
fn a_ruleset_file_the_kb_names_is_part_of_every_key() {
    let tmp = tempfile::tempdir().unwrap();
    let t = tmp.path();
    let (d1, _, _) = two_days(t);
    let kb = t.join("kb.xml");
    std::fs::write(
        &kb,
        "<earth>\n  <info nbfloor=\"2\" rooftype=\"flat\"/>\n  \
         <appearance><values proba=\"1\"/><ruleset file=\"r.cga\"/></appearance>\n</earth>\n",
    )
    .unwrap();
    let rules = t.join("r.cga");
    std::fs::write(&rules, "lot -> extrude(eave){building}\n").unwrap();
    let kb = kb.to_str().unwrap();
    let (o1, same, edited) = (t.join("o1"), t.join("same"), t.join("edited"));
    run_kb(&d1, &o1, "2", "50", kb, &[]);
    let prev = ["--previous", o1.to_str().unwrap()];
    run_kb(&d1, &same, "2", "50", kb, &prev);
    let c = changes(&same);
    assert!(c["tiles_rewritten"].as_array().unwrap().is_empty(), "{c}");
    assert!(c["tiles_reused"].as_u64().unwrap() > 0);
    // The KB file is the same; the ruleset it names is not: nothing is reused.
    std::fs::write(&rules, "lot -> extrude(eave + 2){building}\n").unwrap();
    run_kb(&d1, &edited, "2", "50", kb, &prev);
    let c = changes(&edited);
    assert_eq!(c["tiles_reused"].as_u64(), Some(0), "{c}");
    assert!(files(&edited) != files(&o1));
}

#[test]
fn previous_refuses_what_it_cannot_do() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("x.ifc");
    let o = citygen(&[
        "--osm",
        MONACO,
        "--kb",
        KB,
        "--ifc",
        out.to_str().unwrap(),
        "--tile",
        "500",
        "--previous",
        tmp.path().to_str().unwrap(),
    ]);
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("no citygen-manifest"), "{err}");
    assert!(!out.exists());
}

#[test]
fn at_lod3_a_touching_neighbour_in_another_tile_is_rederived_too() {
    let tmp = tempfile::tempdir().unwrap();
    let t = tmp.path();
    // A town, and a terrace of 14 houses 6 m wide sharing their walls: 84 m, so two of them
    // stand on either side of a border of the 50 m tiles.
    let mut day1 = town(4);
    for k in 0..14 {
        day1.push(B {
            id: 8000 + k,
            at: (3.0 + 6.0 * k as f64, 110.0),
            size: (6.0, 9.0),
            tags: vec![
                ("building", "house".into()),
                ("building:levels", "3".into()),
                ("roof:shape", "flat".into()),
            ],
        });
    }
    let d1 = t.join("day1/town.osm.pbf");
    write_pbf(&d1, &day1);
    let o1 = t.join("o1");
    run(&d1, &o1, "3", "50", &[]);
    let tile_of = |dir: &Path, id: i64| tile_of(dir, &format!("way/{id}"));
    // The house left of the first border (not the terrace's first).
    let left = (8001..8013)
        .find(|&k| tile_of(&o1, k) != tile_of(&o1, k + 1))
        .expect("the terrace crosses a tile border");
    let mut day2 = day1.clone();
    for b in &mut day2 {
        if b.id == left {
            b.tags[1].1 = "5".into();
        }
    }
    let d2 = t.join("day2/town.osm.pbf");
    write_pbf(&d2, &day2);
    let (full, inc) = (t.join("full"), t.join("inc"));
    run(&d2, &full, "3", "50", &[]);
    run(&d2, &inc, "3", "50", &["--previous", o1.to_str().unwrap()]);
    assert!(
        files(&full) == files(&inc),
        "LOD3: the incremental run's bytes differ"
    );
    let c = changes(&inc);
    assert_eq!(ids(&c["changed"]), [format!("way/{left}")].into());
    // Its party-wall neighbours are derived again, the one across the border too.
    assert_eq!(
        ids(&c["affected"]),
        [format!("way/{}", left - 1), format!("way/{}", left + 1)].into()
    );
    let want: BTreeSet<String> = [left - 1, left, left + 1]
        .iter()
        .map(|&k| tile_of(&o1, k))
        .collect();
    assert_eq!(want.len(), 2);
    assert_eq!(ids(&c["tiles_rewritten"]), want);
    assert!(c["tiles_reused"].as_u64().unwrap() >= 1);
}

/// The suffixes of a run's tiles, from its manifest, in grid order.
fn suffixes(dir: &Path) -> Vec<String> {
    manifest(dir)["tiles"]
        .as_array()
        .unwrap()
        .iter()
        .map(|t| t["suffix"].as_str().unwrap().to_string())
        .collect()
}

/// A tile's buildings as written in its CityJSONSeq file (their `sourceId`s).
fn seq_ids(path: &Path) -> BTreeSet<String> {
    std::fs::read_to_string(path)
        .unwrap()
        .lines()
        .filter_map(|l| {
            let at = l.find("\"sourceId\":\"")? + 12;
            Some(l[at..at + l[at..].find('"')?].to_string())
        })
        .collect()
}

#[test]
fn previous_reuses_only_regular_files_inside_its_folder_and_says_why() {
    let tmp = tempfile::tempdir().unwrap();
    let t = tmp.path();
    let d1 = t.join("day1/town.osm.pbf");
    write_pbf(&d1, &town(4));
    let o1 = t.join("o1");
    run(&d1, &o1, "2", "50", &[]);
    let full = files(&o1);
    let sfx = suffixes(&o1);
    assert!(sfx.len() >= 4, "{sfx:?}");
    // Tile 0's CityJSONSeq: a symlink to an outside file of the attacker's, the manifest
    // listing that file's size and SHA-256 (whoever writes the folder writes its manifest).
    let seq0 = format!("t_{}.city.jsonl", sfx[0]);
    let outside = t.join("outside.city.jsonl");
    let evil = b"{\"type\":\"CityJSONFeature\",\"id\":\"evil\"}\n".to_vec();
    std::fs::write(&outside, &evil).unwrap();
    std::fs::remove_file(o1.join(&seq0)).unwrap();
    std::os::unix::fs::symlink(&outside, o1.join(&seq0)).unwrap();
    let mpath = o1.join("citygen-manifest.0-of-1.json");
    let mut m = manifest(&o1);
    for tile in m["tiles"].as_array_mut().unwrap() {
        for f in tile["files"].as_array_mut().unwrap() {
            if f["path"] == seq0.as_str() {
                use sha2::Digest as _;
                f["bytes"] = evil.len().into();
                f["sha256"] = citygen::fsio::hex(&sha2::Sha256::digest(&evil)).into();
            }
        }
    }
    std::fs::write(&mpath, serde_json::to_vec_pretty(&m).unwrap()).unwrap();
    // Tile 1's IFC: a named pipe nobody writes (opening it would block forever); tile 2's
    // glTF: gone.
    let ifc1 = o1.join(format!("t_{}.ifc", sfx[1]));
    std::fs::remove_file(&ifc1).unwrap();
    let st = std::process::Command::new("mkfifo")
        .arg(&ifc1)
        .status()
        .unwrap();
    assert!(st.success());
    std::fs::remove_file(o1.join(format!("t_{}.glb", sfx[2]))).unwrap();
    let inc = t.join("inc");
    run(&d1, &inc, "2", "50", &["--previous", o1.to_str().unwrap()]);
    // The run finished; every file is the full run's: the symlinked tile derived again, its
    // buildings there, nothing of the outside file.
    assert!(files(&inc) == full, "the files differ from the full run's");
    let ids0 = seq_ids(&inc.join(&seq0));
    assert!(!ids0.is_empty() && !ids0.contains("evil"), "{ids0:?}");
    assert!(!std::fs::symlink_metadata(inc.join(&seq0))
        .unwrap()
        .file_type()
        .is_symlink());
    let c = changes(&inc);
    let why = &c["tiles_not_reused"];
    let reason = |s: &str| why[s].as_str().unwrap_or_default().to_string();
    assert!(reason(&sfx[0]).contains("symbolic link"), "{c}");
    assert!(reason(&sfx[0]).contains(&seq0), "{c}");
    assert!(reason(&sfx[1]).contains("named pipe"), "{c}");
    assert!(reason(&sfx[2]).contains("missing"), "{c}");
    assert_eq!(
        ids(&c["tiles_rewritten"]),
        sfx[..3].iter().cloned().collect::<BTreeSet<String>>()
    );
    assert_eq!(c["tiles_reused"].as_u64(), Some(sfx.len() as u64 - 3));
    // --link-previous links no symlink either.
    let inc2 = t.join("inc2");
    run(
        &d1,
        &inc2,
        "2",
        "50",
        &["--previous", o1.to_str().unwrap(), "--link-previous"],
    );
    assert!(files(&inc2) == full, "--link-previous: the files differ");
    assert_eq!(std::fs::read(&outside).unwrap(), evil);
}

#[test]
fn a_named_pipe_manifest_is_refused_without_hanging() {
    let tmp = tempfile::tempdir().unwrap();
    let t = tmp.path();
    let d1 = t.join("day1/town.osm.pbf");
    write_pbf(&d1, &town(2));
    let prev = t.join("prev");
    std::fs::create_dir_all(&prev).unwrap();
    let st = std::process::Command::new("mkfifo")
        .arg(prev.join("citygen-manifest.0-of-1.json"))
        .status()
        .unwrap();
    assert!(st.success());
    let out = t.join("out");
    let a = args(
        &d1,
        &out,
        ("2", "50", KB),
        "report.json",
        &["--previous", prev.to_str().unwrap()],
    );
    let o = citygen_timed(&a);
    assert_eq!(o.status.code(), Some(1));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("citygen-manifest.0-of-1.json") && err.contains("named pipe"),
        "{err}"
    );
    assert!(!out.exists());
}

#[test]
fn no_output_on_a_file_the_run_reads_from_previous_or_osc() {
    let tmp = tempfile::tempdir().unwrap();
    let t = tmp.path();
    let (d1, _, osc) = two_days(t);
    let o1 = t.join("o1");
    run(&d1, &o1, "2", "50", &[]);
    let before = common::files_under(&o1, |_| true);
    let manifest = o1.join("citygen-manifest.0-of-1.json");
    let tile = o1.join(format!("t_{}.ifc", suffixes(&o1)[0]));
    let out = t.join("out");
    let prev = ["--previous", o1.to_str().unwrap()];
    // --report on yesterday's manifest, on one of its tiles; on the change file.
    let osc_flag = ["--osc", osc.to_str().unwrap()];
    let cases: [(&Path, &[&str]); 3] = [(&manifest, &prev), (&tile, &prev), (&osc, &osc_flag)];
    let osc_bytes = std::fs::read(&osc).unwrap();
    for (target, extra) in cases {
        let mut a = args(&d1, &out, ("2", "50", KB), target.to_str().unwrap(), extra);
        a.push("--force-extension".into());
        let o = citygen_timed(&a);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{}: {err}", target.display());
        // Yesterday's manifest is also the manifest this run would write beside its report
        // (the same folder): either refusal names it, before anything is written.
        let refused = err.contains("refusing to overwrite an input")
            || (target == manifest.as_path()
                && err.contains("is the manifest this tiled run writes"));
        assert!(
            refused && err.contains(&*target.display().to_string()),
            "{err}"
        );
        assert!(!out.exists(), "{}", target.display());
    }
    assert!(
        common::files_under(&o1, |_| true) == before,
        "the previous folder changed"
    );
    assert_eq!(std::fs::read(&osc).unwrap(), osc_bytes);
}

#[test]
fn an_update_in_place_leaves_exactly_the_files_of_a_full_run() {
    let tmp = tempfile::tempdir().unwrap();
    let t = tmp.path();
    // A town, and two buildings well outside it that hold the data's bounds (so its centre,
    // the local origin, stays when a tile of the town goes).
    let mut day1 = town(4);
    for (id, at) in [(9001, (-60.0, -60.0)), (9002, (160.0, 160.0))] {
        day1.push(B {
            id,
            at,
            ..day1[0].clone()
        });
    }
    let d1 = t.join("day1/town.osm.pbf");
    write_pbf(&d1, &day1);
    let (place, full) = (t.join("place"), t.join("full"));
    run(&d1, &place, "2", "50", &[]);
    // Day 2: every building of a tile of the town deleted.
    let lots = |t: &serde_json::Value| -> BTreeSet<String> {
        t["lots"]
            .as_array()
            .unwrap()
            .iter()
            .map(|l| l["id"].as_str().unwrap().to_string())
            .collect()
    };
    let gone = manifest(&place)["tiles"]
        .as_array()
        .unwrap()
        .iter()
        .map(lots)
        .find(|ids| !ids.iter().any(|id| id.starts_with("way/900")))
        .unwrap();
    let day2: Vec<B> = day1
        .iter()
        .filter(|b| !gone.contains(&format!("way/{}", b.id)))
        .cloned()
        .collect();
    assert!(!gone.is_empty() && day2.len() + gone.len() == day1.len());
    let d2 = t.join("day2/town.osm.pbf");
    write_pbf(&d2, &day2);
    run(&d2, &full, "2", "50", &[]);
    run(
        &d2,
        &place,
        "2",
        "50",
        &["--previous", place.to_str().unwrap()],
    );
    let all = |d: &Path| common::files_under(d, |_| true);
    let (a, b) = (all(&full), all(&place));
    assert_eq!(
        a.keys().collect::<Vec<_>>(),
        b.keys().collect::<Vec<_>>(),
        "the same files"
    );
    assert!(files(&full) == files(&place), "the same bytes");
    // The manifests are the full run's but for the changes.
    let mut m = manifest(&place);
    let c = m.as_object_mut().unwrap().remove("changes").unwrap();
    assert_eq!(m, manifest(&full));
    assert_eq!(c["tiles_removed"].as_array().unwrap().len(), 1, "{c}");
    assert_eq!(
        c["tiles_reused"].as_u64(),
        Some(suffixes(&place).len() as u64),
        "every other tile reused in place: {c}"
    );
}

#[test]
fn dated_report_names_reuse_every_unchanged_tile_and_a_tile_not_reused_says_why() {
    let tmp = tempfile::tempdir().unwrap();
    let t = tmp.path();
    let (d1, d2, _) = two_days(t);
    let (o1, o2, o3) = (t.join("o1"), t.join("o2"), t.join("o3"));
    let go = |input: &Path, out: &Path, report: &str, extra: &[&str]| {
        let o = citygen_timed(&args(input, out, ("2", "50", KB), report, extra));
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let r: serde_json::Value =
            serde_json::from_slice(&std::fs::read(out.join(report)).unwrap()).unwrap();
        r["changes"].clone()
    };
    go(&d1, &o1, "report-2026-12-05.json", &[]);
    let prev = ["--previous", o1.to_str().unwrap()];
    let tiles = suffixes(&o1).len() as u64;
    // The same input the next day: every tile reused.
    let c = go(&d1, &o2, "report-2026-12-06.json", &prev);
    assert_eq!(c["tiles_reused"].as_u64(), Some(tiles), "{c}");
    assert_eq!(ids(&c["affected"]), BTreeSet::new());
    assert!(
        c.get("not_reused").is_none() && c.get("tiles_not_reused").is_none(),
        "{c}"
    );
    // Day 2's edits: only the edited tiles are derived, each with its reason.
    let c = go(&d2, &o3, "report-2026-12-06.json", &prev);
    assert_eq!(ids(&c["affected"]), BTreeSet::new(), "{c}");
    let rewritten = ids(&c["tiles_rewritten"]);
    assert_eq!(rewritten.len(), 4, "{c}");
    assert_eq!(c["tiles_reused"].as_u64(), Some(tiles - 4), "{c}");
    let why = c["tiles_not_reused"].as_object().unwrap();
    assert_eq!(why.keys().cloned().collect::<BTreeSet<_>>(), rewritten);
    let edited = &why[&tile_of(&o3, "way/1011")];
    assert!(
        edited.as_str().unwrap().contains("1 building(s) edited"),
        "{c}"
    );
    // Another seed: nothing reused, and the report says why.
    let o4 = t.join("o4");
    let c = go(
        &d1,
        &o4,
        "report-2026-12-07.json",
        &["--previous", o1.to_str().unwrap(), "--seed", "7"],
    );
    assert_eq!(c["tiles_reused"].as_u64(), Some(0));
    let not = c["not_reused"].as_str().unwrap_or_default();
    assert!(
        not.contains("context changed") && not.contains("--seed"),
        "{c}"
    );
    assert_eq!(
        c["tiles_not_reused"].as_object().unwrap().len() as u64,
        tiles
    );
}

#[test]
fn an_update_in_place_of_two_shards_by_one_run_leaves_one_manifest() {
    let tmp = tempfile::tempdir().unwrap();
    let t = tmp.path();
    let d1 = t.join("day1/town.osm.pbf");
    write_pbf(&d1, &town(4));
    let (place, full) = (t.join("place"), t.join("full"));
    run(&d1, &place, "2", "50", &["--shard", "0/2"]);
    run(&d1, &place, "2", "50", &["--shard", "1/2"]);
    run(&d1, &full, "2", "50", &[]);
    run(
        &d1,
        &place,
        "2",
        "50",
        &["--previous", place.to_str().unwrap()],
    );
    // The shards' reports (`report_shard-I-of-N.json`) stay: reports are the operator's
    // (dated ones are kept on purpose); no manifest lists them.
    let all = |d: &Path| common::files_under(d, |n| !n.starts_with("report_shard-"));
    assert_eq!(
        all(&full).keys().collect::<Vec<_>>(),
        all(&place).keys().collect::<Vec<_>>(),
        "the shards' manifests are gone"
    );
    let tiles = |d: &Path| {
        let mut f = files(d);
        f.retain(|n, _| !n.starts_with("report_shard-"));
        f
    };
    assert!(tiles(&full) == tiles(&place), "the same bytes");
    let c = changes(&place);
    assert_eq!(
        c["tiles_reused"].as_u64(),
        Some(suffixes(&place).len() as u64),
        "{c}"
    );
}

/// `--textures` with `--previous`: the facade pictures of an unchanged tile are reused with
/// its files and those of an edited tile drawn again, so the increment is the full run byte
/// for byte, pictures included; a previous run without pictures lends nothing to one with
/// them (the option is part of every key), and a picture damaged on disk makes its tile be
/// derived again.
#[test]
fn previous_with_textures_gives_the_full_runs_pictures() {
    let tmp = tempfile::tempdir().unwrap();
    let t = tmp.path();
    let (d1, d2, _) = two_days(t);
    let tex = ["--textures"];
    let (o1, plain, full, inc) = (t.join("o1"), t.join("plain"), t.join("full"), t.join("inc"));
    run(&d1, &o1, "2", "50", &tex);
    run(&d1, &plain, "2", "50", &[]);
    run(&d2, &full, "2", "50", &tex);
    let prev = |d: &Path| ["--textures", "--previous", d.to_str().unwrap()].map(String::from);
    let p = prev(&o1);
    run(
        &d2,
        &inc,
        "2",
        "50",
        &p.iter().map(String::as_str).collect::<Vec<_>>(),
    );
    let (ff, fi) = (files(&full), files(&inc));
    let pngs = ff.keys().filter(|n| n.ends_with(".png")).count();
    assert!(pngs > 0, "the full run drew no picture: {:?}", ff.keys());
    assert_eq!(
        ff.keys().collect::<Vec<_>>(),
        fi.keys().collect::<Vec<_>>(),
        "the same files"
    );
    for (name, bytes) in &ff {
        assert!(
            fi[name] == *bytes,
            "{name}: the incremental run's bytes differ"
        );
    }
    let c = changes(&inc);
    let rewritten = c["tiles_rewritten"].as_array().unwrap().len();
    assert!(
        rewritten > 0 && c["tiles_reused"].as_u64().unwrap() > 0,
        "{c}"
    );
    // The pictures of a reused tile are day 1's.
    let f1 = files(&o1);
    let kept = ff
        .iter()
        .filter(|(n, b)| n.ends_with(".png") && f1.get(*n) == Some(*b))
        .count();
    assert!(kept > 0, "no picture of day 1 reused");
    // A previous run without pictures: nothing reused, still the full run's files.
    let from_plain = t.join("from_plain");
    let p = prev(&plain);
    run(
        &d2,
        &from_plain,
        "2",
        "50",
        &p.iter().map(String::as_str).collect::<Vec<_>>(),
    );
    assert_eq!(changes(&from_plain)["tiles_reused"].as_u64(), Some(0));
    assert!(files(&from_plain) == ff, "from a run without pictures");
    // A picture of an unchanged tile damaged on disk: its tile is derived again.
    let derived: Vec<String> = ids(&c["tiles_rewritten"])
        .iter()
        .map(|s| format!("_{s}_textures/"))
        .collect();
    let victim = ff
        .keys()
        .find(|n| {
            n.ends_with(".png")
                && f1.get(*n) == ff.get(*n)
                && !derived.iter().any(|d| n.contains(d.as_str()))
        })
        .unwrap();
    let path = o1.join(victim);
    let mut bytes = std::fs::read(&path).unwrap();
    let at = bytes.len() / 2;
    bytes[at] ^= 1;
    std::fs::write(&path, bytes).unwrap();
    let again = t.join("again");
    let p = prev(&o1);
    run(
        &d2,
        &again,
        "2",
        "50",
        &p.iter().map(String::as_str).collect::<Vec<_>>(),
    );
    assert!(files(&again) == ff, "after a damaged previous picture");
    assert_eq!(
        changes(&again)["tiles_rewritten"].as_array().unwrap().len(),
        rewritten + 1,
        "the damaged picture's tile is derived again"
    );
    // An update in place: the pictures of the tiles derived again, drawn with the names the
    // previous run's pictures had, are not removed as stale; the folder is the full run's.
    let place = t.join("place");
    run(&d1, &place, "2", "50", &tex);
    let p = prev(&place);
    run(
        &d2,
        &place,
        "2",
        "50",
        &p.iter().map(String::as_str).collect::<Vec<_>>(),
    );
    let all = |d: &Path| common::files_under(d, |_| true);
    assert_eq!(
        all(&full).keys().collect::<Vec<_>>(),
        all(&place).keys().collect::<Vec<_>>(),
        "in place: the same files"
    );
    assert!(files(&place) == ff, "in place: the same bytes");
}
