//! The terrain written beside the buildings (issue 44): the run's elevation grid
//! (`prepare::Site::elevation`) simplified once into RTIN error bounds
//! ([`crate::geometry::tin`]), then cut for each output file to its extent.
//!
//! A file's extent: for a tile (`--tile`), its square of the output CRS grid grown to hold the
//! footprints of its buildings (a building belongs to the tile of its representative point and
//! may reach past the square); for an untiled run, the footprints' bounding box and
//! [`MARGIN_M`] around it. Each edge is then moved onto a line of the grid's samples: an edge
//! of the tile's square to the nearest line (two tiles move their shared edge alike), an edge
//! set by the footprints or the margin outwards (the buildings stay covered). So every point
//! the cut makes along the extent's edge is at a grid sample, its height the kept triangle's
//! there, within the tolerance of the sample (off the sample lines, a cut point on a long
//! triangle over steep ground was metres off the DEM). Both are cut to the grid. Tiles cut from
//! the one mesh meet without cracks: along a shared edge both have the same points, bit for bit
//! (the points are put on the output's millimetre grid, the same way on both sides).
//!
//! Terrain is written whenever the run has an elevation grid, unless `--no-terrain`: a DEM
//! given to seat the buildings is a terrain worth showing, and one flag turns it off.

use std::sync::Arc;

use glam::{DVec2, DVec3};

use crate::geometry::tin::{self, Heights, Rect, Rtin};
use crate::model::{grid_key, on_grid, ElevationGrid, Terrain};
use crate::prepare::Lot;

/// The default largest vertical distance between the terrain written and the DEM's samples
/// (`--terrain-tolerance`), metres: about a DEM's own vertical accuracy (a lidar DEM's 0.1-0.3
/// m, SRTM's several metres), and a few times fewer triangles than 0.1 m on hilly ground.
pub const DEFAULT_TOLERANCE: f64 = 0.5;

/// Metres of terrain around the buildings of an untiled run.
pub const MARGIN_M: f64 = 25.0;

/// The run's ground, ready to be cut per file.
pub(crate) struct Ground<'a> {
    rtin: Rtin<'a>,
    tolerance: f64,
    /// The grid's sample (0, 0) and step (local frame): the lines an extent's edges are put on.
    lattice: (DVec2, f64),
    /// The output CRS's tile size (`--tile`), if tiled, and the local origin's CRS coordinates.
    tile: Option<u32>,
    origin: DVec2,
}

impl<'a> Ground<'a> {
    /// The ground of `grid` at `tolerance` metres; `None` for an empty or malformed grid.
    pub(crate) fn new(
        grid: &'a ElevationGrid,
        tolerance: f64,
        tile: Option<u32>,
        origin: DVec2,
    ) -> Option<Ground<'a>> {
        let ok = grid.step.is_finite()
            && grid.step > 0.0
            && grid.origin.is_finite()
            && grid.nx >= 2
            && grid.ny >= 2
            && grid.z.len() == grid.nx * grid.ny
            && tolerance.is_finite()
            && tolerance >= 0.0;
        if !ok {
            return None;
        }
        let rtin = Rtin::new(Heights {
            origin: grid.origin,
            step: grid.step,
            nx: grid.nx,
            ny: grid.ny,
            z: &grid.z,
            // Blocks anchored on the output CRS, so that the shards of a tiled run, each with
            // its own grid, cut one mesh.
            shift: tin::block_shift(grid.origin + origin, grid.step),
        });
        Some(Ground {
            rtin,
            tolerance,
            lattice: (grid.origin, grid.step),
            tile,
            origin,
        })
    }

    /// The terrain of the file holding `lots` (of the tile at `cell` when tiled); `None` when
    /// it has no triangle.
    pub(crate) fn terrain(&self, lots: &[Lot], cell: (i64, i64)) -> Option<Arc<Terrain>> {
        let extent = self.extent(lots, cell)?;
        let tin = self.rtin.mesh(self.tolerance, extent);
        let terrain = on_the_grid(tin.vertices, &tin.triangles, self.tolerance);
        (!terrain.triangles.is_empty()).then(|| Arc::new(terrain))
    }

    /// The extent of a file (see the module documentation).
    fn extent(&self, lots: &[Lot], cell: (i64, i64)) -> Option<Rect> {
        let footprints = footprint_bounds(lots);
        let (o, step) = self.lattice;
        // `v` (along the axis whose sample 0 is at `o`) on a line of samples: the nearest, or
        // the next one down or up (a value already on a line, to a few ulps, stays on it).
        let line = |v: f64, o: f64, how: fn(f64) -> f64| {
            let k = (v - o) / step;
            let r = k.round();
            if (k - r).abs() <= 1e-9 * r.abs().max(1.0) {
                o + r * step
            } else {
                o + how(k) * step
            }
        };
        let near = |p: DVec2| DVec2::new(line(p.x, o.x, f64::round), line(p.y, o.y, f64::round));
        let down = |p: DVec2| DVec2::new(line(p.x, o.x, f64::floor), line(p.y, o.y, f64::floor));
        let up = |p: DVec2| DVec2::new(line(p.x, o.x, f64::ceil), line(p.y, o.y, f64::ceil));
        match self.tile {
            Some(size) => {
                let size = f64::from(size.max(1));
                let min = DVec2::new(cell.0 as f64, cell.1 as f64) * size - self.origin;
                let square = Rect {
                    min: near(min),
                    max: near(min + size),
                };
                Some(match footprints {
                    Some(f) => Rect {
                        min: square.min.min(down(f.min)),
                        max: square.max.max(up(f.max)),
                    },
                    None => square,
                })
            }
            None => footprints.map(|f| Rect {
                min: down(f.min - MARGIN_M),
                max: up(f.max + MARGIN_M),
            }),
        }
    }
}

/// Heights from a function of the output CRS's (easting, northing), sampled every `step`
/// metres over the run's buildings: the elevation grid of a run that reads no DEM, for tests
/// and programs that embed citygen ([`super::Options::ground_fn`]). The grid's samples are on
/// the CRS's lattice of `step`, so every shard of a run samples the same points. NaN heights
/// are holes.
#[derive(Clone)]
pub struct GroundFn {
    /// Metres between samples (> 0).
    pub step: f64,
    /// The height at (easting, northing) of the output CRS, metres.
    pub height: Arc<dyn Fn(f64, f64) -> f64 + Send + Sync>,
}

impl std::fmt::Debug for GroundFn {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("GroundFn")
            .field("step", &self.step)
            .finish()
    }
}

impl GroundFn {
    /// The grid over `lots` (local frame around `origin`, CRS metres) and `2 * MARGIN_M`
    /// around them; `None` without lots or with a bad step.
    pub(crate) fn grid(&self, lots: &[Lot], origin: DVec2) -> Option<ElevationGrid> {
        let b = footprint_bounds(lots)?;
        let step = self.step;
        if !(step.is_finite() && step > 0.0) {
            return None;
        }
        let lo = ((b.min + origin - 2.0 * MARGIN_M) / step).floor();
        let hi = ((b.max + origin + 2.0 * MARGIN_M) / step).ceil();
        let (nx, ny) = ((hi.x - lo.x) as usize + 1, (hi.y - lo.y) as usize + 1);
        let z = (0..ny)
            .flat_map(|j| (0..nx).map(move |i| (i, j)))
            .map(|(i, j)| {
                let p = (lo + DVec2::new(i as f64, j as f64)) * step;
                (self.height)(p.x, p.y) as f32
            })
            .collect();
        Some(ElevationGrid {
            origin: lo * step - origin,
            step,
            nx,
            ny,
            z,
        })
    }
}

/// The bounding box of every outline and part of `lots` (local frame).
fn footprint_bounds(lots: &[Lot]) -> Option<Rect> {
    let (mut lo, mut hi) = (DVec2::splat(f64::INFINITY), DVec2::splat(f64::NEG_INFINITY));
    let polygons = lots.iter().flat_map(|l| {
        l.polygons
            .iter()
            .chain(l.parts.iter().flat_map(|p| &p.polygons))
    });
    for p in polygons {
        for q in &p.outer {
            if q.is_finite() {
                lo = lo.min(*q);
                hi = hi.max(*q);
            }
        }
    }
    (lo.x <= hi.x && lo.y <= hi.y).then_some(Rect { min: lo, max: hi })
}

/// The TIN as the files write it: every point on the output's millimetre grid, points that
/// fall on one grid point made one, and triangles that became degenerate dropped.
fn on_the_grid(vertices: Vec<DVec3>, triangles: &[[u32; 3]], tolerance: f64) -> Terrain {
    let mut index = std::collections::HashMap::with_capacity(vertices.len());
    let mut out = Terrain {
        tolerance,
        ..Terrain::default()
    };
    let remap: Vec<u32> = vertices
        .into_iter()
        .map(|v| {
            let snapped = DVec3::new(on_grid(v.x), on_grid(v.y), on_grid(v.z));
            let next = out.vertices.len() as u32;
            *index.entry(grid_key(snapped)).or_insert_with(|| {
                out.vertices.push(snapped);
                next
            })
        })
        .collect();
    for t in triangles {
        let t = t.map(|k| remap[k as usize]);
        let p = t.map(|k| out.vertices[k as usize]);
        if tin::cross2(p[0], p[1], p[2]) > MIN_WRITTEN_DOUBLE_AREA {
            out.triangles.push(t);
        }
    }
    out
}

/// Twice the smallest area (m²) of a triangle written: one square millimetre.
pub(crate) const MIN_WRITTEN_DOUBLE_AREA: f64 = 2e-6;

#[cfg(test)]
mod tests {
    use super::*;

    /// A grid of `n` x `n` samples `step` apart from `origin`, heights `f(x, y)` (local).
    pub(crate) fn grid_of(
        origin: DVec2,
        step: f64,
        n: usize,
        f: impl Fn(f64, f64) -> f32,
    ) -> ElevationGrid {
        let z = (0..n * n)
            .map(|k| {
                let p = origin + step * DVec2::new((k % n) as f64, (k / n) as f64);
                f(p.x, p.y)
            })
            .collect();
        ElevationGrid {
            origin,
            step,
            nx: n,
            ny: n,
            z,
        }
    }

    fn lot_at(lo: DVec2, hi: DVec2) -> Lot {
        let d = hi - lo;
        crate::prepare::morph::tests::rect(1, lo.x, lo.y, d.x, d.y, "yes")
    }

    /// Whether `p` lies in (or on) a triangle of `t`, and the TIN's height there.
    fn height_on(t: &Terrain, p: DVec2) -> Option<f64> {
        t.triangles.iter().find_map(|k| {
            let v = k.map(|i| t.vertices[i as usize]);
            let q = p.extend(0.0);
            let w = [
                tin::cross2(v[1], v[2], q),
                tin::cross2(v[2], v[0], q),
                tin::cross2(v[0], v[1], q),
            ];
            if w.iter().any(|w| *w < -1e-9) {
                return None;
            }
            let s: f64 = w.iter().sum();
            Some((w[0] * v[0].z + w[1] * v[1].z + w[2] * v[2].z) / s)
        })
    }

    /// Every vertex of `t` is at a sample of `grid` (the millimetre grid's point nearest it),
    /// within `tolerance` of it: the cut points along the extent's edges too.
    fn at_samples(t: &Terrain, grid: &ElevationGrid, tolerance: f64) {
        for v in &t.vertices {
            let g = (v.truncate() - grid.origin) / grid.step;
            let s = g.round();
            assert!((g - s).abs().max_element() < 1e-3, "{v} is at no sample");
            let z = grid.get(s.x as usize, s.y as usize).unwrap();
            assert!((v.z - z).abs() <= tolerance + 1e-3, "{v}: the sample {z}");
        }
    }

    #[test]
    fn tiles_cover_their_buildings_and_share_their_edges() {
        // Local origin at (500_000, 4_000_000); 100 m tiles; a hill with a cliff.
        let origin = DVec2::new(500_000.0, 4_000_000.0);
        let grid = grid_of(DVec2::new(-0.5, -0.5), 1.0, 302, |x, y| {
            (30.0 * (-((x - 120.0).powi(2) + (y - 80.0).powi(2)) / 4000.0).exp()
                + if x > 170.0 { 8.0 } else { 0.0 }) as f32
        });
        let ground = Ground::new(&grid, 0.5, Some(100), origin).unwrap();
        // A building of tile (5000, 40000) reaching 7 m into the next tile east: that tile's
        // terrain grows to hold it.
        let b = lot_at(DVec2::new(80.0, 10.0), DVec2::new(107.0, 30.0));
        let grown = ground
            .terrain(std::slice::from_ref(&b), (5000, 40000))
            .unwrap();
        for p in &b.polygons[0].outer {
            let h = height_on(&grown, *p).expect("footprint covered");
            let g = grid.height_at(*p).unwrap();
            assert!((h - g).abs() <= 0.5 + 0.01, "{h} vs {g}");
        }
        // Tiles with buildings inside their squares meet along x = 100.5 (the line of samples
        // nearest the squares' edge at 100) with the same points.
        let inside = lot_at(DVec2::new(20.0, 10.0), DVec2::new(40.0, 30.0));
        let west = ground
            .terrain(std::slice::from_ref(&inside), (5000, 40000))
            .unwrap();
        let east = ground.terrain(&[], (5001, 40000)).unwrap();
        let on_edge = |t: &Terrain| -> Vec<(i64, i64, i64)> {
            let mut v: Vec<_> = t
                .vertices
                .iter()
                .filter(|p| p.x == 100.5)
                .map(|p| grid_key(*p))
                .collect();
            v.sort_unstable();
            v
        };
        let (w, e) = (on_edge(&west), on_edge(&east));
        assert!(e.len() > 2);
        assert_eq!(w, e);
        // The grown tile has no edge at x = 100.5 but covers past it.
        assert!(on_edge(&grown).len() < e.len());
        assert!(height_on(&grown, DVec2::new(105.0, 90.0)).is_some());
        for t in [&west, &east, &grown] {
            at_samples(t, &grid, 0.5);
            for k in &t.triangles {
                let v = k.map(|i| t.vertices[i as usize]);
                assert!(tin::cross2(v[0], v[1], v[2]) > MIN_WRITTEN_DOUBLE_AREA);
            }
        }
    }

    #[test]
    fn an_untiled_run_gets_its_buildings_and_a_margin() {
        let grid = grid_of(DVec2::new(-100.0, -100.0), 2.0, 200, |x, y| {
            (0.1 * x + 0.05 * y) as f32
        });
        let ground = Ground::new(&grid, 0.5, None, DVec2::ZERO).unwrap();
        let b = lot_at(DVec2::new(0.0, 0.0), DVec2::new(20.0, 10.0));
        let t = ground.terrain(std::slice::from_ref(&b), (0, 0)).unwrap();
        let (lo, hi) = t.vertices.iter().fold(
            (DVec2::splat(f64::MAX), DVec2::splat(f64::MIN)),
            |(lo, hi), v| (lo.min(v.truncate()), hi.max(v.truncate())),
        );
        // The margin's edges moved out to the lines of samples (every 2 m from -100).
        assert_eq!((lo, hi), (DVec2::splat(-26.0), DVec2::new(46.0, 36.0)));
        at_samples(&t, &grid, 0.5);
        assert!(ground.terrain(&[], (0, 0)).is_none());
    }
}
