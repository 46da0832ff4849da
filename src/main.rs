//! The `citygen` command line: arguments, progress, summary and exit code. All the work is in
//! the library (`citygen::pipeline`).

#![forbid(unsafe_code)]

use std::io::IsTerminal;
use std::path::PathBuf;
use std::process::ExitCode;

use clap::{ArgGroup, Args, Parser, Subcommand};

use citygen::crs::Crs;
use citygen::geometry::Polygon;
use citygen::grammar::Caps;
use citygen::model::Lod;
use citygen::pipeline::{self, Options, RunError, Source};

/// mimalloc (feature `mimalloc`, on by default): the derivation allocates many small
/// short-lived vectors per building, and glibc's malloc took about 30 % of a LOD2 profile.
#[cfg(feature = "mimalloc")]
#[global_allocator]
static ALLOC: mimalloc::MiMalloc = mimalloc::MiMalloc;

/// Turns a city's building footprints (OSM PBF or shapefile) into BIM and city models:
/// IFC4, CityGML 2.0 and glTF 2.0 binary, at LOD1 to LOD4.
///
/// Each footprint is matched to the deepest zone of the knowledge base (or ruled by --rules),
/// derived with the shape grammar, and written to every requested output. Outputs are written
/// atomically. Same inputs and --seed give byte-identical files, whatever --threads is.
///
/// Subcommands: `citygen rules check|derive` for rule authors, `citygen kb
/// check|compile|explain|learn|edit` for knowledge-base authors (`citygen rules --help`, `citygen kb
/// --help`).
///
/// Exit codes: 0 success; 1 bad input (file, knowledge base, rules; a run that generates no
/// building); 2 bad usage (flags, output paths); 3 an output could not be written.
#[derive(Parser, Debug)]
#[command(name = "citygen", version, about, long_about)]
#[command(args_conflicts_with_subcommands = true, subcommand_negates_reqs = true)]
struct Cli {
    #[command(subcommand)]
    command: Option<Command>,
    #[command(flatten)]
    run: RunArgs,
}

/// Tools for rule authors.
#[derive(Subcommand, Debug)]
enum Command {
    /// Check and try grammar rulesets.
    #[command(subcommand)]
    Rules(RulesCommand),
    /// Check, compile, explain and learn knowledge bases.
    #[command(subcommand)]
    Kb(KbCommand),
    /// Check and try SELEX programs (selection expressions and facade grids, docs/selex.md).
    #[command(subcommand)]
    Selex(SelexCommand),
    /// Put the shards of a tiled run together (`--shard I/N`), after checking that their
    /// manifests add up: one run, every shard, tile and building once, every file as listed.
    /// Writes the merged report, the region's CityJSONSeq, its 3D Tiles tileset and a picture.
    Merge(MergeArgs),
    /// Write facade rules by a genetic search (seed 003 §3.7): NSGA-II evolves integer genomes
    /// decoded into grammar rules, each derived on a test facade and scored on the seed's
    /// aesthetic objectives (all minimised). Writes the Pareto front as ruleset files with
    /// pictures, the front and convergence as SVG, and evolve.json.
    Evolve(EvolveArgs),
}

/// `citygen evolve`.
#[derive(Args, Debug)]
struct EvolveArgs {
    /// The objectives, comma-separated: vsym, hsym, uniform, rectilinear, monolithic,
    /// fragmented.
    #[arg(long, value_name = "LIST")]
    objectives: String,
    /// The test facade, WIDTHxHEIGHT metres (default 12x9).
    #[arg(long, value_name = "WxH", conflicts_with = "lot")]
    facade: Option<String>,
    /// A box building on a WIDTHxDEPTH lot instead (its front facade is scored), --height m
    /// to the eaves.
    #[arg(long, value_name = "WxD")]
    lot: Option<String>,
    /// The box building's wall height with --lot, metres.
    #[arg(long, default_value_t = 9.0, requires = "lot")]
    height: f64,
    /// Individuals per generation.
    #[arg(long, default_value_t = 50, value_parser = clap::value_parser!(u32).range(2..=10_000))]
    population: u32,
    /// The generation cap (the search also stops earlier when it has converged: --window).
    #[arg(long, default_value_t = 30, value_parser = clap::value_parser!(u32).range(1..=100_000))]
    generations: u32,
    /// The convergence window: the search stops when the population's min and mean of every
    /// objective have not changed over this many generations.
    #[arg(long, default_value_t = 10, value_parser = clap::value_parser!(u32).range(1..=100_000))]
    window: u32,
    /// The seed of the search and of the test facades' random choices.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// The output folder.
    #[arg(long, value_name = "DIR")]
    out: PathBuf,
    /// Also compare with random search on N seeds (from --seed; the same number of evaluations
    /// each): baseline.json and a table.
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u64).range(1..=1000))]
    baseline: Option<u64>,
    /// Add the best front member of each objective as appearances of --zone in this knowledge
    /// base (rulesets written to evolved/ beside it; the KB edited atomically, checked first).
    #[arg(long, value_name = "KB", requires = "zone")]
    into_kb: Option<PathBuf>,
    /// The zone for --into-kb (a path as `kb explain` prints it, or its tail).
    #[arg(long, value_name = "PATH", requires = "into_kb")]
    zone: Option<String>,
    /// The share of the zone's buildings the new appearances take together (0 < S < 1; a
    /// zone without appearances of its own gets only the new ones).
    #[arg(long, default_value_t = 0.5, requires = "into_kb")]
    share: f64,
    /// Worker threads (default: all cores). The files do not depend on it.
    #[arg(long)]
    threads: Option<usize>,
}

/// `citygen merge`.
#[derive(Args, Debug)]
struct MergeArgs {
    /// Folders holding the shards' outputs and `citygen-manifest.I-of-N.json` files.
    #[arg(required = true, value_name = "OUT_DIR")]
    dirs: Vec<PathBuf>,
    /// Write the merged run report here.
    #[arg(long, value_name = "OUT.json")]
    report: Option<PathBuf>,
    /// Write the region's CityJSONSeq here: one header, then every tile's buildings in grid
    /// order (the shards must have written --cityjsonseq).
    #[arg(long, value_name = "OUT.city.jsonl")]
    cityjsonseq: Option<PathBuf>,
    /// Write the region's OGC 3D Tiles tileset.json into this folder, over the shards' contents
    /// (the shards must have written --tiles3d; URIs relative to the folder).
    #[arg(long, value_name = "DIR")]
    tiles3d: Option<PathBuf>,
    /// Write an overview picture of the region (PNG, rendered in citygen from the 3D Tiles
    /// contents).
    #[arg(long, value_name = "OUT.png")]
    preview: Option<PathBuf>,
    /// Check the files' sizes only, not their SHA-256 (faster on a slow shared disk).
    #[arg(long)]
    no_verify: bool,
    /// No summary.
    #[arg(long, short)]
    quiet: bool,
}

#[derive(Subcommand, Debug)]
enum SelexCommand {
    /// Parse a SELEX program, warn about what parses but looks wrong (the seed's `>` arrow, a
    /// bare word taken as a string, a pattern shorter than its grid), then run it and warn
    /// about every rule whose selection picks nothing (it is skipped) and every constraint
    /// dropped. Exit code 1 on errors, 0 with warnings only.
    Check {
        /// The program (.slx).
        file: PathBuf,
        /// Run it on a box `building` of width x depth x height metres made first, for a
        /// program that only lays out facades (its paths name building_front, ...).
        #[arg(long, value_name = "WxDxH", value_parser = parse_box)]
        lot: Option<(f64, f64, f64)>,
    },
    /// Run a SELEX program and print its shape tree: volumes, faces, grids, the elements with
    /// their rectangles on their face (metres from the bottom-left seen from outside), the
    /// cover, the constraints kept, then the warnings. With an output (--ifc, --citygml,
    /// --gltf, --cityjson, --cityjsonseq), write
    /// the building it makes instead: each volume (box or bay) a part with a flat roof, a bay's
    /// rounded front an arc, the elements doors (door*, entrance*), balconies (balcony*,
    /// ledge*) or windows, rounded and framed as the program asks (docs/selex.md §9).
    Derive {
        /// The program (.slx).
        file: PathBuf,
        /// Run it on a box `building` of width x depth x height metres made first.
        #[arg(long, value_name = "WxDxH", value_parser = parse_box)]
        lot: Option<(f64, f64, f64)>,
        /// Level of detail of the outputs, 1 to 3 (3: storeys, openings, balconies).
        #[arg(long, value_parser = parse_lod, default_value = "3")]
        lod: Lod,
        /// Where the building stands (lon,lat in degrees): it picks the UTM zone of the outputs.
        #[arg(long, value_name = "LON,LAT", value_parser = parse_lonlat, default_value = "1.4442,43.6045")]
        at: (f64, f64),
        /// Write IFC4 (STEP) here.
        #[arg(long, value_name = "OUT.ifc")]
        ifc: Option<PathBuf>,
        /// Write CityGML 2.0 here.
        #[arg(long, value_name = "OUT.gml")]
        citygml: Option<PathBuf>,
        /// Write glTF 2.0 binary (.glb) here.
        #[arg(long, value_name = "OUT.glb")]
        gltf: Option<PathBuf>,
        /// Write CityJSON 2.0 here.
        #[arg(long, value_name = "OUT.city.json")]
        cityjson: Option<PathBuf>,
        /// Write CityJSONSeq here.
        #[arg(long, value_name = "OUT.city.jsonl")]
        cityjsonseq: Option<PathBuf>,
        /// Write the JSON report here (with an output).
        #[arg(long, value_name = "OUT.json")]
        report: Option<PathBuf>,
    },
}

#[derive(Subcommand, Debug)]
enum KbCommand {
    /// Read a knowledge base and list what the lenient reader repaired (with lines), errors and
    /// warnings. Exit code 1 on errors, 0 with repairs or warnings only.
    Check {
        /// The knowledge base.
        kb: PathBuf,
        /// Read our clean format only (schemas/kb.xsd): every repair becomes an error.
        #[arg(long)]
        strict: bool,
        /// Allow `<ruleset file=...>` paths outside the knowledge base's folder.
        #[arg(long)]
        allow_external_rulesets: bool,
    },
    /// Print the grammar rules generated for each appearance of a zone.
    Compile {
        /// The knowledge base.
        kb: PathBuf,
        /// Zone path, e.g. France/Occitanie/Toulouse/Centre-Ville (with or without `earth/`).
        #[arg(long)]
        zone: String,
    },
    /// Explain the zone chain, inherited values, and the appearance chosen for one building.
    #[command(group(ArgGroup::new("explain_input").required(true).args(["osm", "shp"])))]
    Explain {
        /// The knowledge base.
        kb: PathBuf,
        /// The OpenStreetMap extract holding the building.
        #[arg(long, value_name = "FILE.pbf")]
        osm: Option<PathBuf>,
        /// The shapefile holding the building.
        #[arg(long, value_name = "FILE.shp")]
        shp: Option<PathBuf>,
        /// The building: way/123, relation/45 (OSM) or a 0-based shapefile record number.
        #[arg(long)]
        id: String,
        /// The run's --seed: the appearance picked is the one a run with this seed picks.
        #[arg(long, default_value_t = 0)]
        seed: u64,
        /// The run's --infer: what the building takes from its tagged neighbours.
        #[arg(long, value_name = "WHAT", default_value = "kb", value_parser = parse_infer)]
        infer: InferArg,
    },
    /// Edit a knowledge base in a browser: serves a page on 127.0.0.1 (the address, with the
    /// session's token, is printed on start) with the input's footprints on a map, the zone
    /// tree, values, appearances and drawn window splits, and a 3D preview of a building.
    /// Edits are checked as `kb check --strict` checks; saving writes the KB atomically.
    /// Runs until stopped (Ctrl-C). See docs/kb-editor.md.
    Edit {
        /// The knowledge base to edit (the one file saved).
        kb: PathBuf,
        /// An OpenStreetMap extract whose footprints the map shows.
        #[arg(long, value_name = "FILE.pbf", conflicts_with = "shp")]
        osm: Option<PathBuf>,
        /// A shapefile whose footprints the map shows.
        #[arg(long, value_name = "FILE.shp")]
        shp: Option<PathBuf>,
        /// The port to listen on (127.0.0.1 only); 0 picks a free one.
        #[arg(long, default_value_t = 0)]
        port: u16,
        /// The seed of the appearance picks and previews (a run's --seed).
        #[arg(long, default_value_t = 0)]
        seed: u64,
    },
    /// Learn a knowledge base from an extract's tags: storeys (building:levels), roof shape,
    /// floor height, colours and material per grid cell or per zone, written as zones and
    /// appearances to edit. A zone with fewer than --min-samples tagged values of an attribute
    /// takes its parent's (the grid's parent is the whole extract). Errors (exit 1): an input
    /// that cannot be read or holds no building. An extract without any of these tags gives a
    /// KB of the built-in defaults with a comment saying so.
    #[command(group(ArgGroup::new("learn_input").required(true).args(["osm", "shp"])))]
    Learn {
        /// The OpenStreetMap extract to learn from.
        #[arg(long, value_name = "FILE.pbf")]
        osm: Option<PathBuf>,
        /// The shapefile to learn from (its height and level fields detected).
        #[arg(long, value_name = "FILE.shp")]
        shp: Option<PathBuf>,
        /// Group by square cells of this many metres.
        #[arg(long, value_name = "METRES", conflicts_with = "zones",
              default_value_t = citygen::kb::learn::DEFAULT_GRID_M as u32,
              value_parser = clap::value_parser!(u32).range(10..))]
        grid: u32,
        /// Group by the deepest zone of this knowledge base instead of a grid (its zones'
        /// circles and polygons are kept, its values and appearances replaced).
        #[arg(long, value_name = "KB.xml")]
        zones: Option<PathBuf>,
        /// Least tagged values of an attribute for a cell or zone to have its own distribution.
        #[arg(long, value_name = "N", default_value_t = citygen::kb::learn::DEFAULT_MIN_SAMPLES,
              value_parser = clap::builder::RangedU64ValueParser::<usize>::new().range(1..))]
        min_samples: usize,
        /// Most appearances per zone and group (the rare tail is merged, as the file's comments say).
        #[arg(long, value_name = "N", default_value_t = citygen::kb::learn::DEFAULT_MAX_APPEARANCES,
              value_parser = clap::builder::RangedU64ValueParser::<usize>::new().range(1..=100))]
        max_appearances: usize,
        /// Where to write the learned knowledge base.
        #[arg(long, value_name = "LEARNED.xml")]
        out: PathBuf,
    },
}

// Parsed once per process: the size difference between variants does not matter.
#[allow(clippy::large_enum_variant)]
#[derive(Subcommand, Debug)]
enum RulesCommand {
    /// Parse a ruleset and lint it: undefined successors, unreachable rules, probabilities
    /// that do not sum to 1, duplicate deterministic rules, rules that never terminate or
    /// grow exponentially (rule bombs: the derivation would stop at a cap). Exit code 1 on
    /// errors, 0 with warnings only.
    Check {
        /// The ruleset file.
        file: PathBuf,
    },
    /// Derive a ruleset on one test lot and write the outputs, to see a ruleset without a city.
    #[command(group(ArgGroup::new("lot_shape").required(true).args(["lot", "wkt"])))]
    #[command(group(ArgGroup::new("derive_outputs").required(true).multiple(true).args(["ifc", "citygml", "gltf"])))]
    Derive {
        /// The ruleset file.
        file: PathBuf,
        /// A rectangular lot, width x depth in metres, e.g. 20x12.
        #[arg(long, value_name = "WxD", value_parser = parse_lot)]
        lot: Option<Polygon>,
        /// A lot given as WKT in local metres, e.g. "POLYGON ((0 0, 20 0, 20 12, 0 12, 0 0))".
        #[arg(long, value_name = "WKT", value_parser = parse_wkt)]
        wkt: Option<Polygon>,
        /// Where the lot stands (lon,lat in degrees): it picks the UTM zone and the KB zone.
        #[arg(long, value_name = "LON,LAT", value_parser = parse_lonlat, default_value = "1.4442,43.6045")]
        at: (f64, f64),
        /// Knowledge base for default colours and heights (default: built-in defaults).
        #[arg(long, value_name = "KB.xml")]
        kb: Option<PathBuf>,
        /// Level of detail, 1 to 4 (as for the main job).
        #[arg(long, value_parser = parse_lod, default_value = "2")]
        lod: Lod,
        /// Seed of every random choice.
        #[arg(long, default_value_t = 0)]
        seed: u64,
        #[arg(long, value_name = "OUT.ifc")]
        ifc: Option<PathBuf>,
        #[arg(long, value_name = "OUT.gml")]
        citygml: Option<PathBuf>,
        #[arg(long, value_name = "OUT.glb")]
        gltf: Option<PathBuf>,
        #[arg(long, value_name = "OUT.json")]
        report: Option<PathBuf>,
    },
}

/// The main job's arguments.
#[derive(Args, Debug)]
#[command(group(ArgGroup::new("input").required(true).args(["osm", "shp"])))]
#[command(group(ArgGroup::new("style").required(true).args(["kb", "rules"])))]
#[command(group(ArgGroup::new("outputs").required(true).multiple(true).args(["ifc", "citygml", "gltf", "cityjson", "cityjsonseq", "tiles3d", "preview"])))]
struct RunArgs {
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
    /// Level of detail: 1 (blocks), 2 (roofs and semantic surfaces), 3 (storeys, facades,
    /// windows, doors and balconies) or 4 (interiors: rooms, interior walls and doors, stairs).
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
    /// Accept output file names whose extension is not the format's (.ifc, .gml or .xml, .glb,
    /// .json for the report).
    #[arg(long)]
    force_extension: bool,
    /// Write the outputs even when no building is generated (an empty --bbox, every footprint
    /// skipped); without it such a run is an error (exit 1) and writes nothing.
    #[arg(long)]
    allow_empty: bool,
    /// What a building lacking tags takes from the tagged buildings around it: kb (as its
    /// knowledge-base zone says, <info infer="...">), none, all, or a comma-separated list of
    /// levels (storeys: distance-weighted median of the 8 nearest within 300 m, of its own
    /// building=* kind when 3 of them are; at least 3), roof (roof:shape) and colour
    /// (building:colour, roof:colour; the weighted majority). Each building changed has a
    /// report note.
    #[arg(long, value_name = "WHAT", default_value = "kb", value_parser = parse_infer)]
    infer: InferArg,
    /// Write only shard I of N (counted from 0) of a tiled run (needs --tile), and its
    /// manifest `citygen-manifest.I-of-N.json` beside the outputs; `citygen merge` puts the
    /// shards together. Every shard reads the whole input and computes the same assignment of
    /// tiles to shards, so N processes need no coordinator. `auto` takes I from
    /// JOB_COMPLETION_INDEX (Kubernetes Indexed Job) or SLURM_ARRAY_TASK_ID (Slurm array) and
    /// N from --shards or SLURM_ARRAY_TASK_COUNT.
    #[arg(long, value_name = "I/N|auto", value_parser = citygen::pipeline::shard::parse_shard)]
    shard: Option<citygen::pipeline::shard::ShardArg>,
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
    /// No progress bar and no summary.
    #[arg(long, short)]
    quiet: bool,
}

fn parse_lod(s: &str) -> Result<Lod, String> {
    match s.trim() {
        "1" => Ok(Lod::Lod1),
        "2" => Ok(Lod::Lod2),
        "3" => Ok(Lod::Lod3),
        "4" => Ok(Lod::Lod4),
        _ => Err(format!("LOD must be 1, 2, 3 or 4, not {s:?}")),
    }
}

fn parse_crs(s: &str) -> Result<Crs, String> {
    Crs::from_epsg_str(s).map_err(|e| e.to_string())
}

/// `--crs`: a projected CRS. The model is built in metres in a local frame of the output CRS,
/// so a geographic one (degrees) would make every footprint degenerate.
fn parse_output_crs(s: &str) -> Result<Crs, String> {
    let crs = parse_crs(s)?;
    if crs.is_geographic() {
        return Err(format!(
            "{s} is geographic (degrees), and the output CRS must be projected (metres): a UTM \
             zone (EPSG:326xx north, 327xx south, 258xx ETRS89), EPSG:2154 (Lambert-93) or \
             EPSG:27700 (British National Grid); without --crs, citygen uses the UTM zone of the data"
        ));
    }
    Ok(crs)
}

/// `--infer`: `kb` (the zones decide: `None`) or an [`Inference`](citygen::model::Inference).
#[derive(Clone, Copy, Debug)]
struct InferArg(Option<citygen::model::Inference>);

fn parse_infer(s: &str) -> Result<InferArg, String> {
    if s.trim().eq_ignore_ascii_case("kb") {
        return Ok(InferArg(None));
    }
    citygen::model::Inference::parse(s)
        .map(|i| InferArg(Some(i)))
        .ok_or_else(|| "expected kb, none, all, or a list of levels, roof, colour".to_string())
}

fn parse_lot(s: &str) -> Result<Polygon, String> {
    let (w, d) = s.split_once(['x', 'X']).ok_or("expected WxD, e.g. 20x12")?;
    let w: f64 = w.trim().parse().map_err(|_| format!("bad width {w:?}"))?;
    let d: f64 = d.trim().parse().map_err(|_| format!("bad depth {d:?}"))?;
    if !(w.is_finite() && d.is_finite() && w > 0.0 && d > 0.0) {
        return Err("width and depth must be positive".into());
    }
    let v = |x, y| glam::DVec2::new(x, y);
    Ok(Polygon::new(
        vec![
            v(-w / 2.0, -d / 2.0),
            v(w / 2.0, -d / 2.0),
            v(w / 2.0, d / 2.0),
            v(-w / 2.0, d / 2.0),
        ],
        vec![],
    ))
}

fn parse_wkt(s: &str) -> Result<Polygon, String> {
    citygen::input::wkt::parse_polygon(s).map_err(|e| e.to_string())
}

fn parse_bbox(s: &str) -> Result<[f64; 4], String> {
    let v: Vec<f64> = s
        .split(',')
        .map(|x| {
            x.trim()
                .parse::<f64>()
                .map_err(|_| format!("bad number {x:?}"))
        })
        .collect::<Result<_, _>>()?;
    match v[..] {
        [a, b, c, d] if a < c && b < d && v.iter().all(|x| x.is_finite()) => Ok([a, b, c, d]),
        _ => Err("expected LON0,LAT0,LON1,LAT1 with LON0 < LON1 and LAT0 < LAT1".into()),
    }
}

fn parse_lonlat(s: &str) -> Result<(f64, f64), String> {
    let (a, b) = s.split_once(',').ok_or("expected LON,LAT")?;
    let lon: f64 = a
        .trim()
        .parse()
        .map_err(|_| format!("bad longitude {a:?}"))?;
    let lat: f64 = b
        .trim()
        .parse()
        .map_err(|_| format!("bad latitude {b:?}"))?;
    if !((-180.0..=180.0).contains(&lon) && (-84.0..=84.0).contains(&lat)) {
        return Err("longitude must be in -180..180 and latitude in -84..84".into());
    }
    Ok((lon, lat))
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    match cli.command {
        Some(Command::Rules(cmd)) => rules_command(cmd),
        Some(Command::Kb(cmd)) => kb_command(cmd),
        Some(Command::Selex(cmd)) => selex_command(cmd),
        Some(Command::Merge(args)) => merge_command(args),
        Some(Command::Evolve(args)) => evolve_command(args),
        None => run_main(cli.run),
    }
}

/// `citygen evolve`.
fn evolve_command(args: EvolveArgs) -> ExitCode {
    use citygen::evolve::{nsga2, objectives::Objective, run};
    let fail = |msg: String| {
        eprintln!("citygen: error: {msg}");
        ExitCode::from(2)
    };
    if let Some(n) = args.threads {
        let _ = rayon::ThreadPoolBuilder::new()
            .num_threads(n.max(1))
            .build_global();
    }
    let objectives = match Objective::parse_list(&args.objectives) {
        Ok(o) => o,
        Err(e) => return fail(format!("--objectives: {e}")),
    };
    let test = match (&args.lot, &args.facade) {
        (Some(l), _) => run::TestObject::parse(l, true, args.height),
        (None, Some(f)) => run::TestObject::parse(f, false, 0.0),
        (None, None) => Ok(run::TestObject::default()),
    };
    let test = match test {
        Ok(t) => t,
        Err(e) => return fail(e.to_string()),
    };
    if args.lot.is_some() && !(args.height.is_finite() && (2.0..=200.0).contains(&args.height)) {
        return fail(format!("--height {}: give 2-200 m", args.height));
    }
    let settings = run::Settings {
        objectives,
        test,
        config: nsga2::Config {
            population: args.population as usize,
            generations: args.generations as usize,
            seed: args.seed,
            window: args.window as usize,
            ..nsga2::Config::default()
        },
    };
    let (history, secs) = run::search(&settings);
    let w = match run::write_outputs(&args.out, &settings, &history) {
        Ok(w) => w,
        Err(e) => {
            eprintln!("citygen: error: {e}");
            return ExitCode::from(3);
        }
    };
    let gens = history.generations.len();
    eprintln!(
        "citygen evolve: {} generations ({:?}), {} evaluations, {:.2} s ({:.3} s a generation); \
         front of {}, hypervolume {:.1}",
        gens,
        history.stopped,
        history.evaluations,
        secs,
        secs / gens.max(1) as f64,
        w.members.len(),
        history.hypervolume
    );
    for p in &w.files {
        eprintln!("  wrote {}", p.display());
    }
    if let Some(n) = args.baseline {
        let rows = run::baseline(&settings, n);
        eprintln!(
            "  seed  NSGA-II hypervolume (reached after)  random search (reached after)  \
             evaluations  s/generation"
        );
        let after = |e: Option<usize>| e.map_or_else(|| "-".to_string(), |e| e.to_string());
        for r in &rows {
            eprintln!(
                "  {:>4}  {:>19.1} {:>16}  {:>13.1} {:>15}  {:>11}  {:>12.3}",
                r.seed,
                r.nsga2,
                format!("({})", after(r.nsga2_evaluations_to_final)),
                r.random,
                format!("({})", after(r.random_evaluations_to_final)),
                r.evaluations,
                r.seconds_per_generation
            );
        }
        let mean = |f: &dyn Fn(&run::BaselineRow) -> f64| {
            rows.iter().map(f).sum::<f64>() / rows.len().max(1) as f64
        };
        let wins = rows.iter().filter(|r| r.nsga2 > r.random).count();
        let ties: Vec<&run::BaselineRow> = rows.iter().filter(|r| r.nsga2 == r.random).collect();
        let sooner = ties
            .iter()
            .filter(|r| r.nsga2_evaluations_to_final < r.random_evaluations_to_final)
            .count();
        eprintln!(
            "  mean hypervolume: NSGA-II {:.1}, random search {:.1}; NSGA-II higher on {wins} of \
             {} seeds, equal on {} (of which it got there first on {sooner})",
            mean(&|r| r.nsga2),
            mean(&|r| r.random),
            rows.len(),
            ties.len()
        );
        let json = serde_json::to_string_pretty(&rows).unwrap_or_default() + "\n";
        let p = args.out.join("baseline.json");
        if let Err(e) = run::write_atomic(&p, json.as_bytes()) {
            eprintln!("citygen: error: {e}");
            return ExitCode::from(3);
        }
        eprintln!("  wrote {}", p.display());
    }
    if let (Some(kb), Some(zone)) = (args.into_kb, args.zone) {
        // The best member of each objective, once each.
        let mut chosen: Vec<(String, String)> = Vec::new();
        let mut seen = std::collections::BTreeSet::new();
        for &(name, i) in &w.best {
            if !seen.insert(i) {
                continue;
            }
            let Some(m) = w.members.get(i) else { continue };
            match std::fs::read_to_string(args.out.join(&m.rules)) {
                Ok(t) => chosen.push((format!("{name}-{}", args.seed), t)),
                Err(e) => return fail(format!("{}: {e}", m.rules)),
            }
        }
        let target = run::IntoKb {
            kb: kb.clone(),
            zone,
            share: args.share,
        };
        match run::into_kb(&target, &chosen) {
            Ok(a) => {
                eprintln!(
                    "  added {} appearance(s) to {} in {} ({:.0} % of its buildings):",
                    a.rulesets.len(),
                    a.zone,
                    kb.display(),
                    a.share * 100.0
                );
                for (p, w) in a.rulesets.iter().zip(&a.probas) {
                    eprintln!("    proba {w:.4}: {}", p.display());
                }
            }
            Err(e) => return fail(e.to_string()),
        }
    }
    ExitCode::SUCCESS
}

/// `citygen merge`.
fn merge_command(args: MergeArgs) -> ExitCode {
    let opts = citygen::pipeline::merge::MergeOptions {
        dirs: args.dirs,
        report: args.report,
        cityjsonseq: args.cityjsonseq,
        tiles3d: args.tiles3d,
        preview: args.preview,
        verify: !args.no_verify,
    };
    match citygen::pipeline::merge::merge(&opts) {
        Ok(s) => {
            if !args.quiet {
                eprintln!(
                    "citygen merge: {} shards, {} tiles, {} buildings ({} skipped), {} files of {} bytes checked{} in {:.2} s",
                    s.shards,
                    s.tiles,
                    s.buildings,
                    s.skipped,
                    s.files,
                    s.bytes,
                    if opts.verify { " (SHA-256)" } else { " (sizes)" },
                    s.elapsed.as_secs_f64()
                );
                for p in &s.outputs {
                    eprintln!("  wrote {}", p.display());
                }
            }
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("citygen: error: {e}");
            ExitCode::from(exit_code(&e))
        }
    }
}

/// `WxDxH` in metres, each positive.
fn parse_box(s: &str) -> Result<(f64, f64, f64), String> {
    let parts: Vec<&str> = s.split(['x', 'X']).collect();
    let [w, d, h] = parts.as_slice() else {
        return Err(format!(
            "expected WIDTHxDEPTHxHEIGHT in metres, e.g. 12x10x9, not {s:?}"
        ));
    };
    let num = |t: &str| -> Result<f64, String> {
        match t.trim().parse::<f64>() {
            Ok(v) if v.is_finite() && v > 0.0 && v <= 10_000.0 => Ok(v),
            _ => Err(format!("{t:?} is not a size in metres (0 to 10 km)")),
        }
    };
    Ok((num(w)?, num(d)?, num(h)?))
}

/// `citygen selex ...`.
fn selex_command(cmd: SelexCommand) -> ExitCode {
    let (file, lot, print_tree, write) = match cmd {
        SelexCommand::Check { file, lot } => (file, lot, false, None),
        SelexCommand::Derive {
            file,
            lot,
            lod,
            at,
            ifc,
            citygml,
            gltf,
            cityjson,
            cityjsonseq,
            report,
        } => {
            let targets = citygen::pipeline::Targets {
                ifc,
                citygml,
                gltf,
                cityjson,
                cityjsonseq,
                report,
                preview: None,
                tiles3d: None,
                dry_run: false,
                allow_empty: false,
                manifest: None,
            };
            let outputs = targets.ifc.is_some()
                || targets.citygml.is_some()
                || targets.gltf.is_some()
                || targets.cityjson.is_some()
                || targets.cityjsonseq.is_some();
            if targets.report.is_some() && !outputs {
                eprintln!("citygen: error: --report goes with an output (--ifc, --citygml, --gltf, --cityjson, --cityjsonseq)");
                return ExitCode::from(2);
            }
            (file, lot, !outputs, outputs.then_some((targets, lod, at)))
        }
    };
    let text = match citygen::grammar::read_source(&file) {
        Ok(t) => t,
        Err(e) => {
            eprintln!("citygen: error: {}: {e}", file.display());
            return ExitCode::from(1);
        }
    };
    let name = file.display().to_string();
    let program = match citygen::selex::parser::parse(&text, &name) {
        Ok(p) => p,
        Err(e) => {
            eprintln!("{e}");
            return ExitCode::from(1);
        }
    };
    let mut warnings: Vec<String> = citygen::selex::parser::check(&program, &text, &name)
        .into_iter()
        .map(|w| w.to_string())
        .collect();
    let run = match lot {
        Some(b) => citygen::selex::eval::run_on_box(&program, &text, &name, b),
        None => citygen::selex::eval::run(&program, &text, &name),
    };
    let derivation = match run {
        Ok(d) => d,
        Err(e) => {
            for w in &warnings {
                eprintln!("{w}");
            }
            eprintln!("{e}");
            return ExitCode::from(1);
        }
    };
    // Written, the run's warnings are the report's notes (printed with its entries).
    if write.is_none() {
        warnings.extend(
            derivation
                .warnings
                .iter()
                .map(|n| format!("{name}:{}:{}: warning: {}", n.line, n.col, n.message)),
        );
    }
    if print_tree {
        print!("{}", derivation.to_text());
    }
    for w in &warnings {
        eprintln!("{w}");
    }
    if let Some((targets, lod, at)) = write {
        return lot_outcome(citygen::pipeline::derive_selex_lot(
            &file,
            &derivation,
            at,
            lod,
            &targets,
        ));
    }
    eprintln!(
        "{name}: {} commands, {} shapes, {} elements, {} warnings",
        program.commands.len(),
        derivation.shapes.len(),
        derivation.elements().count(),
        warnings.len()
    );
    ExitCode::SUCCESS
}

/// `citygen rules ...`.
fn rules_command(cmd: RulesCommand) -> ExitCode {
    match cmd {
        RulesCommand::Check { file } => {
            let text = match citygen::grammar::read_source(&file) {
                Ok(t) => t,
                Err(e) => {
                    eprintln!("citygen: error: {}: {e}", file.display());
                    return ExitCode::from(1);
                }
            };
            let name = file.display().to_string();
            let rules = match citygen::grammar::parse(&text, &name) {
                Ok(r) => r,
                Err(e) => {
                    eprintln!("{e}");
                    return ExitCode::from(1);
                }
            };
            let diagnostics = citygen::grammar::lint::lint(&rules, &text);
            for d in &diagnostics {
                eprintln!("{d}");
            }
            let errors = citygen::grammar::lint::has_errors(&diagnostics);
            let n_err = diagnostics
                .iter()
                .filter(|d| d.severity == citygen::grammar::lint::Severity::Error)
                .count();
            eprintln!(
                "{name}: {} rules, {n_err} errors, {} warnings",
                rules.rules().len(),
                diagnostics.len() - n_err
            );
            ExitCode::from(if errors { 1 } else { 0 })
        }
        RulesCommand::Derive {
            file,
            lot,
            wkt,
            at,
            kb,
            lod,
            seed,
            ifc,
            citygml,
            gltf,
            report,
        } => {
            let Some(polygon) = lot.or(wkt) else {
                return ExitCode::from(2);
            };
            lot_outcome(citygen::pipeline::derive_lot(
                &file,
                polygon,
                at,
                kb.as_deref(),
                lod,
                seed,
                &citygen::pipeline::Targets {
                    ifc,
                    citygml,
                    gltf,
                    cityjson: None,
                    cityjsonseq: None,
                    report,
                    preview: None,
                    tiles3d: None,
                    dry_run: false,
                    allow_empty: false,
                    manifest: None,
                },
            ))
        }
    }
}

/// The exit of a one-lot derivation (`rules derive`, `selex derive` with outputs): its report's
/// entries, the count, the files written; 0 when the building was made.
fn lot_outcome(
    result: Result<citygen::pipeline::Summary, citygen::pipeline::RunError>,
) -> ExitCode {
    match result {
        Ok(summary) => {
            let r = &summary.report;
            for e in &r.entries {
                eprintln!("  {} {:?}: {}", e.id, e.outcome, e.reason);
            }
            eprintln!(
                "citygen: {} building(s), {} polygons",
                r.generated, summary.polygons
            );
            for p in &summary.outputs {
                eprintln!("  wrote {}", p.display());
            }
            ExitCode::from(if r.generated == 1 { 0 } else { 1 })
        }
        Err(e) => {
            eprintln!("citygen: error: {e}");
            ExitCode::from(exit_code(&e))
        }
    }
}

/// `citygen kb ...`.
fn kb_command(cmd: KbCommand) -> ExitCode {
    use citygen::kb::{tools, KnowledgeBase, ReadMode};
    let load = |p: &PathBuf| {
        KnowledgeBase::load(p)
            .map(|(kb, _)| kb)
            .map_err(|e| e.to_string())
    };
    let fail = |msg: String| {
        eprintln!("citygen: error: {msg}");
        ExitCode::from(1)
    };
    match cmd {
        KbCommand::Check {
            kb,
            strict,
            allow_external_rulesets,
        } => {
            let mode = if strict {
                ReadMode::Strict
            } else {
                ReadMode::Lenient
            };
            match tools::check_report_with(&kb, mode, allow_external_rulesets) {
                Ok(r) => match emit(&r.to_string()) {
                    Ok(()) => ExitCode::from(if r.has_errors() { 1 } else { 0 }),
                    Err(code) => code,
                },
                Err(e) => fail(e.to_string()),
            }
        }
        KbCommand::Edit {
            kb,
            osm,
            shp,
            port,
            seed,
        } => {
            let source = match (osm, shp) {
                (Some(p), _) => Some(citygen::pipeline::Source::Osm(p)),
                (None, Some(p)) => Some(citygen::pipeline::Source::Shp {
                    path: p,
                    height_field: None,
                    levels_field: None,
                }),
                (None, None) => None,
            };
            let opts = citygen::editor::EditOptions {
                kb,
                source,
                port,
                seed,
            };
            match citygen::editor::run(&opts) {
                Ok(()) => ExitCode::SUCCESS,
                Err(e) => fail(e.to_string()),
            }
        }
        KbCommand::Compile { kb, zone } => {
            let kb = match load(&kb) {
                Ok(k) => k,
                Err(e) => return fail(e),
            };
            match tools::compile_zone(&kb, &zone) {
                Ok(list) => {
                    let all: String = list
                        .iter()
                        .map(|(label, text)| format!("# {label}\n{text}\n"))
                        .collect();
                    emit(&all).err().unwrap_or(ExitCode::SUCCESS)
                }
                Err(e) => fail(e.to_string()),
            }
        }
        KbCommand::Explain {
            kb,
            osm,
            shp,
            id,
            seed,
            infer,
        } => {
            let kb = match load(&kb) {
                Ok(k) => k,
                Err(e) => return fail(e),
            };
            let source = match (osm, shp) {
                (Some(p), _) => Source::Osm(p),
                (None, Some(path)) => Source::Shp {
                    path,
                    height_field: None,
                    levels_field: None,
                },
                (None, None) => return ExitCode::from(2),
            };
            match citygen::pipeline::explain_building(&kb, &source, &id, seed, infer.0) {
                Ok(e) => emit(&e.to_string()).err().unwrap_or(ExitCode::SUCCESS),
                Err(e) => fail(e.to_string()),
            }
        }
        KbCommand::Learn {
            osm,
            shp,
            grid,
            zones,
            min_samples,
            max_appearances,
            out,
        } => {
            let (source, file) = match (osm, shp) {
                (Some(p), _) => (Source::Osm(p.clone()), p),
                (None, Some(path)) => (
                    Source::Shp {
                        path: path.clone(),
                        height_field: None,
                        levels_field: None,
                    },
                    path,
                ),
                (None, None) => return ExitCode::from(2),
            };
            let name = file
                .file_name()
                .map(|n| n.to_string_lossy().into_owned())
                .unwrap_or_default();
            let stem = [".osm.pbf", ".pbf", ".shp", ".SHP"]
                .iter()
                .find_map(|ext| name.strip_suffix(ext))
                .unwrap_or(&name)
                .to_string();
            let options = citygen::kb::learn::LearnOptions {
                grouping: citygen::kb::learn::Grouping::Grid {
                    metres: f64::from(grid),
                },
                min_samples,
                max_appearances,
                name: stem,
                source: name,
            };
            match citygen::pipeline::learn_kb(&source, zones.as_deref(), &options, &out) {
                Ok(l) => {
                    eprintln!(
                        "citygen: learned {} buildings into {} zones ({} with data of their own) \
                         and {} appearances ({} per-kind groups); wrote {} ({} bytes)",
                        l.samples,
                        l.zones,
                        l.zones_with_own_data,
                        l.appearances,
                        l.kind_groups,
                        out.display(),
                        l.text.len()
                    );
                    ExitCode::SUCCESS
                }
                Err(e) => {
                    eprintln!("citygen: error: {e}");
                    ExitCode::from(exit_code(&e))
                }
            }
        }
    }
}

/// Writes `text` to standard output, ending it with a newline (nothing for no text). A reader
/// that stops early (`citygen kb explain ... | head`) closes the pipe: that is no error, and
/// nothing more is written. `Err(3)` when standard output could not be written otherwise.
fn emit(text: &str) -> Result<(), ExitCode> {
    use std::io::Write;
    let mut out = std::io::stdout().lock();
    let nl: &[u8] = if text.is_empty() || text.ends_with('\n') {
        b""
    } else {
        b"\n"
    };
    match out
        .write_all(text.as_bytes())
        .and_then(|()| out.write_all(nl))
        .and_then(|()| out.flush())
    {
        Ok(()) => Ok(()),
        Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => Ok(()),
        Err(e) => {
            eprintln!("citygen: error: standard output: {e}");
            Err(ExitCode::from(3))
        }
    }
}

fn exit_code(e: &RunError) -> u8 {
    match e {
        RunError::Input(_) => 1,
        RunError::Usage(_) => 2,
        RunError::Output { .. } => 3,
    }
}

/// The main job.
fn run_main(cli: RunArgs) -> ExitCode {
    if let Some(asked) = cli.threads {
        // More threads than cores buys nothing (the outputs do not depend on the count) and
        // thousands take longer to start than the run.
        let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
        let cap = (4 * cores).max(1);
        let n = asked.clamp(1, cap);
        if n != asked && !cli.quiet {
            eprintln!("citygen: note: --threads {asked} runs {n} threads (at least 1, at most 4 per core: {cores} cores)");
        }
        if let Err(e) = rayon::ThreadPoolBuilder::new()
            .num_threads(n)
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
    use citygen::pipeline::shard::{self, ShardArg};
    let shard = match cli.shard {
        None => None,
        Some(ShardArg::Fixed(s)) => {
            if cli.shards.is_some_and(|n| n as usize != s.count) {
                eprintln!(
                    "citygen: error: --shard {s} and --shards {} disagree",
                    cli.shards.unwrap_or(0)
                );
                return ExitCode::from(2);
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
                Err(e) => {
                    eprintln!("citygen: error: {e}");
                    return ExitCode::from(2);
                }
            }
        }
    };
    let opts = Options {
        source,
        kb: cli.kb.clone(),
        rules: cli.rules.clone(),
        lod: cli.lod,
        ifc: cli.ifc.clone(),
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
        force_extension: cli.force_extension,
        allow_empty: cli.allow_empty,
        infer: cli.infer.0,
        shard,
        previous: cli.previous.clone(),
        link_previous: cli.link_previous,
        osc: cli.osc.clone(),
        source_name: cli.source_name.clone(),
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
            ExitCode::SUCCESS
        }
        Err(e) => {
            bar.finish_and_clear();
            eprintln!("citygen: error: {e}");
            ExitCode::from(exit_code(&e))
        }
    }
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
