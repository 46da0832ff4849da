//! Deriving and writing: [`write_batches`] derives the lots of each batch (the whole site, or
//! one tile) chunk by chunk in parallel and writes them in order to the batch's files
//! ([`write_lots`]), takes the tiles reused from `--previous` as written, and publishes every
//! file once all are complete and closed (the manifest last). Also the files themselves: each
//! output opened on a temporary file, counted and hashed as it streams ([`Counted`]).

use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Instant;

use glam::DVec3;
use rayon::prelude::*;
use sha2::{Digest as _, Sha256};

use super::ifc_parts::{part_path, stale_parts, Parts, SplitIfc};
use super::plan::{tile_targets, tiles3d_contents, tiles3d_terrain};
use super::reuse::{rebased_entry, Keyed, ReusedTile};
use super::{
    file_name, io_err, out_err, relative_to, shard, Model, Progress, RunError, Summary, Targets,
    CHUNK, CHUNK_DETAILED,
};
use crate::derive::Generator;
use crate::export::citygml::{CityGmlWriter, VALIDATOR_MAX_ELEMENTS};
use crate::export::cityjson::{CityJsonSeqWriter, CityJsonWriter};
use crate::export::gltf::GltfWriter;
use crate::export::ifc::IfcWriter;
use crate::export::texture::{Texture, TextureSet};
use crate::export::{
    AtomicFile, BuildingWriter, Checked, ExportError, OutputContext, PendingFile, StreamSink,
};
use crate::model::{Building, Lod};
use crate::prepare;
use crate::report::{Outcome, Report};

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

/// What a tiled run records besides its files: its manifest (path and content so far), and
/// the keys.
#[derive(Default)]
pub(crate) struct Ledger {
    pub(super) manifest: Option<(PathBuf, shard::Manifest)>,
    pub(super) keys: Keyed,
}

/// The lots a run writes: the site's own, or (a run's) taken out of its site, so that each
/// batch's geometry is freed once it is written ([`Lots::release`]).
pub(crate) enum Lots<'a> {
    Borrowed(&'a [prepare::Lot]),
    Owned(Vec<prepare::Lot>),
}

impl Lots<'_> {
    fn all(&self) -> &[prepare::Lot] {
        match self {
            Lots::Borrowed(l) => l,
            Lots::Owned(l) => l,
        }
    }

    /// Frees the geometry of the lots in `range` (written: nothing reads it again). Their ids,
    /// tags and places stay.
    fn release(&mut self, range: std::ops::Range<usize>) {
        if let Lots::Owned(lots) = self {
            for l in lots.get_mut(range).unwrap_or_default() {
                l.polygons = Vec::new();
                l.parts = Vec::new();
                l.drawn = None;
                l.terrain = None;
            }
        }
    }
}

/// Writes each batch to its own files. Every file is complete and closed before any is renamed
/// over its target, so a run that fails (or is killed) part-way publishes nothing.
pub(crate) fn write_batches(
    site: &prepare::Site,
    batches: &[Batch],
    maker: &Maker<'_>,
    files: &FileSet<'_>,
    report: Report,
    ledger: Ledger,
    progress: Progress<'_>,
) -> Result<Summary, RunError> {
    let lots = Lots::Borrowed(&site.lots);
    write_lots_of(site, lots, batches, maker, files, report, ledger, progress)
}

/// [`write_batches`] of `lots` (the site's own, or taken out of it: `site.lots` is not read).
#[allow(clippy::too_many_arguments)]
pub(crate) fn write_lots_of(
    site: &prepare::Site,
    lots: Lots<'_>,
    batches: &[Batch],
    maker: &Maker<'_>,
    files: &FileSet<'_>,
    report: Report,
    ledger: Ledger,
    progress: Progress<'_>,
) -> Result<Summary, RunError> {
    let Ledger {
        manifest,
        keys: keyed,
    } = ledger;
    let (source_name, targets) = (files.name, files.targets);
    let start = Instant::now();
    let mut run = Batches {
        site,
        lots,
        source_name,
        input: files.input,
        targets,
        report,
        manifest,
        changes: keyed.changes.clone(),
        keyed,
        done: 0,
        ground: match (&site.elevation, targets.terrain) {
            (Some(grid), Some(plan)) => {
                super::terrain::Ground::new(grid, plan.tolerance, plan.tile, site.origin)
            }
            _ => None,
        },
        written: Written {
            preview: targets
                .preview
                .as_ref()
                .map(|_| crate::export::preview::Scene::new()),
            ..Default::default()
        },
        progress,
    };
    for batch in batches {
        run.write(batch, maker)?;
    }
    run.finish(batches, start)
}

/// [`write_batches`] between its batches: what it writes, and what is written so far.
struct Batches<'a> {
    site: &'a prepare::Site,
    /// The lots written (not `site.lots`, which may have been taken out).
    lots: Lots<'a>,
    source_name: &'a str,
    /// The input as given, for messages.
    input: Option<&'a Path>,
    targets: &'a Targets,
    report: Report,
    manifest: Option<(PathBuf, shard::Manifest)>,
    keyed: Keyed,
    /// What changed since `--previous`, with the tiles reused and rewritten so far.
    changes: Option<crate::report::Changes>,
    /// Lots written so far (derived or reused).
    done: usize,
    /// The site's ground, cut for each file set's terrain (`None`: no terrain written).
    ground: Option<super::terrain::Ground<'a>>,
    written: Written,
    progress: Progress<'a>,
}

impl Batches<'_> {
    /// Writes one batch to its files: derived, or reused from `--previous`.
    fn write(&mut self, batch: &Batch, maker: &Maker<'_>) -> Result<(), RunError> {
        let (site, source_name, targets) = (self.site, self.source_name, self.targets);
        let tile_targets = tile_targets(targets, batch.suffix.as_deref());
        let name = match &batch.suffix {
            Some(sfx) => format!("{source_name} tile {sfx}"),
            None => source_name.to_string(),
        };
        let lots = &self.lots.all()[batch.range.clone()];
        let mark = self.report.entries.len();
        let written = &mut self.written;
        written.cell = batch.cell;
        written.content_name = batch.suffix.clone().unwrap_or_else(|| "all".into());
        let lot_keys: Vec<shard::LotKey> = lots
            .iter()
            .filter_map(|l| self.keyed.keys.get(&l.id).cloned())
            .collect();
        written.tile = self.manifest.as_ref().map(|(path, _)| TileLog {
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
            .and_then(|sfx| self.keyed.reused.remove(sfx));
        if let Some(reused) = reused {
            let n = lots.len();
            return self.reuse(reused, &tile_targets, n);
        }
        if let (Some(c), Some(sfx)) = (self.changes.as_mut(), &batch.suffix) {
            c.tiles_rewritten.push(sfx.clone());
        }
        let (done, total, progress) = (self.done, self.lots.all().len(), self.progress);
        self.written.terrain = self
            .ground
            .as_ref()
            .and_then(|g| g.terrain(lots, batch.cell));
        write_lots(
            site,
            lots,
            maker,
            &FileSet {
                name: &name,
                input: self.input,
                targets: &tile_targets,
            },
            &mut self.report,
            &mut self.written,
            &|n| progress(done + n, total),
        )?;
        if let (Some((_, m)), Some(mut log)) = (self.manifest.as_mut(), self.written.tile.take()) {
            log.record.entries = self.report.entries[mark..].to_vec();
            m.tiles.push(log.record);
        }
        self.done += lots.len();
        self.lots.release(batch.range.clone());
        Ok(())
    }

    /// Takes a tile reused from `--previous` (`lots` lots) as written: its record's report
    /// entries, counts and 3D Tiles facts, its record in the manifest, and its files to publish.
    fn reuse(
        &mut self,
        (record, files): ReusedTile,
        tile_targets: &Targets,
        lots: usize,
    ) -> Result<(), RunError> {
        let (report, written) = (&mut self.report, &mut self.written);
        let Some(log) = written.tile.take() else {
            return Err(RunError::Input("a reused tile without a manifest".into()));
        };
        let Some((_, m)) = self.manifest.as_mut() else {
            return Err(RunError::Input("a reused tile without a manifest".into()));
        };
        report.entries.extend(record.entries.iter().cloned());
        report.generated += record.buildings.len();
        report.facades.add(&record.facades);
        report.provenance.add(&record.provenance);
        written.polygons += record.polygons;
        written.bytes += record.files.iter().map(|f| f.bytes).sum::<u64>();
        if let Some(p) = &tile_targets.citygml {
            written.count_citygml(p, record.citygml_elements);
        }
        if let (Some(dir), Some(v)) = (&self.targets.tiles3d, &record.tiles3d) {
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
        if let Some(c) = self.changes.as_mut() {
            c.tiles_reused += 1;
        }
        self.done += lots;
        (self.progress)(self.done, self.lots.all().len());
        Ok(())
    }

    /// After the last batch: the report's counts and changes, the run refused if it generated
    /// nothing (unless `allow_empty`), the warnings; then the manifest, preview, tileset and
    /// report rendered, and every file renamed into place, the manifest last.
    fn finish(self, batches: &[Batch], start: Instant) -> Result<Summary, RunError> {
        let total = self.lots.all().len();
        let Batches {
            source_name,
            targets,
            mut report,
            mut manifest,
            changes,
            written,
            keyed,
            ..
        } = self;
        let stale = keyed.stale;
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
            terrain: _,
            stale_parts,
            pictures: _,
        } = written;
        if report.generated == 0 && !targets.allow_empty {
            let named = self
                .input
                .map_or_else(|| source_name.to_string(), |p| p.display().to_string());
            return Err(nothing_generated(&report, &named, total));
        }
        let tiled = batches.iter().any(|b| b.suffix.is_some());
        let warnings = citygml_warnings(largest_citygml, citygml_over_cap, tiled, batches.len());
        for w in &warnings {
            report.add(None, Outcome::Note, w.clone());
        }
        let several = manifest.as_ref().is_some_and(|(_, m)| m.shard.count > 1);
        let manifest_file = render_manifest(&mut manifest, &report, &warnings)?;
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
        // An update in place: the previous run's files that this run no longer has go before
        // the manifest (a run killed here leaves the old manifest, whose missing files the
        // next run derives again).
        // A file this run published again is not stale (a picture of a tile derived again,
        // whose name no tile's list gives before it is drawn: `--textures`).
        let dir = manifest_dir(targets);
        let published: std::collections::HashSet<String> =
            paths.iter().map(|p| relative_to(p, dir)).collect();
        for p in stale
            .iter()
            .filter(|p| !published.contains(&relative_to(p, dir)))
        {
            remove_stale(p, targets)?;
        }
        // The names of a split IFC output's set that this run did not write (a previous
        // run's `out.ifc` beside parts, or its parts beside `out.ifc`).
        for p in &stale_parts {
            match std::fs::remove_file(p) {
                Err(e) if e.kind() != std::io::ErrorKind::NotFound => return Err(io_err(p)(e)),
                _ => {}
            }
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
            phases: Vec::new(),
        })
    }
}

/// The folder of the run's manifest (`.` without one): what a manifest's paths are relative to.
fn manifest_dir(targets: &Targets) -> &Path {
    targets
        .manifest
        .as_deref()
        .and_then(Path::parent)
        .unwrap_or(Path::new("."))
}

/// Removes `path`, a previous run's file that an update in place no longer has, when it lies
/// in the manifest's folder with no symbolic link on the way (a link at the end is removed
/// itself, never what it names); a file already gone is fine.
fn remove_stale(path: &Path, targets: &Targets) -> Result<(), RunError> {
    let dir = manifest_dir(targets);
    let Ok(rel) = path.strip_prefix(dir) else {
        return Ok(());
    };
    let mut cur = dir.to_path_buf();
    let parts: Vec<_> = rel.components().collect();
    for c in &parts[..parts.len().saturating_sub(1)] {
        cur.push(c);
        match std::fs::symlink_metadata(&cur) {
            Ok(m) if m.is_dir() => {}
            _ => return Ok(()),
        }
    }
    match std::fs::remove_file(path) {
        Err(e) if e.kind() != std::io::ErrorKind::NotFound => Err(io_err(path)(e)),
        _ => Ok(()),
    }
}

/// The error of a run that generated no building of its `total` lots (without
/// `--allow-empty`): nothing is written.
fn nothing_generated(report: &Report, source_name: &str, total: usize) -> RunError {
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
    RunError::Input(format!(
        "{source_name}: generated 0 of {total} buildings: {why}. Nothing was written; pass \
         --allow-empty to write empty outputs"
    ))
}

/// The warning, if any, of a CityGML file (the largest, of `files` tiles when `tiled`) with more
/// XML elements than the reference schema validator reads.
fn citygml_warnings(
    largest_citygml: Option<(PathBuf, u64)>,
    citygml_over_cap: usize,
    tiled: bool,
    files: usize,
) -> Vec<String> {
    let mut warnings = Vec::new();
    if let Some((path, n)) = largest_citygml.filter(|(_, n)| *n > VALIDATOR_MAX_ELEMENTS) {
        warnings.push(if tiled {
            format!(
                "{citygml_over_cap} of {} CityGML tiles have more than {VALIDATOR_MAX_ELEMENTS} XML elements, the most the reference schema validator reads (the largest: {}, {n}); a smaller --tile keeps every tile under it",
                files,
                path.display()
            )
        } else {
            format!(
                "{} has {n} XML elements, more than the {VALIDATOR_MAX_ELEMENTS} the reference schema validator reads; --tile METRES splits the outputs into tiles (250 m tiles of a dense centre hold under 300,000 at LOD3)",
                path.display()
            )
        });
    }
    warnings
}

/// The manifest, completed with the report's totals and the `warnings` (paths relative to the
/// manifest), rendered into a closed temporary file beside its path.
fn render_manifest<'m>(
    manifest: &'m mut Option<(PathBuf, shard::Manifest)>,
    report: &Report,
    warnings: &[String],
) -> Result<Option<(&'m Path, PendingFile)>, RunError> {
    let Some((path, m)) = manifest else {
        return Ok(None);
    };
    m.report.generated = report.generated;
    m.report.facades = report.facades.clone();
    m.report.provenance = report.provenance;
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
    Ok(Some((&*path, render_json(path, m).map_err(io_err(path))?)))
}

/// Where one writer's bytes go: a temporary file to publish, or (dry run) nowhere.
enum Sink {
    File(AtomicFile, StreamSink),
    Discard,
    /// A split IFC output's files, each with its own sink (`ifc_parts`).
    Parts,
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
    /// The input as the user gave it (for messages), when there is one.
    pub(crate) input: Option<&'a Path>,
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
    /// The terrain of the file set being written.
    terrain: Option<Arc<crate::model::Terrain>>,
    /// Files of a split IFC output's set that a previous run left and this run does not
    /// write (`ifc_parts::stale_parts`), removed once every file is published.
    stale_parts: Vec<PathBuf>,
    /// The pictures written so far (`--textures`), each once.
    pictures: std::collections::BTreeSet<PathBuf>,
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
        vertical_datum: site.vertical_datum.clone(),
        terrain: written.terrain.clone(),
    };

    // Open every output before the work, so a bad path fails fast.
    let Opened {
        mut outputs,
        citygml_elements,
        contents,
        ifc_parts,
        textures,
    } = open_outputs(
        targets,
        &written.content_name,
        hashed,
        written.terrain.is_some(),
    )?;
    for (path, w, ..) in &mut outputs {
        w.begin(&ctx).map_err(out_err(path))?;
    }
    let polygons = derive_and_write(
        lots,
        maker,
        &site.attributes,
        &mut outputs,
        report,
        written,
        progress,
    )?;
    for (path, w, ..) in &mut outputs {
        w.finish().map_err(out_err(path))?;
    }
    if let (Some(dir), [(full, full_info), (blocks, blocks_info), terrain @ ..]) =
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
            terrain: match terrain.first() {
                Some((p, info)) => Some(content(p, info)?),
                None => None,
            },
        };
        if let Some(log) = written.tile.as_mut() {
            // In the manifest, URIs relative to the manifest's folder.
            let mut rebased = entry.clone();
            rebased.full.uri = relative_to(full, &log.dir);
            rebased.blocks.uri = relative_to(blocks, &log.dir);
            if let (Some(t), Some((p, _))) = (rebased.terrain.as_mut(), terrain.first()) {
                t.uri = relative_to(p, &log.dir);
            }
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
    if let (Some((path, parts)), Some(cap)) = (ifc_parts, targets.ifc_max_bytes) {
        close_parts(&path, &parts, cap, report, written)?;
    }
    close_outputs(outputs, written)?;
    publish_textures(&textures, targets.dry_run, written)
}

/// Writes the pictures each output used (`--textures`) into its folder (`out_textures/`
/// beside `out.gml`), each through a closed temporary in `written.pending` like every output
/// (a failed run publishes none), once a run (a CityGML and a CityJSON output of one name
/// share the folder); counted, and listed in the tile's record. A dry run counts them only.
fn publish_textures(
    textures: &[(PathBuf, TextureSet)],
    dry: bool,
    written: &mut Written,
) -> Result<(), RunError> {
    for (dir, set) in textures {
        let used: Vec<Texture> = set
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .iter()
            .copied()
            .collect();
        for t in used {
            let path = dir.join(t.file_name());
            if !written.pictures.insert(path.clone()) {
                continue;
            }
            let png = t.png();
            written.bytes += png.len() as u64;
            if let Some(log) = written.tile.as_mut() {
                log.record.files.push(shard::FileRecord {
                    path: relative_to(&path, &log.dir),
                    bytes: png.len() as u64,
                    sha256: shard::hex(&Sha256::digest(&png)),
                });
            }
            if dry {
                written.rendered.push(path);
            } else {
                let closed = render_bytes(&path, &png).map_err(io_err(&path))?;
                written.pending.push((path, closed));
            }
        }
    }
    Ok(())
}

/// Closes the files of the IFC output `path` split under `cap` bytes (`ifc_parts`): named,
/// counted, recorded in the tile's record, noted in the report when there are several or
/// one is over the cap; the names of the set they leave stale go to `written.stale_parts`.
fn close_parts(
    path: &Path,
    parts: &Parts<PartFile>,
    cap: u64,
    report: &mut Report,
    written: &mut Written,
) -> Result<(), RunError> {
    let parts = std::mem::take(&mut *parts.lock().unwrap_or_else(|p| p.into_inner()));
    let several = parts.len() > 1;
    let mut names = Vec::with_capacity(parts.len());
    let mut on_disk = false;
    let mut listed = Vec::with_capacity(parts.len());
    for (k, part) in parts.into_iter().enumerate() {
        let name = if several {
            part_path(path, k + 1)
        } else {
            path.to_path_buf()
        };
        let (sink, counted, hash) = part.file;
        let bytes = counted.load(Ordering::Relaxed);
        written.bytes += bytes;
        if let (Some(log), Some(hash)) = (written.tile.as_mut(), hash) {
            let sha = hash
                .lock()
                .unwrap_or_else(|p| p.into_inner())
                .clone()
                .finalize();
            log.record.files.push(shard::FileRecord {
                path: relative_to(&name, &log.dir),
                bytes,
                sha256: shard::hex(&sha),
            });
        }
        if bytes > cap {
            let what = match (part.buildings, part.first) {
                (1, Some(id)) => format!("building {id} alone"),
                _ => "the terrain with the first building".to_string(),
            };
            report.add(
                part.first.filter(|_| part.buildings == 1),
                Outcome::Note,
                format!(
                    "{}: {what} takes {bytes} bytes, more than --ifc-max-mb's {cap}: a file of its own",
                    name.display()
                ),
            );
        }
        listed.push(format!(
            "{} ({} buildings, {bytes} bytes)",
            file_name(&name),
            part.buildings
        ));
        match sink {
            Sink::File(file, done) => {
                done.finish().map_err(io_err(&name))?;
                let closed = file.close().map_err(io_err(&name))?;
                let closed = if several {
                    closed.retarget(&name)
                } else {
                    closed
                };
                written.pending.push((name.clone(), closed));
                on_disk = true;
            }
            Sink::Discard | Sink::Parts => written.rendered.push(name.clone()),
        }
        names.push(name);
    }
    if several {
        report.add(
            None,
            Outcome::Note,
            format!(
                "{} is over --ifc-max-mb's {cap} bytes: written as {} files, each a complete IFC: {}",
                path.display(),
                names.len(),
                listed.join(", ")
            ),
        );
    }
    if on_disk {
        written.stale_parts.extend(stale_parts(path, &names));
    }
    Ok(())
}

/// The outputs of one file set, open ([`open_outputs`]).
struct Opened {
    /// Every model output and 3D Tiles content, in [`Model`] order, the contents last.
    outputs: Vec<Output>,
    /// The XML elements written to the CityGML output.
    citygml_elements: Arc<AtomicU64>,
    /// The 3D Tiles contents (full, blocks) and their facts, once written.
    contents: Vec<(PathBuf, crate::export::tiles3d::ContentInfoHandle)>,
    /// The files of the IFC output split under `--ifc-max-mb`, once written.
    ifc_parts: Option<(PathBuf, Parts<PartFile>)>,
    /// `--textures`: each CityGML and CityJSON output's pictures' folder and the pictures
    /// its writer used, written by [`publish_textures`] once it is complete.
    textures: Vec<(PathBuf, TextureSet)>,
}

/// Where the bytes of one file of a split IFC output went: its sink, count and hash.
type PartFile = (Sink, Arc<AtomicU64>, Option<SharedHash>);

/// Opens every output of the file set, each with its format's writer: the model outputs in
/// [`Model`] order, then the 3D Tiles contents named `content_name` (with the terrain's when
/// the file set has a `terrain`).
fn open_outputs(
    targets: &Targets,
    content_name: &str,
    hashed: bool,
    terrain: bool,
) -> Result<Opened, RunError> {
    let dry = targets.dry_run;
    let mut outputs: Vec<Output> = Vec::new();
    let citygml_elements = Arc::new(AtomicU64::new(0));
    let mut ifc_parts = None;
    let mut textures: Vec<(PathBuf, TextureSet)> = Vec::new();
    // `--textures` for a CityGML or CityJSON output: its pictures' folder (relative URI and
    // path) and the set its writer notes them in.
    let mut pictures = |p: &Path| {
        targets.textures.then(|| {
            let name = crate::export::texture::folder_name(p);
            let set = TextureSet::default();
            let dir = p.parent().unwrap_or(Path::new("")).join(&name);
            textures.push((dir, set.clone()));
            (format!("{name}/"), set)
        })
    };
    for (model, p) in targets.models() {
        let Some(p) = p else { continue };
        if let (Model::Ifc, Some(cap)) = (model, targets.ifc_max_bytes) {
            let open: super::ifc_parts::Opener<OutWriter, PartFile> = Box::new(move |p: &Path| {
                open_output(p, dry, None, hashed)
                    .map(|(w, sink, bytes, hash)| (w, (sink, bytes, hash)))
                    .map_err(|e| ExportError::Invalid(e.to_string()))
            });
            let (w, parts) = SplitIfc::new(p, targets.ifc_schema, cap, open);
            ifc_parts = Some((p.clone(), parts));
            let none = Arc::new(AtomicU64::new(0));
            outputs.push((p.clone(), Box::new(w), Sink::Parts, none, None));
            continue;
        }
        let elements = (model == Model::CityGml).then(|| Arc::clone(&citygml_elements));
        let (w, sink, bytes, hash) = open_output(p, dry, elements, hashed)?;
        let w: Box<dyn BuildingWriter> = match model {
            Model::Ifc => Box::new(
                IfcWriter::new(w)
                    .with_file_name(&file_name(p))
                    .with_schema(targets.ifc_schema),
            ),
            Model::CityGml => Box::new(CityGmlWriter::new(w).with_textures(pictures(p))),
            // A dry run keeps nothing, so its writer needs no scratch files.
            Model::Gltf if dry => {
                Box::new(GltfWriter::discarding(w).with_textures(targets.textures))
            }
            Model::Gltf => Box::new(
                GltfWriter::beside(w, p)
                    .map_err(io_err(p))?
                    .with_textures(targets.textures),
            ),
            // A dry run may name a folder that does not exist: its vertices wait in the
            // system's temporary folder instead.
            Model::CityJson => {
                let scratch = if dry {
                    std::env::temp_dir().join(file_name(p))
                } else {
                    p.clone()
                };
                Box::new(
                    CityJsonWriter::beside(w, &scratch)
                        .and_then(|w| w.with_textures(pictures(p), Some(&scratch)))
                        .map_err(io_err(p))?,
                )
            }
            Model::CityJsonSeq => Box::new(CityJsonSeqWriter::new(w).with_textures(pictures(p))),
        };
        outputs.push((p.clone(), w, sink, bytes, hash));
    }
    let mut contents = Vec::new();
    if let Some(dir) = &targets.tiles3d {
        use crate::export::tiles3d::Tiles3dWriter;
        // Full and Blocks by a pair of writers, which encodes each building once for both.
        let [(_, full), (_, blocks)] = tiles3d_contents(dir, content_name);
        let (fw, fsink, fbytes, fhash) = open_output(&full, dry, None, hashed)?;
        let (bw, bsink, bbytes, bhash) = open_output(&blocks, dry, None, hashed)?;
        let [(fw, finfo), (bw, binfo)] = Tiles3dWriter::pair(fw, bw);
        contents.push((full.clone(), finfo));
        contents.push((blocks.clone(), binfo));
        outputs.push((
            full,
            Box::new(fw.with_textures(targets.textures)),
            fsink,
            fbytes,
            fhash,
        ));
        outputs.push((blocks, Box::new(bw), bsink, bbytes, bhash));
        if terrain {
            let (detail, p) = tiles3d_terrain(dir, content_name);
            let (w, sink, bytes, hash) = open_output(&p, dry, None, hashed)?;
            let (w, info) = Tiles3dWriter::new(w, detail);
            let w = w.with_textures(targets.textures);
            contents.push((p.clone(), info));
            outputs.push((p, Box::new(w), sink, bytes, hash));
        }
    }
    Ok(Opened {
        outputs,
        citygml_elements,
        contents,
        ifc_parts,
        textures,
    })
}

/// Derives `lots` chunk by chunk and writes each chunk to every output, in lot order; notes
/// each lot's outcome in the report and in the tile's record; returns the polygons written.
fn derive_and_write(
    lots: &[prepare::Lot],
    maker: &Maker<'_>,
    attributes: &std::collections::HashMap<crate::model::SourceId, crate::model::Attributes>,
    outputs: &mut [Output],
    report: &mut Report,
    written: &mut Written,
    progress: &(dyn Fn(usize) + Sync),
) -> Result<usize, RunError> {
    let hashed = written.tile.is_some();
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
    let size = if detail { CHUNK_DETAILED } else { CHUNK };
    for (ci, chunk) in lots.chunks(size).enumerate() {
        let (results, chunk_written) = rayon::join(
            || {
                chunk
                    .par_iter()
                    .map(|lot| {
                        maker.make(lot).map(|(mut b, notes)| {
                            // The input's other attributes (issue 47), shared, not copied.
                            b.attributes = attributes.get(&b.id).cloned();
                            let digest = hashed.then(|| b.digest());
                            (b, notes, digest)
                        })
                    })
                    .collect::<Vec<_>>()
            },
            || write_ready(outputs, &ready),
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
                    report.provenance.count(&building.provenance);
                    if let Some(log) = written.tile.as_mut() {
                        log.record.facades.add(&building.facade);
                        log.record.provenance.count(&building.provenance);
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
        progress(((ci + 1) * size).min(lots.len()));
    }
    write_ready(outputs, &ready)?;
    written.preview = preview;
    Ok(polygons)
}

/// Closes the outputs in order: their bytes counted, their hashes recorded in the tile's
/// record, their files closed into `written.pending` (a dry run's paths into
/// `written.rendered`).
fn close_outputs(outputs: Vec<Output>, written: &mut Written) -> Result<(), RunError> {
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
            // Its files are closed by `close_parts`.
            Sink::Parts => {}
        }
    }
    Ok(())
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
