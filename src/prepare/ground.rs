//! Where each lot stands (issue 44): its ground height from the `--dem` files, and the
//! elevation grid of the run's extent.
//!
//! A building's base is the lowest terrain under its footprint (OSM Simple 3D Buildings: its
//! `height` counts from there, so on a slope the low side's walls reach the ground and the
//! high side's lower part is below it). The lowest point is searched at every DEM pixel centre
//! inside the footprint (outlines and parts, holes excluded) and along every ring where a
//! bilinear height can be lowest (`sample_edge`): bilinear heights have no minimum inside a
//! pixel's cell, and along a straight edge they are one quadratic between two crossings of
//! pixel-centre lines, so the search finds the true minimum (to a nodata hole's renormalised
//! weights).
//! Samples over the DEM's nodata are skipped; a footprint with no known sample, or with a
//! sample outside every DEM, is *uncovered*. The base is rounded to the millimetre grid the
//! outputs are written at.

use glam::DVec2;
use rayon::prelude::*;

use super::Lot;
use crate::geometry::Polygon;
use crate::input::dem::{DemError, Framed, Sample, Sampler};
use crate::model::ElevationGrid;

/// Margin around the run's buildings covered by the elevation grid ([`sample_all`]), metres.
pub const GRID_MARGIN: f64 = 50.0;

/// The most samples the elevation grid ([`sample_all`]) holds (2048 x 2048): a larger extent takes coarser
/// steps than the DEM's.
pub const GRID_MAX_CELLS: usize = 1 << 22;

/// The most pixel-line crossings sampled along one ring edge.
const MAX_EDGE_SAMPLES: usize = 20_000;

/// Lots per parallel batch of [`sample_all`]'s grounds (one sampler each).
const BATCH: usize = 64;

/// How far above the lowest height so far a lower bound of a pixel's or a cell's heights must
/// be for [`ground_under`] to skip their samples, metres: a sample a few ulps past the pixel
/// or cell weighs a pixel beyond it by about 1e-12, so it cannot fall this far below the bound.
const SKIP_SLACK: f64 = 1e-6;

/// The lowest known height of the samples taken so far.
struct Lowest(f64);

impl Lowest {
    /// Takes one sample; false for one outside every DEM.
    fn take(&mut self, v: Sample) -> bool {
        match v {
            Sample::Value(z) => {
                self.0 = self.0.min(z);
                true
            }
            Sample::NoData => true,
            Sample::Outside => false,
        }
    }

    /// Whether heights of at least `floor` cannot lower the minimum.
    fn below(&self, floor: Option<f64>) -> bool {
        floor.is_some_and(|f| f > self.0 + SKIP_SLACK)
    }
}

/// The ground of one footprint, or `None` where the DEMs do not cover it.
///
/// With one DEM in the run's CRS ([`Framed::single_local`]) the same samples are taken, less
/// those that cannot lower the minimum (so the same result, bit for bit): the rings' corners
/// first, then each pixel centre inside whose own height is not above the lowest so far, then
/// each stretch of a ring between two pixel-centre lines whose cell's four pixels are not all
/// above it (a bilinear height is a weighted mean of its cell's four pixels).
fn ground_under(
    polygons: &[&Polygon],
    framed: &Framed<'_>,
    s: &mut Sampler<'_>,
) -> Result<Option<f64>, DemError> {
    let mut low = Lowest(f64::INFINITY);
    let bounded = framed.single_local();
    let (mut lo, mut hi) = (DVec2::splat(f64::INFINITY), DVec2::splat(f64::NEG_INFINITY));
    for p in polygons {
        for ring in p.rings() {
            for a in ring {
                lo = lo.min(*a);
                hi = hi.max(*a);
                if bounded && !low.take(s.sample(*a)?) {
                    return Ok(None);
                }
            }
        }
    }
    let edges = |low: &mut Lowest, s: &mut Sampler<'_>| -> Result<bool, DemError> {
        for p in polygons {
            for ring in p.rings() {
                for (k, a) in ring.iter().enumerate() {
                    let b = ring[(k + 1) % ring.len()];
                    if !sample_edge(*a, b, framed, s, low, bounded)? {
                        return Ok(false);
                    }
                }
            }
        }
        Ok(true)
    };
    if !bounded && !edges(&mut low, s)? {
        return Ok(None);
    }
    if !(lo.is_finite() && hi.is_finite()) {
        return Ok(None);
    }
    for c in framed.centres_in(lo, hi) {
        if bounded {
            let z = s.pixel_height(c.file, c.i, c.j)?;
            if z.is_finite() && low.below(Some(f64::from(z))) {
                continue;
            }
        }
        if polygons.iter().any(|p| p.contains(c.p)) && !low.take(s.sample(c.p)?) {
            return Ok(None);
        }
    }
    if bounded && !edges(&mut low, s)? {
        return Ok(None);
    }
    let low = low.0;
    Ok(low.is_finite().then(|| (low * 1000.0).round() / 1000.0))
}

/// Gives `low` the heights of edge `a`→`b` where the lowest can be: its ends, every crossing
/// of a pixel-centre line ([`Framed::crossings`]), and between two of them (one quadratic
/// there) the middle and, where the heights curve upwards, the quadratic's vertex. False as
/// soon as a sample is outside every DEM. `bounded` ([`ground_under`]): `a` was taken
/// already, and a stretch between two crossings whose cell cannot lower the minimum
/// ([`Sampler::cell_floor`]) is skipped.
fn sample_edge(
    a: DVec2,
    b: DVec2,
    framed: &Framed<'_>,
    s: &mut Sampler<'_>,
    low: &mut Lowest,
    bounded: bool,
) -> Result<bool, DemError> {
    let mut ts = vec![0.0];
    ts.extend(framed.crossings(a, b, MAX_EDGE_SAMPLES));
    ts.push(1.0);
    let value = |v: Sample| match v {
        Sample::Value(z) => Some(z),
        _ => None,
    };
    let at = |t: f64| if t == 0.0 { a } else { a.lerp(b, t) };
    let mut prev = None;
    if !bounded {
        let v = s.sample(a)?;
        if !low.take(v) {
            return Ok(false);
        }
        prev = Some(v);
    }
    for w in ts.windows(2) {
        let (t0, t1) = (w[0], w[1]);
        if bounded && low.below(s.cell_floor(at(t0), at(t1))?) {
            prev = None;
            continue;
        }
        let prev_v = match prev {
            Some(v) => v,
            None => {
                let v = s.sample(at(t0))?;
                if !low.take(v) {
                    return Ok(false);
                }
                v
            }
        };
        let tm = (t0 + t1) / 2.0;
        let (mid, end) = (s.sample(a.lerp(b, tm))?, s.sample(a.lerp(b, t1))?);
        if !low.take(mid) || !low.take(end) {
            return Ok(false);
        }
        if let (Some(y0), Some(ym), Some(y1)) = (value(prev_v), value(mid), value(end)) {
            let curve = y0 - 2.0 * ym + y1;
            let tv = tm - (t1 - t0) / 2.0 * (y1 - y0) / (2.0 * curve);
            if curve > 0.0 && tv > t0 && tv < t1 && !low.take(s.sample(a.lerp(b, tv))?) {
                return Ok(false);
            }
        }
        prev = Some(end);
    }
    Ok(true)
}

/// Every polygon of a lot: its outline's and its parts'.
fn footprint(lot: &Lot) -> Vec<&Polygon> {
    lot.polygons
        .iter()
        .chain(lot.parts.iter().flat_map(|p| &p.polygons))
        .collect()
}

/// A key along the Z-order curve of a lot's centre (64 m cells).
fn z_order(lot: &Lot) -> u64 {
    let Some((lo, hi)) = lot.bounds() else {
        return u64::MAX;
    };
    let c = (lo + hi) / 128.0;
    let q = |v: f64| (v + f64::from(1u32 << 31)).clamp(0.0, f64::from(u32::MAX)) as u32;
    let (x, y) = (q(c.x), q(c.y));
    let mut k = 0u64;
    for b in 0..32 {
        k |= u64::from((x >> b) & 1) << (2 * b);
        k |= u64::from((y >> b) & 1) << (2 * b + 1);
    }
    k
}

/// Where the elevation grid's samples are: its first sample, step and size.
struct GridFrame {
    lo: DVec2,
    step: f64,
    nx: usize,
    ny: usize,
}

/// The frame of the elevation grid over the lots `wanted` selects, `None` without a lot.
fn grid_frame(
    lots: &[Lot],
    wanted: impl Fn(usize) -> bool,
    framed: &Framed<'_>,
) -> Option<GridFrame> {
    let (mut lo, mut hi) = (DVec2::splat(f64::INFINITY), DVec2::splat(f64::NEG_INFINITY));
    for (i, l) in lots.iter().enumerate() {
        if let Some((a, b)) = l.bounds().filter(|_| wanted(i)) {
            lo = lo.min(a);
            hi = hi.max(b);
        }
    }
    if !(lo.is_finite() && hi.is_finite()) {
        return None;
    }
    lo -= DVec2::splat(GRID_MARGIN);
    hi += DVec2::splat(GRID_MARGIN);
    let size = hi - lo;
    let fine = framed.cell_size().max(0.1);
    let coarse = (size.x * size.y / GRID_MAX_CELLS as f64).sqrt();
    let mut step = (fine.max(coarse) * 1000.0).ceil() / 1000.0;
    let cells = |step: f64| {
        (
            (size.x / step).ceil() as usize + 1,
            (size.y / step).ceil() as usize + 1,
        )
    };
    while {
        let (nx, ny) = cells(step);
        nx * ny > GRID_MAX_CELLS
    } {
        step *= 1.01;
    }
    let (nx, ny) = cells(step);
    Some(GridFrame { lo, step, nx, ny })
}

impl GridFrame {
    /// Row `j` of the grid: the DEM's heights, NaN where none has one.
    fn row(&self, j: usize, s: &mut Sampler<'_>) -> Result<Vec<f32>, DemError> {
        s.heights(self.nx, |i| {
            self.lo + DVec2::new(i as f64, j as f64) * self.step
        })
    }

    /// The grid of its rows (in row order; the first error in row order).
    fn grid(self, rows: Vec<Result<Vec<f32>, DemError>>) -> Result<ElevationGrid, DemError> {
        let mut z = Vec::with_capacity(self.nx * self.ny);
        for r in rows {
            z.extend(r?);
        }
        Ok(ElevationGrid {
            origin: self.lo,
            step: self.step,
            nx: self.nx,
            ny: self.ny,
            z,
        })
    }
}

/// What [`sample_all`] samples: each lot's ground, and optionally each lot's terrain patch
/// and the elevation grid, over the lots each selects.
pub struct Wanted<'w> {
    /// The lots whose ground is sampled ([`sample_all`]'s grounds).
    pub grounds: &'w (dyn Fn(usize) -> bool + Sync),
    /// The lots whose terrain patch is sampled (in [`sample_all`]), if any.
    pub patches: Option<&'w (dyn Fn(usize) -> bool + Sync)>,
    /// The lots the elevation grid covers (the elevation grid ([`sample_all`])), if one is made.
    pub grid: Option<&'w (dyn Fn(usize) -> bool + Sync)>,
}

/// The results of [`sample_all`], each as its own function gives it.
pub struct Sampled {
    /// As [`sample_all`]'s grounds.
    pub grounds: Result<Vec<Option<f64>>, DemError>,
    /// As [`sample_all`]'s terrain patches (all `None` when not wanted).
    pub patches: Result<Vec<Option<ElevationGrid>>, DemError>,
    /// As the elevation grid ([`sample_all`]) (`None` when not wanted).
    pub grid: Result<Option<ElevationGrid>, DemError>,
}

/// One piece of [`sample_all`]'s work.
enum Job {
    Ground(usize),
    Patch(usize),
    Row(usize),
}

/// One piece of [`sample_all`]'s results.
enum Done {
    Ground(usize, Result<Option<f64>, DemError>),
    Patch(usize, Result<Option<ElevationGrid>, DemError>),
    Row(usize, Result<Vec<f32>, DemError>),
}

/// Every lot's ground, its LOD3 terrain patch and the elevation grid in one pass: every lot
/// and grid row sampled in the order of the DEM chunks it reads ([`Framed::chunk_key`]), so
/// that each strip or tile is decoded about once for all three and the cache stays small
/// (three passes would decode the DEM three times, or hold all of it).
pub fn sample_all(lots: &[Lot], wanted: &Wanted<'_>, framed: &Framed<'_>) -> Sampled {
    let frame = wanted.grid.and_then(|g| grid_frame(lots, g, framed));
    let patch_step = framed.cell_size().clamp(PROFILE_FINEST, PROFILE_STEP);
    let lot_key = |i: usize| {
        let chunk = lots[i]
            .bounds()
            .map_or(u64::MAX, |(lo, hi)| framed.chunk_key((lo + hi) / 2.0));
        (chunk, z_order(&lots[i]), i)
    };
    let mut jobs: Vec<((u64, u64, usize), Job)> = Vec::new();
    for i in (0..lots.len()).filter(|&i| (wanted.grounds)(i)) {
        jobs.push((lot_key(i), Job::Ground(i)));
    }
    if let Some(p) = wanted.patches {
        for i in (0..lots.len()).filter(|&i| p(i)) {
            jobs.push((lot_key(i), Job::Patch(i)));
        }
    }
    if let Some(f) = &frame {
        for j in 0..f.ny {
            let mid = f.lo + DVec2::new(f.nx as f64 / 2.0, j as f64) * f.step;
            jobs.push(((framed.chunk_key(mid), u64::MAX, j), Job::Row(j)));
        }
    }
    jobs.sort_by_key(|(k, job)| (*k, matches!(job, Job::Patch(_))));
    let done: Vec<Done> = jobs
        .par_chunks(BATCH)
        .flat_map_iter(|batch| {
            let mut s = framed.sampler();
            batch
                .iter()
                .map(|(_, job)| match *job {
                    Job::Ground(i) => {
                        Done::Ground(i, ground_under(&footprint(&lots[i]), framed, &mut s))
                    }
                    Job::Patch(i) => Done::Patch(i, profile(&lots[i], patch_step, &mut s)),
                    Job::Row(j) => Done::Row(
                        j,
                        frame.as_ref().map_or(Ok(Vec::new()), |f| f.row(j, &mut s)),
                    ),
                })
                .collect::<Vec<_>>()
        })
        .collect();
    let (mut grounds, mut patches, mut rows) = (
        Vec::with_capacity(done.len()),
        Vec::new(),
        Vec::with_capacity(frame.as_ref().map_or(0, |f| f.ny)),
    );
    for d in done {
        match d {
            Done::Ground(i, r) => grounds.push((i, r)),
            Done::Patch(i, r) => patches.push((i, r)),
            Done::Row(j, r) => rows.push((j, r)),
        }
    }
    rows.sort_by_key(|(j, _)| *j);
    Sampled {
        grounds: in_lot_order(lots.len(), grounds),
        patches: in_lot_order(lots.len(), patches),
        grid: frame.map_or(Ok(None), |f| {
            f.grid(rows.into_iter().map(|(_, r)| r).collect()).map(Some)
        }),
    }
}

/// The finest step of a lot's terrain patch (in [`sample_all`]), metres.
const PROFILE_FINEST: f64 = 0.5;
/// The coarsest step of a lot's terrain patch before its size coarsens it, metres.
const PROFILE_STEP: f64 = 2.0;
/// The most samples one lot's terrain patch holds (64 x 64, 16 KiB): a larger footprint gets
/// coarser steps. The patches are held with the lots for the run: a house on a 1 m DEM holds
/// about 1 KiB.
pub const PROFILE_MAX_CELLS: usize = 1 << 12;

/// One lot's terrain patch for [`sample_all`] (`None` for a lot without bounds).
fn profile(lot: &Lot, fine: f64, s: &mut Sampler<'_>) -> Result<Option<ElevationGrid>, DemError> {
    let (mut lo, mut hi) = (DVec2::splat(f64::INFINITY), DVec2::splat(f64::NEG_INFINITY));
    for p in footprint(lot) {
        let (a, b) = p.bounds();
        lo = lo.min(a);
        hi = hi.max(b);
    }
    if !(lo.is_finite() && hi.is_finite()) {
        return Ok(None);
    }
    let size = hi - lo;
    let coarse = (size.x * size.y / PROFILE_MAX_CELLS as f64).sqrt();
    let step = fine.max(coarse);
    let (nx, ny) = (
        ((size.x / step).ceil() as usize + 3).min(4 * PROFILE_MAX_CELLS),
        ((size.y / step).ceil() as usize + 3).min(4 * PROFILE_MAX_CELLS),
    );
    let origin = lo - DVec2::splat(step);
    let mut z = Vec::with_capacity(nx * ny);
    for j in 0..ny {
        for i in 0..nx {
            let p = origin + DVec2::new(i as f64, j as f64) * step;
            z.push(match s.sample(p)? {
                Sample::Value(v) => v as f32,
                _ => f32::NAN,
            });
        }
    }
    Ok(Some(ElevationGrid {
        origin,
        step,
        nx,
        ny,
        z,
    }))
}

/// Per-lot results (lot index, value) gathered in any order, as one value per lot: the error
/// of the first lot in lot order that failed, so the message does not depend on the threads.
fn in_lot_order<T>(
    n: usize,
    found: Vec<(usize, Result<Option<T>, DemError>)>,
) -> Result<Vec<Option<T>>, DemError> {
    let mut out: Vec<Option<T>> = (0..n).map(|_| None).collect();
    let mut first_err: Option<(usize, DemError)> = None;
    for (i, r) in found {
        match r {
            Ok(g) => out[i] = g,
            Err(e) => {
                if first_err.as_ref().is_none_or(|(j, _)| i < *j) {
                    first_err = Some((i, e));
                }
            }
        }
    }
    match first_err {
        Some((_, e)) => Err(e),
        None => Ok(out),
    }
}

#[cfg(test)]
mod tests {
    use glam::DVec2;

    use super::ground_under;
    use crate::crs::Crs;
    use crate::geometry::Polygon;
    use crate::input::dem::DemSet;
    use crate::rng::Rng;
    use crate::testkit::geotiff::GeoTiff;

    /// The skipping search of one DEM in the run's CRS finds, bit for bit, the lowest height
    /// that the full search finds (here the same file given twice, which takes every sample),
    /// on rough ground with nodata holes, for turned polygons with courtyards, and footprints
    /// reaching off the DEM stay uncovered.
    #[test]
    fn skipping_samples_keeps_the_lowest_bit_for_bit() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("d.tif");
        let mut tiff =
            GeoTiff::projected(32632, (499_900.0, 5_000_100.0), 2.0, (100, 100), |x, y| {
                let (u, v) = (x - 499_900.0, y - 5_000_000.0);
                40.0 + 0.3 * u - 0.2 * v + 3.0 * (u * 0.37).sin() * (v * 0.23).cos()
            });
        for k in (0..tiff.values.len()).step_by(97) {
            tiff.values[k] = f64::NAN;
        }
        tiff.write(&p).unwrap();
        let utm = Crs::Utm {
            zone: 32,
            north: true,
        };
        let origin = DVec2::new(500_000.0, 5_000_000.0);
        let one = DemSet::open(std::slice::from_ref(&p)).unwrap();
        let two = DemSet::open(&[p.clone(), p]).unwrap();
        let (f1, f2) = (one.framed(utm, origin), two.framed(utm, origin));
        assert!(f1.single_local() && !f2.single_local());
        let (mut s1, mut s2) = (f1.sampler(), f2.sampler());
        let mut rng = Rng::new(7, 0);
        let (mut found, mut off) = (0, 0);
        for _ in 0..400 {
            let c = DVec2::new(rng.range(-110.0, 110.0), rng.range(-10.0, 110.0));
            let (w, h, a) = (
                rng.range(0.5, 30.0),
                rng.range(0.5, 30.0),
                rng.range(0.0, 3.2),
            );
            let turn = |x: f64, y: f64| c + DVec2::from_angle(a).rotate(DVec2::new(x, y));
            let outer = vec![turn(0.0, 0.0), turn(w, 0.0), turn(w, h), turn(0.0, h)];
            let holes = vec![vec![
                turn(w * 0.3, h * 0.3),
                turn(w * 0.3, h * 0.6),
                turn(w * 0.6, h * 0.6),
                turn(w * 0.6, h * 0.3),
            ]];
            let poly = Polygon { outer, holes };
            let (g1, g2) = (
                ground_under(&[&poly], &f1, &mut s1).unwrap(),
                ground_under(&[&poly], &f2, &mut s2).unwrap(),
            );
            assert_eq!(g1.map(f64::to_bits), g2.map(f64::to_bits), "{poly:?}");
            if g1.is_some() {
                found += 1;
            } else {
                off += 1;
            }
        }
        assert!(found > 200 && off > 20, "{found} found, {off} off the DEM");
    }
}
