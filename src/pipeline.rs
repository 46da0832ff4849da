//! The whole run: read -> prepare -> derive (parallel, in chunks) -> write (in input order).

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::{Duration, Instant};

use thiserror::Error;

pub mod building;
pub mod eval;
mod ground;
mod ifc_parts;
pub mod incremental;
pub mod merge;
pub(crate) mod outputs;
mod plan;
mod reuse;
pub mod shard;
pub mod split;
pub mod terrain;
mod write;

use crate::crs::Crs;
use crate::derive::{Generator, Rules};
use crate::export::ExportError;
use crate::grammar::Caps;
use crate::input::{self, shp::ShpOptions};
use crate::kb::{self, KnowledgeBase};
use crate::model::{Lod, SourceId};
use crate::prepare;
use crate::report::{Outcome, Report};
use plan::{shard_targets, zone_for, GridPlan};
pub(crate) use write::{render_bytes, render_json};
pub(crate) use write::{write_batches, Batch, FileSet, Ledger, Maker};

/// Buildings derived in parallel before being written; bounds memory.
const CHUNK: usize = 2048;
/// [`CHUNK`] from LOD3 on, where a building holds a hundred times more (its facades' openings,
/// and the writers render a chunk's buildings at once): two chunks of 2048 LOD3 buildings were
/// most of a 10k-building run's peak memory.
const CHUNK_DETAILED: usize = 256;

/// The footprint source.
#[derive(Clone, Debug)]
pub enum Source {
    /// An OpenStreetMap extract (`--osm FILE.pbf`): building ways, multipolygon relations and
    /// `building:part`s, and the streets that front doors turn towards.
    Osm(PathBuf),
    /// An ESRI shapefile (`--shp FILE.shp`, with its `.shx`, `.dbf` and `.prj` beside it).
    Shp {
        /// The `.shp` file.
        path: PathBuf,
        /// The `.dbf` field holding the building height in metres (`--shp-height-field`); `None`
        /// detects it from `HEIGHT_FIELDS`.
        height_field: Option<String>,
        /// The `.dbf` field holding the number of storeys (`--shp-levels-field`); `None` detects it
        /// from `LEVELS_FIELDS`.
        levels_field: Option<String>,
        /// Columns named for citygen's fields (`--field TARGET=COLUMN`; see
        /// `input::features::TARGETS`).
        fields: Vec<(String, String)>,
        /// The GeoPackage layer to read (`--layer`).
        layer: Option<String>,
    },
}

/// Everything a run needs, as the CLI gives it.
#[derive(Clone, Debug)]
pub struct Options {
    /// The footprints to read (`--osm` or `--shp`).
    pub source: Source,
    /// The knowledge base (`--kb`); `None` uses the built-in defaults alone
    /// (`KnowledgeBase::earth_only`).
    pub kb: Option<PathBuf>,
    /// A ruleset file applied to every building (`--rules`); `None` compiles the rules of each
    /// building's appearance from the knowledge base.
    pub rules: Option<PathBuf>,
    /// The LOD every building is cut at (`--lod`, default 2).
    pub lod: Lod,
    /// Write IFC (STEP) here (`--ifc`).
    pub ifc: Option<PathBuf>,
    /// The IFC schema written (`--ifc-schema`, default IFC4).
    pub ifc_schema: crate::export::ifc::IfcSchema,
    /// Split the IFC into files of at most this many bytes (`--ifc-max-mb` times 10^6);
    /// `None`: one file, however large.
    pub ifc_max_bytes: Option<u64>,
    /// Write CityGML 2.0 here (`--citygml`).
    pub citygml: Option<PathBuf>,
    /// Write binary glTF 2.0 (`.glb`) here (`--gltf`).
    pub gltf: Option<PathBuf>,
    /// Write CityJSON 2.0 (`.city.json`) here (`--cityjson`).
    pub cityjson: Option<PathBuf>,
    /// Write CityJSONSeq (`.city.jsonl`) here (`--cityjsonseq`).
    pub cityjsonseq: Option<PathBuf>,
    /// Write the JSON run report here (`--report`); one file for the whole run, even with
    /// `tile`.
    pub report: Option<PathBuf>,
    /// Write an overview picture of the run's buildings here (`--preview`, PNG, rendered by
    /// [`crate::export::preview`]); one picture for the whole run, even with `tile`.
    pub preview: Option<PathBuf>,
    /// Write OGC 3D Tiles 1.1 into this folder (`--tiles3d`): per tile `content/{suffix}.glb`
    /// and `content/{suffix}-blocks.glb` (an untiled run: `content/all…`), and `tileset.json`
    /// (a shard of several leaves the tileset to `citygen merge`).
    pub tiles3d: Option<PathBuf>,
    /// Seed of every random choice (`--seed`, default 0): the same inputs and seed give
    /// byte-identical outputs, whatever the thread count.
    pub seed: u64,
    /// The output CRS (`--crs`); `None`: the WGS84 UTM zone of the centre of the data.
    pub crs: Option<Crs>,
    /// The CRS of the input coordinates (`--src-crs`); it overrides what the reader found (a
    /// shapefile's `.prj`, WGS84 lon/lat for OSM).
    pub src_crs: Option<Crs>,
    /// Derivation limits (`--max-depth`, `--max-shapes`); [`run`] sets `facades` from `lod`.
    pub caps: Caps,
    /// Only the buildings whose representative point is in [min lon, min lat, max lon, max lat].
    pub bbox: Option<[f64; 4]>,
    /// Split the outputs into square tiles of this many metres of the output CRS: each output
    /// path `NAME.EXT` becomes one `NAME_{easting}_{northing}.EXT` per non-empty tile.
    pub tile: Option<u32>,
    /// Derive and render every model output as usual but write none of them: their bytes are
    /// counted and dropped (the glTF writer's scratch files, unlinked at once, still go to
    /// disk). The report, if asked for, is written.
    pub dry_run: bool,
    /// Procedural textures on the walls and roofs of the glTF, 3D Tiles, CityGML and CityJSON
    /// outputs (the last two name PNG files written beside them, `out_textures/`)
    /// (`--textures`, `export::texture`'s pictures; at LOD2 the facades' bays).
    pub textures: bool,
    /// Accept output file names whose extension is not the format's (`--force-extension`).
    pub force_extension: bool,
    /// Publish the outputs even when no building is generated (an empty `--bbox`, every
    /// footprint skipped): without it such a run is an error (`--allow-empty`).
    pub allow_empty: bool,
    /// What buildings lacking tags take from their tagged neighbours ([`prepare::infer`]):
    /// `None` as each building's zone says (`<info infer=...>`, off where no zone says), else
    /// this everywhere (`--infer`). Each building so changed has a report note.
    pub infer: Option<crate::model::Inference>,
    /// Write only this shard's tiles, and its manifest (`--shard`; needs `tile`), with the
    /// sentence saying where the shard came from. A tiled run without it is shard 0 of 1 and
    /// writes its manifest too.
    pub shard: Option<(shard::Shard, String)>,
    /// Yesterday's tiled output (`--previous DIR`, needs `tile`): tiles whose lots and content
    /// keys are unchanged are copied from it instead of derived ([`incremental`]), and the
    /// report lists the buildings added, removed, changed and affected.
    pub previous: Option<PathBuf>,
    /// Reused files are hard links to `previous`'s rather than copies (`--link-previous`),
    /// where both folders are on one file system: no bytes copied, one inode shared.
    pub link_previous: bool,
    /// An OSM change file applied on top of the `--osm` extract (`--osc`, `.osc` or
    /// `.osc.gz`): the run reads the extract as the change leaves it.
    pub osc: Option<PathBuf>,
    /// The source's name written into the files (titles, the IFC project, its GUIDs'
    /// namespace) instead of the input's file name (`--source-name`): a nightly job whose
    /// extract's name carries the date keeps one, so that its files stay the same bytes.
    pub source_name: Option<String>,
    /// Digital elevation models (`--dem`, GeoTIFF, several tiles in any order of priority):
    /// every building stands on the lowest terrain under its footprint, and the run's
    /// [`prepare::Site::elevation`] is resampled from them. Issue 44.
    pub dem: Vec<PathBuf>,
    /// Without a DEM, the height every building stands at (`--ground-height`, metres).
    pub ground_height: Option<f64>,
    /// The largest vertical distance, metres, between the terrain written and the elevation
    /// grid's samples (`--terrain-tolerance`, default [`terrain::DEFAULT_TOLERANCE`]).
    pub terrain_tolerance: f64,
    /// Write no terrain even when the run has an elevation grid (`--no-terrain`).
    pub no_terrain: bool,
    /// Heights from a function, for a run that reads no DEM of its own: tests and programs
    /// that embed citygen give the run an elevation grid this way (no flag sets it).
    pub ground_fn: Option<terrain::GroundFn>,
    /// The head of a `citygen split` part (`--split-part`): `source` is that part's PBF, and
    /// the run takes the whole input's CRS, origin, grid and report share from the head
    /// ([`split`]).
    pub split_part: Option<PathBuf>,
}

/// What each lot may infer: `over` everywhere when given (`--infer`), else its zone's
/// `infer` ([`KnowledgeBase::inference_by_zone`]); `zones[i]` is lot `i`'s zone.
pub(crate) fn inference_wanted(
    kb: &KnowledgeBase,
    zones: &[usize],
    over: Option<crate::model::Inference>,
) -> Vec<crate::model::Inference> {
    if let Some(o) = over {
        return vec![o; zones.len()];
    }
    let by_zone = kb.inference_by_zone();
    zones
        .iter()
        .map(|&z| {
            by_zone
                .get(z)
                .copied()
                .unwrap_or(crate::model::Inference::NONE)
        })
        .collect()
}

/// What the lots' tags leave out: colours from tagged neighbours' votes ([`prepare::infer`]),
/// heights and roofs from the estimator ([`prepare::estimate`]), each where the zone or
/// `--infer` asks. Returns the report note of each lot its neighbours changed, by id, and the
/// run's lines on the estimator's fit, and the estimator's outcome.
pub(crate) fn infer_from_neighbours(
    kb: &KnowledgeBase,
    boundaries: &crate::kb::BoundaryZones,
    lots: &mut [prepare::Lot],
    over: Option<crate::model::Inference>,
) -> Inferred {
    use rayon::prelude::*;
    let start = Instant::now();
    let zones: Vec<usize> = lots
        .par_iter()
        .map(|l| kb.locate_with(boundaries, l.lonlat.0, l.lonlat.1).zone)
        .collect();
    let wanted = inference_wanted(kb, &zones, over);
    let colours = |i: usize| crate::model::Inference {
        colour: wanted[i].colour,
        ..crate::model::Inference::NONE
    };
    let inferred = prepare::infer::infer(lots, colours, Default::default());
    let mut notes: std::collections::HashMap<SourceId, String> =
        prepare::infer::apply(lots, &inferred)
            .into_iter()
            .map(|(i, note)| (lots[i].id, note))
            .collect();
    // Freed before the estimator's own working set (a peak of memory otherwise).
    drop(inferred);
    let mut phases = vec![Phase::mark("colours", start)];
    let models = prepare::estimate::Models::shipped();
    let mixes = roof_mixes(kb, lots, &zones);
    drop(zones);
    let outcome = prepare::estimate::estimate_owned(lots, mixes, &wanted, &models, false);
    phases.push(Phase::mark("estimate", start));
    if kb.has_conditions() {
        // The KB draws appearances by the footprint's form: every lot's, tagged or not.
        prepare::estimate::apply_forms(lots, &outcome.features);
    }
    if outcome.estimates.iter().all(Option::is_none) {
        return Inferred {
            notes,
            lines: Vec::new(),
            outcome,
            phases,
        };
    }
    for (id, phrase) in prepare::estimate::neighbour_notes(lots, &outcome) {
        notes
            .entry(id)
            .and_modify(|n| {
                n.push_str("; ");
                n.push_str(&phrase);
            })
            .or_insert(phrase);
    }
    prepare::estimate::apply(lots, &outcome.estimates);
    Inferred {
        notes,
        lines: prepare::estimate::describe(&outcome),
        outcome,
        phases,
    }
}

/// Runs what a run infers from the neighbours (colours, then the height and roof estimator)
/// over `lots`, every inference on, as [`run`] does between its `fronts` and `select` stages:
/// for `tests/memory_estimate.rs`, which measures its working set. Returns
/// how many lots have storeys after it (tagged or estimated).
#[doc(hidden)]
pub fn infer_all(kb: &KnowledgeBase, lots: &mut [prepare::Lot]) -> usize {
    let all = crate::model::Inference {
        levels: true,
        roof: true,
        colour: true,
    };
    let boundaries = crate::kb::BoundaryZones::default();
    drop(infer_from_neighbours(kb, &boundaries, lots, Some(all)));
    lots.iter().filter(|l| l.tags.levels.is_some()).count()
}

/// Per lot, its zone's roof and storey prior for its kind ([`KnowledgeBase::roof_mix`]), each
/// (zone, kind) computed once.
pub(crate) fn roof_mixes(
    kb: &KnowledgeBase,
    lots: &[prepare::Lot],
    zones: &[usize],
) -> Vec<crate::model::RoofMix> {
    let mut cache: std::collections::HashMap<(usize, Option<&str>), crate::model::RoofMix> =
        std::collections::HashMap::new();
    lots.iter()
        .zip(zones)
        .map(|(l, &zone)| {
            let kind = l.tags.building.as_deref();
            *cache
                .entry((zone, kind))
                .or_insert_with(|| kb.roof_mix(zone, kind))
        })
        .collect()
}

/// What [`infer_from_neighbours`] found.
pub(crate) struct Inferred {
    /// The report note of each lot its neighbours changed, by id.
    pub notes: std::collections::HashMap<SourceId, String>,
    /// The run's lines on the estimator's fit.
    pub lines: Vec<String>,
    /// The estimator's outcome, lot by lot.
    pub outcome: prepare::estimate::Outcome,
    /// Its stages' ends (`colours`, `estimate`), seconds from its start.
    pub phases: Vec<Phase>,
}

/// The buildings of `lots` (those `keep` selects) whose zone came through one of the input's
/// matched admin boundaries, counted per boundary into `report.boundaries`; nothing when no
/// boundary matched a zone.
pub(crate) fn count_boundary_zones(
    generator: &Generator,
    lots: &[prepare::Lot],
    keep: impl Fn(usize) -> bool + Sync,
    report: &mut Report,
) {
    use rayon::prelude::*;
    let matched = generator.boundaries().matched();
    if matched.is_empty() {
        return;
    }
    let counts = lots
        .par_iter()
        .enumerate()
        .fold(
            || vec![0usize; matched.len()],
            |mut acc, (i, lot)| {
                if keep(i) {
                    if let Some(b) = generator.zone_of(lot).boundary {
                        acc[b] += 1;
                    }
                }
                acc
            },
        )
        .reduce(
            || vec![0usize; matched.len()],
            |a, b| a.iter().zip(&b).map(|(x, y)| x + y).collect(),
        );
    let kb = &generator.kb;
    let section = report.boundaries.get_or_insert_with(Default::default);
    section.zones = matched
        .iter()
        .zip(counts)
        .map(|(m, buildings)| crate::report::BoundaryZone {
            boundary: m.id.to_string(),
            name: m.name.clone(),
            admin_level: m.admin_level,
            zone: kb.zone_path(m.zone).to_string(),
            buildings,
        })
        .collect();
}

/// What went wrong, for the exit code and the message.
#[derive(Debug, Error)]
pub enum RunError {
    /// Bad input file (exit code 1).
    #[error("{0}")]
    Input(String),
    /// The command line asks for something that cannot be done, found before any work (exit
    /// code 2): two outputs on one path, an output on an input, an output in a folder that is a
    /// file, an extension that is not the format's.
    #[error("{0}")]
    Usage(String),
    /// An output could not be written (exit code 3).
    #[error("{path}: {source}")]
    Output {
        /// The output file (for a tiled run, the tile's file; for the report, `--report`).
        path: PathBuf,
        /// The writer's or the file system's error.
        source: ExportError,
    },
}

/// Totals of a run, for the summary line.
#[derive(Clone, Debug, Default)]
pub struct Summary {
    /// The run report (what `--report` writes), with its `skipped` and `repaired` counts
    /// computed from its entries.
    pub report: Report,
    /// Planar polygons of all generated buildings, as
    /// `Building::polygon_count` counts them.
    pub polygons: usize,
    /// Wall-clock time: of the whole run for [`run`]; of deriving and writing for
    /// `generate_and_write` and `derive_lot`.
    pub elapsed: Duration,
    /// The files written, or with `dry_run` the files that would have been.
    pub outputs: Vec<PathBuf>,
    /// Bytes of every output file together (written, or rendered and dropped with `dry_run`).
    pub bytes: u64,
    /// The tiles the outputs were split into (`--tile`); 0 for an untiled run.
    pub tiles: usize,
    /// What the user should know about the outputs although the run succeeded (a CityGML file
    /// too big for the reference validator); each is also a note in the report.
    pub warnings: Vec<String>,
    /// The run's stages in order, each with its end time and memory ([`Phase`]); empty for
    /// the runs that are not [`run`].
    pub phases: Vec<Phase>,
}

/// One stage of a [`run`] as it ended: `read` (the input read), `project` (the lots in the
/// output CRS), `fronts`, `colours` (from the neighbours), `estimate` (heights and roofs
/// estimated), `infer` (both applied),
/// `prepare` (the generator ready), `select` (grid, keys, surroundings), `write` (derived and
/// written).
/// Memory from `/proc/self/status` (Linux; `None` elsewhere): the peak so far
/// (`VmHWM`) at the end of the first stage is that stage's own peak.
#[derive(Clone, Debug, PartialEq)]
pub struct Phase {
    /// The stage's name.
    pub name: &'static str,
    /// Seconds since the run started, at the stage's end.
    pub secs: f64,
    /// Resident set size at the stage's end, KiB.
    pub rss_kib: Option<u64>,
    /// The process's peak resident set size so far, KiB.
    pub peak_kib: Option<u64>,
}

impl Phase {
    /// The stage `name` ending now, `start` being the run's start.
    pub(crate) fn mark(name: &'static str, start: Instant) -> Phase {
        let status = std::fs::read_to_string("/proc/self/status").unwrap_or_default();
        let field = |key: &str| {
            let line = status.lines().find(|l| l.starts_with(key))?;
            line[key.len()..]
                .trim()
                .trim_end_matches("kB")
                .trim()
                .parse()
                .ok()
        };
        Phase {
            name,
            secs: start.elapsed().as_secs_f64(),
            rss_kib: field("VmRSS:"),
            peak_kib: field("VmHWM:"),
        }
    }
}

/// Called after each chunk with (buildings done, buildings in all).
pub(crate) type Progress<'a> = &'a (dyn Fn(usize, usize) + Sync);

/// Runs the pipeline and writes every requested output atomically.
pub fn run(opts: &Options, progress: Progress<'_>) -> Result<Summary, RunError> {
    let start = Instant::now();
    let (targets, shard) = checked_targets(opts)?;
    let previous = previous_run(opts, &targets)?;
    if let Some(prev) = &previous {
        // No output on a file the run reads from yesterday's folder (its manifests, its
        // tiles); the outputs were checked against each other and the rest above.
        outputs::check(&targets.flagged(), &prev.read_files(), true)?;
    }
    // The DEMs' headers first: a file that cannot serve fails the run before any reading.
    let dems = ground::open(opts)?;
    let mut run = RunState::prepare(opts, targets, shard, start)?;
    check_kb_files(&run)?;
    run.select();
    run.seat(dems.as_ref())?;
    // A tiled run's content keys; with --previous, what changed and the tiles reused (copied
    // now, so that the LOD3 surroundings are derived only around the tiles derived).
    let (mut keyed, run_key) = reuse::key_lots(&run, previous.as_ref())?;
    if opts.lod >= Lod::Lod3 {
        run.surroundings(&keyed.reused);
    }
    run.retain_in_bbox()?;
    let manifest = run.manifest(run_key, &keyed.context)?;
    keyed.previous = previous;
    let mut phases = std::mem::take(&mut run.phases);
    phases.push(Phase::mark("select", start));
    let mut summary = run.write(manifest, keyed, progress)?;
    phases.push(Phase::mark("write", start));
    summary.phases = phases;
    summary.elapsed = start.elapsed();
    Ok(summary)
}

/// The run's targets as its options name them, checked against each other and the inputs
/// ([`outputs::check`]) before any work, and its shard ([`plan::shard_targets`]).
fn checked_targets(opts: &Options) -> Result<(Targets, (shard::Shard, String)), RunError> {
    let inputs = run_inputs(opts);
    let targets = Targets {
        ifc: opts.ifc.clone(),
        ifc_schema: opts.ifc_schema,
        ifc_max_bytes: opts.ifc_max_bytes,
        citygml: opts.citygml.clone(),
        gltf: opts.gltf.clone(),
        cityjson: opts.cityjson.clone(),
        cityjsonseq: opts.cityjsonseq.clone(),
        report: opts.report.clone(),
        preview: opts.preview.clone(),
        tiles3d: opts.tiles3d.clone(),
        dry_run: opts.dry_run,
        textures: opts.textures,
        allow_empty: opts.allow_empty,
        manifest: None,
        terrain: (!opts.no_terrain).then_some(TerrainPlan {
            tolerance: opts.terrain_tolerance,
            tile: opts.tile,
        }),
    };
    outputs::check(&targets.flagged(), &inputs, opts.force_extension)?;
    shard_targets(opts, targets)
}

/// Checks the run's outputs against the files the knowledge base's appearances name (their
/// rulesets and SELEX programs: inputs too, known once the KB is read), before anything is
/// written ([`outputs::check`]).
fn check_kb_files(run: &RunState<'_>) -> Result<(), RunError> {
    let kb = &run.generator.kb;
    let mut inputs = Vec::new();
    for (z, zone) in kb.zones().iter().enumerate() {
        for a in 0..zone.appearances.len() {
            let named = [kb.ruleset_path(z, a, false), kb.selex_path(z, a)];
            for p in named.into_iter().filter_map(|p| p.ok().flatten()) {
                inputs.push(("a --kb appearance", p));
            }
        }
    }
    if inputs.is_empty() {
        return Ok(());
    }
    outputs::check(&run.targets.flagged(), &inputs, run.opts.force_extension)
}

/// The files the run reads as its options name them, each with its flag: the source (a
/// shapefile's parts), `--kb`, `--rules` and `--osc`.
fn run_inputs(opts: &Options) -> Vec<(&'static str, PathBuf)> {
    let mut inputs = match &opts.source {
        Source::Osm(p) => vec![("--osm", p.clone())],
        Source::Shp { path, .. } => outputs::shapefile_parts(path)
            .into_iter()
            .map(|p| ("--shp", p))
            .collect(),
    };
    inputs.extend(opts.kb.iter().map(|p| ("--kb", p.clone())));
    inputs.extend(opts.rules.iter().map(|p| ("--rules", p.clone())));
    inputs.extend(opts.osc.iter().map(|p| ("--osc", p.clone())));
    inputs.extend(opts.dem.iter().map(|p| ("--dem", p.clone())));
    inputs
}

/// Yesterday's run (`--previous`), loaded, or the usage error of asking for it where it
/// cannot serve.
fn previous_run(
    opts: &Options,
    targets: &Targets,
) -> Result<Option<incremental::Previous>, RunError> {
    match &opts.previous {
        None => Ok(None),
        Some(_) if opts.dry_run => Err(RunError::Usage(
            "--previous with --dry-run: a dry run writes no tile to reuse into".into(),
        )),
        Some(_) if opts.tile.is_none() || targets.manifest.is_none() => Err(RunError::Usage(
            "--previous needs --tile METRES and a model output: it reuses the tiles of a \
             tiled run"
                .into(),
        )),
        Some(_) if opts.preview.is_some() => Err(RunError::Usage(
            "--previous with --preview: a reused tile is not derived, so this run cannot \
             draw it; draw the region with `citygen merge DIR --preview F.png` (from the \
             3D Tiles contents, --tiles3d)"
                .into(),
        )),
        Some(d) => {
            let mut prev =
                incremental::load_previous(d).map_err(|e| RunError::Input(e.to_string()))?;
            prev.link = opts.link_previous;
            Ok(Some(prev))
        }
    }
}

/// A run between the steps of [`run`]: its targets, the site as read and prepared, the
/// generator, the report so far, and which lots it writes.
struct RunState<'a> {
    opts: &'a Options,
    targets: Targets,
    shard: (shard::Shard, String),
    report: Report,
    source_name: String,
    site: prepare::Site,
    generator: Generator,
    /// The lots as read, before anything is lent to them (a tiled run records content keys).
    own_keys: Option<std::collections::HashMap<SourceId, incremental::Key>>,
    /// What each lot inferred from its neighbours, noted for the lots the run keeps.
    inferred_notes: std::collections::HashMap<SourceId, String>,
    /// The estimator's touching pairs (its rows), for `citygen split`; emptied by `select`.
    touching: Vec<(u32, u32, f32)>,
    /// The lots this run writes: those in --bbox, and of a shard, those of its tiles.
    selected: Vec<bool>,
    /// The lots of the run, all shards' (for the changes since --previous).
    in_run: Vec<bool>,
    /// The tile grid of a tiled run.
    grid: Option<GridPlan>,
    /// The head of the `citygen split` part the run reads (`--split-part`).
    split: Option<split::SplitHead>,
    /// The stages ended so far.
    phases: Vec<Phase>,
}

impl<'a> RunState<'a> {
    /// Reads the source and the knowledge base, prepares the site (output CRS, fronts,
    /// inference) and makes the generator, its rulesets and SELEX programs loaded.
    fn prepare(
        opts: &'a Options,
        targets: Targets,
        shard: (shard::Shard, String),
        start: Instant,
    ) -> Result<RunState<'a>, RunError> {
        let split = match &opts.split_part {
            Some(p) => Some(split::load_head(p, opts)?),
            None => None,
        };
        let mut report = Report::default();
        let read = read_source(&opts.source, opts.osc.as_deref(), opts.src_crs, &mut report)?;
        let mut phases = vec![Phase::mark("read", start)];
        let source_crs = opts.src_crs.or(read.source_crs);
        let source_name = match (&opts.source_name, &opts.source, &split) {
            (Some(n), _, _) => n.clone(),
            (None, _, Some(h)) => h.source_name.clone(),
            (None, Source::Osm(p) | Source::Shp { path: p, .. }, None) => file_name(p),
        };

        let kb = load_kb(opts.kb.as_deref(), &mut report)?;
        let rules = match &opts.rules {
            Some(p) => Rules::File(Arc::new(read_rules(p)?)),
            None => Rules::Kb,
        };

        let crs = match (&split, opts.crs) {
            // The whole input's CRS and origin, not the part's.
            (Some(h), _) => h.crs()?,
            (None, Some(c)) => c,
            // Errors name the input as given (two `b.shp` in two folders are two inputs).
            (None, None) => zone_for(&read.footprints, source_crs, opts.bbox, &source_label(opts))?,
        };
        let origin = split
            .as_ref()
            .map(|h| glam::DVec2::new(h.origin[0], h.origin[1]));
        let mut site =
            prepare::prepare_at(read.footprints, source_crs, Some(crs), origin, &mut report);
        site.boundaries = read.boundaries;
        site.attributes = read.attributes;
        phases.push(Phase::mark("project", start));
        prepare::assign_fronts(&mut site, &read.streets, source_crs);
        drop(read.streets);
        phases.push(Phase::mark("fronts", start));
        // Only a run with a manifest records keys (`reuse::key_lots`): a dry run holds none.
        let own_keys = (opts.tile.is_some() && targets.manifest.is_some())
            .then(|| incremental::own_keys(&site.lots));
        let caps = Caps {
            facades: opts.lod >= Lod::Lod3,
            ..opts.caps
        };
        let mut generator = Generator::new(kb, rules, opts.lod, opts.seed, caps);
        generator.match_boundaries(&site.boundaries);
        // Before --bbox, so that the neighbours outside the box count; noted for the buildings
        // the run keeps.
        let before = start.elapsed().as_secs_f64();
        let mut inferred = infer_from_neighbours(
            &generator.kb,
            generator.boundaries(),
            &mut site.lots,
            opts.infer,
        );
        phases.extend(inferred.phases.into_iter().map(|p| Phase {
            secs: p.secs + before,
            ..p
        }));
        // The estimator's outcome lot by lot is not needed past here (but its rows by
        // `citygen split`, until `select`).
        let touching = std::mem::take(&mut inferred.outcome.touching);
        drop(inferred.outcome);
        for line in inferred.lines {
            report.add(None, Outcome::Note, line);
        }
        let inferred_notes = inferred.notes;
        phases.push(Phase::mark("infer", start));
        if matches!(generator.rules, Rules::Kb) {
            generator
                .load_selex()
                .map_err(|e| RunError::Input(e.to_string()))?;
            for n in generator.load_rulesets() {
                report.add(None, Outcome::Note, n);
            }
        }
        phases.push(Phase::mark("prepare", start));
        Ok(RunState {
            opts,
            targets,
            shard,
            report,
            source_name,
            site,
            generator,
            own_keys,
            inferred_notes,
            touching,
            selected: Vec::new(),
            in_run: Vec::new(),
            grid: None,
            split,
            phases,
        })
    }

    /// Chooses the lots this run writes (`selected`, and all shards' `in_run`) and, with
    /// `--tile`, the grid.
    fn select(&mut self) {
        self.touching = Vec::new();
        let (opts, site) = (self.opts, &self.site);
        let mut selected: Vec<bool> = match opts.bbox {
            Some(b) => site
                .lots
                .iter()
                .map(|l| prepare::in_bbox(l.lonlat, b))
                .collect(),
            None => vec![true; site.lots.len()],
        };
        let grid = opts.tile.map(|size| match &self.split {
            Some(h) => GridPlan::from_grid(&h.grid, size, self.shard.0),
            None => GridPlan::new(site, size, &selected, self.shard.0),
        });
        self.in_run = selected.clone();
        if let Some(g) = &grid {
            for (flag, lot) in selected.iter_mut().zip(&site.lots) {
                *flag = *flag && g.is_mine(site.crs, lot);
            }
        }
        count_boundary_zones(
            &self.generator,
            &site.lots,
            |i| selected[i],
            &mut self.report,
        );
        self.selected = selected;
        self.grid = grid;
    }

    /// Party walls: every building the run derives, and those that touch one, at LOD2 first
    /// (not those of tiles `reused` from --previous).
    fn surroundings(&mut self, reused: &std::collections::BTreeMap<String, reuse::ReusedTile>) {
        let site = &self.site;
        let derived: Vec<bool> = match &self.grid {
            Some(g) if !reused.is_empty() => site
                .lots
                .iter()
                .zip(&self.selected)
                .map(|(l, s)| *s && !reused.contains_key(&g.suffix_of(site.crs, l)))
                .collect(),
            _ => self.selected.clone(),
        };
        let keep = if derived.iter().all(|k| *k) {
            derived
        } else {
            prepare::near_selected(&site.lots, &derived, incremental::NEIGHBOUR_MARGIN_M)
        };
        self.generator.surroundings = self.generator.neighbours_of(&site.lots, |i| keep[i]);
    }

    /// Keeps the lots in `--bbox` (none left is an error without `--allow-empty`), and notes
    /// what the lots kept inferred.
    fn retain_in_bbox(&mut self) -> Result<(), RunError> {
        if let Some(b) = self.opts.bbox {
            if let Err(why) = prepare::retain_in_bbox(&mut self.site, b, &mut self.report) {
                if !self.opts.allow_empty {
                    return Err(RunError::Input(format!(
                        "{why} (pass --allow-empty to write empty outputs)"
                    )));
                }
            }
        }
        for lot in &self.site.lots {
            if let Some(note) = self.inferred_notes.remove(&lot.id) {
                self.report.add(Some(lot.id), Outcome::Note, note);
            }
        }
        Ok(())
    }

    /// A tiled run's manifest: its path and head (the run key, `context`, and the report so
    /// far, which becomes this shard's share); the site then keeps this shard's lots only.
    fn manifest(
        &mut self,
        run_key: Option<shard::RunKey>,
        context: &str,
    ) -> Result<Option<(PathBuf, shard::Manifest)>, RunError> {
        let (Some(g), Some(path)) = (&self.grid, &self.targets.manifest) else {
            return Ok(None);
        };
        let rk = match run_key {
            Some(rk) => rk,
            None => g.run_key(
                self.opts,
                &self.targets,
                &self.site,
                &self.generator.kb,
                self.split.as_ref().map(|h| h.inputs.as_slice()),
            )?,
        };
        let mut head = g.manifest_head(rk, &self.shard, &self.site, &mut self.report)?;
        if let Some(h) = &self.split {
            // The read and prepare stages' share as the whole input gives it, not the part.
            head.report = h.share.clone();
            self.report = h.report.clone();
        }
        head.context = context.to_string();
        let crs = self.site.crs;
        self.site.lots.retain(|l| g.is_mine(crs, l));
        Ok(Some((path.clone(), head)))
    }

    /// Derives and writes the site, one batch per tile with `--tile` ([`write_batches`]).
    fn write(
        self,
        manifest: Option<(PathBuf, shard::Manifest)>,
        keys: reuse::Keyed,
        progress: Progress<'_>,
    ) -> Result<Summary, RunError> {
        let RunState {
            opts,
            targets,
            report,
            source_name,
            mut site,
            generator,
            ..
        } = self;
        if site.elevation.is_none() {
            if let Some(f) = &opts.ground_fn {
                site.elevation = f.grid(&site.lots, site.origin);
            }
        }
        let batches: Vec<Batch> = match opts.tile {
            None => vec![Batch {
                suffix: None,
                range: 0..site.lots.len(),
                cell: (0, 0),
            }],
            Some(size) => prepare::group_into_tiles(&mut site, size)
                .into_iter()
                .map(|t| Batch {
                    suffix: Some(t.suffix()),
                    cell: crate::export::tiles3d::TileEntry::cell_of(t.corner, size),
                    range: t.range,
                })
                .collect(),
        };
        // The lots out of the site, so that each tile's geometry is freed once written.
        let lots = write::Lots::Owned(std::mem::take(&mut site.lots));
        write::write_lots_of(
            &site,
            lots,
            &batches,
            &Maker::Generator(&generator),
            &FileSet {
                name: &source_name,
                input: Some(match &opts.source {
                    Source::Osm(p) | Source::Shp { path: p, .. } => p.as_path(),
                }),
                targets: &targets,
            },
            report,
            Ledger { manifest, keys },
            progress,
        )
    }
}

/// Reads the footprints of the source (with `src_crs` overriding a shapefile's `.prj`).
pub(crate) fn read_source(
    source: &Source,
    osc: Option<&Path>,
    src_crs: Option<Crs>,
    report: &mut Report,
) -> Result<input::ReadResult, RunError> {
    match source {
        Source::Osm(p) => input::osm::read_osm_with_changes(p, osc, report),
        Source::Shp { .. } if osc.is_some() => {
            return Err(RunError::Usage(
                "--osc applies an OSM change file to an --osm extract, not to a shapefile".into(),
            ))
        }
        Source::Shp {
            path,
            height_field,
            levels_field,
            fields,
            layer,
        } => {
            let o = ShpOptions {
                height_field: height_field.clone(),
                levels_field: levels_field.clone(),
                src_crs,
                fields: fields.clone(),
                layer: layer.clone(),
            };
            let gpkg = input::gpkg::looks_like_gpkg(path);
            if let (Some(l), false) = (layer, gpkg) {
                return Err(RunError::Usage(format!(
                    "--layer {l} names a GeoPackage layer, and {} is not a GeoPackage",
                    path.display()
                )));
            }
            if input::geojson::looks_like_geojson(path) {
                input::geojson::read_geojson(path, &o, report)
            } else if gpkg {
                input::gpkg::read_gpkg(path, &o, report)
            } else if input::fgb::looks_like_fgb(path) {
                input::fgb::read_fgb(path, &o, report)
            } else {
                input::shp::read_shp(path, &o, report)
            }
        }
    }
    .map_err(|e| RunError::Input(e.to_string()))
}

pub(crate) fn load_kb(path: Option<&Path>, report: &mut Report) -> Result<KnowledgeBase, RunError> {
    match path {
        Some(p) => {
            let (kb, repairs) =
                KnowledgeBase::load(p).map_err(|e| RunError::Input(e.to_string()))?;
            for r in repairs {
                report.add(None, Outcome::Note, format!("{}: {r}", p.display()));
            }
            for n in kb::tools::ruleset_notes(&kb) {
                report.add(None, Outcome::Note, n);
            }
            Ok(kb)
        }
        None => Ok(KnowledgeBase::earth_only()),
    }
}

pub(crate) fn read_rules(p: &Path) -> Result<crate::grammar::RuleSet, RunError> {
    // At most grammar::MAX_SOURCE_BYTES are read: a huge file is refused, not read whole.
    let text = crate::grammar::read_source(p)
        .map_err(|e| RunError::Input(format!("{}: {e}", p.display())))?;
    crate::grammar::parse(&text, &p.display().to_string())
        .map_err(|e| RunError::Input(e.to_string()))
}

/// Where a run writes.
#[derive(Clone, Debug, Default)]
pub(crate) struct Targets {
    /// Write IFC (STEP) here.
    pub ifc: Option<PathBuf>,
    /// The IFC schema written (IFC4 unless `--ifc-schema` says otherwise).
    pub ifc_schema: crate::export::ifc::IfcSchema,
    /// The most bytes of an IFC file ([`Options::ifc_max_bytes`]).
    pub ifc_max_bytes: Option<u64>,
    /// Write CityGML 2.0 here.
    pub citygml: Option<PathBuf>,
    /// Write binary glTF 2.0 (`.glb`) here.
    pub gltf: Option<PathBuf>,
    /// Write CityJSON 2.0 (`.city.json`) here.
    pub cityjson: Option<PathBuf>,
    /// Write CityJSONSeq (`.city.jsonl`) here.
    pub cityjsonseq: Option<PathBuf>,
    /// Write the JSON run report here.
    pub report: Option<PathBuf>,
    /// Write an overview picture (PNG) of the buildings here.
    pub preview: Option<PathBuf>,
    /// Write OGC 3D Tiles into this folder ([`Options::tiles3d`]).
    pub tiles3d: Option<PathBuf>,
    /// Render the model outputs but write none (see [`Options::dry_run`]).
    pub dry_run: bool,
    /// Textures in the glTF and 3D Tiles outputs ([`Options::textures`]).
    pub textures: bool,
    /// Publish the outputs even when no building was generated ([`Options::allow_empty`]).
    pub allow_empty: bool,
    /// Write a shard manifest here ([`shard::Manifest`]): every output is hashed as written.
    pub manifest: Option<PathBuf>,
    /// Write the terrain of the site's elevation grid, when it has one (not `--no-terrain`).
    pub terrain: Option<TerrainPlan>,
}

/// How a run writes its terrain ([`terrain`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct TerrainPlan {
    /// [`Options::terrain_tolerance`].
    pub tolerance: f64,
    /// The tile size (`--tile`): each tile's terrain is cut to its square.
    pub tile: Option<u32>,
}

impl Targets {
    /// The model outputs' paths, each with its format, in [`Model`] order: with
    /// [`Targets::models_mut`], the one place that lists them.
    fn models(&self) -> [(Model, &Option<PathBuf>); 5] {
        [
            (Model::Ifc, &self.ifc),
            (Model::CityGml, &self.citygml),
            (Model::Gltf, &self.gltf),
            (Model::CityJson, &self.cityjson),
            (Model::CityJsonSeq, &self.cityjsonseq),
        ]
    }

    /// The model outputs' paths, to change, in [`Model`] order.
    fn models_mut(&mut self) -> [&mut Option<PathBuf>; 5] {
        [
            &mut self.ifc,
            &mut self.citygml,
            &mut self.gltf,
            &mut self.cityjson,
            &mut self.cityjsonseq,
        ]
    }

    /// The paths asked for, each with the flag that names it (for [`outputs::check`]); for
    /// `--tiles3d`, its `tileset.json`.
    pub(crate) fn flagged(&self) -> Vec<(&'static str, PathBuf)> {
        self.models()
            .into_iter()
            .map(|(m, p)| (m.flag(), p))
            .chain([("--report", &self.report), ("--preview", &self.preview)])
            .filter_map(|(flag, p)| p.clone().map(|p| (flag, p)))
            .chain(
                self.tiles3d
                    .as_ref()
                    .map(|d| ("--tiles3d", d.join("tileset.json"))),
            )
            .collect()
    }
}

/// The model formats of [`Targets`], in the order a run opens, checks, writes and publishes
/// their files.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Model {
    Ifc,
    CityGml,
    Gltf,
    CityJson,
    CityJsonSeq,
}

impl Model {
    /// The flag naming its output (`--ifc`, ...).
    fn flag(self) -> &'static str {
        match self {
            Model::Ifc => "--ifc",
            Model::CityGml => "--citygml",
            Model::Gltf => "--gltf",
            Model::CityJson => "--cityjson",
            Model::CityJsonSeq => "--cityjsonseq",
        }
    }

    /// Its name in a run key's outputs ([`shard::RunKey::outputs`]): the flag without dashes.
    fn name(self) -> &'static str {
        &self.flag()[2..]
    }
}

/// Derives every lot of the site (in parallel, chunk by chunk) and writes the buildings in lot
/// order to every target, atomically. `report` already holds what reading and preparing said.
pub(crate) fn generate_and_write(
    site: &prepare::Site,
    generator: &Generator,
    source_name: &str,
    targets: &Targets,
    report: Report,
    progress: Progress<'_>,
) -> Result<Summary, RunError> {
    let all = [Batch {
        suffix: None,
        range: 0..site.lots.len(),
        cell: (0, 0),
    }];
    write_batches(
        site,
        &all,
        &Maker::Generator(generator),
        &FileSet {
            name: source_name,
            input: None,
            targets,
        },
        report,
        Ledger::default(),
        progress,
    )
}

/// `path` relative to `dir` with `/` separators where it lies below it, else as given.
fn relative_to(path: &Path, dir: &Path) -> String {
    let rel = path.strip_prefix(dir).unwrap_or(path);
    rel.components()
        .map(|c| c.as_os_str().to_string_lossy().into_owned())
        .collect::<Vec<_>>()
        .join("/")
}

/// Maps a writer error on an output path to a [`RunError`].
fn out_err(p: &Path) -> impl Fn(ExportError) -> RunError + '_ {
    move |e| RunError::Output {
        path: p.to_path_buf(),
        source: e,
    }
}

/// Maps an I/O error on an output path to a [`RunError`].
fn io_err(p: &Path) -> impl Fn(std::io::Error) -> RunError + '_ {
    move |e| RunError::Output {
        path: p.to_path_buf(),
        source: e.into(),
    }
}

/// The run's input as errors name it: its path as given (`--source-name` when set).
fn source_label(opts: &Options) -> String {
    match (&opts.source_name, &opts.source) {
        (Some(n), _) => n.clone(),
        (None, Source::Osm(p) | Source::Shp { path: p, .. }) => p.display().to_string(),
    }
}

pub(crate) fn file_name(p: &Path) -> String {
    p.file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_model_paths_are_listed_and_changed_in_one_order() {
        let mut t = Targets::default();
        for (i, p) in t.models_mut().into_iter().enumerate() {
            *p = Some(PathBuf::from(i.to_string()));
        }
        let listed: Vec<(&str, String)> = t
            .models()
            .into_iter()
            .map(|(m, p)| (m.name(), p.as_ref().unwrap().display().to_string()))
            .collect();
        let names = ["ifc", "citygml", "gltf", "cityjson", "cityjsonseq"];
        let expected: Vec<(&str, String)> = names
            .into_iter()
            .enumerate()
            .map(|(i, n)| (n, i.to_string()))
            .collect();
        assert_eq!(listed, expected);
        assert_eq!(t.ifc, Some(PathBuf::from("0")));
        assert_eq!(t.cityjsonseq, Some(PathBuf::from("4")));
    }

    #[test]
    fn a_phase_holds_this_process_memory_where_the_kernel_gives_it() {
        let held: Vec<u8> = std::hint::black_box(vec![1; 8 << 20]);
        let p = Phase::mark("x", Instant::now());
        assert_eq!(p.name, "x");
        if cfg!(target_os = "linux") {
            let (rss, peak) = (p.rss_kib.unwrap(), p.peak_kib.unwrap());
            // The 8 MiB touched above are resident.
            assert!(rss >= 8 << 10 && peak >= rss, "{rss} {peak}");
        } else {
            assert_eq!((p.rss_kib, p.peak_kib), (None, None));
        }
        drop(held);
    }
}
