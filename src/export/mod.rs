//! Writers: IFC4 (STEP), CityGML 2.0, CityJSON 2.0 (and CityJSONSeq), glTF 2.0 binary, OGC 3D
//! Tiles 1.1 (GLB contents and the tileset), and a PNG preview picture.
//! Each consumes [`crate::model::Building`] values one at a time (streaming) and nothing else.

pub mod citygml;
pub mod cityjson;
#[cfg(test)]
mod datum_tests;
#[cfg(test)]
pub(crate) mod fixtures;
mod format;
mod glb;
pub mod gltf;
pub(crate) mod ids;
pub mod ifc;
pub mod lod3geom;
pub mod lod4geom;
pub(crate) mod png;
pub mod preview;
pub mod step;
#[cfg(test)]
mod terrain_tests;
pub(crate) mod texture;
pub mod tiles3d;

use std::io;

use glam::DVec3;
use thiserror::Error;

use crate::crs::Crs;
pub(crate) use crate::fsio::scratch_beside;
pub use crate::fsio::{AtomicFile, PendingFile, StreamSink};
use crate::model::{Building, Lod};

/// What every writer needs to know about the run, given once before the first building.
#[derive(Clone, Debug)]
pub struct OutputContext {
    /// The output CRS (projected).
    pub crs: Crs,
    /// Coordinates, in `crs`, of the local frame's origin: a model point p is at `origin + p`.
    pub origin: DVec3,
    /// The origin as WGS84 (lon, lat) degrees.
    pub origin_lonlat: (f64, f64),
    /// The run's level of detail (`--lod`): the buildings are already cut at it.
    pub lod: Lod,
    /// Name of the input file (for headers and descriptions).
    pub source_name: String,
    /// The run's `--seed`: written in the files' descriptions, and part of the namespace of
    /// the IFC GlobalIds.
    pub seed: u64,
    /// What the heights are measured from (`None` without terrain: buildings stand on z = 0
    /// and no datum is stated). Issue 44.
    pub vertical_datum: Option<crate::model::VerticalDatum>,
    /// The terrain of this file's extent, to be written beside the buildings (`None` without
    /// `--dem`).
    pub terrain: Option<std::sync::Arc<crate::model::Terrain>>,
}

/// The heights' datum the run states, as (EPSG code when known, name); `None` when it states
/// none (no terrain: buildings on z = 0). Each writer states it its own way (docs/terrain.md):
/// a compound CRS or a vertical CRS beside the horizontal one where a code fits, the name where
/// a name does.
pub(crate) fn vertical_datum(ctx: &OutputContext) -> Option<(Option<u32>, &str)> {
    match &ctx.vertical_datum {
        Some(crate::model::VerticalDatum::Orthometric { epsg, name }) => Some((*epsg, name)),
        None => None,
    }
}

/// Why a writer could not write.
#[derive(Debug, Error)]
pub enum ExportError {
    /// The output (or a scratch file) could not be written.
    #[error("write failed: {0}")]
    Io(#[from] io::Error),
    /// What the writer was given cannot be written as a valid file: a non-finite coordinate,
    /// a call out of order, a file over a format limit. The message says which.
    #[error("{0}")]
    Invalid(String),
}

/// [`Building::check_finite`] as the [`ExportError::Invalid`] of `writer` (e.g. `"IFC writer"`):
/// every writer calls it before writing anything of a building, unless given the buildings
/// [`Checked`].
pub(crate) fn check_finite(writer: &str, b: &Building) -> Result<(), ExportError> {
    b.check_finite()
        .map_err(|e| ExportError::Invalid(format!("{writer}: {e}")))
}

/// Buildings checked once for every writer (`Building::check_finite`): those before the
/// first that is refused, and why that one is. It borrows the buildings, so they cannot
/// change while it is held: a writer given one ([`BuildingWriter::write_checked`]) need not
/// check again.
pub struct Checked<'a> {
    buildings: &'a [Building],
    /// How many buildings are finite before the first refused one.
    ok: usize,
    refused: Option<crate::model::NotFinite>,
}

impl<'a> Checked<'a> {
    /// Checks `buildings` (in parallel).
    pub fn check(buildings: &'a [Building]) -> Checked<'a> {
        use rayon::prelude::*;
        let first_bad = if buildings.len() > 1 {
            buildings
                .par_iter()
                .position_first(|b| b.check_finite().is_err())
        } else {
            buildings.iter().position(|b| b.check_finite().is_err())
        };
        match first_bad {
            Some(i) => Checked {
                buildings,
                ok: i,
                refused: buildings[i].check_finite().err(),
            },
            None => Checked {
                buildings,
                ok: buildings.len(),
                refused: None,
            },
        }
    }

    /// The buildings before the first refused one (all of them if none is).
    pub fn finite(&self) -> &'a [Building] {
        &self.buildings[..self.ok]
    }

    /// The [`ExportError::Invalid`] of `writer` for the first refused building, if any.
    pub fn refused(&self, writer: &str) -> Result<(), ExportError> {
        match &self.refused {
            Some(e) => Err(ExportError::Invalid(format!("{writer}: {e}"))),
            None => Ok(()),
        }
    }
}

/// Buildings a writer's `write_all` renders in parallel at a time: enough to keep the cores
/// busy, few enough that their rendered bytes (a few MB a LOD4 building) stay small.
pub(crate) const PARALLEL_BATCH: usize = 16;

/// The output polygons ([`Building::polygon_count`]) past which a parallel batch ends early
/// ([`batches`]): at LOD3 a tower renders to tens of MB (27 MB of CityGML for the largest of the
/// bench input), and sixteen of them in flight in each writer were most of a run's peak memory.
pub(crate) const BATCH_POLYGONS: usize = 8_192;

/// A writer's reused per-building buffer that grew past this many bytes (a tower's) is freed
/// after its batch rather than kept for the next one, so that what the writers keep between
/// batches stays bounded (about `PARALLEL_BATCH` times this at most).
pub(crate) const SLOT_KEPT: usize = 1 << 20;

/// `buildings` cut, in order, into the batches a writer renders in parallel: at most
/// [`PARALLEL_BATCH`] buildings each, and a batch ends with the building that brings its
/// polygons to [`BATCH_POLYGONS`] (so it holds at least one). Writers append the batches'
/// buildings in order, so the cut changes no byte, only how much is rendered at once.
pub(crate) fn batches(buildings: &[Building]) -> impl Iterator<Item = &[Building]> {
    let mut rest = buildings;
    std::iter::from_fn(move || {
        if rest.is_empty() {
            return None;
        }
        let mut polygons = 0;
        let mut n = 0;
        while n < rest.len() && n < PARALLEL_BATCH && polygons < BATCH_POLYGONS {
            polygons += rest[n].polygon_count();
            n += 1;
        }
        let (batch, after) = rest.split_at(n);
        rest = after;
        Some(batch)
    })
}

/// A streaming writer of one output format.
///
/// Call order: `begin` once, `write` per building in output order, `finish` once. Output is a
/// pure function of the context and the buildings in order (no clock, no randomness), so equal
/// inputs give byte-identical files.
pub trait BuildingWriter: Send {
    /// Starts the file: header, project and site, or their equivalents, from the run's context.
    fn begin(&mut self, ctx: &OutputContext) -> Result<(), ExportError>;
    /// Writes one building (after [`BuildingWriter::begin`], in output order).
    fn write(&mut self, building: &Building) -> Result<(), ExportError>;
    /// Writes `buildings` in order: the same bytes as `write` on each, and the same first error.
    /// A writer may do its per-building work in parallel here (rayon) and append the results
    /// in order.
    fn write_all(&mut self, buildings: &[Building]) -> Result<(), ExportError> {
        buildings.iter().try_for_each(|b| self.write(b))
    }
    /// `write_all` of buildings already checked ([`Checked`]), so that a run checks them once
    /// for all its writers: the same bytes and first error. A writer that checks in its
    /// `write_all` anyway keeps this default.
    fn write_checked(&mut self, checked: &Checked<'_>) -> Result<(), ExportError> {
        // The refused building is given too, for the writer's own error.
        let n = checked.ok + usize::from(checked.refused.is_some());
        self.write_all(&checked.buildings[..n])
    }
    /// Flushes and completes the file. The writer is unusable afterwards.
    fn finish(&mut self) -> Result<(), ExportError>;
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Several batches of buildings, LOD4 and LOD3 alike, for the `write_all` checks.
    fn many_buildings() -> Vec<Building> {
        let all = fixtures::lod4_all();
        (0..3 * PARALLEL_BATCH + 5)
            .map(|i| {
                let mut b = all[i % all.len()].clone();
                b.id = crate::model::SourceId::Way(1000 + i as i64);
                b
            })
            .collect()
    }

    fn ctx() -> OutputContext {
        OutputContext {
            crs: Crs::Lambert93,
            origin: DVec3::new(574_000.25, 6_279_000.5, 140.0),
            origin_lonlat: (1.44, 43.6),
            lod: Lod::Lod4,
            source_name: "batches.osm.pbf".into(),
            seed: 3,
            vertical_datum: None,
            terrain: None,
        }
    }

    /// What one writer leaves in its sink: one `write` per building, or one `write_all`.
    fn both_ways<W: BuildingWriter>(
        make: impl Fn() -> W,
        sink: impl Fn(W) -> Vec<u8>,
        buildings: &[Building],
    ) -> [(Vec<u8>, Option<String>); 2] {
        let run = |all: bool| {
            let mut w = make();
            w.begin(&ctx()).unwrap();
            let r = if all {
                w.write_all(buildings)
            } else {
                buildings.iter().try_for_each(|b| w.write(b))
            };
            let err = match r {
                Ok(()) => {
                    w.finish().unwrap();
                    None
                }
                Err(e) => Some(e.to_string()),
            };
            (sink(w), err)
        };
        [run(false), run(true)]
    }

    #[test]
    fn write_all_writes_the_bytes_and_the_first_error_of_one_write_per_building() {
        use crate::export::citygml::CityGmlWriter;
        use crate::export::gltf::GltfWriter;
        let mut buildings = many_buildings();
        let gml = |b: &[Building]| {
            both_ways(
                || CityGmlWriter::new(Vec::new()),
                CityGmlWriter::into_inner,
                b,
            )
        };
        let glb = |b: &[Building]| {
            both_ways(
                || GltfWriter::new(Vec::new(), tempfile::tempfile().unwrap()),
                |w| w.into_inner(),
                b,
            )
        };
        let [one, all] = gml(&buildings);
        assert!(one.1.is_none() && one.0.len() > 100_000);
        assert!(one == all, "CityGML: write_all differs from write");
        let [one, all] = glb(&buildings);
        assert!(one.1.is_none() && one.0.len() > 100_000);
        assert!(one == all, "glTF: write_all differs from write");

        // A dry run's glTF writer keeps nothing but writes a GLB of the same length.
        let dry = both_ways(
            || GltfWriter::discarding(Vec::new()),
            |w| w.into_inner(),
            &buildings,
        );
        for (d, real) in dry.iter().zip([&one, &all]) {
            assert_eq!(d.0.len(), real.0.len(), "dry glTF length");
            assert_eq!(d.0[..12], real.0[..12], "GLB header");
        }

        // Towers cut the batches short: the same bytes.
        let towers = with_towers();
        let [one, all] = gml(&towers);
        assert!(one.1.is_none() && one == all, "CityGML: towers");
        let [one, all] = glb(&towers);
        assert!(one.1.is_none() && one == all, "glTF: towers");

        // A building the CityGML writer refuses, in the middle of a batch: the buildings before
        // it are written, the error is the same, nothing after it is written.
        buildings[PARALLEL_BATCH + 3].measured_height = f64::NAN;
        let [one, all] = gml(&buildings);
        let err = one.1.clone().expect("the NaN height is refused");
        assert!(err.contains("not finite"), "{err}");
        assert!(
            one == all,
            "CityGML: write_all differs from write on an error"
        );
    }

    /// [`many_buildings`] with five towers in a row (3..8), each of more than a quarter of
    /// [`BATCH_POLYGONS`] (one wall's opening repeated).
    fn with_towers() -> Vec<Building> {
        let mut buildings = many_buildings();
        let mut tower = buildings[3].clone();
        let wall = tower
            .parts
            .iter_mut()
            .flat_map(|p| p.walls.iter_mut())
            .find(|w| !w.openings.is_empty())
            .expect("a wall with an opening");
        let o = wall.openings[0].clone();
        wall.openings
            .extend(std::iter::repeat_n(o, BATCH_POLYGONS / 4));
        for (i, b) in buildings.iter_mut().enumerate().take(8).skip(3) {
            *b = Building {
                id: crate::model::SourceId::Way(1000 + i as i64),
                ..tower.clone()
            };
        }
        buildings
    }

    #[test]
    fn batches_keep_the_order_and_end_early_on_large_buildings() {
        let buildings = with_towers();
        let cut: Vec<&[Building]> = batches(&buildings).collect();
        let ids: Vec<_> = cut.iter().flat_map(|b| b.iter().map(|b| &b.id)).collect();
        let want: Vec<_> = buildings.iter().map(|b| &b.id).collect();
        assert_eq!(ids, want, "every building once, in order");
        for (k, batch) in cut.iter().enumerate() {
            assert!(!batch.is_empty() && batch.len() <= PARALLEL_BATCH);
            let polygons: Vec<usize> = batch.iter().map(Building::polygon_count).collect();
            let before_last: usize = polygons[..polygons.len() - 1].iter().sum();
            assert!(
                before_last < BATCH_POLYGONS,
                "batch {k} went on past the budget"
            );
            if k + 1 < cut.len() {
                assert!(
                    batch.len() == PARALLEL_BATCH
                        || polygons.iter().sum::<usize>() >= BATCH_POLYGONS,
                    "batch {k} ended early without reaching the budget"
                );
            }
        }
        // The towers ended the first batch early (by the fourth tower).
        assert!(
            cut[0].len() < PARALLEL_BATCH,
            "{:?}",
            cut.iter().map(|b| b.len()).collect::<Vec<_>>()
        );
        assert!(batches(&[]).next().is_none());
    }
}
