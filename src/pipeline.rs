//! The whole run: read -> prepare -> derive (parallel, in chunks) -> write (in input order).

use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use glam::DVec3;
use rayon::prelude::*;
use thiserror::Error;

pub mod building;
pub mod incremental;
pub mod merge;
pub(crate) mod outputs;
pub mod shard;

use sha2::{Digest as _, Sha256};

use crate::crs::Crs;
use crate::derive::{Generator, Rules};
use crate::export::citygml::{CityGmlWriter, VALIDATOR_MAX_ELEMENTS};
use crate::export::cityjson::{CityJsonSeqWriter, CityJsonWriter};
use crate::export::gltf::GltfWriter;
use crate::export::ifc::IfcWriter;
use crate::export::{BuildingWriter, Checked, ExportError, OutputContext};
use crate::fsio::{AtomicFile, PendingFile, StreamSink};
use crate::grammar::Caps;
use crate::input::{self, shp::ShpOptions};
use crate::kb::{self, KnowledgeBase};
use crate::model::{Building, Lod, SourceId};
use crate::prepare;
use crate::report::{Outcome, Report};

/// Buildings derived in parallel before being written; bounds memory.
const CHUNK: usize = 2048;

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
        /// detects it from [`HEIGHT_FIELDS`](crate::input::shp::HEIGHT_FIELDS).
        height_field: Option<String>,
        /// The `.dbf` field holding the number of storeys (`--shp-levels-field`); `None` detects it
        /// from [`LEVELS_FIELDS`](crate::input::shp::LEVELS_FIELDS).
        levels_field: Option<String>,
    },
}

/// Everything a run needs, as the CLI gives it.
#[derive(Clone, Debug)]
pub struct Options {
    /// The footprints to read (`--osm` or `--shp`).
    pub source: Source,
    /// The knowledge base (`--kb`); `None` uses the built-in defaults alone
    /// ([`KnowledgeBase::earth_only`]).
    pub kb: Option<PathBuf>,
    /// A ruleset file applied to every building (`--rules`); `None` compiles the rules of each
    /// building's appearance from the knowledge base.
    pub rules: Option<PathBuf>,
    /// The LOD every building is cut at (`--lod`, default 2).
    pub lod: Lod,
    /// Write IFC4 (STEP) here (`--ifc`).
    pub ifc: Option<PathBuf>,
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
}

/// What each lot may infer: `over` everywhere when given (`--infer`), else its zone's
/// `infer` ([`KnowledgeBase::inference_by_zone`]). The zone lookups are skipped when no zone
/// infers anything.
pub fn inference_wanted(
    kb: &KnowledgeBase,
    lots: &[prepare::Lot],
    over: Option<crate::model::Inference>,
) -> Vec<crate::model::Inference> {
    use rayon::prelude::*;
    if let Some(o) = over {
        return vec![o; lots.len()];
    }
    let by_zone = kb.inference_by_zone();
    if !by_zone.iter().any(|i| i.any()) {
        return vec![crate::model::Inference::NONE; lots.len()];
    }
    lots.par_iter()
        .map(|l| by_zone[kb.locate(l.lonlat.0, l.lonlat.1)])
        .collect()
}

/// Infers what the lots lack from their tagged neighbours ([`prepare::infer`]) and returns
/// the report note of each lot changed, by id.
pub(crate) fn infer_from_neighbours(
    kb: &KnowledgeBase,
    lots: &mut [prepare::Lot],
    over: Option<crate::model::Inference>,
) -> std::collections::HashMap<SourceId, String> {
    let wanted = inference_wanted(kb, lots, over);
    let inferred = prepare::infer::infer(lots, |i| wanted[i], Default::default());
    prepare::infer::apply(lots, &inferred)
        .into_iter()
        .map(|(i, note)| (lots[i].id, note))
        .collect()
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
    /// Planar polygons of all generated buildings, as [`Building::polygon_count`] counts them.
    pub polygons: usize,
    /// Wall-clock time: of the whole run for [`run`]; of deriving and writing for
    /// [`generate_and_write`] and `rules derive`.
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
}

/// Called after each chunk with (buildings done, buildings in all).
pub type Progress<'a> = &'a (dyn Fn(usize, usize) + Sync);

/// Runs the pipeline and writes every requested output atomically.
pub fn run(opts: &Options, progress: Progress<'_>) -> Result<Summary, RunError> {
    let start = Instant::now();
    let mut inputs = match &opts.source {
        Source::Osm(p) => vec![("--osm", p.clone())],
        Source::Shp { path, .. } => outputs::shapefile_parts(path)
            .into_iter()
            .map(|p| ("--shp", p))
            .collect(),
    };
    inputs.extend(opts.kb.iter().map(|p| ("--kb", p.clone())));
    inputs.extend(opts.rules.iter().map(|p| ("--rules", p.clone())));
    let targets = Targets {
        ifc: opts.ifc.clone(),
        citygml: opts.citygml.clone(),
        gltf: opts.gltf.clone(),
        cityjson: opts.cityjson.clone(),
        cityjsonseq: opts.cityjsonseq.clone(),
        report: opts.report.clone(),
        preview: opts.preview.clone(),
        tiles3d: opts.tiles3d.clone(),
        dry_run: opts.dry_run,
        allow_empty: opts.allow_empty,
        manifest: None,
    };
    outputs::check(&targets.flagged(), &inputs, opts.force_extension)?;
    let (targets, shard) = shard_targets(opts, targets)?;
    let previous = match &opts.previous {
        None => None,
        Some(_) if opts.dry_run => {
            return Err(RunError::Usage(
                "--previous with --dry-run: a dry run writes no tile to reuse into".into(),
            ))
        }
        Some(_) if opts.tile.is_none() || targets.manifest.is_none() => {
            return Err(RunError::Usage(
                "--previous needs --tile METRES and a model output: it reuses the tiles of a \
                 tiled run"
                    .into(),
            ))
        }
        Some(_) if opts.preview.is_some() => {
            return Err(RunError::Usage(
                "--previous with --preview: a reused tile is not derived, so this run cannot \
                 draw it; draw the region with `citygen merge DIR --preview F.png` (from the \
                 3D Tiles contents, --tiles3d)"
                    .into(),
            ))
        }
        Some(d) => {
            let mut prev =
                incremental::load_previous(d).map_err(|e| RunError::Input(e.to_string()))?;
            prev.link = opts.link_previous;
            Some(prev)
        }
    };
    let mut report = Report::default();
    let read = read_source(&opts.source, opts.osc.as_deref(), opts.src_crs, &mut report)?;
    let source_crs = opts.src_crs.or(read.source_crs);
    let source_name = match (&opts.source_name, &opts.source) {
        (Some(n), _) => n.clone(),
        (None, Source::Osm(p) | Source::Shp { path: p, .. }) => file_name(p),
    };

    let kb = load_kb(opts.kb.as_deref(), &mut report)?;
    let rules = match &opts.rules {
        Some(p) => Rules::File(Arc::new(read_rules(p)?)),
        None => Rules::Kb,
    };

    let crs = match opts.crs {
        Some(c) => c,
        None => zone_for(&read.footprints, source_crs, opts.bbox, &source_name)?,
    };
    let mut site = prepare::prepare(read.footprints, source_crs, Some(crs), &mut report);
    prepare::assign_fronts(&mut site, &read.streets, source_crs);
    // The lots as read, before anything is lent to them (a tiled run records content keys).
    let own_keys = opts.tile.map(|_| incremental::own_keys(&site.lots));
    // Before --bbox, so that the neighbours outside the box count; noted for the buildings
    // the run keeps.
    let mut inferred_notes = infer_from_neighbours(&kb, &mut site.lots, opts.infer);
    let caps = Caps {
        facades: opts.lod >= Lod::Lod3,
        ..opts.caps
    };
    let mut generator = Generator::new(kb, rules, opts.lod, opts.seed, caps);
    if matches!(generator.rules, Rules::Kb) {
        generator
            .load_selex()
            .map_err(|e| RunError::Input(e.to_string()))?;
        for n in generator.load_rulesets() {
            report.add(None, Outcome::Note, n);
        }
    }
    // The lots this run writes: those in --bbox, and of a shard, those of its tiles.
    let mut selected: Vec<bool> = match opts.bbox {
        Some(b) => site
            .lots
            .iter()
            .map(|l| prepare::in_bbox(l.lonlat, b))
            .collect(),
        None => vec![true; site.lots.len()],
    };
    let grid = opts
        .tile
        .map(|size| GridPlan::new(&site, size, &selected, shard.0));
    // The lots of the run, all shards' (for the changes since --previous).
    let in_run = selected.clone();
    if let Some(g) = &grid {
        for (flag, lot) in selected.iter_mut().zip(&site.lots) {
            *flag = *flag && g.is_mine(site.crs, lot);
        }
    }
    // A tiled run's content keys; with --previous, what changed and the tiles reused (copied
    // now, so that the LOD3 surroundings are derived only around the tiles derived).
    let mut keyed = Keyed::default();
    let mut run_key = None;
    if let (Some(g), Some(path), Some(own)) = (&grid, &targets.manifest, &own_keys) {
        let rk = g.run_key(opts, &site, &generator.kb)?;
        let dir = path
            .parent()
            .filter(|d| !d.as_os_str().is_empty())
            .unwrap_or(Path::new("."))
            .to_path_buf();
        let mut outs: Vec<String> = targets
            .flagged()
            .into_iter()
            .map(|(flag, p)| format!("{flag} {}", relative_to(&p, &dir)))
            .collect();
        outs.sort();
        let context = incremental::context_key(&rk, &source_name, &outs);
        keyed.context = incremental::key_hex(&context);
        // Over every lot: neighbours outside --bbox count.
        keyed.keys =
            incremental::with_context(&context, incremental::full_keys(&site.lots, own, opts.lod));
        if let Some(prev) = &previous {
            let run_lots: std::collections::BTreeMap<String, (String, String)> = site
                .lots
                .iter()
                .zip(&in_run)
                .filter(|(_, s)| **s)
                .filter_map(|(l, _)| {
                    let k = keyed.keys.get(&l.id)?;
                    Some((l.id.to_string(), (k.own.clone(), k.key.clone())))
                })
                .collect();
            let mut changes = incremental::changes(prev, &run_lots);
            let here: std::collections::BTreeSet<&str> =
                g.tiles.iter().map(|t| t.suffix.as_str()).collect();
            changes.tiles_removed = prev
                .tiles
                .keys()
                .filter(|s| !here.contains(s.as_str()))
                .cloned()
                .collect();
            keyed.changes = Some(changes);
            keyed.reused = plan_reuse(prev, &site, g, &selected, &keyed.keys, &targets, &dir);
        }
        run_key = Some(rk);
    }
    if opts.lod >= Lod::Lod3 {
        // Party walls: every building the run derives, and those that touch one, at LOD2
        // first (not those of tiles reused from --previous).
        let derived: Vec<bool> = match &grid {
            Some(g) if !keyed.reused.is_empty() => site
                .lots
                .iter()
                .zip(&selected)
                .map(|(l, s)| *s && !keyed.reused.contains_key(&g.suffix_of(site.crs, l)))
                .collect(),
            _ => selected,
        };
        let keep = if derived.iter().all(|k| *k) {
            derived
        } else {
            prepare::near_selected(&site.lots, &derived, incremental::NEIGHBOUR_MARGIN_M)
        };
        generator.surroundings = generator.neighbours_of(&site.lots, |i| keep[i]);
    }
    if let Some(b) = opts.bbox {
        if let Err(why) = prepare::retain_in_bbox(&mut site, b, &mut report) {
            if !opts.allow_empty {
                return Err(RunError::Input(format!(
                    "{why} (pass --allow-empty to write empty outputs)"
                )));
            }
        }
    }
    for lot in &site.lots {
        if let Some(note) = inferred_notes.remove(&lot.id) {
            report.add(Some(lot.id), Outcome::Note, note);
        }
    }
    let manifest = match (&grid, &targets.manifest) {
        (Some(g), Some(path)) => {
            let rk = match run_key {
                Some(rk) => rk,
                None => g.run_key(opts, &site, &generator.kb)?,
            };
            let mut head = g.manifest_head(rk, &shard, &site, &mut report)?;
            head.context = keyed.context.clone();
            let crs = site.crs;
            site.lots.retain(|l| g.is_mine(crs, l));
            Some((path.clone(), head))
        }
        _ => None,
    };
    keyed.previous = previous;
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
    let mut summary = write_batches(
        &site,
        &batches,
        &Maker::Generator(&generator),
        &FileSet {
            name: &source_name,
            targets: &targets,
        },
        report,
        Ledger {
            manifest,
            keys: keyed,
        },
        progress,
    )?;
    summary.elapsed = start.elapsed();
    Ok(summary)
}

/// What a tiled run records besides its files: its manifest (path and content so far), and
/// the keys.
#[derive(Default)]
pub(crate) struct Ledger {
    manifest: Option<(PathBuf, shard::Manifest)>,
    keys: Keyed,
}

/// The content keys of a tiled run's lots, and yesterday's run with what changed since
/// (`--previous`).
#[derive(Default)]
struct Keyed {
    /// The run's context key, hex.
    context: String,
    keys: std::collections::HashMap<crate::model::SourceId, shard::LotKey>,
    previous: Option<incremental::Previous>,
    changes: Option<crate::report::Changes>,
    /// The tiles reused from `previous`, by suffix: their records and files, copied and
    /// checked.
    reused: std::collections::BTreeMap<String, ReusedTile>,
}

/// A tile reused from `--previous`: its record and its files (closed temporaries, to be
/// renamed with the run's others; `None` for a file that is already in place).
type ReusedTile = (shard::TileRecord, Vec<(PathBuf, Option<PendingFile>)>);

/// The tiles of this shard that `prev` holds with the same lots, in the same order, with the
/// same keys, and the same files: each one's files copied beside their targets (checked
/// against the previous manifest's size and SHA-256; a tile whose file fails is left out, to
/// be derived). `dir` is the manifest's folder. Tiles are copied in parallel.
fn plan_reuse(
    prev: &incremental::Previous,
    site: &prepare::Site,
    grid: &GridPlan,
    selected: &[bool],
    keys: &std::collections::HashMap<SourceId, shard::LotKey>,
    targets: &Targets,
    dir: &Path,
) -> std::collections::BTreeMap<String, ReusedTile> {
    // Each tile's lots in file order: input order within a tile (prepare::group_into_tiles).
    let mut lots: std::collections::BTreeMap<String, Vec<shard::LotKey>> = Default::default();
    for (lot, _) in site.lots.iter().zip(selected).filter(|(_, s)| **s) {
        let Some(k) = keys.get(&lot.id) else { continue };
        lots.entry(grid.suffix_of(site.crs, lot))
            .or_default()
            .push(k.clone());
    }
    lots.into_par_iter()
        .filter_map(|(suffix, lots)| {
            let tile = tile_targets(targets, Some(&suffix));
            let found = reuse_tile(prev, dir, &suffix, &lots, &tile)?;
            Some((suffix, found))
        })
        .collect()
}

/// The targets of a shard (`--shard`) or of any tiled run: its manifest's path (in the folder
/// of the first output of `--report`, `--cityjsonseq`, `--cityjson`, `--gltf`, `--citygml`,
/// `--ifc`), and for a shard of several its report named `NAME_shard-I-of-N.json`. Also the
/// shard (shard 0 of 1 for an unsharded run).
fn shard_targets(
    opts: &Options,
    mut targets: Targets,
) -> Result<(Targets, (shard::Shard, String)), RunError> {
    let shard = opts
        .shard
        .clone()
        .unwrap_or((shard::Shard::ONE, "an unsharded tiled run".into()));
    if opts.tile.is_none() || (opts.dry_run && opts.shard.is_none()) {
        if opts.shard.is_some() {
            return Err(RunError::Usage(
                "--shard needs --tile METRES: shards share out the tiles of the run (e.g. --tile 500)"
                    .into(),
            ));
        }
        return Ok((targets, shard));
    }
    if opts.dry_run {
        return Err(RunError::Usage(
            "--shard with --dry-run: a shard's manifest lists the files it wrote, and a dry run \
             writes none"
                .into(),
        ));
    }
    let first = [
        &targets.report,
        &targets.cityjsonseq,
        &targets.cityjson,
        &targets.gltf,
        &targets.citygml,
        &targets.ifc,
    ]
    .into_iter()
    .find_map(|p| p.clone());
    let Some(first) = first else {
        if opts.shard.is_some() {
            return Err(RunError::Usage(
                "--shard writes its tiles and a manifest beside them: name at least one output"
                    .into(),
            ));
        }
        return Ok((targets, shard));
    };
    let dir = first
        .parent()
        .filter(|d| !d.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    targets.manifest = Some(dir.join(shard.0.manifest_name()));
    if shard.0.count > 1 {
        let sfx = format!("shard-{}-of-{}", shard.0.index, shard.0.count);
        targets.report = targets.report.map(|p| tile_path(&p, &sfx));
        // A shard may hold no tile, or only buildings that fail: the merge judges the whole.
        targets.allow_empty = true;
    }
    Ok((targets, shard))
}

/// The tile grid of a tiled run, and which shard writes each tile.
struct GridPlan {
    size: u32,
    shard: shard::Shard,
    /// Every tile holding a selected lot, in grid order.
    tiles: Vec<shard::GridTile>,
    /// The shard of each tile, by grid cell.
    of_cell: std::collections::BTreeMap<(i64, i64), usize>,
    /// Selected lots in all.
    lots: usize,
}

impl GridPlan {
    /// The grid over the `selected` lots of `site` (those `--bbox` keeps), `size`-metre tiles,
    /// assigned to `shard.count` shards by [`shard::assign`].
    fn new(site: &prepare::Site, size: u32, selected: &[bool], shard: shard::Shard) -> GridPlan {
        let mut counts: std::collections::BTreeMap<(i64, i64), usize> = Default::default();
        for (lot, _) in site.lots.iter().zip(selected).filter(|(_, s)| **s) {
            *counts
                .entry(prepare::tile_cell(site.crs, lot, size))
                .or_default() += 1;
        }
        let loads: Vec<usize> = counts.values().copied().collect();
        let assigned = shard::assign(&loads, shard.count);
        let size_m = i64::from(size.max(1));
        let tiles: Vec<shard::GridTile> = counts
            .iter()
            .zip(&assigned)
            .map(|((cell, lots), s)| {
                let corner = [cell.0 * size_m, cell.1 * size_m];
                shard::GridTile {
                    suffix: format!("{}_{}", corner[0], corner[1]),
                    corner,
                    lots: *lots,
                    shard: *s,
                }
            })
            .collect();
        let of_cell = counts.keys().copied().zip(assigned).collect();
        GridPlan {
            size,
            shard,
            tiles,
            of_cell,
            lots: loads.iter().sum(),
        }
    }

    /// The suffix of the lot's tile ([`shard::GridTile::suffix`]).
    fn suffix_of(&self, crs: Crs, lot: &prepare::Lot) -> String {
        let (x, y) = prepare::tile_cell(crs, lot, self.size);
        let s = i64::from(self.size.max(1));
        format!("{}_{}", x * s, y * s)
    }

    /// Whether the lot's tile is this shard's.
    fn is_mine(&self, crs: Crs, lot: &prepare::Lot) -> bool {
        self.of_cell.get(&prepare::tile_cell(crs, lot, self.size)) == Some(&self.shard.index)
    }

    /// What decides the run's outputs ([`shard::RunKey`]): the inputs' and KB's hashes, seed,
    /// LOD, CRS, origin, tile size, options and outputs.
    fn run_key(
        &self,
        opts: &Options,
        site: &prepare::Site,
        kb: &kb::KnowledgeBase,
    ) -> Result<shard::RunKey, RunError> {
        let key = |p: &Path| {
            shard::file_key(p).map_err(|e| RunError::Input(format!("{}: {e}", p.display())))
        };
        let mut inputs = match &opts.source {
            Source::Osm(p) => vec![key(p)?],
            Source::Shp { path, .. } => outputs::shapefile_parts(path)
                .iter()
                .filter(|p| p.exists())
                .map(|p| key(p))
                .collect::<Result<_, _>>()?,
        };
        if let Some(p) = &opts.osc {
            inputs.push(key(p)?);
        }
        let mut outputs: Vec<String> = [
            ("ifc", opts.ifc.is_some()),
            ("citygml", opts.citygml.is_some()),
            ("gltf", opts.gltf.is_some()),
            ("cityjson", opts.cityjson.is_some()),
            ("cityjsonseq", opts.cityjsonseq.is_some()),
        ]
        .into_iter()
        .filter(|(_, on)| *on)
        .map(|(k, _)| k.to_string())
        .collect();
        if opts.dry_run {
            outputs.push("dry-run".into());
        }
        // The files the KB's appearances name, keyed by the name the KB gives them.
        let mut kb_files = std::collections::BTreeMap::new();
        for (z, zone) in kb.zones().iter().enumerate() {
            for (a, app) in zone.appearances.iter().enumerate() {
                let named = [
                    (app.ruleset.as_deref(), kb.ruleset_path(z, a, false)),
                    (app.selex.as_deref(), kb.selex_path(z, a)),
                ];
                for (name, path) in named {
                    if let (Some(name), Ok(Some(path))) = (name, path) {
                        if path.is_file() && !kb_files.contains_key(name) {
                            let mut k = key(&path)?;
                            k.name = name.to_string();
                            kb_files.insert(name.to_string(), k);
                        }
                    }
                }
            }
        }
        Ok(shard::RunKey {
            inputs,
            kb: opts.kb.as_deref().map(key).transpose()?,
            kb_files: kb_files.into_values().collect(),
            rules: opts.rules.as_deref().map(key).transpose()?,
            seed: opts.seed,
            lod: opts.lod as u8,
            crs: site.crs.to_string(),
            origin: [site.origin.x, site.origin.y],
            tile_size: self.size,
            options: format!(
                "bbox={:?} crs={:?} src_crs={:?} max_depth={} max_shapes={} infer={:?}",
                opts.bbox,
                opts.crs.map(|c| c.to_string()),
                opts.src_crs.map(|c| c.to_string()),
                opts.caps.max_depth,
                opts.caps.max_shapes,
                opts.infer
            ),
            outputs,
        })
    }

    /// The manifest without its tiles: the run's key, the grid, and the shard's share of the
    /// report so far, which becomes `report` (the entries of the read and prepare stages that
    /// name one of this shard's lots, or for shard 0 no lot of the run).
    fn manifest_head(
        &self,
        run: shard::RunKey,
        shard: &(shard::Shard, String),
        site: &prepare::Site,
        report: &mut Report,
    ) -> Result<shard::Manifest, RunError> {
        let owner: std::collections::BTreeMap<String, usize> = site
            .lots
            .iter()
            .map(|l| {
                let cell = prepare::tile_cell(site.crs, l, self.size);
                (
                    l.id.to_string(),
                    self.of_cell.get(&cell).copied().unwrap_or(0),
                )
            })
            .collect();
        let mut prepared = Vec::new();
        let mut kept = Vec::new();
        for (i, e) in std::mem::take(&mut report.entries).into_iter().enumerate() {
            if shard::owner_of(&e, &owner) == shard.0.index {
                prepared.push((i, e.clone()));
                kept.push(e);
            }
        }
        report.entries = kept;
        Ok(shard::Manifest {
            format: shard::MANIFEST_FORMAT.into(),
            citygen: env!("CARGO_PKG_VERSION").into(),
            shard: shard.0,
            shard_from: shard.1.clone(),
            run,
            grid: shard::Grid {
                lots: self.lots,
                tiles: self.tiles.clone(),
            },
            tiles: Vec::new(),
            report: shard::ShardReport {
                read: report.read,
                parts_read: report.parts_read,
                prepared,
                ..Default::default()
            },
            context: String::new(),
            changes: None,
        })
    }
}

/// The output CRS for a run without `--crs` ([`prepare::choose_output_crs`]), or an error when
/// no one zone fits the data: a building that the zone would stretch by more than
/// [`prepare::MAX_SCALE_ERROR`] is far from the zone's centre (two cities in one file, a
/// country), and would be written with wrong lengths.
fn zone_for(
    footprints: &[input::Footprint],
    source_crs: Option<Crs>,
    bbox: Option<[f64; 4]>,
    source_name: &str,
) -> Result<Crs, RunError> {
    let choice = prepare::choose_output_crs(footprints, source_crs, bbox);
    match choice.worst {
        Some((error, id, (lon, lat))) if error > prepare::MAX_SCALE_ERROR => {
            let (west, east) = choice.west_east;
            let zone = |lon: f64| match Crs::utm_for(lon, 0.0) {
                Crs::Utm { zone, .. } => zone,
                _ => 0,
            };
            Err(RunError::Input(format!(
                "{source_name}: the buildings span longitude {west:.4} to {east:.4} (UTM zones {} to {}), too wide for one projection: in {} (EPSG:{}), the zone of their centre, {id} at {lon:.5}, {lat:.5} would be stretched by {:.2} % (at most {:.2} % is allowed). Run each area on its own (--bbox W,S,E,N), or pass --crs EPSG:code to accept the error",
                zone(west),
                zone(east),
                choice.crs.name(),
                choice.crs.epsg(),
                100.0 * error,
                100.0 * prepare::MAX_SCALE_ERROR,
            )))
        }
        _ => Ok(choice.crs),
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
        } => {
            let o = ShpOptions {
                height_field: height_field.clone(),
                levels_field: levels_field.clone(),
                src_crs,
            };
            input::shp::read_shp(path, &o, report)
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
pub struct Targets {
    /// Write IFC4 (STEP) here.
    pub ifc: Option<PathBuf>,
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
    /// Publish the outputs even when no building was generated ([`Options::allow_empty`]).
    pub allow_empty: bool,
    /// Write a shard manifest here ([`shard::Manifest`]): every output is hashed as written.
    pub manifest: Option<PathBuf>,
}

impl Targets {
    /// The paths asked for, each with the flag that names it (for [`outputs::check`]); for
    /// `--tiles3d`, its `tileset.json`.
    pub(crate) fn flagged(&self) -> Vec<(&'static str, PathBuf)> {
        [
            ("--ifc", &self.ifc),
            ("--citygml", &self.citygml),
            ("--gltf", &self.gltf),
            ("--cityjson", &self.cityjson),
            ("--cityjsonseq", &self.cityjsonseq),
            ("--report", &self.report),
            ("--preview", &self.preview),
        ]
        .into_iter()
        .filter_map(|(flag, p)| p.clone().map(|p| (flag, p)))
        .chain(
            self.tiles3d
                .as_ref()
                .map(|d| ("--tiles3d", d.join("tileset.json"))),
        )
        .collect()
    }
}

/// Derives every lot of the site (in parallel, chunk by chunk) and writes the buildings in lot
/// order to every target, atomically. `report` already holds what reading and preparing said.
pub fn generate_and_write(
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
            targets,
        },
        report,
        Ledger::default(),
        progress,
    )
}

/// What makes each lot's building for [`write_batches`]: the generator, or (`selex derive`)
/// a function, with the LOD and seed the outputs name.
pub(crate) enum Maker<'a> {
    Generator(&'a Generator),
    Made {
        lod: Lod,
        seed: u64,
        #[allow(clippy::type_complexity)]
        make: &'a (dyn Fn(&prepare::Lot) -> Result<(Building, Vec<crate::derive::Note>), String>
                 + Sync),
    },
}

impl Maker<'_> {
    fn lod(&self) -> Lod {
        match self {
            Maker::Generator(g) => g.lod,
            Maker::Made { lod, .. } => *lod,
        }
    }

    fn seed(&self) -> u64 {
        match self {
            Maker::Generator(g) => g.seed,
            Maker::Made { seed, .. } => *seed,
        }
    }

    fn make(&self, lot: &prepare::Lot) -> Result<(Building, Vec<crate::derive::Note>), String> {
        match self {
            Maker::Generator(g) => g.generate(lot),
            Maker::Made { make, .. } => make(lot),
        }
    }
}

/// A run of consecutive lots written to one set of files: the whole site, or one tile.
pub(crate) struct Batch {
    /// Inserted before the extension of every output path (`None`: the paths as given).
    pub(crate) suffix: Option<String>,
    pub(crate) range: std::ops::Range<usize>,
    /// The tile's grid cell (its corner over the tile size; `(0, 0)` untiled), for 3D Tiles.
    pub(crate) cell: (i64, i64),
}

/// Writes each batch to its own files. Every file is complete and closed before any is renamed
/// over its target, so a run that fails (or is killed) part-way publishes nothing.
pub(crate) fn write_batches(
    site: &prepare::Site,
    batches: &[Batch],
    maker: &Maker<'_>,
    files: &FileSet<'_>,
    mut report: Report,
    ledger: Ledger,
    progress: Progress<'_>,
) -> Result<Summary, RunError> {
    let Ledger {
        mut manifest,
        keys: mut keyed,
    } = ledger;
    let (source_name, targets) = (files.name, files.targets);
    let start = Instant::now();
    let total = site.lots.len();
    let mut changes = keyed.changes.clone();
    let mut done = 0usize;
    let mut written = Written {
        preview: targets
            .preview
            .as_ref()
            .map(|_| crate::export::preview::Scene::new()),
        ..Default::default()
    };
    for batch in batches {
        let tile_targets = tile_targets(targets, batch.suffix.as_deref());
        let name = match &batch.suffix {
            Some(sfx) => format!("{source_name} tile {sfx}"),
            None => source_name.to_string(),
        };
        let lots = &site.lots[batch.range.clone()];
        let mark = report.entries.len();
        written.cell = batch.cell;
        written.content_name = batch.suffix.clone().unwrap_or_else(|| "all".into());
        let lot_keys: Vec<shard::LotKey> = lots
            .iter()
            .filter_map(|l| keyed.keys.get(&l.id).cloned())
            .collect();
        written.tile = manifest.as_ref().map(|(path, _)| TileLog {
            record: shard::TileRecord {
                suffix: batch.suffix.clone().unwrap_or_default(),
                lots: lot_keys,
                ..Default::default()
            },
            dir: path
                .parent()
                .filter(|d| !d.as_os_str().is_empty())
                .unwrap_or(Path::new("."))
                .to_path_buf(),
        });
        let reused = batch
            .suffix
            .as_ref()
            .and_then(|sfx| keyed.reused.remove(sfx));
        if let Some((record, files)) = reused {
            let Some(log) = written.tile.take() else {
                return Err(RunError::Input("a reused tile without a manifest".into()));
            };
            let Some((_, m)) = manifest.as_mut() else {
                return Err(RunError::Input("a reused tile without a manifest".into()));
            };
            report.entries.extend(record.entries.iter().cloned());
            report.generated += record.buildings.len();
            report.facades.add(&record.facades);
            written.polygons += record.polygons;
            written.bytes += record.files.iter().map(|f| f.bytes).sum::<u64>();
            if let Some(p) = &tile_targets.citygml {
                written.count_citygml(p, record.citygml_elements);
            }
            if let (Some(dir), Some(v)) = (&targets.tiles3d, &record.tiles3d) {
                written.tiles3d.push(rebased_entry(v, &log.dir, dir)?);
            }
            for (path, file) in files {
                match file {
                    Some(f) => written.pending.push((path, f)),
                    None => written.rendered.push(path),
                }
            }
            m.tiles.push(shard::TileRecord {
                lots: log.record.lots,
                ..record
            });
            if let Some(c) = changes.as_mut() {
                c.tiles_reused += 1;
            }
            done += lots.len();
            progress(done, total);
            continue;
        }
        if let (Some(c), Some(sfx)) = (changes.as_mut(), &batch.suffix) {
            c.tiles_rewritten.push(sfx.clone());
        }
        write_lots(
            site,
            lots,
            maker,
            &FileSet {
                name: &name,
                targets: &tile_targets,
            },
            &mut report,
            &mut written,
            &|n| progress(done + n, total),
        )?;
        if let (Some((_, m)), Some(mut log)) = (manifest.as_mut(), written.tile.take()) {
            log.record.entries = report.entries[mark..].to_vec();
            m.tiles.push(log.record);
        }
        done += lots.len();
    }
    report.skipped = report
        .entries
        .iter()
        .filter(|e| e.outcome == Outcome::Skipped)
        .count();
    report.repaired = report
        .entries
        .iter()
        .filter(|e| e.outcome == Outcome::Repaired)
        .count();
    if let Some((_, m)) = manifest.as_mut() {
        m.changes = changes.clone();
    }
    report.changes = changes;
    let Written {
        pending,
        rendered: mut paths,
        polygons,
        bytes,
        largest_citygml,
        citygml_over_cap,
        tile: _,
        preview,
        tiles3d,
        cell: _,
        content_name: _,
    } = written;
    if report.generated == 0 && !targets.allow_empty {
        let shown: Vec<String> = report
            .entries
            .iter()
            .filter(|e| e.outcome == Outcome::Skipped)
            .take(3)
            .map(|e| format!("{}: {}", e.id, e.reason))
            .collect();
        let why = if shown.is_empty() {
            "the input holds no building".to_string()
        } else {
            format!("every building was skipped, e.g. {}", shown.join("; "))
        };
        return Err(RunError::Input(format!(
            "{source_name}: generated 0 of {total} buildings: {why}. Nothing was written; pass \
             --allow-empty to write empty outputs"
        )));
    }
    let tiled = batches.iter().any(|b| b.suffix.is_some());
    let mut warnings = Vec::new();
    if let Some((path, n)) = largest_citygml.filter(|(_, n)| *n > VALIDATOR_MAX_ELEMENTS) {
        warnings.push(if tiled {
            format!(
                "{citygml_over_cap} of {} CityGML tiles have more than {VALIDATOR_MAX_ELEMENTS} XML elements, the most the reference schema validator reads (the largest: {}, {n}); a smaller --tile keeps every tile under it",
                batches.len(),
                path.display()
            )
        } else {
            format!(
                "{} has {n} XML elements, more than the {VALIDATOR_MAX_ELEMENTS} the reference schema validator reads; --tile METRES splits the outputs into tiles (250 m tiles of a dense centre hold under 300,000 at LOD3)",
                path.display()
            )
        });
    }
    for w in &warnings {
        report.add(None, Outcome::Note, w.clone());
    }
    let several = manifest.as_ref().is_some_and(|(_, m)| m.shard.count > 1);
    let manifest_file = match &mut manifest {
        Some((path, m)) => {
            m.report.generated = report.generated;
            m.report.facades = report.facades.clone();
            // Paths relative to the manifest, so that a shard run again elsewhere, or on
            // another machine's mount, writes the same manifest.
            let dir = path
                .parent()
                .filter(|d| !d.as_os_str().is_empty())
                .map(|d| format!("{}{}", d.display(), std::path::MAIN_SEPARATOR));
            m.report.notes = warnings
                .iter()
                .map(|w| crate::report::Entry {
                    id: String::new(),
                    outcome: Outcome::Note,
                    reason: match &dir {
                        Some(d) => w.replace(d.as_str(), ""),
                        None => w.clone(),
                    },
                })
                .collect();
            Some((&*path, render_json(path, m).map_err(io_err(path))?))
        }
        None => None,
    };
    // Every file, the report too, is complete and closed before the first is renamed into
    // place, so a failure up to here leaves every target as it was.
    let preview_file = match (&targets.preview, preview) {
        (Some(p), Some(scene)) => {
            let png = scene
                .render(&crate::export::preview::View::default())
                .to_png();
            Some((p, render_bytes(p, &png).map_err(io_err(p))?))
        }
        _ => None,
    };
    let tileset_file = match &targets.tiles3d {
        Some(dir) if !several && !targets.dry_run => {
            let p = dir.join("tileset.json");
            let text = crate::export::tiles3d::tileset_json(&tiles3d).map_err(out_err(&p))?;
            Some((
                p.clone(),
                render_bytes(&p, text.as_bytes()).map_err(io_err(&p))?,
            ))
        }
        _ => None,
    };
    let report_file = match &targets.report {
        Some(p) => Some((p, render_report(p, &report).map_err(io_err(p))?)),
        None => None,
    };
    for (path, file) in pending {
        file.commit().map_err(io_err(&path))?;
        paths.push(path);
    }
    if let Some((p, file)) = tileset_file {
        file.commit().map_err(io_err(&p))?;
        paths.push(p);
    }
    if let Some((p, file)) = preview_file {
        file.commit().map_err(io_err(p))?;
        paths.push(p.clone());
    }
    if let Some((p, file)) = report_file {
        file.commit().map_err(io_err(p))?;
    }
    // Last: a manifest on disk says that every file it lists is in place.
    if let Some((p, file)) = manifest_file {
        file.commit().map_err(io_err(p))?;
    }
    Ok(Summary {
        report,
        polygons,
        elapsed: start.elapsed(),
        outputs: paths,
        bytes,
        tiles: if tiled { batches.len() } else { 0 },
        warnings,
    })
}

/// Where one writer's bytes go: a temporary file to publish, or (dry run) nowhere.
enum Sink {
    File(AtomicFile, StreamSink),
    Discard,
}

/// Counts the bytes that pass through it (below the writer's buffer, so once per flush), and
/// for XML the elements (`elements`, with the state of a `<` at the end of the last write).
struct Counted<W> {
    inner: W,
    bytes: Arc<AtomicU64>,
    elements: Option<(Arc<AtomicU64>, bool)>,
    hash: Option<SharedHash>,
}

impl<W: Write> Write for Counted<W> {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        let n = self.inner.write(buf)?;
        self.bytes.fetch_add(n as u64, Ordering::Relaxed);
        if let Some(h) = &self.hash {
            h.lock()
                .unwrap_or_else(|p| p.into_inner())
                .update(&buf[..n]);
        }
        if let Some((count, after_lt)) = &mut self.elements {
            let e = crate::export::citygml::count_elements(&buf[..n], after_lt);
            count.fetch_add(e, Ordering::Relaxed);
        }
        Ok(n)
    }

    fn flush(&mut self) -> std::io::Result<()> {
        self.inner.flush()
    }
}

/// A buffered, counted writer for `path`: on its temporary file, or on nothing for a dry run.
type OutWriter = BufWriter<Counted<Box<dyn Write + Send>>>;

/// `elements`: also count the XML elements written, into it.
fn open_output(
    path: &Path,
    dry_run: bool,
    elements: Option<Arc<AtomicU64>>,
    hashed: bool,
) -> Result<(OutWriter, Sink, Arc<AtomicU64>, Option<SharedHash>), RunError> {
    let (inner, sink): (Box<dyn Write + Send>, Sink) = if dry_run {
        (Box::new(std::io::sink()), Sink::Discard)
    } else {
        let f = AtomicFile::create(path).map_err(io_err(path))?;
        let (w, done) = f.stream().map_err(io_err(path))?;
        (w, Sink::File(f, done))
    };
    let bytes = Arc::new(AtomicU64::new(0));
    // No buffer to copy the bytes into where the sink buffers them itself (Linux's stream of a
    // written file: aligned blocks), or where a dry run's CityGML writer hands over whole
    // buildings, which only need counting. The writers hand over whole buildings or batches.
    let sink_buffers = !dry_run && cfg!(target_os = "linux");
    let capacity = if sink_buffers || (dry_run && elements.is_some()) {
        0
    } else {
        1 << 20
    };
    let hash = hashed.then(|| Arc::new(Mutex::new(Sha256::new())));
    let w = BufWriter::with_capacity(
        capacity,
        Counted {
            inner,
            bytes: Arc::clone(&bytes),
            elements: elements.map(|e| (e, false)),
            hash: hash.clone(),
        },
    );
    Ok((w, sink, bytes, hash))
}

/// One set of files of a run (the whole site, or one tile): the name the files give as their
/// source, and their paths.
pub(crate) struct FileSet<'a> {
    pub(crate) name: &'a str,
    pub(crate) targets: &'a Targets,
}

/// What the batches of a run have written so far.
#[derive(Default)]
struct Written {
    /// Complete and closed files, ready to be renamed over their targets.
    pending: Vec<(PathBuf, PendingFile)>,
    /// The targets of a dry run, rendered and dropped.
    rendered: Vec<PathBuf>,
    polygons: usize,
    bytes: u64,
    /// The CityGML file with the most elements so far, and their count.
    largest_citygml: Option<(PathBuf, u64)>,
    /// CityGML files with more than [`VALIDATOR_MAX_ELEMENTS`] elements.
    citygml_over_cap: usize,
    /// What the tile being written records for the manifest (a tiled run).
    tile: Option<TileLog>,
    /// The run's overview picture so far (`--preview`): every tile's buildings.
    preview: Option<crate::export::preview::Scene>,
    /// The 3D Tiles contents written so far, URIs relative to the `--tiles3d` folder.
    tiles3d: Vec<crate::export::tiles3d::TileEntry>,
    /// The cell of the tile being written.
    cell: (i64, i64),
    /// The name of its 3D Tiles contents: the tile's suffix, `all` untiled.
    content_name: String,
}

impl Written {
    /// Counts a CityGML file of `n` XML elements, for the warning of files over the
    /// validator's cap.
    fn count_citygml(&mut self, p: &Path, n: u64) {
        if self.largest_citygml.as_ref().is_none_or(|(_, m)| n > *m) {
            self.largest_citygml = Some((p.to_path_buf(), n));
        }
        if n > VALIDATOR_MAX_ELEMENTS {
            self.citygml_over_cap += 1;
        }
    }
}

/// Derives `lots` (in parallel, chunk by chunk) and writes them in order to the file set,
/// whose files are left closed in `written.pending`, ready to be renamed (for a dry run, their
/// paths go to `written.rendered`); adds the polygons and the bytes written.
fn write_lots(
    site: &prepare::Site,
    lots: &[prepare::Lot],
    maker: &Maker<'_>,
    files: &FileSet<'_>,
    report: &mut Report,
    written: &mut Written,
    progress: &(dyn Fn(usize) + Sync),
) -> Result<(), RunError> {
    let (source_name, targets) = (files.name, files.targets);
    let hashed = written.tile.is_some();
    let ctx = OutputContext {
        crs: site.crs,
        origin: DVec3::new(site.origin.x, site.origin.y, 0.0),
        origin_lonlat: site.origin_lonlat,
        lod: maker.lod(),
        source_name: source_name.to_string(),
        seed: maker.seed(),
    };

    // Open every output before the work, so a bad path fails fast.
    let dry = targets.dry_run;
    let mut outputs: Vec<Output> = Vec::new();
    if let Some(p) = &targets.ifc {
        let (w, sink, bytes, hash) = open_output(p, dry, None, hashed)?;
        let w = IfcWriter::new(w).with_file_name(&file_name(p));
        outputs.push((p.clone(), Box::new(w), sink, bytes, hash));
    }
    let citygml_elements = Arc::new(AtomicU64::new(0));
    if let Some(p) = &targets.citygml {
        let (w, sink, bytes, hash) =
            open_output(p, dry, Some(Arc::clone(&citygml_elements)), hashed)?;
        outputs.push((
            p.clone(),
            Box::new(CityGmlWriter::new(w)),
            sink,
            bytes,
            hash,
        ));
    }
    if let Some(p) = &targets.gltf {
        let (w, sink, bytes, hash) = open_output(p, dry, None, hashed)?;
        // A dry run keeps nothing, so its writer needs no scratch files.
        let w = if dry {
            GltfWriter::discarding(w)
        } else {
            GltfWriter::beside(w, p).map_err(io_err(p))?
        };
        outputs.push((p.clone(), Box::new(w), sink, bytes, hash));
    }
    if let Some(p) = &targets.cityjson {
        let (w, sink, bytes, hash) = open_output(p, dry, None, hashed)?;
        let w = CityJsonWriter::beside(w, p).map_err(io_err(p))?;
        outputs.push((p.clone(), Box::new(w), sink, bytes, hash));
    }
    if let Some(p) = &targets.cityjsonseq {
        let (w, sink, bytes, hash) = open_output(p, dry, None, hashed)?;
        outputs.push((
            p.clone(),
            Box::new(CityJsonSeqWriter::new(w)),
            sink,
            bytes,
            hash,
        ));
    }
    let mut contents = Vec::new();
    if let Some(dir) = &targets.tiles3d {
        use crate::export::tiles3d::{Detail, Tiles3dWriter};
        let name = written.content_name.clone();
        for (detail, sfx) in [(Detail::Full, ""), (Detail::Blocks, "-blocks")] {
            let p = dir.join("content").join(format!("{name}{sfx}.glb"));
            let (w, sink, bytes, hash) = open_output(&p, dry, None, hashed)?;
            let (w, info) = Tiles3dWriter::new(w, detail);
            contents.push((p.clone(), info));
            outputs.push((p, Box::new(w), sink, bytes, hash));
        }
    }
    for (path, w, ..) in &mut outputs {
        w.begin(&ctx).map_err(out_err(path))?;
    }

    let mut polygons = 0usize;
    // Deriving chunk k + 1 overlaps writing chunk k, and each writer writes a chunk in its own
    // task, so every core stays busy although each writer is sequential. Each writer still gets
    // every building in lot order; at most two chunks of buildings are held.
    let mut ready: Vec<Building> = Vec::new();
    let mut preview = written.preview.take();
    let detail = maker.lod() >= Lod::Lod3;
    let mut write_ready = |outputs: &mut [Output], ready: &[Building]| {
        let wrote = write_chunk(outputs, ready);
        if let Some(scene) = preview.as_mut() {
            for b in ready {
                // A building the writers refuse (not finite) is left out of the picture too.
                let _ = scene.add_building(b, detail);
            }
        }
        wrote
    };
    for (ci, chunk) in lots.chunks(CHUNK).enumerate() {
        let (results, chunk_written) = rayon::join(
            || {
                chunk
                    .par_iter()
                    .map(|lot| {
                        maker.make(lot).map(|(b, notes)| {
                            let digest = hashed.then(|| b.digest());
                            (b, notes, digest)
                        })
                    })
                    .collect::<Vec<_>>()
            },
            || write_ready(&mut outputs, &ready),
        );
        chunk_written?;
        ready.clear();
        for (lot, result) in chunk.iter().zip(results) {
            match result {
                Ok((building, notes, digest)) => {
                    for (outcome, text) in notes {
                        report.add(Some(lot.id), outcome, text);
                    }
                    if let (Some(log), Some(d)) = (written.tile.as_mut(), digest) {
                        log.record.buildings.push(shard::BuildingRecord {
                            id: building.id.to_string(),
                            digest: format!("{d:016x}"),
                        });
                    }
                    polygons += building.polygon_count();
                    report.facades.add(&building.facade);
                    if let Some(log) = written.tile.as_mut() {
                        log.record.facades.add(&building.facade);
                        log.record.polygons += building.polygon_count();
                    }
                    report.generated += 1;
                    ready.push(building);
                }
                Err(reason) => {
                    if let Some(log) = written.tile.as_mut() {
                        log.record.skipped.push(lot.id.to_string());
                    }
                    report.add(Some(lot.id), Outcome::Skipped, reason)
                }
            }
        }
        progress(((ci + 1) * CHUNK).min(lots.len()));
    }
    write_ready(&mut outputs, &ready)?;
    written.preview = preview;
    for (path, w, ..) in &mut outputs {
        w.finish().map_err(out_err(path))?;
    }
    if let (Some(dir), [(full, full_info), (blocks, blocks_info)]) =
        (&targets.tiles3d, contents.as_slice())
    {
        let content = |p: &Path, info: &crate::export::tiles3d::ContentInfoHandle| {
            info.get()
                .map(|info| crate::export::tiles3d::TileContent {
                    uri: relative_to(p, dir),
                    info,
                })
                .ok_or_else(|| out_err(p)(ExportError::Invalid("no content facts".into())))
        };
        let entry = crate::export::tiles3d::TileEntry {
            cell: written.cell,
            full: content(full, full_info)?,
            blocks: content(blocks, blocks_info)?,
        };
        if let Some(log) = written.tile.as_mut() {
            // In the manifest, URIs relative to the manifest's folder.
            let mut rebased = entry.clone();
            rebased.full.uri = relative_to(full, &log.dir);
            rebased.blocks.uri = relative_to(blocks, &log.dir);
            log.record.tiles3d = serde_json::to_value(&rebased).ok();
        }
        written.tiles3d.push(entry);
    }
    written.polygons += polygons;
    if let Some(p) = &targets.citygml {
        let n = citygml_elements.load(Ordering::Relaxed);
        written.count_citygml(p, n);
        if let Some(log) = written.tile.as_mut() {
            log.record.citygml_elements = n;
        }
    }
    for (path, writer, sink, counted, hash) in outputs {
        drop(writer);
        let bytes = counted.load(Ordering::Relaxed);
        written.bytes += bytes;
        if let (Some(log), Some(hash)) = (written.tile.as_mut(), hash) {
            let sha = match Arc::try_unwrap(hash) {
                Ok(m) => m.into_inner().unwrap_or_else(|p| p.into_inner()).finalize(),
                Err(shared) => shared
                    .lock()
                    .unwrap_or_else(|p| p.into_inner())
                    .clone()
                    .finalize(),
            };
            log.record.files.push(shard::FileRecord {
                path: relative_to(&path, &log.dir),
                bytes,
                sha256: shard::hex(&sha),
            });
        }
        match sink {
            Sink::File(file, done) => {
                done.finish().map_err(io_err(&path))?;
                let closed = file.close().map_err(io_err(&path))?;
                written.pending.push((path, closed));
            }
            Sink::Discard => written.rendered.push(path),
        }
    }
    Ok(())
}

/// The targets of one tile (`suffix`; `None` untiled: the run's own paths): every model
/// output's path with the suffix inserted, the 3D Tiles folder as it is, no report.
fn tile_targets(targets: &Targets, suffix: Option<&str>) -> Targets {
    let path = |p: &Option<PathBuf>| match (suffix, p) {
        (Some(sfx), Some(p)) => Some(tile_path(p, sfx)),
        (_, p) => p.clone(),
    };
    Targets {
        ifc: path(&targets.ifc),
        citygml: path(&targets.citygml),
        gltf: path(&targets.gltf),
        cityjson: path(&targets.cityjson),
        cityjsonseq: path(&targets.cityjsonseq),
        report: None,
        preview: None,
        tiles3d: targets.tiles3d.clone(),
        dry_run: targets.dry_run,
        allow_empty: targets.allow_empty,
        manifest: None,
    }
}

/// The files a tile writes: its model outputs and its 3D Tiles contents.
fn tile_files(targets: &Targets, content_name: &str) -> Vec<PathBuf> {
    let mut out: Vec<PathBuf> = [
        &targets.ifc,
        &targets.citygml,
        &targets.gltf,
        &targets.cityjson,
        &targets.cityjsonseq,
    ]
    .into_iter()
    .flatten()
    .cloned()
    .collect();
    if let Some(dir) = &targets.tiles3d {
        for sfx in ["", "-blocks"] {
            out.push(dir.join("content").join(format!("{content_name}{sfx}.glb")));
        }
    }
    out
}

/// The previous run's record of tile `suffix`, and its files copied (checked) to this run's
/// `targets` for the tile, when the tile's lots and keys are `lots` (in order) and its files
/// are those this tile writes ([`incremental::Previous::reusable`]); `None` to derive the tile
/// (also when a previous file is not what its manifest lists). `dir` is this run's manifest's
/// folder.
fn reuse_tile(
    prev: &incremental::Previous,
    dir: &Path,
    suffix: &str,
    lots: &[shard::LotKey],
    targets: &Targets,
) -> Option<ReusedTile> {
    if targets.dry_run {
        return None;
    }
    let paths = tile_files(targets, suffix);
    let rel: std::collections::BTreeMap<String, PathBuf> = paths
        .iter()
        .map(|p| (relative_to(p, dir), p.clone()))
        .collect();
    let names = rel.keys().cloned().collect();
    let (folder, record) = prev.reusable(suffix, lots, &names)?;
    let mut files = Vec::with_capacity(record.files.len());
    for f in &record.files {
        let dst = rel.get(&f.path)?;
        let src = folder.join(&f.path);
        // On a mismatch the temporaries made so far are dropped (removed).
        let p = incremental::copy_checked(&src, dst, f.bytes, &f.sha256, prev.link).ok()?;
        files.push((dst.clone(), p));
    }
    // Its paths (the 3D Tiles URIs too) are relative to the manifest's folder, and the same
    // here: the files land at the same places relative to this run's manifest.
    Some((record.clone(), files))
}

/// Rebases the `uri`s of a manifest's 3D Tiles facts (`full`, `blocks`) from folder `from` to
/// folder `to`.
fn rebase_uris(v: &mut serde_json::Value, from: &Path, to: &Path) {
    for part in ["full", "blocks"] {
        if let Some(serde_json::Value::String(u)) = v.get_mut(part).and_then(|c| c.get_mut("uri")) {
            *u = relative_to(&from.join(&*u), to);
        }
    }
}

/// A manifest's 3D Tiles facts (URIs relative to `manifest_dir`) as a tileset entry with URIs
/// relative to the `--tiles3d` folder.
fn rebased_entry(
    v: &serde_json::Value,
    manifest_dir: &Path,
    tiles3d: &Path,
) -> Result<crate::export::tiles3d::TileEntry, RunError> {
    let mut v = v.clone();
    rebase_uris(&mut v, manifest_dir, tiles3d);
    serde_json::from_value(v)
        .map_err(|e| RunError::Input(format!("a previous manifest's 3D Tiles facts: {e}")))
}

/// An open output: target path, format writer, where its bytes go, and their count.
type Output = (
    PathBuf,
    Box<dyn BuildingWriter>,
    Sink,
    Arc<AtomicU64>,
    Option<SharedHash>,
);

/// The SHA-256 of an output's bytes, fed as they pass [`Counted`].
type SharedHash = Arc<Mutex<Sha256>>;

/// What one tile of a manifest'd run records as it is written, and the manifest's folder (the
/// files' paths are relative to it).
struct TileLog {
    record: shard::TileRecord,
    dir: PathBuf,
}

/// `path` relative to `dir` with `/` separators where it lies below it, else as given.
fn relative_to(path: &Path, dir: &Path) -> String {
    let rel = path.strip_prefix(dir).unwrap_or(path);
    rel.components()
        .map(|c| c.as_os_str().to_string_lossy().into_owned())
        .collect::<Vec<_>>()
        .join("/")
}

/// Writes `buildings` in order with every writer, the writers in parallel; the first error in
/// writer order wins, so the error reported does not depend on scheduling.
fn write_chunk(outputs: &mut [Output], buildings: &[Building]) -> Result<(), RunError> {
    if buildings.is_empty() {
        return Ok(());
    }
    // A panic in a writer (a bug) ends the run with an error naming the file and the buildings
    // being written, not with a crash; no output is published, as for any failed run.
    // Checked once for every writer.
    let checked = Checked::check(buildings);
    let results: Vec<Result<(), RunError>> = outputs
        .par_iter_mut()
        .map(|(path, w, ..)| {
            let what = || {
                let (first, last) = (&buildings[0].id, &buildings[buildings.len() - 1].id);
                format!("writing the buildings from {first} to {last}")
            };
            match crate::guard::caught(what, || w.write_checked(&checked)) {
                Ok(written) => written.map_err(out_err(path)),
                Err(e) => Err(out_err(path)(ExportError::Invalid(e.to_string()))),
            }
        })
        .collect();
    results.into_iter().collect()
}

/// `dir/NAME.EXT` with `_SUFFIX` inserted before the extension: `dir/NAME_SUFFIX.EXT`; the
/// CityJSON names keep their double extension (`NAME.city.json` gives `NAME_SUFFIX.city.json`).
fn tile_path(p: &Path, suffix: &str) -> PathBuf {
    let mut stem = p
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    let name = match p.extension() {
        Some(ext) => {
            let mut ext = ext.to_string_lossy().into_owned();
            let json = matches!(ext.to_ascii_lowercase().as_str(), "json" | "jsonl");
            let cut = stem.len().saturating_sub(5);
            if json
                && cut > 0
                && stem.is_char_boundary(cut)
                && stem[cut..].eq_ignore_ascii_case(".city")
            {
                ext = format!("{}.{ext}", &stem[cut + 1..]);
                stem.truncate(cut);
            }
            format!("{stem}_{suffix}.{ext}")
        }
        None => format!("{stem}_{suffix}"),
    };
    p.with_file_name(name)
}

/// The report as JSON in a closed temporary file beside `path`, ready to be renamed over it.
fn render_report(path: &Path, report: &Report) -> std::io::Result<PendingFile> {
    render_json(path, report)
}

/// `bytes` in a closed temporary file beside `path`, ready to be renamed over it.
pub(crate) fn render_bytes(path: &Path, bytes: &[u8]) -> std::io::Result<PendingFile> {
    let f = AtomicFile::create(path)?;
    let mut w = f.writer()?;
    w.write_all(bytes)?;
    w.flush()?;
    drop(w);
    f.close()
}

/// `value` as pretty JSON in a closed temporary file beside `path`, ready to be renamed over it.
pub(crate) fn render_json(
    path: &Path,
    value: &impl serde::Serialize,
) -> std::io::Result<PendingFile> {
    let f = AtomicFile::create(path)?;
    let mut w = f.writer()?;
    serde_json::to_writer_pretty(&mut w, value).map_err(std::io::Error::other)?;
    std::io::Write::write_all(&mut w, b"\n")?;
    std::io::Write::flush(&mut w)?;
    drop(w);
    f.close()
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

pub(crate) fn file_name(p: &Path) -> String {
    p.file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::export::fixtures::lod4_house;

    /// Panics on its second building.
    struct Faulty(usize);

    impl BuildingWriter for Faulty {
        fn begin(&mut self, _: &OutputContext) -> Result<(), ExportError> {
            Ok(())
        }
        fn write(&mut self, _: &Building) -> Result<(), ExportError> {
            self.0 += 1;
            assert!(self.0 < 2, "index out of range in a writer");
            Ok(())
        }
        fn finish(&mut self) -> Result<(), ExportError> {
            Ok(())
        }
    }

    #[test]
    fn tile_paths_insert_the_suffix_before_the_extension() {
        let t = |p: &str| tile_path(Path::new(p), "100_200").display().to_string();
        assert_eq!(t("out/m.gml"), "out/m_100_200.gml");
        assert_eq!(t("out/m.city.json"), "out/m_100_200.city.json");
        assert_eq!(t("out/m.City.jsonl"), "out/m_100_200.City.jsonl");
        assert_eq!(t("out/m.city.gml"), "out/m.city_100_200.gml");
        assert_eq!(t("out/.city.json"), "out/.city_100_200.json");
        assert_eq!(t("out/m"), "out/m_100_200");
    }

    #[test]
    fn a_panicking_writer_is_an_error_naming_the_file_and_the_buildings() {
        let path = PathBuf::from("out/city.ifc");
        let mut outputs: Vec<Output> = vec![(
            path,
            Box::new(Faulty(0)),
            Sink::Discard,
            Arc::new(AtomicU64::new(0)),
            None,
        )];
        let buildings = vec![lod4_house(), lod4_house()];
        let e = write_chunk(&mut outputs, &buildings)
            .unwrap_err()
            .to_string();
        assert!(
            e.starts_with("out/city.ifc: internal error while writing"),
            "{e}"
        );
        assert!(e.contains("index out of range in a writer"), "{e}");
        assert!(e.contains(&buildings[0].id.to_string()), "{e}");
    }
}
