//! The ground a run stands on (issue 44): `--dem` files opened before any reading, every lot's
//! ground ([`prepare::ground::sample_all`]) and the run's elevation grid once the lots are
//! selected, or `--ground-height` for all; the vertical datum the writers are given and the
//! report's `terrain` line.

use std::path::Path;

use super::{RunError, RunState};
use crate::input::dem::{vertical_name, DemSet};
use crate::model::{Lod, VerticalDatum};
use crate::prepare;
use crate::report::NO_TERRAIN;

/// How many uncovered buildings the error names.
const NAMED: usize = 10;

/// The `--dem` files, opened (headers and georeferencing), or `None` without.
pub(super) fn open(opts: &super::Options) -> Result<Option<DemSet>, RunError> {
    if opts.dem.is_empty() {
        return Ok(None);
    }
    if opts.ground_height.is_some() {
        return Err(RunError::Usage(
            "--ground-height and --dem: the DEM gives the ground; give one of them".into(),
        ));
    }
    DemSet::open(&opts.dem)
        .map(Some)
        .map_err(|e| RunError::Input(e.to_string()))
}

/// The files as a list for messages: `a.tif, b.tif`.
fn listed(paths: &[&Path]) -> String {
    paths
        .iter()
        .map(|p| p.display().to_string())
        .collect::<Vec<_>>()
        .join(", ")
}

impl RunState<'_> {
    /// Sets every lot's ground, the site's elevation grid and vertical datum, and the report's
    /// terrain: from `dems`, else `--ground-height`, else nothing (z = 0). A building of the
    /// run that the DEMs do not cover is an input error naming the files and the first
    /// buildings, before anything is written.
    pub(super) fn seat(&mut self, dems: Option<&DemSet>) -> Result<(), RunError> {
        if let Some(h) = self.opts.ground_height {
            let g = (h * 1000.0).round() / 1000.0;
            for l in &mut self.site.lots {
                l.ground = g;
            }
            self.site.vertical_datum = Some(VerticalDatum::Orthometric {
                epsg: None,
                name: "heights above the ground level given by --ground-height (datum not \
                       stated)"
                    .into(),
            });
            self.report.terrain = Some(format!(
                "--ground-height {g} m: every building stands at {g} m (no DEM)"
            ));
            return Ok(());
        }
        let Some(dems) = dems else {
            self.report.terrain = Some(NO_TERRAIN.into());
            return Ok(());
        };
        let input = |e: crate::input::dem::DemError| RunError::Input(e.to_string());
        let framed = dems.framed(self.site.crs, self.site.origin);
        // The run's buildings, and at LOD3 and above the neighbours their facades look at.
        let wanted = if self.opts.lod >= Lod::Lod3 {
            prepare::near_selected(
                &self.site.lots,
                &self.in_run,
                super::incremental::NEIGHBOUR_MARGIN_M,
            )
        } else {
            self.in_run.clone()
        };
        // Grounds, LOD3's patches and the grid in one pass over the DEM (each strip or tile
        // decoded about once); the errors reported in the order of three passes. The grid
        // only serves the terrain written beside the buildings: none with `--no-terrain`.
        let in_run = &self.in_run;
        let (of_ground, of_run) = (|i: usize| wanted[i], |i: usize| in_run[i]);
        let sampled = prepare::ground::sample_all(
            &self.site.lots,
            &prepare::ground::Wanted {
                grounds: &of_ground,
                patches: (self.opts.lod >= Lod::Lod3).then_some(&of_run as _),
                grid: (!self.opts.no_terrain).then_some(&of_run as _),
            },
            &framed,
        );
        let grounds = sampled.grounds.map_err(input)?;
        let uncovered: Vec<String> = self
            .site
            .lots
            .iter()
            .zip(&grounds)
            .zip(&self.in_run)
            .filter(|((_, g), run)| **run && g.is_none())
            .map(|((l, _), _)| l.id.to_string())
            .collect();
        if !uncovered.is_empty() {
            let more = uncovered.len().saturating_sub(NAMED);
            return Err(RunError::Input(format!(
                "{}: the DEM does not cover {} building(s) of the run: {}{} (no height under \
                 the whole footprint: outside every file, or only nodata); give DEM tiles \
                 that cover them, or leave them out with --bbox",
                listed(&dems.paths()),
                uncovered.len(),
                uncovered[..uncovered.len().min(NAMED)].join(", "),
                if more > 0 {
                    format!(" and {more} more")
                } else {
                    String::new()
                }
            )));
        }
        for (l, g) in self.site.lots.iter_mut().zip(grounds) {
            // A neighbour outside the DEMs (not written by this run) stays on z = 0.
            l.ground = g.unwrap_or(0.0);
        }
        // At LOD3 and above the facades look at the terrain along their walls (the entrance
        // at the terrain, no opening under it): each building of the run has its patch.
        let patches = sampled.patches.map_err(input)?;
        if self.opts.lod >= Lod::Lod3 {
            for (l, p) in self.site.lots.iter_mut().zip(patches) {
                l.terrain = p.map(std::sync::Arc::new);
            }
        }
        let grid = sampled.grid.map_err(input)?;
        if !self.opts.no_terrain {
            self.site.elevation = grid;
        }
        // The decoded DEM is not sampled again: its memory goes to the buildings.
        dems.release();
        let epsg = dems.vertical_epsg().map_err(input)?;
        self.site.vertical_datum = Some(VerticalDatum::Orthometric {
            epsg: epsg.map(u32::from),
            name: epsg.map_or_else(
                || "DEM heights (the DEM states no vertical datum)".to_string(),
                vertical_name,
            ),
        });
        let grid = self.site.elevation.as_ref().map_or(String::new(), |g| {
            format!("; elevation grid {} x {} at {:.2} m", g.nx, g.ny, g.step)
        });
        self.report.terrain = Some(format!(
            "DEM {} ({}): each building stands on the lowest terrain under its footprint{grid}",
            listed(&dems.paths()),
            epsg.map_or_else(|| "vertical datum not stated".to_string(), vertical_name),
        ));
        Ok(())
    }
}
