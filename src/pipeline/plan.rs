//! The plan of a run before any work: the targets of a shard or tiled run
//! ([`shard_targets`]), the tile grid and which shard writes each tile ([`GridPlan`], with the
//! run's key and the manifest's head), the output CRS when none is given ([`zone_for`]), and
//! the files of each tile ([`tile_targets`], [`tile_files`], named by [`tile_path`]).

use std::path::{Path, PathBuf};

use super::{outputs, shard, Options, RunError, Source, Targets};
use crate::crs::Crs;
use crate::input;
use crate::kb;
use crate::prepare;
use crate::report::Report;

/// The targets of a shard (`--shard`) or of any tiled run: its manifest's path (in the folder
/// of the first output of `--report`, `--cityjsonseq`, `--cityjson`, `--gltf`, `--citygml`,
/// `--ifc`), and for a shard of several its report named `NAME_shard-I-of-N.json`. Also the
/// shard (shard 0 of 1 for an unsharded run).
pub(super) fn shard_targets(
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
    let first = std::iter::once(&targets.report)
        .chain(targets.models().into_iter().rev().map(|(_, p)| p))
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
    let manifest = dir.join(shard.0.manifest_name());
    if shard.0.count > 1 {
        let sfx = format!("shard-{}-of-{}", shard.0.index, shard.0.count);
        targets.report = targets.report.map(|p| tile_path(&p, &sfx));
        // A shard may hold no tile, or only buildings that fail: the merge judges the whole.
        targets.allow_empty = true;
    }
    // The outputs written at their own path (not a tile's) are not the manifest.
    let own: Vec<(&'static str, PathBuf)> = targets
        .flagged()
        .into_iter()
        .filter(|(flag, _)| matches!(*flag, "--report" | "--preview" | "--tiles3d"))
        .collect();
    outputs::check_manifest(&own, &manifest)?;
    targets.manifest = Some(manifest);
    Ok((targets, shard))
}

/// The tile grid of a tiled run, and which shard writes each tile.
pub(super) struct GridPlan {
    size: u32,
    shard: shard::Shard,
    /// Every tile holding a selected lot, in grid order.
    pub(super) tiles: Vec<shard::GridTile>,
    /// The shard of each tile, by grid cell.
    of_cell: std::collections::BTreeMap<(i64, i64), usize>,
    /// Selected lots in all.
    lots: usize,
}

impl GridPlan {
    /// The grid over the `selected` lots of `site` (those `--bbox` keeps), `size`-metre tiles,
    /// assigned to `shard.count` shards by [`shard::assign`].
    pub(super) fn new(
        site: &prepare::Site,
        size: u32,
        selected: &[bool],
        shard: shard::Shard,
    ) -> GridPlan {
        let mut counts: std::collections::BTreeMap<(i64, i64), usize> = Default::default();
        for (lot, _) in site.lots.iter().zip(selected).filter(|(_, s)| **s) {
            *counts
                .entry(prepare::tile_cell(site.crs, lot, size))
                .or_default() += 1;
        }
        let loads: Vec<usize> = counts.values().copied().collect();
        let cells: Vec<(i64, i64)> = counts.keys().copied().collect();
        let assigned = shard::assign(&cells, &loads, shard.count);
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
    pub(super) fn suffix_of(&self, crs: Crs, lot: &prepare::Lot) -> String {
        let (x, y) = prepare::tile_cell(crs, lot, self.size);
        let s = i64::from(self.size.max(1));
        format!("{}_{}", x * s, y * s)
    }

    /// Whether the lot's tile is this shard's.
    /// The shard writing `lot`'s tile (0 for a lot of no tile of the grid).
    pub(super) fn shard_of(&self, crs: Crs, lot: &prepare::Lot) -> usize {
        self.of_cell
            .get(&prepare::tile_cell(crs, lot, self.size))
            .copied()
            .unwrap_or(0)
    }

    /// Every tile's cell (its lower-left corner over the tile size) with its shard.
    pub(super) fn cells(&self) -> std::collections::BTreeMap<(i64, i64), usize> {
        self.of_cell.clone()
    }

    /// The same grid seen from shard `index` of the same count.
    pub(super) fn set_index(&mut self, index: usize) {
        self.shard.index = index;
    }

    /// The grid a `citygen split` head recorded ([`super::split::SplitHead::grid`]): the
    /// whole input's tiles and shards, whatever the part holds.
    pub(super) fn from_grid(grid: &shard::Grid, size: u32, shard: shard::Shard) -> GridPlan {
        let s = i64::from(size.max(1));
        GridPlan {
            size,
            shard,
            tiles: grid.tiles.clone(),
            of_cell: grid
                .tiles
                .iter()
                .map(|t| ((t.corner[0] / s, t.corner[1] / s), t.shard))
                .collect(),
            lots: grid.lots,
        }
    }

    pub(super) fn is_mine(&self, crs: Crs, lot: &prepare::Lot) -> bool {
        self.of_cell.get(&prepare::tile_cell(crs, lot, self.size)) == Some(&self.shard.index)
    }

    /// What decides the run's outputs ([`shard::RunKey`]): the inputs' and KB's hashes, seed,
    /// LOD, CRS, origin, tile size, options and outputs.
    pub(super) fn run_key(
        &self,
        opts: &Options,
        targets: &Targets,
        site: &prepare::Site,
        kb: &kb::KnowledgeBase,
        split_inputs: Option<&[shard::FileKey]>,
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
        if let Some(i) = split_inputs {
            // A split part's run read the input that was split.
            inputs = i.to_vec();
        }
        let mut outputs: Vec<String> = targets
            .models()
            .into_iter()
            .filter(|(_, p)| p.is_some())
            .map(|(m, _)| m.name().to_string())
            .collect();
        if opts.dry_run {
            outputs.push("dry-run".into());
        }
        // The files the KB's appearances name, keyed by the name the KB gives them.
        let mut kb_files = std::collections::BTreeMap::new();
        for (z, zone) in kb.zones().iter().enumerate() {
            for (a, app) in zone.appearances.iter().enumerate() {
                let named = [
                    (app.ruleset.as_deref(), kb.ruleset_file(z, a, false)),
                    (app.selex.as_deref(), kb.selex_file(z, a)),
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
        let mut options = format!(
            "bbox={:?} crs={:?} src_crs={:?} max_depth={} max_shapes={} infer={:?}",
            opts.bbox,
            opts.crs.map(|c| c.to_string()),
            opts.src_crs.map(|c| c.to_string()),
            opts.caps.max_depth,
            opts.caps.max_shapes,
            opts.infer
        );
        // The terrain's tolerance, in a run that writes one (a run without keeps its key).
        let grid = site.elevation.is_some() || opts.ground_fn.is_some();
        if grid && !opts.no_terrain {
            options.push_str(&format!(" terrain={}", opts.terrain_tolerance));
        }
        // Only when not IFC4: the options of IFC4 runs are those of before.
        if opts.textures {
            options.push_str(" textures");
        }
        if opts.ifc.is_some() && opts.ifc_schema != crate::export::ifc::IfcSchema::Ifc4 {
            options.push_str(&format!(" ifc_schema={}", opts.ifc_schema));
        }
        // Only when given: the files of a capped IFC are not those of an uncapped one.
        if let (Some(_), Some(cap)) = (&opts.ifc, opts.ifc_max_bytes) {
            options.push_str(&format!(" ifc_max_bytes={cap}"));
        }
        // Only when given: the options of runs without a ground height are those of before.
        if let Some(h) = opts.ground_height {
            options.push_str(&format!(" ground_height={h}"));
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
            options,
            outputs,
            dems: opts.dem.iter().map(|p| key(p)).collect::<Result<_, _>>()?,
        })
    }

    /// The manifest without its tiles: the run's key, the grid, and the shard's share of the
    /// report so far, which becomes `report` (the entries of the read and prepare stages that
    /// name one of this shard's lots, or for shard 0 no lot of the run).
    pub(super) fn manifest_head(
        &self,
        run: shard::RunKey,
        shard: &(shard::Shard, String),
        site: &prepare::Site,
        report: &mut Report,
    ) -> Result<shard::Manifest, RunError> {
        // Without entries (`citygen split` cuts them itself) there is nothing to own.
        let owner: std::collections::BTreeMap<String, usize> = site
            .lots
            .iter()
            .take(if report.entries.is_empty() {
                0
            } else {
                usize::MAX
            })
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
                boundaries: report.boundaries.clone(),
                terrain: report
                    .terrain
                    .clone()
                    .filter(|t| t != crate::report::NO_TERRAIN),
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
pub(super) fn zone_for(
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

/// The targets of one tile (`suffix`; `None` untiled: the run's own paths): every model
/// output's path with the suffix inserted, the 3D Tiles folder as it is, no report.
pub(super) fn tile_targets(targets: &Targets, suffix: Option<&str>) -> Targets {
    let mut tile = Targets {
        report: None,
        preview: None,
        manifest: None,
        ..targets.clone()
    };
    if let Some(sfx) = suffix {
        for p in tile.models_mut().into_iter().flatten() {
            *p = tile_path(p, sfx);
        }
    }
    tile
}

/// The files a tile writes: its model outputs and its 3D Tiles contents.
pub(super) fn tile_files(targets: &Targets, content_name: &str) -> Vec<PathBuf> {
    let mut out: Vec<PathBuf> = targets
        .models()
        .into_iter()
        .filter_map(|(_, p)| p.clone())
        .collect();
    if let Some(dir) = &targets.tiles3d {
        out.extend(tiles3d_contents(dir, content_name).map(|(_, p)| p));
    }
    out
}

/// The folders of a tile's pictures (`--textures`): one beside each CityGML, CityJSON and
/// CityJSONSeq output of `targets` (a tile's targets, [`tile_targets`]), named by
/// [`crate::export::texture::folder_name`]; none without `--textures`. Which pictures a tile
/// draws is known once it is derived, so a previous run's record lists them and
/// [`super::incremental::Previous::reusable`] takes its files in these folders as the tile's.
pub(super) fn picture_dirs(targets: &Targets) -> Vec<PathBuf> {
    use super::Model;
    if !targets.textures {
        return Vec::new();
    }
    let mut dirs: Vec<PathBuf> = targets
        .models()
        .into_iter()
        .filter(|(m, _)| matches!(m, Model::CityGml | Model::CityJson | Model::CityJsonSeq))
        .filter_map(|(_, p)| p.as_ref())
        .map(|p| {
            let name = crate::export::texture::folder_name(p);
            p.parent().unwrap_or(Path::new("")).join(name)
        })
        .collect();
    dirs.sort();
    dirs.dedup();
    dirs
}

/// The 3D Tiles contents of the tile named `name` in the `--tiles3d` folder `dir`: full
/// detail, then blocks.
pub(super) fn tiles3d_contents(
    dir: &Path,
    name: &str,
) -> [(crate::export::tiles3d::Detail, PathBuf); 2] {
    use crate::export::tiles3d::Detail;
    [(Detail::Full, ""), (Detail::Blocks, "-blocks")]
        .map(|(detail, sfx)| (detail, dir.join("content").join(format!("{name}{sfx}.glb"))))
}

/// The terrain content of the tile named `name` ([`Detail::Terrain`](crate::export::tiles3d::Detail)):
/// `dir/content/{name}-terrain.glb`.
pub(super) fn tiles3d_terrain(dir: &Path, name: &str) -> (crate::export::tiles3d::Detail, PathBuf) {
    let p = dir.join("content").join(format!("{name}-terrain.glb"));
    (crate::export::tiles3d::Detail::Terrain, p)
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

#[cfg(test)]
mod tests {
    use super::*;

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
}
