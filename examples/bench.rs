//! Benchmark of the release `citygen` binary (see the README's "Benchmark" section).
//!
//! ```text
//! cargo build --release
//! cargo run --release --example bench -- data/monaco/monaco.osm.pbf 5      # a file, best of 5
//! cargo run --release --example bench -- 10000 100000                      # tiled inputs
//! cargo run --release --example bench -- --make 100000 target/bench-inputs/x.osm.pbf
//! ```
//!
//! Inputs: a path (`.osm.pbf` or `.shp`), or a building count `N` (`10000`, `100k`, `1M`): the
//! tiled input `target/bench-inputs/jittered-N.osm.pbf`, made first when missing. `--make N OUT`
//! only makes one: the buildings of data/monaco and the Clifton shapefile's footprints
//! (converted to lon/lat and moved beside Monaco, keeping their size in metres) are repeated in
//! a grid of copies with coordinate offsets and new node/way/relation ids per copy, until there
//! are N buildings (the last copy is partial). Every copy is turned, scaled and its nodes moved
//! by a few centimetres ([`Jitter`]), so no two footprints are the same shape.
//!
//! For each input it runs the `citygen` binary next to this example (target/release/citygen)
//! as a child process per configuration: LOD 1, 2, 3 × (IFC, CityGML, glTF, all three), and
//! prints buildings/s, output polygons/s, output MB/s and the child's peak RSS (from `wait4`),
//! best wall-clock time of the repetitions. Then, for a PBF, the raw osmpbf decode speed of the
//! same file (every blob, osmpbf's parallel reader, counting nodes, ways and relations) beside
//! citygen's read phase alone (`input::osm::read_osm`, in this process).
//!
//! Flags: `--lods 1,2,3` (default all), `--formats all,ifc,gml,glb` (default all four),
//! `--reps R` (default 1, or the number after a file path), `--kb FILE`, `--threads N`,
//! `--tile METRES` and `--dry-run` (passed on to citygen; a dry run renders every output and
//! counts its bytes but writes none, for runs whose outputs the disk cannot hold), `--read`
//! (only the read comparison, no citygen runs). MB out is the byte count citygen's summary
//! gives, the same whether written or not.

use std::collections::{BTreeMap, BTreeSet};
use std::fs::File;
use std::io::{BufWriter, Read};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::Instant;

use citygen::testkit::pbf_write::{MemberKind, PbfWriter};
use osmpbf::{Element, ElementReader, RelMemberType};

type Error = Box<dyn std::error::Error>;

/// Where generated inputs go (gitignored, never committed).
const INPUT_DIR: &str = "target/bench-inputs";

fn main() -> Result<(), Error> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let mut inputs: Vec<String> = Vec::new();
    let mut reps: Option<usize> = None;
    let mut lods = vec![1u8, 2, 3];
    let mut formats: Vec<Format> = Format::ALL.to_vec();
    let mut kb = PathBuf::from("knowledge_base/kb.xml");
    let mut extra: Vec<String> = Vec::new();
    let mut i = 0;
    while i < args.len() {
        let a = args[i].as_str();
        let mut value = || -> Result<String, Error> {
            i += 1;
            args.get(i)
                .cloned()
                .ok_or_else(|| format!("{a} needs a value").into())
        };
        match a {
            "--make" => {
                let n = parse_count(&value()?)?;
                let out = PathBuf::from(value()?);
                return make_tiled(n, &out).map(|_| ());
            }
            "--reps" => reps = Some(value()?.parse()?),
            // Only the read comparison (raw osmpbf decode vs citygen's read phase).
            "--read" => lods.clear(),
            "--kb" => kb = PathBuf::from(value()?),
            "--threads" => extra.extend(["--threads".to_string(), value()?]),
            "--tile" => extra.extend(["--tile".to_string(), value()?]),
            "--dry-run" => extra.push("--dry-run".into()),
            "--lods" => {
                lods = value()?
                    .split(',')
                    .map(|s| s.trim().parse::<u8>())
                    .collect::<Result<_, _>>()?
            }
            "--formats" => {
                formats = value()?
                    .split(',')
                    .map(|s| Format::parse(s.trim()).ok_or(format!("unknown format {s}")))
                    .collect::<Result<_, _>>()?
            }
            _ => {
                // `FILE REPS` (the historical form): a bare number after a path is REPS.
                if !inputs.is_empty()
                    && Path::new(&inputs[inputs.len() - 1]).exists()
                    && a.parse::<usize>().is_ok()
                    && reps.is_none()
                {
                    reps = a.parse().ok();
                } else {
                    inputs.push(a.to_string());
                }
            }
        }
        i += 1;
    }
    if inputs.is_empty() {
        inputs.push("data/monaco/monaco.osm.pbf".into());
    }
    let reps = reps.unwrap_or(1).max(1);
    let bin = citygen_binary()?;
    let out_dir = PathBuf::from("target/bench-out");
    std::fs::create_dir_all(&out_dir)?;
    println!(
        "citygen binary {}; {} CPU(s); best of {reps}; timings on a shared machine are noisy",
        bin.display(),
        std::thread::available_parallelism().map_or(1, |n| n.get())
    );
    for input in &inputs {
        let path = match parse_count(input) {
            Ok(n) if !Path::new(input).exists() => {
                let p = Path::new(INPUT_DIR).join(format!("jittered-{n}.osm.pbf"));
                if !p.exists() {
                    make_tiled(n, &p)?;
                }
                p
            }
            _ => PathBuf::from(input),
        };
        bench_input(&bin, &path, &kb, &lods, &formats, reps, &extra, &out_dir)?;
    }
    Ok(())
}

/// `10000`, `10k`, `1M`.
fn parse_count(s: &str) -> Result<usize, Error> {
    let t = s.trim();
    let (num, mul) = match t.chars().last() {
        Some('k' | 'K') => (&t[..t.len() - 1], 1_000),
        Some('m' | 'M') => (&t[..t.len() - 1], 1_000_000),
        _ => (t, 1),
    };
    Ok(num.parse::<usize>()? * mul)
}

/// The release binary beside this example, rebuilt first when run by cargo.
fn citygen_binary() -> Result<PathBuf, Error> {
    if let Ok(cargo) = std::env::var("CARGO") {
        let status = Command::new(cargo)
            .args(["build", "--release", "--quiet", "--bin", "citygen"])
            .status()?;
        if !status.success() {
            return Err("cargo build --release --bin citygen failed".into());
        }
    }
    let exe = std::env::current_exe()?;
    let dir = exe
        .parent()
        .and_then(Path::parent)
        .ok_or("cannot locate target/release")?;
    let bin = dir.join(format!("citygen{}", std::env::consts::EXE_SUFFIX));
    if !bin.exists() {
        return Err(format!("{} is missing: run cargo build --release", bin.display()).into());
    }
    Ok(bin)
}

/// An output configuration of the matrix.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Format {
    Ifc,
    Gml,
    Glb,
    All,
}

impl Format {
    const ALL: [Format; 4] = [Format::Ifc, Format::Gml, Format::Glb, Format::All];

    fn parse(s: &str) -> Option<Format> {
        match s {
            "ifc" => Some(Format::Ifc),
            "gml" | "citygml" => Some(Format::Gml),
            "glb" | "gltf" => Some(Format::Glb),
            "all" => Some(Format::All),
            _ => None,
        }
    }

    fn name(self) -> &'static str {
        match self {
            Format::Ifc => "IFC",
            Format::Gml => "CityGML",
            Format::Glb => "glTF",
            Format::All => "all three",
        }
    }

    fn flags(self, dir: &Path) -> Vec<String> {
        let f =
            |flag: &str, name: &str| vec![flag.to_string(), dir.join(name).display().to_string()];
        match self {
            Format::Ifc => f("--ifc", "b.ifc"),
            Format::Gml => f("--citygml", "b.gml"),
            Format::Glb => f("--gltf", "b.glb"),
            Format::All => [
                f("--ifc", "b.ifc"),
                f("--citygml", "b.gml"),
                f("--gltf", "b.glb"),
            ]
            .concat(),
        }
    }
}

/// One child run.
struct RunResult {
    secs: f64,
    /// User + system CPU seconds of the child (on a shared machine, steadier than wall time).
    cpu: f64,
    buildings: u64,
    polygons: u64,
    bytes: u64,
    rss_kib: u64,
}

#[allow(clippy::too_many_arguments)]
fn bench_input(
    bin: &Path,
    input: &Path,
    kb: &Path,
    lods: &[u8],
    formats: &[Format],
    reps: usize,
    extra: &[String],
    out_dir: &Path,
) -> Result<(), Error> {
    let size = std::fs::metadata(input)?.len();
    let is_shp = input.extension().is_some_and(|e| e == "shp");
    println!(
        "\n== {} ({:.1} MB)\n{:<4} {:<10} {:>9} {:>10} {:>8} {:>8} {:>11} {:>12} {:>9} {:>8} {:>9}",
        input.display(),
        size as f64 / 1e6,
        "LOD",
        "formats",
        "buildings",
        "polygons",
        "s",
        "CPU s",
        "buildings/s",
        "polygons/s",
        "MB out",
        "MB/s",
        "RSS MiB"
    );
    for &lod in lods {
        for &format in formats {
            let mut best: Option<RunResult> = None;
            for _ in 0..reps {
                let r = run_child(bin, input, is_shp, kb, lod, format, extra, out_dir)?;
                let rss = best.as_ref().map_or(0, |b| b.rss_kib).max(r.rss_kib);
                if best.as_ref().is_none_or(|b| r.secs < b.secs) {
                    best = Some(RunResult { rss_kib: rss, ..r });
                } else if let Some(b) = &mut best {
                    b.rss_kib = rss;
                }
            }
            let Some(r) = best else { continue };
            println!(
                "{:<4} {:<10} {:>9} {:>10} {:>8.2} {:>8.2} {:>11.0} {:>12.0} {:>9.1} {:>8.1} {:>9.1}",
                lod,
                format.name(),
                r.buildings,
                r.polygons,
                r.secs,
                r.cpu,
                r.buildings as f64 / r.secs,
                r.polygons as f64 / r.secs,
                r.bytes as f64 / 1e6,
                r.bytes as f64 / 1e6 / r.secs,
                r.rss_kib as f64 / 1024.0
            );
        }
    }
    if !is_shp {
        read_bench(input, size, reps)?;
    }
    Ok(())
}

/// Runs the binary once; wall-clock time, counts from its summary, output size, peak RSS.
#[allow(clippy::too_many_arguments)]
fn run_child(
    bin: &Path,
    input: &Path,
    is_shp: bool,
    kb: &Path,
    lod: u8,
    format: Format,
    extra: &[String],
    out_dir: &Path,
) -> Result<RunResult, Error> {
    clear(out_dir);
    let mut cmd = Command::new(bin);
    cmd.arg(if is_shp { "--shp" } else { "--osm" })
        .arg(input)
        .arg("--kb")
        .arg(kb)
        .arg("--lod")
        .arg(lod.to_string())
        .args(format.flags(out_dir))
        .stdout(Stdio::null())
        .stderr(Stdio::piped());
    cmd.args(extra);
    let t = Instant::now();
    let mut child = cmd.spawn()?;
    let mut stderr = String::new();
    if let Some(mut e) = child.stderr.take() {
        e.read_to_string(&mut stderr)?;
    }
    let (ok, rss_kib, cpu) = wait_with_rss(&mut child)?;
    let secs = t.elapsed().as_secs_f64();
    if !ok {
        return Err(format!("citygen failed on {}:\n{stderr}", input.display()).into());
    }
    let number_after = |key: &str| -> u64 {
        stderr
            .split(key)
            .nth(1)
            .and_then(|s| s.split(|c: char| !c.is_ascii_digit()).next())
            .and_then(|s| s.parse().ok())
            .unwrap_or(0)
    };
    clear(out_dir);
    Ok(RunResult {
        secs,
        cpu,
        buildings: number_after("generated "),
        polygons: number_after("output: "),
        bytes: number_after(" polygons, "),
        rss_kib,
    })
}

/// Removes the outputs of a run (`b.*`, and `b_*` tiles) from the bench's output folder.
fn clear(out_dir: &Path) {
    if let Ok(entries) = std::fs::read_dir(out_dir) {
        for e in entries.flatten() {
            if e.file_name().to_string_lossy().starts_with('b') {
                let _ = std::fs::remove_file(e.path());
            }
        }
    }
}

/// Waits for the child and returns (success, peak RSS in KiB, user + system CPU seconds) of
/// that child alone.
#[cfg(unix)]
fn wait_with_rss(child: &mut std::process::Child) -> Result<(bool, u64, f64), Error> {
    let pid = child.id() as libc::pid_t;
    let mut status: libc::c_int = 0;
    // SAFETY: plain FFI call with valid out-pointers; the child is ours and not yet reaped.
    let mut usage: libc::rusage = unsafe { std::mem::zeroed() };
    let r = unsafe { libc::wait4(pid, &mut status, 0, &mut usage) };
    if r != pid {
        return Err(std::io::Error::last_os_error().into());
    }
    let ok = libc::WIFEXITED(status) && libc::WEXITSTATUS(status) == 0;
    // ru_maxrss is in KiB on Linux.
    let tv = |t: libc::timeval| t.tv_sec as f64 + t.tv_usec as f64 / 1e6;
    let cpu = tv(usage.ru_utime) + tv(usage.ru_stime);
    Ok((ok, usage.ru_maxrss.max(0) as u64, cpu))
}

#[cfg(not(unix))]
fn wait_with_rss(child: &mut std::process::Child) -> Result<(bool, u64, f64), Error> {
    Ok((child.wait()?.success(), 0, 0.0))
}

/// Raw osmpbf decode (parallel, all blobs) vs citygen's read phase, best of `reps`.
fn read_bench(input: &Path, size: u64, reps: usize) -> Result<(), Error> {
    let mut raw = f64::INFINITY;
    let mut counts = (0u64, 0u64, 0u64);
    for _ in 0..reps {
        let t = Instant::now();
        counts = ElementReader::from_path(input)?.par_map_reduce(
            |e| match e {
                Element::Node(_) | Element::DenseNode(_) => (1, 0, 0),
                Element::Way(_) => (0, 1, 0),
                Element::Relation(_) => (0, 0, 1),
            },
            || (0u64, 0u64, 0u64),
            |a, b| (a.0 + b.0, a.1 + b.1, a.2 + b.2),
        )?;
        raw = raw.min(t.elapsed().as_secs_f64());
    }
    let elements = counts.0 + counts.1 + counts.2;
    let mut read = f64::INFINITY;
    let mut footprints = 0;
    for _ in 0..reps {
        let mut report = citygen::report::Report::default();
        let t = Instant::now();
        let r = citygen::input::osm::read_osm(input, &mut report)?;
        read = read.min(t.elapsed().as_secs_f64());
        footprints = r.footprints.len();
    }
    println!(
        "raw osmpbf decode: {} nodes, {} ways, {} relations in {:.3} s: {:.0} elements/s, {:.1} MB/s",
        counts.0,
        counts.1,
        counts.2,
        raw,
        elements as f64 / raw,
        size as f64 / 1e6 / raw
    );
    println!(
        "citygen read (input::osm::read_osm): {footprints} footprints in {:.3} s: {:.0} elements/s, {:.1} MB/s, {:.0} % of raw decode speed",
        read,
        elements as f64 / read,
        size as f64 / 1e6 / read,
        100.0 * raw / read
    );
    Ok(())
}

// ---- tiled inputs ----

/// OSM tags as owned (key, value) pairs.
type Tags = Vec<(String, String)>;

/// Polygons of one footprint in lon/lat: (outer ring, holes).
type LonLatPolygons = Vec<(Vec<(f64, f64)>, Vec<Vec<(f64, f64)>>)>;

/// The footprints repeated per copy, with dense ids (1-based per kind) and lon/lat nodes.
#[derive(Default)]
struct Template {
    nodes: Vec<(f64, f64)>,
    /// (node indices (0-based), tags).
    ways: Vec<(Vec<usize>, Tags)>,
    /// (members as (is_way, index), roles, tags); only way members.
    relations: Vec<(Vec<(usize, String)>, Tags)>,
    /// Top-level buildings in order: (true = way, false = relation, index).
    buildings: Vec<(bool, usize)>,
    /// Extent in degrees: (min lon, min lat, max lon, max lat).
    bounds: [f64; 4],
}

fn is_building(tags: &[(String, String)]) -> bool {
    tags.iter()
        .any(|(k, v)| k == "building" && v.trim() != "no")
}

fn is_part(tags: &[(String, String)]) -> bool {
    tags.iter()
        .any(|(k, v)| k == "building:part" && v.trim() != "no")
}

/// Building ways and relations (with their member ways and nodes) of data/monaco, then the
/// Clifton footprints beside them.
fn template() -> Result<Template, Error> {
    let monaco = Path::new("data/monaco/monaco.osm.pbf");
    let mut nodes: BTreeMap<i64, (f64, f64)> = BTreeMap::new();
    let mut ways: BTreeMap<i64, (Vec<i64>, Tags)> = BTreeMap::new();
    let mut rels: BTreeMap<i64, (Vec<(i64, String)>, Tags)> = BTreeMap::new();
    let tags_of = |it: &mut dyn Iterator<Item = (&str, &str)>| -> Vec<(String, String)> {
        it.map(|(k, v)| (k.to_string(), v.to_string())).collect()
    };
    ElementReader::from_path(monaco)?.for_each(|e| match e {
        Element::Node(n) => {
            nodes.insert(n.id(), (n.lon(), n.lat()));
        }
        Element::DenseNode(n) => {
            nodes.insert(n.id(), (n.lon(), n.lat()));
        }
        Element::Way(w) => {
            ways.insert(w.id(), (w.refs().collect(), tags_of(&mut w.tags())));
        }
        Element::Relation(r) => {
            let tags = tags_of(&mut r.tags());
            let multipolygon = tags.iter().any(|(k, v)| k == "type" && v == "multipolygon");
            if multipolygon && (is_building(&tags) || is_part(&tags)) {
                let members = r
                    .members()
                    .filter(|m| m.member_type == RelMemberType::Way)
                    .map(|m| (m.member_id, m.role().unwrap_or("").to_string()))
                    .collect();
                rels.insert(r.id(), (members, tags));
            }
        }
    })?;
    let member_ways: BTreeSet<i64> = rels
        .values()
        .flat_map(|(m, _)| m.iter().map(|(id, _)| *id))
        .collect();
    let mut t = Template::default();
    let mut node_index: BTreeMap<i64, usize> = BTreeMap::new();
    let mut way_index: BTreeMap<i64, usize> = BTreeMap::new();
    for (id, (refs, tags)) in &ways {
        let top = is_building(tags);
        if !(top || is_part(tags) || member_ways.contains(id)) {
            continue;
        }
        if refs.iter().any(|r| !nodes.contains_key(r)) {
            continue;
        }
        let idx: Vec<usize> = refs
            .iter()
            .map(|r| {
                let next = t.nodes.len();
                *node_index.entry(*r).or_insert_with(|| {
                    t.nodes.push(nodes[r]);
                    next
                })
            })
            .collect();
        way_index.insert(*id, t.ways.len());
        if top {
            t.buildings.push((true, t.ways.len()));
        }
        t.ways.push((idx, tags.clone()));
    }
    for (members, tags) in rels.values() {
        let m: Vec<(usize, String)> = members
            .iter()
            .filter_map(|(id, role)| way_index.get(id).map(|&w| (w, role.clone())))
            .collect();
        if m.is_empty() {
            continue;
        }
        if is_building(tags) {
            t.buildings.push((false, t.relations.len()));
        }
        t.relations.push((m, tags.clone()));
    }
    let monaco_bounds = bounds(&t.nodes);
    add_clifton(&mut t, monaco_bounds)?;
    t.bounds = bounds(&t.nodes);
    Ok(t)
}

fn bounds(pts: &[(f64, f64)]) -> [f64; 4] {
    pts.iter().fold(
        [
            f64::INFINITY,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::NEG_INFINITY,
        ],
        |b, &(x, y)| [b[0].min(x), b[1].min(y), b[2].max(x), b[3].max(y)],
    )
}

/// The Clifton shapefile's footprints, to lon/lat, then moved east of `beside` keeping their
/// size in metres (longitudes scaled by the ratio of the latitudes' cosines).
fn add_clifton(t: &mut Template, beside: [f64; 4]) -> Result<(), Error> {
    let mut report = citygen::report::Report::default();
    let read = citygen::input::shp::read_shp(
        Path::new("data/clifton/clifton_test.shp"),
        &Default::default(),
        &mut report,
    )?;
    let crs = read.source_crs.ok_or("the Clifton shapefile has no CRS")?;
    let lonlat: Vec<LonLatPolygons> = read
        .footprints
        .iter()
        .map(|f| {
            f.polygons
                .iter()
                .map(|p| {
                    let conv = |r: &Vec<(f64, f64)>| {
                        r.iter()
                            .map(|&(x, y)| crs.to_lonlat(x, y))
                            .collect::<Vec<_>>()
                    };
                    (conv(&p.outer), p.holes.iter().map(conv).collect())
                })
                .collect()
        })
        .collect();
    let all: Vec<(f64, f64)> = lonlat
        .iter()
        .flatten()
        .flat_map(|(o, _)| o.iter().copied())
        .collect();
    let b = bounds(&all);
    let src_lat = (b[1] + b[3]) / 2.0;
    let dst_lat = (beside[1] + beside[3]) / 2.0;
    let kx = src_lat.to_radians().cos() / dst_lat.to_radians().cos();
    let gap = 0.002;
    let map = |(lon, lat): (f64, f64)| {
        (
            beside[2] + gap + (lon - b[0]) * kx,
            beside[1] + (lat - b[1]),
        )
    };
    for (f, polys) in read.footprints.iter().zip(&lonlat) {
        let mut tags = vec![("building".to_string(), "yes".to_string())];
        if let Some(h) = f.tags.height {
            tags.push(("height".into(), format!("{h}")));
        }
        if let Some(l) = f.tags.levels {
            tags.push(("building:levels".into(), format!("{l}")));
        }
        let ring_way = |t: &mut Template, r: &[(f64, f64)], tags: Vec<(String, String)>| {
            let first = t.nodes.len();
            t.nodes.extend(r.iter().map(|&p| map(p)));
            let mut idx: Vec<usize> = (first..t.nodes.len()).collect();
            idx.push(first);
            t.ways.push((idx, tags));
            t.ways.len() - 1
        };
        if polys.len() == 1 && polys[0].1.is_empty() {
            let w = ring_way(t, &polys[0].0, tags);
            t.buildings.push((true, w));
        } else {
            let mut members = Vec::new();
            for (outer, holes) in polys {
                members.push((ring_way(t, outer, Vec::new()), "outer".to_string()));
                for h in holes {
                    members.push((ring_way(t, h, Vec::new()), "inner".to_string()));
                }
            }
            tags.push(("type".into(), "multipolygon".into()));
            t.buildings.push((false, t.relations.len()));
            t.relations.push((members, tags));
        }
    }
    Ok(())
}

/// What one copy holds: every object, or (last copy) the first `k` buildings only.
struct Selection {
    nodes: Vec<bool>,
    ways: Vec<bool>,
    relations: Vec<bool>,
}

fn select(t: &Template, k: Option<usize>) -> Selection {
    let Some(k) = k else {
        return Selection {
            nodes: vec![true; t.nodes.len()],
            ways: vec![true; t.ways.len()],
            relations: vec![true; t.relations.len()],
        };
    };
    let mut s = Selection {
        nodes: vec![false; t.nodes.len()],
        ways: vec![false; t.ways.len()],
        relations: vec![false; t.relations.len()],
    };
    for &(is_way, i) in t.buildings.iter().take(k) {
        if is_way {
            s.ways[i] = true;
        } else {
            s.relations[i] = true;
            for (w, _) in &t.relations[i].0 {
                s.ways[*w] = true;
            }
        }
    }
    for (w, _) in t.ways.iter().enumerate().filter(|(i, _)| s.ways[*i]) {
        for &n in &t.ways[w].0 {
            s.nodes[n] = true;
        }
    }
    s
}

/// How one copy differs from the template, so that no two footprints of a tiled input are the
/// same shape (a cache of identical footprints would flatter the bench and speed up no real
/// city): the whole copy is turned by up to 6 degrees and scaled by up to 4 % about the
/// template's centre, and every node moves by up to 3 cm on its own. Nodes shared by two
/// buildings move together, so party walls stay party walls.
struct Jitter {
    copy: u64,
    cos: f64,
    sin: f64,
    scale: f64,
}

impl Jitter {
    fn of_copy(copy: u64) -> Jitter {
        let angle = (unit(copy, 0) * 2.0 - 1.0) * 6f64.to_radians();
        Jitter {
            copy,
            cos: angle.cos(),
            sin: angle.sin(),
            scale: 1.0 + (unit(copy, 1) * 2.0 - 1.0) * 0.04,
        }
    }

    /// Node `node` at `(lon, lat)`, turned and scaled about `centre` in a frame where one unit
    /// is as long east as north (`kx`: cos of the latitude), then moved by its own few cm.
    fn apply(&self, (lon, lat): (f64, f64), centre: (f64, f64), kx: f64, node: u64) -> (f64, f64) {
        const METRE: f64 = 1.0 / 111_320.0; // degrees of latitude
        let (x, y) = ((lon - centre.0) * kx, lat - centre.1);
        let (x, y) = (
            self.scale * (x * self.cos - y * self.sin),
            self.scale * (x * self.sin + y * self.cos),
        );
        let k = (self.copy << 32) ^ node;
        let (ex, ey) = (
            (unit(k, 2) * 2.0 - 1.0) * 0.03 * METRE,
            (unit(k, 3) * 2.0 - 1.0) * 0.03 * METRE,
        );
        (centre.0 + (x + ex) / kx, centre.1 + y + ey)
    }
}

/// A number in [0, 1) from `(key, salt)` (splitmix64).
fn unit(key: u64, salt: u64) -> f64 {
    let mut z = key
        .wrapping_mul(0x9E37_79B9_7F4A_7C15)
        .wrapping_add(salt.wrapping_mul(0xBF58_476D_1CE4_E5B9))
        .wrapping_add(0x94D0_49BB_1331_11EB);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^= z >> 31;
    (z >> 11) as f64 / (1u64 << 53) as f64
}

/// Writes `n` buildings tiled from the template to `out` (see the module documentation).
fn make_tiled(n: usize, out: &Path) -> Result<PathBuf, Error> {
    let t = Instant::now();
    let tpl = template()?;
    let per = tpl.buildings.len();
    if per == 0 {
        return Err("no buildings in the template".into());
    }
    let copies = n.div_ceil(per);
    let cols = (copies as f64).sqrt().ceil() as usize;
    let [x0, y0, x1, y1] = tpl.bounds;
    // Room for the copy's rotation (at most 6 degrees) and scale (at most 4 %).
    let (dx, dy) = ((x1 - x0) * 1.2, (y1 - y0) * 1.2);
    let (cx, cy) = ((x0 + x1) / 2.0, (y0 + y1) / 2.0);
    let kx = cy.to_radians().cos();
    let full = select(&tpl, None);
    let last = select(&tpl, Some(n - (copies - 1) * per));
    let sel = |c: usize| if c + 1 == copies { &last } else { &full };
    let (nn, nw, nr) = (
        tpl.nodes.len() as i64,
        tpl.ways.len() as i64,
        tpl.relations.len() as i64,
    );
    if let Some(dir) = out.parent() {
        std::fs::create_dir_all(dir)?;
    }
    let tmp = out.with_extension("tmp");
    let mut w = PbfWriter::new(BufWriter::with_capacity(1 << 20, File::create(&tmp)?))?;
    for c in 0..copies {
        let (ox, oy) = ((c % cols) as f64 * dx, (c / cols) as f64 * dy);
        let s = sel(c);
        let jitter = Jitter::of_copy(c as u64);
        for (i, &p) in tpl.nodes.iter().enumerate() {
            if s.nodes[i] {
                let (lon, lat) = jitter.apply(p, (cx, cy), kx, i as u64);
                w.node(c as i64 * nn + i as i64 + 1, lon + ox, lat + oy, &[])?;
            }
        }
    }
    let mut refs = Vec::new();
    for c in 0..copies {
        let s = sel(c);
        for (i, (nodes, tags)) in tpl.ways.iter().enumerate() {
            if s.ways[i] {
                refs.clear();
                refs.extend(nodes.iter().map(|&k| c as i64 * nn + k as i64 + 1));
                let tags: Vec<(&str, &str)> =
                    tags.iter().map(|(k, v)| (k.as_str(), v.as_str())).collect();
                w.way(c as i64 * nw + i as i64 + 1, &refs, &tags)?;
            }
        }
    }
    for c in 0..copies {
        let s = sel(c);
        for (i, (members, tags)) in tpl.relations.iter().enumerate() {
            if s.relations[i] {
                let m: Vec<(MemberKind, i64, &str)> = members
                    .iter()
                    .map(|(wi, role)| {
                        (
                            MemberKind::Way,
                            c as i64 * nw + *wi as i64 + 1,
                            role.as_str(),
                        )
                    })
                    .collect();
                let tags: Vec<(&str, &str)> =
                    tags.iter().map(|(k, v)| (k.as_str(), v.as_str())).collect();
                w.relation(c as i64 * nr + i as i64 + 1, &m, &tags)?;
            }
        }
    }
    w.finish()?;
    std::fs::rename(&tmp, out)?;
    println!(
        "made {} ({n} buildings: {copies} copies of {per} in {cols} columns, {:.1} MB) in {:.1} s",
        out.display(),
        std::fs::metadata(out)?.len() as f64 / 1e6,
        t.elapsed().as_secs_f64()
    );
    Ok(out.to_path_buf())
}
