//! One building of a prepared site, for `citygen kb edit`: the site read and prepared as a run
//! prepares it (`load_site`), a lot explained (`explain_lot`, what `kb explain` says) and
//! derived into a GLB held in memory (`derive_glb`, the run's own derivation: inference from
//! the neighbours, the KB's rulesets and SELEX programs, at LOD3 the surroundings).

use std::io::Write;
use std::sync::atomic::{AtomicU64, Ordering};

use glam::DVec3;

use super::{file_name, infer_from_neighbours, read_source, zone_for, RunError, Source};
use crate::derive::{Generator, Rules};
use crate::export::gltf::GltfWriter;
use crate::export::{BuildingWriter, ExportError, OutputContext};
use crate::grammar::Caps;
use crate::kb::{tools::Explanation, BoundaryZones, KnowledgeBase};
use crate::model::Lod;
use crate::prepare::{self, Site};
use crate::report::Report;

/// The site of `source` as [`super::run`] prepares it without `--crs`, `--bbox` or `--tile`:
/// read, projected to the UTM zone of its centre, cleaned, parts grouped, fronts assigned. The
/// source's file name comes with it.
pub(crate) fn load_site(source: &Source) -> Result<(Site, String), RunError> {
    let name = match source {
        Source::Osm(p) | Source::Shp { path: p, .. } => file_name(p),
    };
    let mut report = Report::default();
    let read = read_source(source, None, None, &mut report)?;
    // Errors name the input as given (two `b.shp` in two folders are two inputs).
    let given = match source {
        Source::Osm(p) | Source::Shp { path: p, .. } => p.display().to_string(),
    };
    let crs = zone_for(&read.footprints, read.source_crs, None, &given)?;
    let mut site = prepare::prepare(read.footprints, read.source_crs, Some(crs), &mut report);
    site.boundaries = read.boundaries;
    prepare::assign_fronts(&mut site, &read.streets, read.source_crs);
    Ok((site, name))
}

/// The lots of `site` after the inference `kb`'s zones ask for (a copy: the site stays as
/// read, so that another KB infers afresh).
fn inferred_lots(kb: &KnowledgeBase, boundaries: &BoundaryZones, site: &Site) -> Vec<prepare::Lot> {
    let mut lots = site.lots.clone();
    let _ = infer_from_neighbours(kb, boundaries, &mut lots, None);
    lots
}

/// What `kb explain` says of lot `index` of `site` under `kb` and `seed` (the lot's own tags
/// after inference; its zone, values and appearance as the generator picks them). `None` for
/// an index out of range.
pub(crate) fn explain_lot(
    kb: &KnowledgeBase,
    site: &Site,
    index: usize,
    seed: u64,
) -> Option<Explanation> {
    let boundaries = BoundaryZones::new(kb, &site.boundaries);
    let lots = inferred_lots(kb, &boundaries, site);
    let lot = lots.get(index)?;
    Some(crate::kb::tools::explain_at(
        kb,
        &boundaries,
        lot.lonlat.0,
        lot.lonlat.1,
        &lot.tags,
        lot.id.seed_value(),
        seed,
    ))
}

/// Scratch files of concurrent previews get distinct names.
static PREVIEWS: AtomicU64 = AtomicU64::new(0);

/// Lot `index` of `site` derived at `lod` with `kb` (its rulesets and SELEX programs loaded
/// as a run loads them; at LOD3 and above its touching neighbours derived at LOD2 first, for
/// party walls) and written as a binary glTF into memory by the run's glTF writer. The
/// scratch file the writer spools to lies in `scratch_dir`. Errors: the index, a KB whose
/// SELEX programs do not load, a building that cannot be derived (the reason), a write error.
pub(crate) fn derive_glb(
    kb: KnowledgeBase,
    site: &Site,
    index: usize,
    lod: Lod,
    seed: u64,
    source_name: &str,
    scratch_dir: &std::path::Path,
) -> Result<Vec<u8>, RunError> {
    let caps = Caps {
        facades: lod >= Lod::Lod3,
        ..Caps::default()
    };
    let mut generator = Generator::new(kb, Rules::Kb, lod, seed, caps);
    generator.match_boundaries(&site.boundaries);
    let lots = inferred_lots(&generator.kb, generator.boundaries(), site);
    let Some(lot) = lots.get(index) else {
        return Err(RunError::Usage(format!("no lot {index}")));
    };
    generator
        .load_selex()
        .map_err(|e| RunError::Input(e.to_string()))?;
    generator.load_rulesets();
    if lod >= Lod::Lod3 {
        let mut selected = vec![false; lots.len()];
        selected[index] = true;
        let near = prepare::near_selected(&lots, &selected, super::incremental::NEIGHBOUR_MARGIN_M);
        generator.surroundings = generator.neighbours_of(&lots, |i| near[i]);
    }
    let (building, _) = generator
        .generate(lot)
        .map_err(|why| RunError::Input(format!("{}: {why}", lot.id)))?;
    let n = PREVIEWS.fetch_add(1, Ordering::Relaxed);
    let target = scratch_dir.join(format!("preview{n}.glb"));
    let output = |e: ExportError| RunError::Output {
        path: target.clone(),
        source: e,
    };
    let (scratch, left) =
        crate::export::scratch_beside(&target, "bin").map_err(|e| output(e.into()))?;
    let mut w = GltfWriter::new(Vec::new(), scratch);
    let ctx = OutputContext {
        crs: site.crs,
        origin: DVec3::new(site.origin.x, site.origin.y, 0.0),
        origin_lonlat: site.origin_lonlat,
        lod,
        source_name: source_name.to_string(),
        seed,
        vertical_datum: None,
        terrain: None,
    };
    let written = w
        .begin(&ctx)
        .and_then(|()| w.write(&building))
        .and_then(|()| w.finish());
    let mut bytes = w.into_inner();
    if let Some(p) = left {
        let _ = std::fs::remove_file(p);
    }
    written.map_err(output)?;
    bytes.flush().map_err(|e| output(e.into()))?;
    Ok(bytes)
}
