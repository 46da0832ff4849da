//! The `citygen` command line: arguments, progress, summary and exit code. All the work is in
//! the library (`citygen::pipeline`).

use std::io::IsTerminal;
use std::path::PathBuf;
use std::process::ExitCode;

use clap::{ArgGroup, Parser};

use citygen::crs::Crs;
use citygen::grammar::Caps;
use citygen::model::Lod;
use citygen::pipeline::{self, Options, RunError, Source};

/// Turns a city's building footprints (OSM PBF or shapefile) into BIM and city models:
/// IFC4, CityGML 2.0 (LOD1-2) and glTF 2.0 binary.
///
/// Each footprint is matched to the deepest zone of the knowledge base (or ruled by --rules),
/// derived with the shape grammar, and written to every requested output. Outputs are written
/// atomically. Same inputs and --seed give byte-identical files, whatever --threads is.
///
/// Exit codes: 0 success; 1 bad input (file, knowledge base, rules); 2 bad usage;
/// 3 an output could not be written.
#[derive(Parser, Debug)]
#[command(name = "citygen", version, about, long_about)]
#[command(group(ArgGroup::new("input").required(true).args(["osm", "shp"])))]
#[command(group(ArgGroup::new("style").required(true).args(["kb", "rules"])))]
#[command(group(ArgGroup::new("outputs").required(true).multiple(true).args(["ifc", "citygml", "gltf"])))]
struct Cli {
    /// OpenStreetMap extract (.osm.pbf) to read building footprints from.
    #[arg(long, value_name = "FILE.pbf")]
    osm: Option<PathBuf>,
    /// ESRI shapefile (.shp with its .shx, .dbf and .prj) to read footprints from.
    #[arg(long, value_name = "FILE.shp")]
    shp: Option<PathBuf>,
    /// Knowledge base of regional appearance (XML, seed 003 format).
    #[arg(long, value_name = "KB.xml")]
    kb: Option<PathBuf>,
    /// Grammar ruleset applied to every footprint instead of the knowledge base's rules.
    #[arg(long, value_name = "FILE")]
    rules: Option<PathBuf>,
    /// Level of detail: 1 (blocks) or 2 (roofs and semantic surfaces).
    #[arg(long, value_parser = parse_lod, default_value = "2")]
    lod: Lod,
    /// Write IFC4 (STEP) here.
    #[arg(long, value_name = "OUT.ifc")]
    ifc: Option<PathBuf>,
    /// Write CityGML 2.0 here.
    #[arg(long, value_name = "OUT.gml")]
    citygml: Option<PathBuf>,
    /// Write glTF 2.0 binary (.glb) here.
    #[arg(long, value_name = "OUT.glb")]
    gltf: Option<PathBuf>,
    /// Write the JSON report (counts, skipped and repaired footprints with reasons) here.
    #[arg(long, value_name = "OUT.json")]
    report: Option<PathBuf>,
    /// Seed of every random choice (appearances, rand() in rules).
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Output CRS, e.g. EPSG:2154 (Lambert-93). Default: the UTM zone of the data.
    #[arg(long, value_name = "EPSG:n", value_parser = parse_crs)]
    crs: Option<Crs>,
    /// CRS of the input coordinates, overriding a shapefile's .prj.
    #[arg(long, value_name = "EPSG:n", value_parser = parse_crs)]
    src_crs: Option<Crs>,
    /// Shapefile attribute holding the building height in metres (default: detected).
    #[arg(long, value_name = "NAME")]
    shp_height_field: Option<String>,
    /// Shapefile attribute holding the number of storeys (default: detected).
    #[arg(long, value_name = "NAME")]
    shp_levels_field: Option<String>,
    /// Worker threads for derivation (default: all cores). Outputs do not depend on it.
    #[arg(long, value_name = "N")]
    threads: Option<usize>,
    /// Maximum derivation depth per building.
    #[arg(long, default_value_t = Caps::default().max_depth)]
    max_depth: usize,
    /// Maximum number of shapes per building.
    #[arg(long, default_value_t = Caps::default().max_shapes)]
    max_shapes: usize,
    /// No progress bar and no summary.
    #[arg(long, short)]
    quiet: bool,
}

fn parse_lod(s: &str) -> Result<Lod, String> {
    match s.trim() {
        "1" => Ok(Lod::Lod1),
        "2" => Ok(Lod::Lod2),
        "3" | "4" => Err(format!("LOD {s} is not available yet; use 1 or 2")),
        _ => Err(format!("LOD must be 1 or 2, not {s:?}")),
    }
}

fn parse_crs(s: &str) -> Result<Crs, String> {
    Crs::from_epsg_str(s).map_err(|e| e.to_string())
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    if let Some(n) = cli.threads {
        if let Err(e) = rayon::ThreadPoolBuilder::new()
            .num_threads(n.max(1))
            .build_global()
        {
            eprintln!("citygen: cannot start {n} threads: {e}");
            return ExitCode::from(2);
        }
    }
    let source = match (&cli.osm, &cli.shp) {
        (Some(p), _) => Source::Osm(p.clone()),
        (None, Some(p)) => Source::Shp {
            path: p.clone(),
            height_field: cli.shp_height_field.clone(),
            levels_field: cli.shp_levels_field.clone(),
        },
        (None, None) => unreachable!("clap requires --osm or --shp"),
    };
    let opts = Options {
        source,
        kb: cli.kb.clone(),
        rules: cli.rules.clone(),
        lod: cli.lod,
        ifc: cli.ifc.clone(),
        citygml: cli.citygml.clone(),
        gltf: cli.gltf.clone(),
        report: cli.report.clone(),
        seed: cli.seed,
        crs: cli.crs,
        src_crs: cli.src_crs,
        caps: Caps {
            max_depth: cli.max_depth,
            max_shapes: cli.max_shapes,
            ..Caps::default()
        },
    };
    let show = !cli.quiet && std::io::stderr().is_terminal();
    let bar = indicatif::ProgressBar::hidden();
    if show {
        bar.set_draw_target(indicatif::ProgressDrawTarget::stderr());
        bar.set_style(
            indicatif::ProgressStyle::with_template(
                "{bar:40} {pos}/{len} buildings  {per_sec}  eta {eta}",
            )
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
        );
    }
    let progress = |done: usize, total: usize| {
        bar.set_length(total as u64);
        bar.set_position(done as u64);
    };
    match pipeline::run(&opts, &progress) {
        Ok(summary) => {
            bar.finish_and_clear();
            if !cli.quiet {
                let r = &summary.report;
                let secs = summary.elapsed.as_secs_f64().max(1e-9);
                eprintln!(
                    "citygen: read {} buildings and {} parts; generated {}, repaired {}, skipped {} in {:.2} s ({:.0} buildings/s, {:.0} polygons/s)",
                    r.read,
                    r.parts_read,
                    r.generated,
                    r.repaired,
                    r.skipped,
                    secs,
                    r.generated as f64 / secs,
                    summary.polygons as f64 / secs
                );
                for p in &summary.outputs {
                    eprintln!("  wrote {}", p.display());
                }
            }
            ExitCode::SUCCESS
        }
        Err(e) => {
            bar.finish_and_clear();
            eprintln!("citygen: error: {e}");
            ExitCode::from(match e {
                RunError::Input(_) => 1,
                RunError::Output { .. } => 3,
            })
        }
    }
}
