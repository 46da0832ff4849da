//! `citygen merge OUT_DIR...`: the shards of a run put together, after proving they add up.
//!
//! The manifests (`super::shard::Manifest`) of every folder given are read and checked as a
//! set before anything is written: one run (the same citygen version, inputs, knowledge base,
//! rules, seed, LOD, CRS and origin, tile size, options and outputs), every shard of it once,
//! every tile of its grid written once and by its shard, every lot of the grid once in all
//! (generated or skipped), and every file listed present with its size and SHA-256. A set that
//! does not add up is refused with a message naming the manifest, shard, tile, building or file.
//! Every file is read through `fsio::contained::open_contained`: a listed path or content URI
//! leaving its shard's folder (`..`, absolute, a URI, a symlink out) or a file that is not a
//! regular file is refused. The outputs are checked before anything is written: none on a file
//! the merge reads, no new manifest in a shard's folder, no two on one path.
//! Then the merge writes what a region needs from the tiles: the merged report, the region's
//! CityJSONSeq (one header, every tile's features in grid order), and the tileset of the 3D
//! Tiles contents. Outputs are written atomically, all closed before the first is renamed.

use std::collections::{BTreeMap, BTreeSet};
use std::io::{BufRead, BufReader, Read, Write};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use rayon::prelude::*;

use super::shard::{self, Manifest};
use super::{render_json, RunError};
use crate::fsio::contained::{open_contained, relative_inside};
use crate::fsio::{AtomicFile, PendingFile};
use crate::report::{Entry, Outcome, Report};

/// What `citygen merge` is asked to do.
#[derive(Clone, Debug, Default)]
pub struct MergeOptions {
    /// Folders holding the shards' manifests and outputs.
    pub dirs: Vec<PathBuf>,
    /// Write the merged report here.
    pub report: Option<PathBuf>,
    /// Write the region's CityJSONSeq here (the shards must have written `--cityjsonseq`).
    pub cityjsonseq: Option<PathBuf>,
    /// Write the region's 3D Tiles `tileset.json` into this folder, over the shards' contents
    /// (the shards must have written `--tiles3d`).
    pub tiles3d: Option<PathBuf>,
    /// Write an overview picture of the region here (PNG), drawn from the 3D Tiles contents.
    pub preview: Option<PathBuf>,
    /// Check the files' SHA-256 (on by default; sizes are always checked).
    pub verify: bool,
}

/// What a merge found and wrote.
#[derive(Clone, Debug, Default)]
pub struct MergeSummary {
    /// Shards merged.
    pub shards: usize,
    /// Tiles in the grid.
    pub tiles: usize,
    /// Buildings generated in all.
    pub buildings: usize,
    /// Lots skipped in all (with reasons in the report).
    pub skipped: usize,
    /// Files the shards wrote, checked.
    pub files: usize,
    /// Their bytes.
    pub bytes: u64,
    /// The files the merge wrote.
    pub outputs: Vec<PathBuf>,
    /// Wall-clock time.
    pub elapsed: Duration,
}

/// A manifest read back, with where it was found.
struct Found {
    path: PathBuf,
    dir: PathBuf,
    manifest: Manifest,
}

/// Merges the shards in `opts.dirs`.
pub fn merge(opts: &MergeOptions) -> Result<MergeSummary, RunError> {
    let start = Instant::now();
    if opts.dirs.is_empty() {
        return Err(RunError::Usage(
            "merge: name the shards' output folders".into(),
        ));
    }
    let found = read_manifests(&opts.dirs)?;
    let shards = check_set(&found)?;
    check_outputs(opts, &shards)?;
    let (files, bytes) = check_files(&shards, opts.verify)?;
    let first = &shards[0].manifest;

    // Everything is rendered into closed temporary files first.
    let mut pending: Vec<(PathBuf, PendingFile)> = Vec::new();
    if let Some(p) = &opts.cityjsonseq {
        pending.push((p.clone(), region_seq(p, &shards)?));
    }
    let entries = if opts.tiles3d.is_some() || opts.preview.is_some() {
        tile_entries(&shards)?
    } else {
        Vec::new()
    };
    if let Some(dir) = &opts.tiles3d {
        let p = dir.join("tileset.json");
        let tiles = rebased(&entries, dir);
        let text = crate::export::tiles3d::tileset_json(&tiles).map_err(|e| RunError::Output {
            path: p.clone(),
            source: e,
        })?;
        let file = super::render_bytes(&p, text.as_bytes()).map_err(io_err(&p))?;
        pending.push((p, file));
    }
    if let Some(p) = &opts.preview {
        let png = region_picture(&entries)?;
        let file = super::render_bytes(p, &png).map_err(io_err(p))?;
        pending.push((p.clone(), file));
    }
    let report = merged_report(&shards);
    if let Some(p) = &opts.report {
        let file = render_json(p, &report).map_err(io_err(p))?;
        pending.push((p.clone(), file));
    }
    let mut outputs = Vec::new();
    for (p, f) in pending {
        f.commit().map_err(io_err(&p))?;
        outputs.push(p);
    }
    Ok(MergeSummary {
        shards: first.shard.count,
        tiles: first.grid.tiles.len(),
        buildings: report.generated,
        skipped: report.skipped,
        files,
        bytes,
        outputs,
        elapsed: start.elapsed(),
    })
}

fn io_err(p: &Path) -> impl Fn(std::io::Error) -> RunError + '_ {
    move |e| RunError::Input(format!("{}: {e}", p.display()))
}

/// Every `citygen-manifest.I-of-N.json` of the folders, parsed, in folder then name order.
fn read_manifests(dirs: &[PathBuf]) -> Result<Vec<Found>, RunError> {
    let mut found = Vec::new();
    for dir in dirs {
        let entries = std::fs::read_dir(dir).map_err(io_err(dir))?;
        let mut names: Vec<PathBuf> = entries
            .filter_map(|e| e.ok())
            .map(|e| e.path())
            .filter(|p| is_manifest_name(p))
            .collect();
        if names.is_empty() {
            return Err(RunError::Input(format!(
                "merge: {} holds no citygen-manifest.I-of-N.json (a shard writes its manifest \
                 beside its outputs when it succeeds)",
                dir.display()
            )));
        }
        names.sort();
        for path in names {
            let text = read_manifest(dir, &path)?;
            let manifest: Manifest = serde_json::from_str(&text).map_err(|e| {
                RunError::Input(format!("{}: not a citygen manifest: {e}", path.display()))
            })?;
            if manifest.format != shard::MANIFEST_FORMAT {
                return Err(RunError::Input(format!(
                    "{}: manifest format {:?}, this citygen reads {:?}",
                    path.display(),
                    manifest.format,
                    shard::MANIFEST_FORMAT
                )));
            }
            found.push(Found {
                path,
                dir: dir.clone(),
                manifest,
            });
        }
    }
    Ok(found)
}

/// Whether `p`'s file name is a shard manifest's (`citygen-manifest.*.json`).
fn is_manifest_name(p: &Path) -> bool {
    p.file_name()
        .and_then(|n| n.to_str())
        .is_some_and(|n| n.starts_with("citygen-manifest.") && n.ends_with(".json"))
}

/// The text of the manifest `path` found in `dir`: a regular file in the folder itself
/// ([`open_contained`]: not a symlink, not a FIFO).
fn read_manifest(dir: &Path, path: &Path) -> Result<String, RunError> {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let (mut file, _) = open_contained(dir, &name)
        .map_err(|e| RunError::Input(format!("merge refused: {}: {e}", path.display())))?;
    let mut text = String::new();
    file.read_to_string(&mut text).map_err(io_err(path))?;
    Ok(text)
}

/// Checks that the manifests are the shards of one run, each once, and that their tiles and
/// buildings add up to its grid; returns them in shard order.
fn check_set(found: &[Found]) -> Result<Vec<&Found>, RunError> {
    check_one_run(found)?;
    let shards = check_shards(found)?;
    check_tiles(&found[0], &shards)?;
    Ok(shards)
}

/// A refusal of the set.
fn refuse<T>(m: String) -> Result<T, RunError> {
    Err(RunError::Input(format!("merge refused: {m}")))
}

/// Checks that every manifest was made by the first one's run: the same citygen, seed,
/// inputs, knowledge base and its files, rules, LOD, tile size, shard count, options and grid.
fn check_one_run(found: &[Found]) -> Result<(), RunError> {
    let first = &found[0];
    let a = &first.manifest;
    for f in &found[1..] {
        let b = &f.manifest;
        let differ = |what: &str, x: String, y: String| {
            format!(
                "{} was made with {what} {y}, {} with {what} {x}: they are not shards of one run",
                f.path.display(),
                first.path.display()
            )
        };
        let (ra, rb) = (&a.run, &b.run);
        let names = |k: &[shard::FileKey]| {
            k.iter()
                .map(|k| {
                    format!(
                        "{} (sha256 {}…)",
                        k.name,
                        k.sha256.chars().take(12).collect::<String>()
                    )
                })
                .collect::<Vec<_>>()
                .join(", ")
        };
        let opt = |k: &Option<shard::FileKey>| match k {
            Some(k) => names(std::slice::from_ref(k)),
            None => "none".into(),
        };
        let mismatch = if a.citygen != b.citygen {
            Some(differ("citygen", a.citygen.clone(), b.citygen.clone()))
        } else if ra.seed != rb.seed {
            Some(differ("seed", ra.seed.to_string(), rb.seed.to_string()))
        } else if ra.inputs != rb.inputs {
            Some(differ("input", names(&ra.inputs), names(&rb.inputs)))
        } else if ra.kb != rb.kb {
            Some(differ("knowledge base", opt(&ra.kb), opt(&rb.kb)))
        } else if ra.kb_files != rb.kb_files {
            Some(differ(
                "the knowledge base's files",
                names(&ra.kb_files),
                names(&rb.kb_files),
            ))
        } else if ra.rules != rb.rules {
            Some(differ("rules", opt(&ra.rules), opt(&rb.rules)))
        } else if ra.lod != rb.lod {
            Some(differ("LOD", ra.lod.to_string(), rb.lod.to_string()))
        } else if ra.tile_size != rb.tile_size {
            Some(differ(
                "tile size",
                ra.tile_size.to_string(),
                rb.tile_size.to_string(),
            ))
        } else if a.shard.count != b.shard.count {
            Some(differ(
                "shard count",
                a.shard.count.to_string(),
                b.shard.count.to_string(),
            ))
        } else if ra != rb {
            Some(differ(
                "options",
                format!("{} {:?} {} {:?}", ra.crs, ra.origin, ra.options, ra.outputs),
                format!("{} {:?} {} {:?}", rb.crs, rb.origin, rb.options, rb.outputs),
            ))
        } else if a.grid != b.grid {
            Some(differ(
                "a tile grid of",
                format!("{} tiles, {} lots", a.grid.tiles.len(), a.grid.lots),
                format!("{} tiles, {} lots", b.grid.tiles.len(), b.grid.lots),
            ))
        } else {
            None
        };
        if let Some(m) = mismatch {
            return refuse(m);
        }
    }
    Ok(())
}

/// Checks that the manifests hold every shard of the run once (and a grid that names no other
/// shard); returns them in shard order.
fn check_shards(found: &[Found]) -> Result<Vec<&Found>, RunError> {
    let first = &found[0];
    let a = &first.manifest;
    let n = a.shard.count;
    // A manifest is read from disk: a grid naming a shard the run does not have is refused,
    // not indexed.
    if let Some(t) = a.grid.tiles.iter().find(|t| t.shard >= n) {
        return refuse(format!(
            "{} gives tile {} to shard {}, but the run has {n} shards: the manifest is damaged",
            first.path.display(),
            t.suffix,
            t.shard
        ));
    }
    let mut by_index: Vec<Option<&Found>> = vec![None; n];
    for f in found {
        let i = f.manifest.shard.index;
        if i >= n {
            return refuse(format!(
                "{} says shard {i} of {n}, which does not exist",
                f.path.display()
            ));
        }
        if let Some(other) = by_index[i] {
            return refuse(format!(
                "shard {i} of {n} is there twice: {} and {}",
                other.path.display(),
                f.path.display()
            ));
        }
        by_index[i] = Some(f);
    }
    let missing: Vec<usize> = (0..n).filter(|i| by_index[*i].is_none()).collect();
    if let Some(&i) = missing.first() {
        let tiles: Vec<&str> = a
            .grid
            .tiles
            .iter()
            .filter(|t| t.shard == i)
            .map(|t| t.suffix.as_str())
            .collect();
        let dirs: BTreeSet<String> = found.iter().map(|f| f.dir.display().to_string()).collect();
        return refuse(format!(
            "shard {i} of {n} is missing: no {} in {} ({} shard(s) missing in all; its {} tile(s): {}{})",
            shard::Shard { index: i, count: n }.manifest_name(),
            dirs.into_iter().collect::<Vec<_>>().join(", "),
            missing.len(),
            tiles.len(),
            tiles.iter().take(5).copied().collect::<Vec<_>>().join(", "),
            if tiles.len() > 5 { ", ..." } else { "" }
        ));
    }
    Ok(by_index.into_iter().flatten().collect())
}

/// Checks the tiles of the `shards` against the grid of `first`'s run: each grid tile once,
/// written by its shard, with its lots, and each building once in all.
fn check_tiles(first: &Found, shards: &[&Found]) -> Result<(), RunError> {
    let a = &first.manifest;
    let n = a.shard.count;
    let grid: BTreeMap<&str, &shard::GridTile> = a
        .grid
        .tiles
        .iter()
        .map(|t| (t.suffix.as_str(), t))
        .collect();
    let mut seen_tiles: BTreeMap<&str, &Path> = BTreeMap::new();
    let mut seen_ids: BTreeMap<&str, &str> = BTreeMap::new();
    let mut lots = 0usize;
    for f in shards {
        for t in &f.manifest.tiles {
            let Some(g) = grid.get(t.suffix.as_str()) else {
                return refuse(format!(
                    "{} lists tile {}, which is not in the run's grid",
                    f.path.display(),
                    t.suffix
                ));
            };
            if g.shard != f.manifest.shard.index {
                return refuse(format!(
                    "{} lists tile {}, which the grid gives to shard {}",
                    f.path.display(),
                    t.suffix,
                    g.shard
                ));
            }
            if let Some(other) = seen_tiles.insert(&t.suffix, &f.path) {
                return refuse(format!(
                    "tile {} is there twice: in {} and {}",
                    t.suffix,
                    other.display(),
                    f.path.display()
                ));
            }
            let here = t.buildings.len() + t.skipped.len();
            if here != g.lots {
                return refuse(format!(
                    "tile {} of {} holds {here} buildings (generated or skipped), its grid {}",
                    t.suffix,
                    f.path.display(),
                    g.lots
                ));
            }
            lots += here;
            for id in t
                .buildings
                .iter()
                .map(|b| b.id.as_str())
                .chain(t.skipped.iter().map(|s| s.as_str()))
            {
                if let Some(other) = seen_ids.insert(id, &t.suffix) {
                    return refuse(format!(
                        "building {id} is there twice: in tile {other} and in tile {} ({})",
                        t.suffix,
                        f.path.display()
                    ));
                }
            }
        }
    }
    if let Some(g) = a
        .grid
        .tiles
        .iter()
        .find(|g| !seen_tiles.contains_key(g.suffix.as_str()))
    {
        return refuse(format!(
            "tile {} ({} buildings) is missing: shard {} of {n} ({}) does not list it",
            g.suffix,
            g.lots,
            g.shard,
            shards[g.shard].path.display()
        ));
    }
    if lots != a.grid.lots {
        return refuse(format!(
            "the tiles hold {lots} buildings, the run's grid {}",
            a.grid.lots
        ));
    }
    Ok(())
}

/// Where a manifest lists a file: `{manifest}, tile {suffix}, file {rel:?}`.
fn entry(f: &Found, t: &shard::TileRecord, what: &str, rel: &str) -> String {
    format!("{}, tile {}, {what} {rel:?}", f.path.display(), t.suffix)
}

/// Every file the shards list, with its manifest and tile.
fn listed<'a>(
    shards: &[&'a Found],
) -> Vec<(&'a Found, &'a shard::TileRecord, &'a shard::FileRecord)> {
    shards
        .iter()
        .flat_map(|f| {
            f.manifest
                .tiles
                .iter()
                .flat_map(move |t| t.files.iter().map(move |r| (*f, t, r)))
        })
        .collect()
}

/// Checks that every file the manifests list is there, inside its shard's folder, with its
/// size (and with `verify` its SHA-256); returns the files and bytes.
fn check_files(shards: &[&Found], verify: bool) -> Result<(usize, u64), RunError> {
    let files = listed(shards);
    if shards[0]
        .manifest
        .run
        .outputs
        .iter()
        .any(|o| o == "dry-run")
    {
        return Err(RunError::Input(format!(
            "merge refused: {} is a dry run's manifest: its files were never written",
            shards[0].path.display()
        )));
    }
    let problems: Vec<String> = files
        .par_iter()
        .filter_map(|(f, t, r)| check_file(f, t, r, verify).err())
        .collect();
    if let Some(first) = problems.first() {
        return Err(RunError::Input(format!(
            "merge refused: {first}{}",
            if problems.len() > 1 {
                format!(" (and {} more files)", problems.len() - 1)
            } else {
                String::new()
            }
        )));
    }
    Ok((files.len(), files.iter().map(|(_, _, r)| r.bytes).sum()))
}

/// `Err` (in words) unless the file `r` that `f` lists for tile `t` is a regular file inside
/// `f`'s folder with the size (and with `verify` the SHA-256) listed.
fn check_file(
    f: &Found,
    t: &shard::TileRecord,
    r: &shard::FileRecord,
    verify: bool,
) -> Result<(), String> {
    let (mut file, path) = open_contained(&f.dir, &r.path)
        .map_err(|e| format!("{}: {e}", entry(f, t, "file", &r.path)))?;
    let meta = file
        .metadata()
        .map_err(|e| format!("{} (listed by {}): {e}", path.display(), f.path.display()))?;
    if meta.len() != r.bytes {
        return Err(format!(
            "{} has {} bytes, {} lists {}",
            path.display(),
            meta.len(),
            f.path.display(),
            r.bytes
        ));
    }
    if verify {
        match crate::fsio::read_sha256(&mut file) {
            Ok((n, sha)) if n == r.bytes && sha == r.sha256 => {}
            Ok(_) => {
                return Err(format!(
                    "{} is not the file {} lists (its SHA-256 differs)",
                    path.display(),
                    f.path.display()
                ))
            }
            Err(e) => return Err(format!("{}: {e}", path.display())),
        }
    }
    Ok(())
}

/// The content URIs of tile `t`'s 3D Tiles facts (Full, Blocks), each checked to be a path
/// inside `f`'s folder that the tile lists among its files (so that its size and SHA-256 are
/// checked): no `..`, no absolute path, no `file:` or `http:` URI.
fn content_uris(f: &Found, t: &shard::TileRecord) -> Result<Vec<String>, RunError> {
    let Some(v) = &t.tiles3d else {
        return Ok(Vec::new());
    };
    let mut out = Vec::new();
    for part in ["full", "blocks"] {
        let Some(uri) = v
            .get(part)
            .and_then(|c| c.get("uri"))
            .and_then(|u| u.as_str())
        else {
            continue;
        };
        let at = entry(f, t, "3D Tiles content uri", uri);
        if let Err(e) = relative_inside(uri) {
            return refuse(format!("{at}: {e}"));
        }
        if !t.files.iter().any(|r| r.path == uri) {
            return refuse(format!(
                "{at}: not one of the files the tile lists (a content must be a file the \
                 shard wrote and listed)"
            ));
        }
        out.push(uri.to_string());
    }
    Ok(out)
}

/// The outputs merge is asked for, each with its flag.
fn merge_outputs(opts: &MergeOptions) -> Vec<(&'static str, PathBuf)> {
    let mut outs = Vec::new();
    outs.extend(opts.report.iter().map(|p| ("--report", p.clone())));
    outs.extend(
        opts.cityjsonseq
            .iter()
            .map(|p| ("--cityjsonseq", p.clone())),
    );
    outs.extend(
        opts.tiles3d
            .iter()
            .map(|d| ("--tiles3d", d.join("tileset.json"))),
    );
    outs.extend(opts.preview.iter().map(|p| ("--preview", p.clone())));
    outs
}

/// Checks merge's outputs before anything is read past the manifests or written: each with its
/// format's extension, in a folder, on its own path (`super::outputs::check`), and none on a
/// file merge reads (a manifest, a file a manifest lists, a 3D Tiles content) nor a new
/// manifest in a shard's folder (the next merge would read it). Also checks every content URI
/// ([`content_uris`]).
fn check_outputs(opts: &MergeOptions, shards: &[&Found]) -> Result<(), RunError> {
    let outs = merge_outputs(opts);
    for f in shards {
        for t in &f.manifest.tiles {
            content_uris(f, t)?;
        }
    }
    super::outputs::check(&outs, &[], false)?;
    let dirs: BTreeSet<PathBuf> = shards
        .iter()
        .map(|f| super::outputs::resolve(&f.dir))
        .collect();
    let mut read: BTreeMap<PathBuf, String> = BTreeMap::new();
    for f in shards {
        read.insert(
            super::outputs::resolve(&f.path),
            format!("the shard manifest {}", f.path.display()),
        );
    }
    for (f, t, r) in listed(shards) {
        if relative_inside(&r.path).is_ok() {
            read.entry(super::outputs::resolve(&f.dir.join(&r.path)))
                .or_insert_with(|| format!("the file {}", entry(f, t, "file", &r.path)));
        }
    }
    for (flag, p) in &outs {
        let at = super::outputs::resolve(p);
        if let Some(what) = read.get(&at) {
            return Err(RunError::Usage(format!(
                "merge {flag} {} is {what}, which merge reads: refusing to overwrite a shard's \
                 file (write the merge's outputs elsewhere)",
                p.display()
            )));
        }
        let in_shard = at.parent().is_some_and(|d| dirs.contains(d));
        if in_shard && is_manifest_name(&at) {
            return Err(RunError::Usage(format!(
                "merge {flag} {}: a file of that name in a shard's folder would be read as a \
                 shard manifest by the next merge; name the output otherwise",
                p.display()
            )));
        }
    }
    Ok(())
}

/// The run's report from the shards': the counts summed, the read and prepare entries in the
/// single run's order, then each tile's in grid order, then the shards' notes.
fn merged_report(shards: &[&Found]) -> Report {
    let first = &shards[0].manifest;
    let mut report = Report {
        read: first.report.read,
        parts_read: first.report.parts_read,
        boundaries: merged_boundaries(shards),
        terrain: Some(
            first
                .report
                .terrain
                .clone()
                .unwrap_or_else(|| crate::report::NO_TERRAIN.into()),
        ),
        ..Default::default()
    };
    let mut prepared: Vec<&(usize, Entry)> = shards
        .iter()
        .flat_map(|f| &f.manifest.report.prepared)
        .collect();
    prepared.sort_by_key(|(i, _)| *i);
    report.entries = prepared.into_iter().map(|(_, e)| e.clone()).collect();
    let mut tiles: Vec<&shard::TileRecord> =
        shards.iter().flat_map(|f| &f.manifest.tiles).collect();
    let order: BTreeMap<&str, usize> = first
        .grid
        .tiles
        .iter()
        .enumerate()
        .map(|(i, t)| (t.suffix.as_str(), i))
        .collect();
    tiles.sort_by_key(|t| order.get(t.suffix.as_str()).copied().unwrap_or(usize::MAX));
    for t in tiles {
        report.entries.extend(t.entries.iter().cloned());
    }
    for f in shards {
        report.generated += f.manifest.report.generated;
        report.facades.add(&f.manifest.report.facades);
        report.provenance.add(&f.manifest.report.provenance);
        report
            .entries
            .extend(f.manifest.report.notes.iter().cloned());
    }
    // Every shard of an incremental run lists the same changes of buildings (the whole
    // region's); the tiles each reused or rewrote are its own.
    report.changes = first.changes.clone().map(|mut c| {
        c.tiles_reused = shards
            .iter()
            .filter_map(|f| f.manifest.changes.as_ref())
            .map(|c| c.tiles_reused)
            .sum();
        let mut rewritten: Vec<String> = shards
            .iter()
            .filter_map(|f| f.manifest.changes.as_ref())
            .flat_map(|c| c.tiles_rewritten.iter().cloned())
            .collect();
        rewritten.sort_by_key(|s| order.get(s.as_str()).copied().unwrap_or(usize::MAX));
        c.tiles_rewritten = rewritten;
        c.tiles_not_reused = shards
            .iter()
            .filter_map(|f| f.manifest.changes.as_ref())
            .flat_map(|c| c.tiles_not_reused.clone())
            .collect();
        c
    });
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
    report
}

/// The input's boundaries as every shard read them, with the buildings each placed summed
/// over the shards (their lists are in one order: the boundaries' of the one input).
fn merged_boundaries(shards: &[&Found]) -> Option<crate::report::Boundaries> {
    let mut out = shards[0].manifest.report.boundaries.clone()?;
    for z in &mut out.zones {
        z.buildings = 0;
    }
    for f in shards {
        let Some(b) = &f.manifest.report.boundaries else {
            continue;
        };
        for (z, theirs) in out.zones.iter_mut().zip(&b.zones) {
            if z.boundary == theirs.boundary {
                z.buildings += theirs.buildings;
            }
        }
    }
    Some(out)
}

/// The tiles of the run in grid order, each with the folder of the shard that wrote it.
fn tiles_in_order<'a>(shards: &[&'a Found]) -> Vec<(&'a Found, &'a shard::TileRecord)> {
    let first = &shards[0].manifest;
    let by_suffix: BTreeMap<&str, (&Found, &shard::TileRecord)> = shards
        .iter()
        .flat_map(|f| {
            f.manifest
                .tiles
                .iter()
                .map(move |t| (t.suffix.as_str(), (*f, t)))
        })
        .collect();
    first
        .grid
        .tiles
        .iter()
        .filter_map(|g| by_suffix.get(g.suffix.as_str()).copied())
        .collect()
}

/// The region's CityJSONSeq: one header (the tiles' header, which is the same but for the
/// tile named in its title), then every tile's feature lines in grid order.
fn region_seq(target: &Path, shards: &[&Found]) -> Result<PendingFile, RunError> {
    let first = &shards[0].manifest;
    if !first.run.outputs.iter().any(|o| o == "cityjsonseq") {
        return Err(RunError::Usage(format!(
            "merge --cityjsonseq: the shards wrote no CityJSONSeq ({} lists {}); run them with \
             --cityjsonseq",
            shards[0].path.display(),
            first.run.outputs.join(", ")
        )));
    }
    let tiles = tiles_in_order(shards);
    let file = AtomicFile::create(target).map_err(io_err(target))?;
    let mut w = file.writer().map_err(io_err(target))?;
    let mut header: Option<String> = None;
    let n_tiles = tiles.len();
    for (f, t) in tiles {
        let Some(rec) = t.files.iter().find(|r| r.path.ends_with(".city.jsonl")) else {
            continue;
        };
        let (file, path) = open_contained(&f.dir, &rec.path).map_err(|e| {
            RunError::Input(format!(
                "merge refused: {}: {e}",
                entry(f, t, "file", &rec.path)
            ))
        })?;
        let mut lines = BufReader::new(file).lines();
        let head = match lines.next() {
            Some(l) => l.map_err(io_err(&path))?,
            None => {
                return Err(RunError::Input(format!(
                    "{}: empty, no CityJSON header line",
                    path.display()
                )))
            }
        };
        let tile_words = format!(" tile {}", t.suffix);
        let region_head = head.replacen(
            &tile_words,
            &format!(" ({n_tiles} tiles of {} m)", first.run.tile_size),
            1,
        );
        match &header {
            None => {
                w.write_all(region_head.as_bytes())
                    .map_err(io_err(target))?;
                w.write_all(b"\n").map_err(io_err(target))?;
                header = Some(region_head);
            }
            Some(h) if *h == region_head => {}
            Some(_) => {
                return Err(RunError::Input(format!(
                    "merge refused: the CityJSON header of {} differs from the first tile's \
                     (transform, CRS or LOD): not one run",
                    path.display()
                )))
            }
        }
        // `--textures`: the tile's pictures' URIs, relative to the tile's file, made relative
        // to the region's.
        let rebase = picture_rebase(&path, target);
        for line in lines {
            let line = line.map_err(io_err(&path))?;
            let line = match &rebase {
                Some((old, new)) if line.contains(old.as_str()) => line.replace(old, new),
                _ => line,
            };
            w.write_all(line.as_bytes()).map_err(io_err(target))?;
            w.write_all(b"\n").map_err(io_err(target))?;
        }
    }
    w.flush().map_err(io_err(target))?;
    drop(w);
    file.close().map_err(io_err(target))
}

/// The text a tile's CityJSONSeq at `tile` names its pictures with (`--textures`:
/// `"image":"out_0_0_textures/`) and the text that names them from the region's file `target`
/// (a relative path, `..` where the tile lies outside `target`'s folder); `None` when the two
/// are the same or a folder cannot be resolved.
fn picture_rebase(tile: &Path, target: &Path) -> Option<(String, String)> {
    let name = crate::export::texture::folder_name(tile);
    let folder = |p: &Path| {
        let d = p
            .parent()
            .filter(|d| !d.as_os_str().is_empty())
            .unwrap_or(Path::new("."));
        std::fs::canonicalize(d).ok()
    };
    let (from, to) = (folder(target)?, folder(tile)?.join(&name));
    let common = from
        .components()
        .zip(to.components())
        .take_while(|(a, b)| a == b)
        .count();
    let mut parts: Vec<String> = vec!["..".to_string(); from.components().count() - common];
    parts.extend(
        to.components()
            .skip(common)
            .map(|c| c.as_os_str().to_string_lossy().into_owned()),
    );
    let rel = parts.join("/");
    let quoted = |s: &str| {
        let q = serde_json::to_string(&format!("{s}/")).ok()?;
        Some(format!("\"image\":{}", q.strip_suffix('"')?))
    };
    let (old, new) = (quoted(&name)?, quoted(&rel)?);
    (old != new).then_some((old, new))
}

/// A tile's 3D Tiles entry (its URIs as absolute paths) with the shard folder its contents
/// lie in and their URIs relative to it, as the manifest gives them (Full, Blocks).
struct Placed<'a> {
    entry: crate::export::tiles3d::TileEntry,
    dir: &'a Path,
    rel: [String; 2],
}

/// The 3D Tiles entries of every tile in grid order, their URIs as absolute paths.
fn tile_entries<'a>(shards: &[&'a Found]) -> Result<Vec<Placed<'a>>, RunError> {
    let mut out = Vec::new();
    for (f, t) in tiles_in_order(shards) {
        let Some(v) = &t.tiles3d else {
            return Err(RunError::Usage(format!(
                "merge --tiles3d/--preview: tile {} of {} has no 3D Tiles contents; run the \
                 shards with --tiles3d DIR",
                t.suffix,
                f.path.display()
            )));
        };
        let mut e: crate::export::tiles3d::TileEntry =
            serde_json::from_value(v.clone()).map_err(|e| {
                RunError::Input(format!(
                    "{}: tile {}: bad 3D Tiles facts: {e}",
                    f.path.display(),
                    t.suffix
                ))
            })?;
        let rel = [e.full.uri.clone(), e.blocks.uri.clone()];
        for c in e.contents_mut() {
            relative_inside(&c.uri).map_err(|err| {
                RunError::Input(format!(
                    "merge refused: {}: {err}",
                    entry(f, t, "3D Tiles content uri", &c.uri)
                ))
            })?;
            c.uri = super::outputs::resolve(&f.dir.join(&c.uri))
                .display()
                .to_string();
        }
        out.push(Placed {
            entry: e,
            dir: &f.dir,
            rel,
        });
    }
    Ok(out)
}

/// The entries with URIs relative to the tileset's folder `dir` (`..` where a content lies
/// outside it), `/`-separated.
fn rebased(entries: &[Placed<'_>], dir: &Path) -> Vec<crate::export::tiles3d::TileEntry> {
    let base = super::outputs::resolve(dir);
    entries
        .iter()
        .map(|p| {
            let mut e = p.entry.clone();
            for c in e.contents_mut() {
                c.uri = relative_uri(Path::new(&c.uri), &base);
            }
            e
        })
        .collect()
}

/// `path` relative to the folder `base` (both absolute), `/`-separated.
fn relative_uri(path: &Path, base: &Path) -> String {
    let p: Vec<_> = path.components().collect();
    let b: Vec<_> = base.components().collect();
    let common = p.iter().zip(&b).take_while(|(x, y)| x == y).count();
    let mut parts: Vec<String> = vec!["..".to_string(); b.len() - common];
    parts.extend(
        p[common..]
            .iter()
            .map(|c| c.as_os_str().to_string_lossy().into_owned()),
    );
    parts.join("/")
}

/// The region drawn from its tiles' contents (the Full ones; the Blocks beyond 20 million
/// triangles), in an east-north-up frame at the first tile's origin, as a PNG.
fn region_picture(entries: &[Placed<'_>]) -> Result<Vec<u8>, RunError> {
    use crate::export::preview::{glb_triangles, Scene, View};
    let placed: Vec<_> = entries
        .iter()
        .filter_map(|e| e.entry.full.info.placement.as_ref().map(|p| (e, p)))
        .collect();
    let Some((_, first)) = placed.first() else {
        return Err(RunError::Input(
            "merge --preview: the region has no building to draw".into(),
        ));
    };
    let triangles: u64 = placed
        .iter()
        .map(|(e, _)| e.entry.full.info.triangles)
        .sum();
    let blocks = triangles > 20_000_000;
    let [lon, lat, h] = first.origin;
    let o = crate::crs::wgs84_to_ecef(lon, lat, h);
    let (sl, cl) = lon.to_radians().sin_cos();
    let (sp, cp) = lat.to_radians().sin_cos();
    let east = [-sl, cl, 0.0];
    let north = [-sp * cl, -sp * sl, cp];
    let up = [cp * cl, cp * sl, sp];
    let dot = |a: [f64; 3], b: [f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    let mut scene = Scene::new();
    for (p, _) in &placed {
        let (content, rel) = if blocks {
            (&p.entry.blocks, &p.rel[1])
        } else {
            (&p.entry.full, &p.rel[0])
        };
        let Some(place) = &content.info.placement else {
            continue;
        };
        let m = place.transform;
        let to_frame = |p: [f64; 3]| {
            // The tile transform (column-major), then ECEF to the region's frame.
            let x = [
                m[0] * p[0] + m[4] * p[1] + m[8] * p[2] + m[12] - o[0],
                m[1] * p[0] + m[5] * p[1] + m[9] * p[2] + m[13] - o[1],
                m[2] * p[0] + m[6] * p[1] + m[10] * p[2] + m[14] - o[2],
            ];
            [dot(x, east), dot(x, north), dot(x, up)]
        };
        let (mut file, path) = open_contained(p.dir, rel).map_err(|e| {
            RunError::Input(format!("merge refused: 3D Tiles content {rel:?}: {e}"))
        })?;
        let mut bytes = Vec::new();
        file.read_to_end(&mut bytes).map_err(io_err(&path))?;
        let path = path.as_path();
        let meshes = glb_triangles(&bytes, &to_frame)
            .map_err(|e| RunError::Input(format!("{}: {e}", path.display())))?;
        scene.add_glb_meshes(&meshes);
    }
    Ok(scene.render(&View::default()).to_png())
}
