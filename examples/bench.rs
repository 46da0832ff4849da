//! Benchmark of the release `citygen` binary (see the README's "Benchmark" section).
//!
//! ```text
//! cargo build --release
//! cargo run --release --example bench -- data/monaco/monaco.osm.pbf 5      # a file, best of 5
//! cargo run --release --example bench -- 10000 100000                      # tiled inputs
//! cargo run --release --example bench -- --make 100000 target/bench-inputs/x.osm.pbf
//! cargo run --release --example bench -- --make-day2 100000 target/bench-inputs/day2 --seed 1 [--clustered]
//! ```
//!
//! Inputs: a path (`.osm.pbf` or `.shp`), or a building count `N` (`10000`, `100k`, `1M`): the
//! tiled input `target/bench-inputs/jittered-N.osm.pbf`, made first when missing. `--make N OUT`
//! only makes one: the buildings of data/monaco and the Clifton shapefile's footprints
//! (converted to lon/lat and moved beside Monaco, keeping their size in metres) are repeated in
//! a grid of copies with coordinate offsets and new node/way/relation ids per copy, until there
//! are N buildings (the last copy is partial). Every copy is turned, scaled and its nodes moved
//! by a few centimetres, so no two footprints are the same shape ([`citygen::testkit::tiled`]).
//!
//! `--make-day2 N DIR [--seed S] [--clustered]` (seed 1 by default; edits anywhere, or in
//! clusters as a day of OSM changesets) makes the input of an incremental run
//! ([`citygen::testkit::day2`]): in DIR, `day1.osm.pbf` (the bytes of `--make N`),
//! `day2.osm.pbf` (about 1 % of the N buildings changed, 0.5 % added, 0.5 % removed),
//! `changes.osc.gz` (the gzipped osmChange from day 1 to day 2) and `edits.json`
//! (`{"added": [...], "removed": [...], "changed": [...]}` as `way/ID`, sorted by id), then
//! checks with citygen's reader that the list is exactly what differs between the two days.
//!
//! For each input it runs the `citygen` binary next to this example (target/release/citygen)
//! as a child process per configuration: LOD 1, 2, 3 × (IFC, CityGML, glTF, all three), and
//! prints buildings/s, output polygons/s, output MB/s and the child's peak RSS (from `wait4`),
//! best wall-clock time of the repetitions, with that peak per building (`B/bldg`) and the
//! read's share of it (`read%`: the peak when citygen's read ends, from its `memory:` line). Then, for a PBF, the raw osmpbf decode speed of the
//! same file (every blob, osmpbf's parallel reader, counting nodes, ways and relations) beside
//! citygen's read phase alone (`input::osm::read_osm`, in this process).
//!
//! Flags: `--lods 1,2,3` (default all), `--formats all,ifc,gml,glb` (default all four),
//! `--reps R` (default 1, or the number after a file path), `--kb FILE`, `--threads N`,
//! `--tile METRES` and `--dry-run` (passed on to citygen; a dry run renders every output and
//! counts its bytes but writes none, for runs whose outputs the disk cannot hold), `--dem FILE`
//! (each repetition also runs on the DEM, alternated, and a line gives the median CPU seconds
//! with and without it: the cost of terrain), `--read`
//! (only the read comparison, no citygen runs). MB out is the byte count citygen's summary
//! gives, the same whether written or not.

use std::io::Read;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::Instant;

use osmpbf::{Element, ElementReader};

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
    let mut day2: Option<(usize, PathBuf)> = None;
    let mut seed = 1u64;
    let mut spread = citygen::testkit::day2::Spread::Uniform;
    let mut dem: Option<String> = None;
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
                return make_tiled(n, &out);
            }
            "--make-day2" => {
                let n = parse_count(&value()?)?;
                day2 = Some((n, PathBuf::from(value()?)));
            }
            "--seed" => seed = value()?.parse()?,
            "--clustered" => spread = citygen::testkit::day2::Spread::Clustered,
            "--reps" => reps = Some(value()?.parse()?),
            // Only the read comparison (raw osmpbf decode vs citygen's read phase).
            "--read" => lods.clear(),
            "--kb" => kb = PathBuf::from(value()?),
            "--threads" => extra.extend(["--threads".to_string(), value()?]),
            "--tile" => extra.extend(["--tile".to_string(), value()?]),
            "--dry-run" => extra.push("--dry-run".into()),
            "--dem" => dem = Some(value()?),
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
    if let Some((n, dir)) = day2 {
        return make_day2(n, &dir, seed, spread);
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
        let dem = dem.as_deref();
        bench_input(
            &bin, &path, &kb, &lods, &formats, reps, &extra, dem, &out_dir,
        )?;
    }
    Ok(())
}

/// The median of `v` (0 when empty).
fn median(v: &mut [f64]) -> f64 {
    if v.is_empty() {
        return 0.0;
    }
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        (v[n / 2 - 1] + v[n / 2]) / 2.0
    }
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
    /// The read's own peak RSS (KiB), from citygen's `memory:` line (Linux; 0 elsewhere).
    read_kib: u64,
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
    dem: Option<&str>,
    out_dir: &Path,
) -> Result<(), Error> {
    let size = std::fs::metadata(input)?.len();
    let with_dem: Option<Vec<String>> =
        dem.map(|d| [extra, &["--dem".to_string(), d.to_string()]].concat());
    let is_shp = input.extension().is_some_and(|e| e == "shp");
    println!(
        "\n== {} ({:.1} MB)\n{:<4} {:<10} {:>9} {:>10} {:>8} {:>8} {:>11} {:>12} {:>9} {:>8} {:>9} {:>8} {:>6}",
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
        "RSS MiB",
        "B/bldg",
        "read%"
    );
    for &lod in lods {
        for &format in formats {
            let mut best: Option<RunResult> = None;
            // With `--dem`, each repetition runs the same configuration on the DEM right after,
            // so the two alternate and share the machine's load.
            let (mut cpu, mut cpu_dem, mut rss_dem) = (Vec::new(), Vec::new(), 0u64);
            for _ in 0..reps {
                if let Some(w) = &with_dem {
                    let d = run_child(bin, input, is_shp, kb, lod, format, w, out_dir)?;
                    cpu_dem.push(d.cpu);
                    rss_dem = rss_dem.max(d.rss_kib);
                }
                let r = run_child(bin, input, is_shp, kb, lod, format, extra, out_dir)?;
                cpu.push(r.cpu);
                let rss = best.as_ref().map_or(0, |b| b.rss_kib).max(r.rss_kib);
                if best.as_ref().is_none_or(|b| r.secs < b.secs) {
                    best = Some(RunResult { rss_kib: rss, ..r });
                } else if let Some(b) = &mut best {
                    b.rss_kib = rss;
                }
            }
            let Some(r) = best else { continue };
            println!(
                "{:<4} {:<10} {:>9} {:>10} {:>8.2} {:>8.2} {:>11.0} {:>12.0} {:>9.1} {:>8.1} {:>9.1} {:>8.0} {:>6.0}",
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
                r.rss_kib as f64 / 1024.0,
                r.rss_kib as f64 * 1024.0 / r.buildings.max(1) as f64,
                100.0 * r.read_kib as f64 / r.rss_kib.max(1) as f64
            );
            if !cpu_dem.is_empty() {
                let (base, with) = (median(&mut cpu), median(&mut cpu_dem));
                println!(
                    "     with --dem: CPU s {with:.2} against {base:.2} (medians of {reps}): {:+.1} %, RSS {:.1} MiB",
                    100.0 * (with / base - 1.0),
                    rss_dem as f64 / 1024.0
                );
            }
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
        read_kib: read_peak_kib(&stderr),
    })
}

/// The read's own peak RSS in KiB from citygen's summary line `  memory: read to S s, RSS R
/// MiB, peak P MiB; ...` (the peak so far when the read ends); 0 without the line.
fn read_peak_kib(stderr: &str) -> u64 {
    stderr
        .lines()
        .find_map(|l| l.trim_start().strip_prefix("memory: read to "))
        .and_then(|l| l.split(';').next())
        .and_then(|l| l.split("peak ").nth(1))
        .and_then(|l| l.trim_end_matches(" MiB").trim().parse::<f64>().ok())
        .map_or(0, |mib| (mib * 1024.0) as u64)
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

/// Writes the tiled input of `n` buildings to `out` ([`citygen::testkit::tiled`]) and says so.
fn make_tiled(n: usize, out: &Path) -> Result<(), Error> {
    let t = Instant::now();
    let made = citygen::testkit::tiled::make_tiled(n, out)?;
    println!(
        "made {} ({n} buildings: {} copies of {} in {} columns, {:.1} MB) in {:.1} s",
        out.display(),
        made.copies,
        made.per_copy,
        made.columns,
        std::fs::metadata(out)?.len() as f64 / 1e6,
        t.elapsed().as_secs_f64()
    );
    Ok(())
}

/// Writes day 1, day 2, the osmChange and the edit list of `n` buildings into `dir`
/// ([`citygen::testkit::day2`]), then checks the edit list with citygen's reader.
fn make_day2(
    n: usize,
    dir: &Path,
    seed: u64,
    spread: citygen::testkit::day2::Spread,
) -> Result<(), Error> {
    use citygen::testkit::day2;
    let t = Instant::now();
    let d = day2::make_day2_spread(n, dir, seed, spread)?;
    let made = t.elapsed().as_secs_f64();
    let (create, modify, delete) = d.osc_counts();
    println!(
        "made {} (seed {seed}, {spread:?} edits): day 1 {n} buildings ({} copies of {}), {} changed ({} moved), \
         {} added, {} removed; osmChange: {create} create, {modify} modify, {delete} delete \
         elements, in {made:.1} s",
        dir.display(),
        d.tiled.copies,
        d.tiled.per_copy,
        d.changed.len(),
        d.moved.len(),
        d.added.len(),
        d.removed.len(),
    );
    let t = Instant::now();
    let v = day2::verify_day2(dir)?;
    println!(
        "checked with citygen's reader: {} footprints on day 1, {} on day 2, {} changed in tags, \
         {} in rings; every other footprint the same, in {:.1} s",
        v.day1_footprints,
        v.day2_footprints,
        v.tags_changed,
        v.rings_changed,
        t.elapsed().as_secs_f64()
    );
    Ok(())
}
