//! The main job (`citygen --osm ... --kb ... --gltf ...`): its arguments, the thread pool,
//! the progress bar, the summary line (with the peak RSS) and the warnings.

use std::io::IsTerminal;
use std::path::PathBuf;

use clap::{ArgGroup, Args};

use super::args::{
    parse_bbox, parse_crs, parse_ground_height, parse_infer, parse_lod, parse_megabytes,
    parse_output_crs, InferArg,
};
use super::{AppError, Outcome};
use crate::crs::Crs;
use crate::grammar::Caps;
use crate::model::Lod;
use crate::pipeline::{self, Options, Source};

/// The main job's arguments.
#[derive(Args, Debug)]
#[command(group(ArgGroup::new("input").required(true).args(["osm", "shp"])))]
#[command(group(ArgGroup::new("style").required(true).args(["kb", "rules"])))]
#[command(group(ArgGroup::new("outputs").required(true).multiple(true).args(["ifc", "citygml", "gltf", "cityjson", "cityjsonseq", "tiles3d", "preview"])))]
pub(crate) struct RunArgs {
    /// OpenStreetMap extract to read building footprints from: OSM PBF, or OSM XML (.osm, plain,
    /// .osm.gz or .osm.bz2), told by the content.
    #[arg(long, value_name = "FILE.pbf")]
    osm: Option<PathBuf>,
    /// GIS footprints to read: an ESRI shapefile (.shp with its .shx, .dbf and .prj), a
    /// GeoJSON FeatureCollection, a GeoPackage or a FlatGeobuf file (told apart by content;
    /// also `--footprints`).
    #[arg(
        long,
        visible_alias = "footprints",
        value_name = "FILE.shp|FILE.geojson|FILE.gpkg|FILE.fgb"
    )]
    shp: Option<PathBuf>,
    /// Knowledge base of regional appearance (XML, seed 003 format).
    #[arg(long, value_name = "KB.xml")]
    kb: Option<PathBuf>,
    /// Grammar ruleset applied to every footprint instead of the knowledge base's rules.
    #[arg(long, value_name = "FILE")]
    rules: Option<PathBuf>,
    /// Level of detail: 1 (blocks), 2 (roofs and semantic surfaces), 3 (storeys, facades,
    /// windows, doors and balconies) or 4 (interiors: rooms, interior walls and doors, stairs).
    #[arg(long, value_parser = parse_lod, default_value = "2")]
    lod: Lod,
    /// Write IFC (STEP) here: IFC4 unless --ifc-schema says otherwise.
    #[arg(long, value_name = "OUT.ifc")]
    ifc: Option<PathBuf>,
    /// The IFC schema of --ifc: IFC4 (the default), IFC2X3 (for tools that read nothing newer:
    /// site latitude/longitude instead of a map conversion, window and door styles, a
    /// surface-model terrain) or IFC4X3_ADD2 (IfcWall instead of IfcWallStandardCase).
    #[arg(
        long,
        value_name = "IFC2X3|IFC4|IFC4X3_ADD2",
        default_value = "IFC4",
        requires = "ifc"
    )]
    ifc_schema: crate::export::ifc::IfcSchema,
    /// Keep every IFC file under N MB (10^6 bytes, decimals allowed; the buildingSMART
    /// validation service takes 256): a larger IFC is split, in lot order, into complete IFC files (each with its
    /// project, site, units and map conversion) named OUT-001.ifc, OUT-002.ifc, ...; OUT.ifc
    /// when it fits. With --tile each tile's file is split on its own. A building larger than
    /// the cap alone gets a file of its own (noted in the report).
    #[arg(long, value_name = "N", value_parser = parse_megabytes, requires = "ifc")]
    ifc_max_mb: Option<u64>,
    /// Write CityGML 2.0 here.
    #[arg(long, value_name = "OUT.gml")]
    citygml: Option<PathBuf>,
    /// Write glTF 2.0 binary (.glb) here.
    #[arg(long, value_name = "OUT.glb")]
    gltf: Option<PathBuf>,
    /// Write CityJSON 2.0 here (one file; vertices in millimetres around the run's origin).
    #[arg(long, value_name = "OUT.city.json")]
    cityjson: Option<PathBuf>,
    /// Write CityJSONSeq here (a header line, then one CityJSONFeature line per building).
    #[arg(long, value_name = "OUT.city.jsonl")]
    cityjsonseq: Option<PathBuf>,
    /// Write the JSON report (counts, skipped and repaired footprints with reasons) here.
    #[arg(long, value_name = "OUT.json")]
    report: Option<PathBuf>,
    /// Write an overview picture of the run's buildings (PNG, a bird's-eye view rendered in
    /// citygen, no browser needed): one picture for the whole run, even with --tile.
    #[arg(long, value_name = "OUT.png")]
    preview: Option<PathBuf>,
    /// Write OGC 3D Tiles 1.1 into this folder: tileset.json and per tile two GLB contents in
    /// the tile's east-north-up frame (content/{tile}.glb as derived, content/{tile}-blocks.glb
    /// LOD1 blocks for distant views), every building a feature with its id, zone, appearance,
    /// height and storeys (EXT_mesh_features, EXT_structural_metadata). With --shard,
    /// `citygen merge --tiles3d` writes the tileset.
    #[arg(long, value_name = "DIR")]
    tiles3d: Option<PathBuf>,
    /// Seed of every random choice (appearances, rand() in rules).
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Output CRS, projected (metres), e.g. EPSG:2154 (Lambert-93). Default: the UTM zone of
    /// the data's centre (inside --bbox); data too wide for one zone needs --crs or --bbox.
    #[arg(long, value_name = "EPSG:n", value_parser = parse_output_crs)]
    crs: Option<Crs>,
    /// CRS of the input coordinates, overriding a shapefile's .prj or a GeoJSON's crs member.
    #[arg(long, value_name = "EPSG:n", value_parser = parse_crs)]
    src_crs: Option<Crs>,
    /// Shapefile attribute (or GeoJSON property) holding the building height in metres
    /// (default: detected).
    #[arg(long, value_name = "NAME")]
    shp_height_field: Option<String>,
    /// Shapefile attribute (or GeoJSON property) holding the number of storeys (default:
    /// detected).
    #[arg(long, value_name = "NAME")]
    shp_levels_field: Option<String>,
    /// The column of the footprints file that gives one of citygen's fields, as
    /// TARGET=COLUMN (e.g. height=HOEHE; repeatable). Targets: id, height, min_height, ground
    /// (the elevation an absolute height counts from), levels, min_level, roof_shape,
    /// roof_height, roof_colour, colour, material, roof_material, kind, name. Default: found
    /// by common names (OSM keys, Overture's, 3DBAG's b3_*, HOEHE, heightroof, ...).
    #[arg(long = "field", value_name = "TARGET=COLUMN", value_parser = crate::input::features::parse_field)]
    fields: Vec<(String, String)>,
    /// The GeoPackage layer to read (default: the only one, else the first polygon layer).
    #[arg(long, value_name = "NAME")]
    layer: Option<String>,
    /// Worker threads for derivation (default: all cores). Outputs do not depend on it.
    #[arg(long, value_name = "N")]
    threads: Option<usize>,
    /// Maximum derivation depth per building.
    #[arg(long, default_value_t = Caps::default().max_depth)]
    max_depth: usize,
    /// Maximum number of shapes per building.
    #[arg(long, default_value_t = Caps::default().max_shapes)]
    max_shapes: usize,
    /// Only generate the buildings whose representative point lies in this box (degrees:
    /// min lon, min lat, max lon, max lat), e.g. to split a region across machines. The others
    /// are counted in the report.
    #[arg(long, value_name = "LON0,LAT0,LON1,LAT1", value_parser = parse_bbox)]
    bbox: Option<[f64; 4]>,
    /// Split the outputs into square tiles of this many metres of the output CRS: `out.gml`
    /// becomes `out_{easting}_{northing}.gml` per tile holding buildings (the lower-left
    /// corner of the tile). A building belongs to the tile of its representative point.
    #[arg(long, value_name = "METRES", value_parser = clap::value_parser!(u32).range(10..))]
    tile: Option<u32>,
    /// Derive every building and render every output, but write none of them (the --report
    /// is still written): the summary says which files and how many bytes a real run would
    /// write. For checking a region's input, or sizing its outputs, before a nightly run.
    #[arg(long)]
    dry_run: bool,
    /// Procedural textures (drawn by citygen, no image assets) on the walls and roofs of the
    /// glTF, 3D Tiles, CityGML and CityJSON outputs: each material's pattern in metres (brick
    /// courses, stone, boards, tile and slate rows), and at LOD2 each wall's windows and
    /// storeys, the bays its LOD3 facade would have. glTF and 3D Tiles hold the pictures;
    /// CityGML and CityJSON name PNG files written beside them (out.gml: out_textures/). Off
    /// by default.
    #[arg(long)]
    textures: bool,
    /// Accept output file names whose extension is not the format's (.ifc, .gml or .xml, .glb,
    /// .json for the report).
    #[arg(long)]
    force_extension: bool,
    /// Write the outputs even when no building is generated (an empty --bbox, every footprint
    /// skipped); without it such a run is an error (exit 1) and writes nothing.
    #[arg(long)]
    allow_empty: bool,
    /// What is estimated for a building lacking tags: kb (as its knowledge-base zone says,
    /// <info infer="...">), none (the zone's appearances draw everything), all, or a
    /// comma-separated list of levels (height and storeys), roof (flat or pitched, and the
    /// shape) and colour (building:colour, roof:colour: the weighted majority of at least 3
    /// tagged neighbours). Heights and roofs come from the estimator: a prior from the
    /// footprint's form and context and the zone's level (its nbfloor), at least 3 tagged
    /// neighbours (the nearest 24 within 500 m), caps by
    /// kind and size, attached rows made one. Every estimate carries its source and
    /// uncertainty in every output; buildings its neighbours moved have a report note.
    #[arg(long, value_name = "WHAT", default_value = "kb", value_parser = parse_infer)]
    infer: InferArg,
    /// Write only shard I of N (counted from 0) of a tiled run (needs --tile), and its
    /// manifest `citygen-manifest.I-of-N.json` beside the outputs; `citygen merge` puts the
    /// shards together. Every shard reads the whole input and computes the same assignment of
    /// tiles to shards, so N processes need no coordinator. `auto` takes I from
    /// JOB_COMPLETION_INDEX (Kubernetes Indexed Job) or SLURM_ARRAY_TASK_ID (Slurm array) and
    /// N from --shards or SLURM_ARRAY_TASK_COUNT.
    #[arg(long, value_name = "I/N|auto", value_parser = crate::pipeline::shard::parse_shard)]
    shard: Option<crate::pipeline::shard::ShardArg>,
    /// The head of a `citygen split` part (`part-I-of-N.split.json`): --osm is its PBF
    /// (`part-I-of-N.osm.pbf`) and --shard must be I/N. The run reads only its part of the
    /// input and writes the files and manifest the same shard writes from the whole input.
    #[arg(
        long,
        value_name = "PART.split.json",
        requires = "shard",
        requires = "osm"
    )]
    split_part: Option<PathBuf>,
    /// The number of shards for --shard auto (a Kubernetes Indexed Job's completions).
    #[arg(long, value_name = "N", requires = "shard", value_parser = clap::value_parser!(u32).range(1..=100_000))]
    shards: Option<u32>,
    /// Yesterday's tiled output folder (its citygen-manifest.*.json and tiles; needs --tile):
    /// every tile whose buildings and their content keys are unchanged is copied from it
    /// (checked by SHA-256) instead of derived; the report's "changes" lists the buildings
    /// added, removed, changed and affected, and the tiles reused, rewritten and gone.
    #[arg(long, value_name = "DIR", requires = "tile")]
    previous: Option<PathBuf>,
    /// Reuse --previous's files as hard links instead of copies (as rsync --link-dest): no
    /// bytes copied where both folders are on one file system (copied where they are not).
    /// The two runs then share those files' inodes: citygen never writes a file in place, but
    /// another tool that does would change both.
    #[arg(long, requires = "previous")]
    link_previous: bool,
    /// An OSM change file (osmChange XML, .osc or .osc.gz, e.g. a replication diff) applied on
    /// top of the --osm extract: the run reads the extract as the change leaves it.
    #[arg(long, value_name = "FILE.osc[.gz]", requires = "osm")]
    osc: Option<PathBuf>,
    /// The source's name written into the outputs (titles, the IFC project and its GUIDs'
    /// namespace), instead of the input's file name: a nightly job whose extract carries the
    /// date in its name (region-20261204.osm.pbf) passes a stable one, so that unchanged
    /// buildings keep their bytes and GUIDs from day to day.
    #[arg(long, value_name = "NAME")]
    source_name: Option<String>,
    /// A digital elevation model (GeoTIFF, heights in metres; repeat for several tiles, the
    /// first given that has a height at a point wins): every building stands on the lowest
    /// terrain under its footprint. Its CRS must be one citygen knows (reproject with
    /// `gdalwarp -t_srs EPSG:...`).
    #[arg(long, value_name = "FILE.tif", conflicts_with = "ground_height")]
    dem: Vec<PathBuf>,
    /// Without a DEM: the height (metres) every building stands at.
    #[arg(long, value_name = "METRES", value_parser = parse_ground_height)]
    ground_height: Option<f64>,
    /// The largest vertical distance, in metres, between the terrain written beside the
    /// buildings and the elevation samples it simplifies (a TIN; see docs/terrain-output.md).
    #[arg(long, value_name = "M", default_value_t = crate::pipeline::terrain::DEFAULT_TOLERANCE, value_parser = parse_tolerance)]
    terrain_tolerance: f64,
    /// Write no terrain: by default a run with an elevation grid writes the terrain beside the
    /// buildings in every model output and 3D Tiles.
    #[arg(long)]
    no_terrain: bool,
    /// No progress bar and no summary.
    #[arg(long, short)]
    quiet: bool,
}

/// `--terrain-tolerance`: a finite number of metres, 0 to 1000.
fn parse_tolerance(s: &str) -> Result<f64, String> {
    match s.parse::<f64>() {
        Ok(v) if v.is_finite() && (0.0..=1000.0).contains(&v) => Ok(v),
        _ => Err(format!("{s:?} is not a tolerance in metres from 0 to 1000")),
    }
}

/// The main job.
pub(crate) fn run(cli: RunArgs) -> Result<Outcome, AppError> {
    if let Some(asked) = cli.threads {
        // More threads than cores buys nothing (the outputs do not depend on the count) and
        // thousands take longer to start than the run.
        let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
        let cap = (4 * cores).max(1);
        let n = asked.clamp(1, cap);
        if n != asked && !cli.quiet {
            eprintln!("citygen: note: --threads {asked} runs {n} threads (at least 1, at most 4 per core: {cores} cores)");
        }
        if let Err(source) = rayon::ThreadPoolBuilder::new()
            .num_threads(n)
            .build_global()
        {
            return Err(AppError::Threads { threads: n, source });
        }
    }
    if let (Some(p), Some(c)) = (&cli.osm, cli.src_crs) {
        if c != crate::crs::Crs::Wgs84 {
            return Err(AppError::Usage(format!(
                "--src-crs {} does not apply to --osm {}: OpenStreetMap coordinates are always longitude and latitude (EPSG:4326); --src-crs is for shapefiles whose .prj is missing or wrong",
                c.epsg(),
                p.display()
            )));
        }
    }
    let source = match (&cli.osm, &cli.shp) {
        (Some(p), _) => Source::Osm(p.clone()),
        (None, Some(p)) => Source::Shp {
            path: p.clone(),
            height_field: cli.shp_height_field.clone(),
            levels_field: cli.shp_levels_field.clone(),
            fields: cli.fields.clone(),
            layer: cli.layer.clone(),
        },
        (None, None) => unreachable!("clap requires --osm or --shp"),
    };
    use crate::pipeline::shard::{self, ShardArg};
    let shard = match cli.shard {
        None => None,
        Some(ShardArg::Fixed(s)) => {
            if cli.shards.is_some_and(|n| n as usize != s.count) {
                return Err(AppError::Usage(format!(
                    "--shard {s} and --shards {} disagree",
                    cli.shards.unwrap_or(0)
                )));
            }
            Some((s, format!("--shard {s}")))
        }
        Some(ShardArg::Auto) => {
            match shard::from_env(cli.shards.map(|n| n as usize), &|k| std::env::var(k).ok()) {
                Ok(found) => {
                    if !cli.quiet {
                        eprintln!("citygen: {}", found.1);
                    }
                    Some(found)
                }
                Err(e) => return Err(AppError::Usage(e.to_string())),
            }
        }
    };
    let opts = Options {
        source,
        kb: cli.kb.clone(),
        rules: cli.rules.clone(),
        lod: cli.lod,
        ifc: cli.ifc.clone(),
        ifc_schema: cli.ifc_schema,
        ifc_max_bytes: cli.ifc_max_mb,
        citygml: cli.citygml.clone(),
        gltf: cli.gltf.clone(),
        cityjson: cli.cityjson.clone(),
        cityjsonseq: cli.cityjsonseq.clone(),
        report: cli.report.clone(),
        preview: cli.preview.clone(),
        tiles3d: cli.tiles3d.clone(),
        seed: cli.seed,
        crs: cli.crs,
        src_crs: cli.src_crs,
        caps: Caps {
            max_depth: cli.max_depth,
            max_shapes: cli.max_shapes,
            ..Caps::default()
        },
        bbox: cli.bbox,
        tile: cli.tile,
        dry_run: cli.dry_run,
        textures: cli.textures,
        force_extension: cli.force_extension,
        allow_empty: cli.allow_empty,
        infer: cli.infer.0,
        shard,
        previous: cli.previous.clone(),
        link_previous: cli.link_previous,
        osc: cli.osc.clone(),
        source_name: cli.source_name.clone(),
        dem: cli.dem.clone(),
        ground_height: cli.ground_height,
        terrain_tolerance: cli.terrain_tolerance,
        no_terrain: cli.no_terrain,
        ground_fn: None,
        split_part: cli.split_part.clone(),
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
                let files = summary.outputs.len();
                let rss = peak_rss_kib()
                    .map(|kib| format!("; peak RSS {:.1} MiB", kib as f64 / 1024.0))
                    .unwrap_or_default();
                let split = match (summary.tiles, cli.tile) {
                    (0, _) | (_, None) => String::new(),
                    (n, Some(size)) => format!(" ({n} tiles of {size} m)"),
                };
                eprintln!(
                    "  output: {} polygons, {} bytes in {files} file(s){split}{rss}{}",
                    summary.polygons,
                    summary.bytes,
                    if cli.dry_run {
                        " (dry run: nothing written)"
                    } else {
                        ""
                    }
                );
                if let Some(line) = phases_line(&summary) {
                    eprintln!("{line}");
                }
                let verb = if cli.dry_run { "would write" } else { "wrote" };
                // One screen: a tiled run may write thousands of files.
                const SHOWN: usize = 9;
                for p in summary.outputs.iter().take(SHOWN) {
                    eprintln!("  {verb} {}", p.display());
                }
                if files > SHOWN {
                    eprintln!("  ... and {} more files ({files} in all)", files - SHOWN);
                }
            }
            for w in &summary.warnings {
                eprintln!("citygen: warning: {w}");
            }
            Ok(Outcome::Done)
        }
        Err(e) => {
            bar.finish_and_clear();
            Err(e.into())
        }
    }
}

/// The summary's line of the run's stages (`pipeline::Phase`): each one's end in seconds,
/// resident set size and the peak so far, then the peak per building generated and the read's
/// share of it (the read's own peak over the run's). `None` where the kernel gives no sizes.
fn phases_line(summary: &pipeline::Summary) -> Option<String> {
    let mib = |k: u64| k as f64 / 1024.0;
    let mut parts = Vec::new();
    for p in &summary.phases {
        parts.push(format!(
            "{} to {:.1} s, RSS {:.0} MiB, peak {:.0} MiB",
            p.name,
            p.secs,
            mib(p.rss_kib?),
            mib(p.peak_kib?)
        ));
    }
    let read = summary.phases.first()?.peak_kib?;
    let peak = summary.phases.last()?.peak_kib?;
    let per = (peak as f64 * 1024.0) / summary.report.generated.max(1) as f64;
    Some(format!(
        "  memory: {}; peak {:.0} bytes a building, the read's peak {:.0} % of it",
        parts.join("; "),
        per,
        100.0 * read as f64 / peak.max(1) as f64
    ))
}

/// This process's peak resident set size in KiB (`VmHWM` of /proc/self/status), on Linux only;
/// `None` where the kernel does not report it.
fn peak_rss_kib() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    line.trim_start_matches("VmHWM:")
        .trim()
        .trim_end_matches("kB")
        .trim()
        .parse()
        .ok()
}
