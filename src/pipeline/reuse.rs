//! Incremental runs' side of a tiled run: the content keys of its lots, and with `--previous`
//! what changed since and the tiles reused ([`key_lots`]: planned and copied before the LOD3
//! surroundings, so that only the derived tiles' neighbours are derived).

use std::path::{Path, PathBuf};

use rayon::prelude::*;

use super::plan::{tile_files, tile_targets, GridPlan};
use super::{incremental, relative_to, shard, RunError, RunState, Targets};
use crate::export::PendingFile;
use crate::model::SourceId;
use crate::prepare;

/// The content keys of a tiled run's lots, and yesterday's run with what changed since
/// (`--previous`).
#[derive(Default)]
pub(super) struct Keyed {
    /// The run's context key, hex.
    pub(super) context: String,
    pub(super) keys: std::collections::HashMap<crate::model::SourceId, shard::LotKey>,
    pub(super) previous: Option<incremental::Previous>,
    pub(super) changes: Option<crate::report::Changes>,
    /// The tiles reused from `previous`, by suffix: their records and files, copied and
    /// checked.
    pub(super) reused: std::collections::BTreeMap<String, ReusedTile>,
    /// In an update in place (`--previous` is the manifest's folder): the previous run's files
    /// that no tile of this run (any shard's) writes, and its manifests of another shard
    /// count, to remove once every new file is in place and before the manifest
    /// ([`stale_files`]).
    pub(super) stale: Vec<PathBuf>,
}

/// A tile reused from `--previous`: its record and its files (closed temporaries, to be
/// renamed with the run's others; `None` for a file that is already in place).
pub(super) type ReusedTile = (shard::TileRecord, Vec<(PathBuf, Option<PendingFile>)>);

/// A tiled run's content keys, and the run key computed on the way; with `previous`, what
/// changed since and the tiles reused (copied now, [`plan_reuse`]). Nothing for a run without
/// a manifest.
pub(super) fn key_lots(
    run: &RunState<'_>,
    previous: Option<&incremental::Previous>,
) -> Result<(Keyed, Option<shard::RunKey>), RunError> {
    let mut keyed = Keyed::default();
    let (Some(g), Some(path), Some(own)) = (&run.grid, &run.targets.manifest, &run.own_keys) else {
        return Ok((keyed, None));
    };
    let (opts, site) = (run.opts, &run.site);
    let rk = g.run_key(
        opts,
        &run.targets,
        site,
        &run.generator.kb,
        run.split.as_ref().map(|h| h.inputs.as_slice()),
    )?;
    let dir = path
        .parent()
        .filter(|d| !d.as_os_str().is_empty())
        .unwrap_or(Path::new("."))
        .to_path_buf();
    // The outputs whose names decide the tiles' bytes and places: not the report's or the
    // preview's (an operator's dated report names must not make every tile new).
    let mut outs: Vec<String> = run
        .targets
        .flagged()
        .into_iter()
        .filter(|(flag, _)| !matches!(*flag, "--report" | "--preview"))
        .map(|(flag, p)| format!("{flag} {}", relative_to(&p, &dir)))
        .collect();
    outs.sort();
    let context = incremental::context_key(&rk, &run.source_name, &outs);
    keyed.context = incremental::key_hex(&context);
    // Over every lot: neighbours outside --bbox count.
    // The zone an input boundary gave a lot is part of what decides its bytes (the boundary
    // may be edited while the building is not).
    let gen = &run.generator;
    let zone = |l: &crate::prepare::Lot| {
        let at = gen.zone_of(l);
        at.boundary.map(|_| gen.kb.zone_path(at.zone).to_string())
    };
    keyed.keys = incremental::with_context(
        &context,
        incremental::full_keys(&site.lots, own, opts.lod, zone),
    );
    if let Some(prev) = previous {
        let run_lots: std::collections::BTreeMap<String, (String, String)> = site
            .lots
            .iter()
            .zip(&run.in_run)
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
        changes.not_reused = prev.context_change(&keyed.context, &rk);
        let (reused, why) = plan_reuse(
            prev,
            site,
            (g, &run.selected),
            &keyed.keys,
            &run.targets,
            (&dir, changes.not_reused.is_some()),
        );
        changes.tiles_not_reused = why;
        keyed.changes = Some(changes);
        keyed.reused = reused;
        let inputs: Vec<PathBuf> = super::run_inputs(opts)
            .into_iter()
            .map(|(_, p)| super::outputs::resolve(&p))
            .collect();
        keyed.stale = stale_files(prev, g, (&run.targets, &inputs), &dir);
    }
    Ok((keyed, Some(rk)))
}

/// The tiles of this shard that `prev` holds with the same lots, in the same order, with the
/// same keys, and the same files: each one's files copied beside their targets (checked
/// against the previous manifest's size and SHA-256; a tile whose file fails is left out, to
/// be derived); and why each other tile is not reused. `dir` is the manifest's folder;
/// `context_changed` whether the run's context is not the previous run's. Tiles are copied in
/// parallel.
fn plan_reuse(
    prev: &incremental::Previous,
    site: &prepare::Site,
    (grid, selected): (&GridPlan, &[bool]),
    keys: &std::collections::HashMap<SourceId, shard::LotKey>,
    targets: &Targets,
    (dir, context_changed): (&Path, bool),
) -> (
    std::collections::BTreeMap<String, ReusedTile>,
    std::collections::BTreeMap<String, String>,
) {
    // Each tile's lots in file order: input order within a tile (prepare::group_into_tiles).
    let mut lots: std::collections::BTreeMap<String, Vec<shard::LotKey>> = Default::default();
    for (lot, _) in site.lots.iter().zip(selected).filter(|(_, s)| **s) {
        let Some(k) = keys.get(&lot.id) else { continue };
        lots.entry(grid.suffix_of(site.crs, lot))
            .or_default()
            .push(k.clone());
    }
    let found: Vec<(String, Result<ReusedTile, String>)> = lots
        .into_par_iter()
        .map(|(suffix, lots)| {
            let tile = tile_targets(targets, Some(&suffix));
            let found = reuse_tile(prev, (dir, context_changed), &suffix, &lots, &tile);
            (suffix, found)
        })
        .collect();
    let mut reused = std::collections::BTreeMap::new();
    let mut why = std::collections::BTreeMap::new();
    for (suffix, found) in found {
        match found {
            Ok(t) => {
                reused.insert(suffix, t);
            }
            Err(reason) => {
                why.insert(suffix, reason);
            }
        }
    }
    (reused, why)
}

/// The previous run's record of tile `suffix`, and its files copied (checked) to this run's
/// `targets` for the tile, when the tile's lots and keys are `lots` (in order) and its files
/// are those this tile writes ([`incremental::Previous::reusable`]); else why the tile is
/// derived (its lots, or a previous file missing, not a regular file inside the folder, or not
/// what its manifest lists). `dir` is this run's manifest's folder.
fn reuse_tile(
    prev: &incremental::Previous,
    (dir, context_changed): (&Path, bool),
    suffix: &str,
    lots: &[shard::LotKey],
    targets: &Targets,
) -> Result<ReusedTile, String> {
    if targets.dry_run {
        return Err("a dry run".into());
    }
    let paths = tile_files(targets, suffix);
    let rel: std::collections::BTreeMap<String, PathBuf> = paths
        .iter()
        .map(|p| (relative_to(p, dir), p.clone()))
        .collect();
    let names = rel.keys().cloned().collect();
    let pictures: Vec<String> = super::plan::picture_dirs(targets)
        .iter()
        .map(|d| relative_to(d, dir))
        .collect();
    let (folder, record) = prev.reusable(suffix, lots, (&names, &pictures), context_changed)?;
    let mut files = Vec::with_capacity(record.files.len());
    for f in &record.files {
        // A picture (`--textures`) lands where the previous run had it, relative to the
        // manifest's folder, like every file: in a picture folder of this tile's outputs.
        let picture = (!rel.contains_key(&f.path) && incremental::is_picture(&f.path, &pictures))
            .then(|| dir.join(&f.path));
        let dst = rel
            .get(&f.path)
            .or(picture.as_ref())
            .ok_or_else(|| format!("{}: not a file of this run", f.path))?;
        // On a failure the temporaries made so far are dropped (removed).
        let p = incremental::copy_checked(folder, &f.path, dst, (f.bytes, &f.sha256), prev.link)
            .map_err(|e| e.to_string())?;
        files.push((dst.clone(), p));
    }
    // Its paths (the 3D Tiles URIs too) are relative to the manifest's folder, and the same
    // here: the files land at the same places relative to this run's manifest.
    Ok((record.clone(), files))
}

/// In an update in place (a folder of `prev`'s manifests is this run's manifest folder
/// `dir`): the files its manifests there list that no tile of this run's `grid` (every
/// shard's) writes with these `targets`, and its manifests of another shard count than this
/// run's. Only files still as listed ([`incremental::still_listed`]: regular, inside the
/// folder, same size and SHA-256) and none of the run's `inputs` (resolved paths) are
/// listed; empty for another folder.
fn stale_files(
    prev: &incremental::Previous,
    grid: &GridPlan,
    (targets, inputs): (&Targets, &[PathBuf]),
    dir: &Path,
) -> Vec<PathBuf> {
    let here = super::outputs::resolve(dir);
    let in_place = |folder: &Path| super::outputs::resolve(folder) == here;
    let written: std::collections::BTreeSet<String> = grid
        .tiles
        .iter()
        .flat_map(|t| tile_files(&tile_targets(targets, Some(&t.suffix)), &t.suffix))
        // A tile's terrain content, which a run with terrain may write: never stale.
        .chain(grid.tiles.iter().filter_map(|t| {
            let dir = targets
                .tiles3d
                .as_ref()
                .filter(|_| targets.terrain.is_some())?;
            Some(super::plan::tiles3d_terrain(dir, &t.suffix).1)
        }))
        .chain(targets.flagged().into_iter().map(|(_, p)| p))
        .map(|p| relative_to(&p, dir))
        .collect();
    let mut stale: std::collections::BTreeSet<PathBuf> = prev
        .tiles
        .values()
        .filter(|(folder, _)| in_place(folder))
        .flat_map(|(folder, t)| t.files.iter().map(move |f| (folder, f)))
        .filter(|(folder, f)| {
            !written.contains(&f.path)
                && incremental::still_listed(folder, &f.path, f.bytes, &f.sha256)
        })
        .map(|(_, f)| dir.join(&f.path))
        .filter(|p| !inputs.contains(&super::outputs::resolve(p)))
        .collect();
    // This run's shard count, from its manifest's name `citygen-manifest.I-of-N.json`.
    let count = targets
        .manifest
        .as_ref()
        .and_then(|m| m.file_name())
        .and_then(|n| n.to_str())
        .and_then(|n| n.rsplit_once("-of-"))
        .map(|(_, n)| n.to_string());
    for m in &prev.manifests {
        let folder = m.path.parent().unwrap_or(Path::new("."));
        let name = m.path.file_name().and_then(|n| n.to_str());
        let other_count = match (&count, name) {
            (Some(c), Some(n)) => !n.ends_with(&format!("-of-{c}")),
            _ => false,
        };
        let regular = std::fs::symlink_metadata(&m.path).is_ok_and(|m| m.is_file());
        if other_count && regular && in_place(folder) {
            if let Some(n) = name {
                stale.insert(dir.join(n));
            }
        }
    }
    stale.into_iter().collect()
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
pub(super) fn rebased_entry(
    v: &serde_json::Value,
    manifest_dir: &Path,
    tiles3d: &Path,
) -> Result<crate::export::tiles3d::TileEntry, RunError> {
    let mut v = v.clone();
    rebase_uris(&mut v, manifest_dir, tiles3d);
    serde_json::from_value(v)
        .map_err(|e| RunError::Input(format!("a previous manifest's 3D Tiles facts: {e}")))
}
