//! A regular grid of heights simplified into a TIN (triangulated irregular network) within a
//! stated vertical tolerance, clipped to a rectangle: the terrain written beside the buildings
//! (issue 44).
//!
//! # The algorithm: a right-triangulated irregular network (RTIN)
//!
//! The grid is cut into square blocks of [`BLOCK`] cells anchored at sample (0, 0). Each block
//! is two right isosceles triangles, each split in two at the midpoint of its hypotenuse, and
//! so on down to half-cells (the hierarchy of Evans, Kirkpatrick and Townsend's RTIN, as
//! Mapbox's Martini draws it). A triangle is split when its *error bound* passes the
//! tolerance. Three properties make the result usable as a terrain:
//!
//! - **A true bound.** Martini's error is the interpolation error at each midpoint alone, so a
//!   kept triangle may stray further than the tolerance from samples deeper inside it. Here a
//!   triangle's bound is its own midpoint's error plus the larger bound of its two children
//!   (a child's plane differs from its parent's by at most that midpoint error, at the
//!   midpoint): every grid sample under a kept triangle is within the tolerance of it.
//! - **No cracks, inside a block or between blocks.** The bound is stored per midpoint, as the
//!   largest of the triangles that share the hypotenuse, and it only grows upwards; so the two
//!   triangles on either side of an edge split together, and a triangle splits when any of its
//!   descendants does. Every block has the same hierarchy, and the triangles along a block's
//!   edge are the same on both sides; computing the bounds level by level over all blocks
//!   (finest first) lets a midpoint on a block's edge see both sides. The mesh of the whole
//!   grid is one conforming mesh, and any rectangle of it is cut from that one mesh.
//! - **Holes left out.** A sample without data (NaN), or past the grid's edge (the last blocks
//!   overhang), gives every triangle around it an infinite bound: those triangles split down
//!   to half-cells, and a half-cell is kept only when its three samples have data.
//!
//! A rectangle (one output file's extent) keeps the triangles inside it and cuts those across
//! its edges ([`clip_triangle`]): each cut point is computed from the uncut triangle only (its
//! edge and the rectangle's line, the height on its plane), so two files that share an edge
//! get bit-identical points along it and meet without cracks.
//!
//! Hand-written rather than taken from a crate: the crates at hand (`spade`, a dev-dependency,
//! and the Delaunay crates of the registry) triangulate points they are given and choose no
//! points; greedy insertion (Garland and Heckbert) costs a priority queue over every sample,
//! and neither keeps tiles crack-free without a shared mesh. The RTIN needs one pass over the
//! samples for the bounds (O(n)), then only walks the triangles kept.

use std::collections::HashMap;

use glam::{DVec2, DVec3};

/// Cells along a block's side: a power of two. A block of 256 cells is 256 m at 1 m, 7.7 km at
/// SRTM's 30 m; the largest kept triangle has legs of one block.
pub const BLOCK: usize = 256;
/// `BLOCK`'s exponent.
const BLOCK_BITS: u32 = BLOCK.trailing_zeros();
/// Triangle depths of a block that have a grid sample at their hypotenuse's midpoint (depth
/// `SPLITTABLE` is the half-cell, never split).
const SPLITTABLE: u32 = 2 * BLOCK_BITS;

/// A grid of heights as [`Rtin::new`] reads it (the fields of `model::ElevationGrid`).
#[derive(Clone, Copy, Debug)]
pub struct Heights<'a> {
    /// Local (x, y) of sample (0, 0).
    pub origin: DVec2,
    /// Distance between samples, metres (> 0).
    pub step: f64,
    /// Samples along x.
    pub nx: usize,
    /// Samples along y.
    pub ny: usize,
    /// Row by row from the south; NaN where there is no data. `nx * ny` long.
    pub z: &'a [f32],
    /// Where sample (0, 0) lies in the lattice of blocks, in samples from a block's corner
    /// (each below [`BLOCK`]): grids of one run that are cut from one larger lattice (the
    /// shards of a tiled run) give the same triangles where they overlap when their blocks
    /// are anchored alike, e.g. at multiples of `BLOCK * step` of the output CRS
    /// ([`block_shift`]).
    pub shift: (usize, usize),
}

/// The [`Heights::shift`] of a grid whose sample (0, 0) is at `corner` (output CRS metres,
/// on the lattice of `step`): blocks anchored at multiples of `BLOCK * step`.
pub fn block_shift(corner: DVec2, step: f64) -> (usize, usize) {
    let s = |v: f64| ((v / step).round() as i64).rem_euclid(BLOCK as i64) as usize;
    (s(corner.x), s(corner.y))
}

/// An axis-aligned rectangle of the local frame, bounds included.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Rect {
    /// South-west corner.
    pub min: DVec2,
    /// North-east corner.
    pub max: DVec2,
}

/// A triangulated surface: shared vertices, triangles counter-clockwise seen from above.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Tin {
    /// The points, local frame.
    pub vertices: Vec<DVec3>,
    /// Indices into `vertices`.
    pub triangles: Vec<[u32; 3]>,
}

/// A grid's RTIN error bounds, ready to be cut at any tolerance and any rectangle.
#[derive(Debug)]
pub struct Rtin<'a> {
    h: Heights<'a>,
    /// Blocks along x and y.
    blocks: (usize, usize),
    /// Samples along x of the padded grid (`blocks.0 * BLOCK + 1`).
    width: usize,
    /// Per sample of the padded grid: the bound of the triangles whose hypotenuse's midpoint it
    /// is (0 for samples that are no midpoint), rounded up to f32.
    bounds: Vec<f32>,
}

/// A triangle of the hierarchy in sample indices of the padded grid: `a`, `b` the hypotenuse,
/// `c` the right angle; counter-clockwise.
#[derive(Clone, Copy)]
struct Tri {
    a: (usize, usize),
    b: (usize, usize),
    c: (usize, usize),
}

impl Tri {
    fn mid(&self) -> (usize, usize) {
        ((self.a.0 + self.b.0) / 2, (self.a.1 + self.b.1) / 2)
    }

    /// The two halves, counter-clockwise again.
    fn children(&self) -> [Tri; 2] {
        let m = self.mid();
        [
            Tri {
                a: self.c,
                b: self.a,
                c: m,
            },
            Tri {
                a: self.b,
                b: self.c,
                c: m,
            },
        ]
    }

    /// The block's two top triangles, corner `(i0, j0)`.
    fn roots(i0: usize, j0: usize) -> [Tri; 2] {
        let (i1, j1) = (i0 + BLOCK, j0 + BLOCK);
        [
            Tri {
                a: (i1, j1),
                b: (i0, j0),
                c: (i1, j0),
            },
            Tri {
                a: (i0, j0),
                b: (i1, j1),
                c: (i0, j1),
            },
        ]
    }

    /// Index-space bounding box: (min i, min j, max i, max j).
    fn bbox(&self) -> (usize, usize, usize, usize) {
        let (xs, ys) = (
            [self.a.0, self.b.0, self.c.0],
            [self.a.1, self.b.1, self.c.1],
        );
        (
            xs.into_iter().min().unwrap_or(0),
            ys.into_iter().min().unwrap_or(0),
            xs.into_iter().max().unwrap_or(0),
            ys.into_iter().max().unwrap_or(0),
        )
    }
}

/// A triangle of one block's hierarchy in samples from the block's corner (each coordinate at
/// most [`BLOCK`]): [`Rtin::new`] walks the triangles of each depth from these lists instead of
/// descending from the roots once per depth.
#[derive(Clone, Copy)]
struct Offsets([u16; 6]);

impl Offsets {
    /// The triangle of the block whose corner is sample `(i0, j0)`.
    fn at(self, i0: usize, j0: usize) -> Tri {
        let o = self.0.map(usize::from);
        Tri {
            a: (i0 + o[0], j0 + o[1]),
            b: (i0 + o[2], j0 + o[3]),
            c: (i0 + o[4], j0 + o[5]),
        }
    }
}

/// Per depth below [`SPLITTABLE`], a block's triangles in the order a descent from its two
/// roots meets them (the same for every block; 131,070 triangles, 1.5 MB, made once).
static LEVELS: std::sync::LazyLock<Vec<Vec<Offsets>>> = std::sync::LazyLock::new(|| {
    fn walk(t: Tri, depth: u32, out: &mut [Vec<Offsets>]) {
        let u = |v: usize| u16::try_from(v).unwrap_or(u16::MAX);
        out[depth as usize].push(Offsets([
            u(t.a.0),
            u(t.a.1),
            u(t.b.0),
            u(t.b.1),
            u(t.c.0),
            u(t.c.1),
        ]));
        if depth + 1 < SPLITTABLE {
            for child in t.children() {
                walk(child, depth + 1, out);
            }
        }
    }
    let mut out = vec![Vec::new(); SPLITTABLE as usize];
    for root in Tri::roots(0, 0) {
        walk(root, 0, &mut out);
    }
    out
});

/// `v` as an f32 no smaller than it (bounds must not shrink when stored).
fn round_up(v: f64) -> f32 {
    let f = v as f32;
    if f64::from(f) < v && f.is_finite() && f >= 0.0 {
        f32::from_bits(f.to_bits() + 1)
    } else {
        f
    }
}

impl<'a> Rtin<'a> {
    /// Computes the error bounds of every triangle of the hierarchy over the grid: one pass
    /// per depth over all blocks, finest first.
    pub fn new(h: Heights<'a>) -> Rtin<'a> {
        let shift = (h.shift.0 % BLOCK, h.shift.1 % BLOCK);
        let h = Heights { shift, ..h };
        let cells = |n: usize, s: usize| (n.saturating_sub(1) + s).div_ceil(BLOCK).max(1);
        let blocks = (cells(h.nx, shift.0), cells(h.ny, shift.1));
        let width = blocks.0 * BLOCK + 1;
        let height = blocks.1 * BLOCK + 1;
        let mut rtin = Rtin {
            h,
            blocks,
            width,
            bounds: vec![0.0; width * height],
        };
        let levels = &*LEVELS;
        for depth in (0..SPLITTABLE).rev() {
            for bj in 0..blocks.1 {
                for bi in 0..blocks.0 {
                    let (i0, j0) = (bi * BLOCK, bj * BLOCK);
                    for t in &levels[depth as usize] {
                        rtin.bound_of(t.at(i0, j0), depth);
                    }
                }
            }
        }
        rtin
    }

    /// The height of sample `(i, j)` of the padded grid; NaN past the grid or without data.
    fn z(&self, (i, j): (usize, usize)) -> f64 {
        let (Some(i), Some(j)) = (i.checked_sub(self.h.shift.0), j.checked_sub(self.h.shift.1))
        else {
            return f64::NAN;
        };
        if i >= self.h.nx || j >= self.h.ny {
            return f64::NAN;
        }
        self.h
            .z
            .get(j * self.h.nx + i)
            .map_or(f64::NAN, |&v| f64::from(v))
    }

    fn bound(&self, (i, j): (usize, usize)) -> f32 {
        self.bounds[j * self.width + i]
    }

    /// Sets the bound of triangle `t` (at `depth`) from its own midpoint's error and its
    /// children's bounds.
    fn bound_of(&mut self, t: Tri, depth: u32) {
        let m = t.mid();
        let [za, zb, zc, zm] = [t.a, t.b, t.c, m].map(|p| self.z(p));
        let own = if [za, zb, zc, zm].iter().all(|v| v.is_finite()) {
            (zm - 0.5 * (za + zb)).abs()
        } else {
            f64::INFINITY
        };
        let below = if depth + 1 < SPLITTABLE {
            let [c1, c2] = t.children();
            f64::from(self.bound(c1.mid()).max(self.bound(c2.mid())))
        } else {
            0.0
        };
        let e = round_up(own + below);
        let slot = &mut self.bounds[m.1 * self.width + m.0];
        if e > *slot || e.is_nan() {
            *slot = if e.is_nan() { f32::INFINITY } else { e };
        }
    }

    /// The local point of padded sample `(i, j)` with its height.
    fn point(&self, (i, j): (usize, usize)) -> DVec3 {
        let (si, sj) = (self.h.shift.0 as f64, self.h.shift.1 as f64);
        let xy = self.h.origin + self.h.step * DVec2::new(i as f64 - si, j as f64 - sj);
        xy.extend(self.z((i, j)))
    }

    /// The TIN of the grid within `tolerance` metres (vertically) of every sample it covers,
    /// cut to `extent`. Vertices are numbered in the order the triangles first use them, the
    /// triangles in block order (south-west first, row by row) then down the hierarchy: the
    /// same grid, tolerance and extent give the same TIN.
    pub fn mesh(&self, tolerance: f64, extent: Rect) -> Tin {
        let mut out = TinBuilder::default();
        // The extent in sample indices, no further than the grid's last samples.
        let shift = DVec2::new(self.h.shift.0 as f64, self.h.shift.1 as f64);
        let last = DVec2::new(
            self.h.nx.saturating_sub(1) as f64,
            self.h.ny.saturating_sub(1) as f64,
        ) + shift;
        let lo = ((extent.min - self.h.origin) / self.h.step + shift).max(shift);
        let hi = ((extent.max - self.h.origin) / self.h.step + shift).min(last);
        if !(lo.x <= hi.x && lo.y <= hi.y) || hi.x < 0.0 || hi.y < 0.0 {
            return Tin::default();
        }
        let clamp = |v: f64, n: usize| (v.max(0.0) as usize / BLOCK).min(n - 1);
        let walk = Walk {
            tolerance,
            extent,
            lo,
            hi,
        };
        for bj in clamp(lo.y, self.blocks.1)..=clamp(hi.y, self.blocks.1) {
            for bi in clamp(lo.x, self.blocks.0)..=clamp(hi.x, self.blocks.0) {
                for root in Tri::roots(bi * BLOCK, bj * BLOCK) {
                    self.keep(root, 0, &walk, &mut out);
                }
            }
        }
        out.tin
    }

    /// Walks `t` (at `depth`): splits it where its bound passes the tolerance, keeps it where
    /// not (cut to the extent), skips it outside the extent or over a hole.
    fn keep(&self, t: Tri, depth: u32, w: &Walk, out: &mut TinBuilder) {
        let (i0, j0, i1, j1) = t.bbox();
        let (i0, j0, i1, j1) = (i0 as f64, j0 as f64, i1 as f64, j1 as f64);
        if i1 < w.lo.x || i0 > w.hi.x || j1 < w.lo.y || j0 > w.hi.y {
            return;
        }
        if depth < SPLITTABLE && f64::from(self.bound(t.mid())) > w.tolerance {
            for child in t.children() {
                self.keep(child, depth + 1, w, out);
            }
            return;
        }
        let p = [t.a, t.b, t.c].map(|s| self.point(s));
        if p.iter().any(|v| !v.z.is_finite()) {
            return;
        }
        if i0 >= w.lo.x && i1 <= w.hi.x && j0 >= w.lo.y && j1 <= w.hi.y {
            out.triangle(p);
        } else {
            for tri in clip_triangle(p, w.extent) {
                out.triangle(tri);
            }
        }
    }
}

/// What [`Rtin::keep`] walks with.
struct Walk {
    tolerance: f64,
    extent: Rect,
    /// The extent in sample indices.
    lo: DVec2,
    hi: DVec2,
}

/// Vertices shared by position as triangles come.
#[derive(Default)]
struct TinBuilder {
    tin: Tin,
    index: HashMap<(u64, u64), u32>,
}

impl TinBuilder {
    fn vertex(&mut self, p: DVec3) -> u32 {
        let key = (p.x.to_bits(), p.y.to_bits());
        let next = self.tin.vertices.len() as u32;
        *self.index.entry(key).or_insert_with(|| {
            self.tin.vertices.push(p);
            next
        })
    }

    fn triangle(&mut self, p: [DVec3; 3]) {
        if cross2(p[0], p[1], p[2]) <= MIN_DOUBLE_AREA {
            return;
        }
        let t = p.map(|v| self.vertex(v));
        if t[0] != t[1] && t[1] != t[2] && t[0] != t[2] {
            self.tin.triangles.push(t);
        }
    }
}

/// Twice the smallest area, m², of a triangle kept: below it a triangle is degenerate.
pub const MIN_DOUBLE_AREA: f64 = 1e-12;

/// Twice the signed area of (a, b, c) seen from above (positive counter-clockwise).
pub fn cross2(a: DVec3, b: DVec3, c: DVec3) -> f64 {
    (b.x - a.x) * (c.y - a.y) - (b.y - a.y) * (c.x - a.x)
}

/// The height at (x, y) on the plane of `p` (not vertical), always computed the same way from
/// the same triangle.
fn on_plane(p: &[DVec3; 3], x: f64, y: f64) -> f64 {
    let d = cross2(p[0], p[1], p[2]);
    let l1 = ((x - p[0].x) * (p[2].y - p[0].y) - (y - p[0].y) * (p[2].x - p[0].x)) / d;
    let l2 = ((p[1].x - p[0].x) * (y - p[0].y) - (p[1].y - p[0].y) * (x - p[0].x)) / d;
    p[0].z + l1 * (p[1].z - p[0].z) + l2 * (p[2].z - p[0].z)
}

/// Triangle `p` (counter-clockwise) cut to `r`: the convex polygon of their intersection in
/// triangles, counter-clockwise, fanned from one of its corners when it has more than three
/// (no point added inside: one there would be no grid sample, its height the uncut triangle's
/// plane's, not the terrain's; no triangle is degenerate, and every point on its
/// edges is a corner of a triangle, so a neighbour cut to the next rectangle meets it without
/// T-junctions). Every new point is
/// computed from the uncut triangle alone: from an edge taken in a fixed order (by x, then y)
/// and the rectangle's line, or a corner of the rectangle, with its height on the plane.
pub fn clip_triangle(p: [DVec3; 3], r: Rect) -> Vec<[DVec3; 3]> {
    let inside_r = |q: DVec2| q.x >= r.min.x && q.x <= r.max.x && q.y >= r.min.y && q.y <= r.max.y;
    let mut pts: Vec<DVec2> = p
        .iter()
        .map(|v| v.truncate())
        .filter(|q| inside_r(*q))
        .collect();
    for q in [
        r.min,
        DVec2::new(r.max.x, r.min.y),
        r.max,
        DVec2::new(r.min.x, r.max.y),
    ] {
        let q3 = q.extend(0.0);
        if (0..3).all(|k| cross2(p[k], p[(k + 1) % 3], q3) >= 0.0) {
            pts.push(q);
        }
    }
    for k in 0..3 {
        let (mut a, mut b) = (p[k].truncate(), p[(k + 1) % 3].truncate());
        if (b.x, b.y) < (a.x, a.y) {
            std::mem::swap(&mut a, &mut b);
        }
        for x in [r.min.x, r.max.x] {
            if (a.x - x) * (b.x - x) < 0.0 {
                let y = a.y + (x - a.x) / (b.x - a.x) * (b.y - a.y);
                if y >= r.min.y && y <= r.max.y {
                    pts.push(DVec2::new(x, y));
                }
            }
        }
        for y in [r.min.y, r.max.y] {
            if (a.y - y) * (b.y - y) < 0.0 {
                let x = a.x + (y - a.y) / (b.y - a.y) * (b.x - a.x);
                if x >= r.min.x && x <= r.max.x {
                    pts.push(DVec2::new(x, y));
                }
            }
        }
    }
    convex_fan(&p, pts)
}

/// The convex polygon of `pts` (in any order, maybe repeated) in counter-clockwise triangles on
/// the plane of `p`.
fn convex_fan(p: &[DVec3; 3], mut pts: Vec<DVec2>) -> Vec<[DVec3; 3]> {
    pts.sort_by(|u, v| {
        (u.x, u.y)
            .partial_cmp(&(v.x, v.y))
            .unwrap_or(std::cmp::Ordering::Equal)
    });
    pts.dedup();
    if pts.len() < 3 {
        return Vec::new();
    }
    let centre = pts.iter().copied().sum::<DVec2>() / pts.len() as f64;
    let angle = |q: &DVec2| (q.y - centre.y).atan2(q.x - centre.x);
    pts.sort_by(|u, v| angle(u).total_cmp(&angle(v)));
    let lift = |q: DVec2| {
        // The triangle's own corners keep their own heights.
        match p.iter().find(|v| v.x == q.x && v.y == q.y) {
            Some(v) => *v,
            None => q.extend(on_plane(p, q.x, q.y)),
        }
    };
    let ring: Vec<DVec3> = pts.into_iter().map(lift).collect();
    let (ring, n) = (&ring, ring.len());
    let fan = |apex: usize| {
        (1..n - 1).map(move |k| {
            let (b, c) = ((apex + k) % n, (apex + k + 1) % n);
            [ring[apex], ring[b], ring[c]]
        })
    };
    // Fanned from the corner whose thinnest triangle is the widest (the first such corner):
    // no point is added, so every corner is a grid sample or a cut point on the rectangle's
    // edge, and a corner in line with two others is no apex while another can be.
    let thinnest = |apex: usize| {
        fan(apex)
            .map(|t| cross2(t[0], t[1], t[2]))
            .fold(f64::INFINITY, f64::min)
    };
    let apex = (1..n).fold(0, |best, k| {
        if thinnest(k) > thinnest(best) {
            k
        } else {
            best
        }
    });
    fan(apex)
        .filter(|t| cross2(t[0], t[1], t[2]) > MIN_DOUBLE_AREA)
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A grid of `nx` x `ny` samples, 1 m apart from (10, 20), heights from `f(x, y)`.
    fn grid(nx: usize, ny: usize, f: impl Fn(f64, f64) -> f64) -> (Vec<f32>, DVec2) {
        let origin = DVec2::new(10.0, 20.0);
        let z = (0..ny)
            .flat_map(|j| (0..nx).map(move |i| (i, j)))
            .map(|(i, j)| f(i as f64, j as f64) as f32)
            .collect();
        (z, origin)
    }

    fn heights(z: &[f32], origin: DVec2, nx: usize, ny: usize) -> Heights<'_> {
        Heights {
            origin,
            step: 1.0,
            nx,
            ny,
            z,
            shift: (0, 0),
        }
    }

    fn whole(h: &Heights<'_>) -> Rect {
        Rect {
            min: h.origin,
            max: h.origin + DVec2::new((h.nx - 1) as f64, (h.ny - 1) as f64) * h.step,
        }
    }

    /// For every sample under a triangle: the worst distance to the TIN, and how many samples
    /// with data no triangle covers; panics on a triangle that is clockwise, degenerate or over
    /// a sample without data.
    fn check(h: &Heights<'_>, tin: &Tin, tolerance: f64) -> (f64, usize) {
        let mut covered = vec![false; h.nx * h.ny];
        let mut worst: f64 = 0.0;
        for t in &tin.triangles {
            let p = t.map(|k| tin.vertices[k as usize]);
            assert!(cross2(p[0], p[1], p[2]) > MIN_DOUBLE_AREA, "{p:?}");
            let g = p.map(|v| (v.truncate() - h.origin) / h.step);
            let lo = g.iter().fold(DVec2::splat(f64::MAX), |a, v| a.min(*v));
            let hi = g.iter().fold(DVec2::splat(f64::MIN), |a, v| a.max(*v));
            for j in (lo.y.ceil() as usize)..=(hi.y.floor() as usize).min(h.ny - 1) {
                for i in (lo.x.ceil() as usize)..=(hi.x.floor() as usize).min(h.nx - 1) {
                    let q = (h.origin + h.step * DVec2::new(i as f64, j as f64)).extend(0.0);
                    if (0..3).any(|k| cross2(p[k], p[(k + 1) % 3], q) < -1e-9) {
                        continue;
                    }
                    let z = h.z[j * h.nx + i];
                    assert!(z.is_finite(), "a triangle over the hole at ({i}, {j})");
                    covered[j * h.nx + i] = true;
                    worst = worst.max((on_plane(&p, q.x, q.y) - f64::from(z)).abs());
                }
            }
        }
        assert!(worst <= tolerance + 1e-9, "{worst} > {tolerance}");
        let missed = (0..h.nx * h.ny)
            .filter(|&k| h.z[k].is_finite() && !covered[k])
            .count();
        (worst, missed)
    }

    fn hill(x: f64, y: f64) -> f64 {
        let (dx, dy) = (x - 150.0, y - 90.0);
        40.0 * (-(dx * dx + dy * dy) / 5000.0).exp() + 0.02 * x
    }

    #[test]
    fn a_plane_is_two_triangles_a_block() {
        let (z, o) = grid(257, 257, |x, y| 3.0 + 0.1 * x - 0.2 * y);
        let h = heights(&z, o, 257, 257);
        let tin = Rtin::new(h).mesh(0.01, whole(&h));
        assert_eq!(tin.triangles.len(), 2);
        assert_eq!(tin.vertices.len(), 4);
        assert_eq!(check(&h, &tin, 0.01).1, 0);
    }

    #[test]
    fn a_hill_and_a_cliff_stay_within_the_tolerance_and_cover_the_grid() {
        let (nx, ny) = (301, 183);
        let cliff = |x: f64, y: f64| hill(x, y) + if x + 0.3 * y > 200.0 { 12.0 } else { 0.0 };
        for f in [hill as fn(f64, f64) -> f64, cliff] {
            let (z, o) = grid(nx, ny, f);
            let h = heights(&z, o, nx, ny);
            let rtin = Rtin::new(h);
            let mut sizes = Vec::new();
            for tol in [0.05, 0.5, 2.0] {
                let tin = rtin.mesh(tol, whole(&h));
                let (_, missed) = check(&h, &tin, tol);
                assert_eq!(missed, 0, "tolerance {tol}");
                sizes.push(tin.triangles.len());
            }
            // Simplified, and more so at a larger tolerance.
            assert!(sizes[0] > sizes[1] && sizes[1] > sizes[2], "{sizes:?}");
            assert!(sizes[1] < nx * ny / 4, "{sizes:?}");
        }
    }

    #[test]
    fn holes_are_left_out_and_the_rest_covered() {
        let (nx, ny) = (120, 90);
        let (mut z, o) = grid(nx, ny, hill);
        // A round hole and one lone sample without data.
        for j in 0..ny {
            for i in 0..nx {
                let (dx, dy) = (i as f64 - 60.0, j as f64 - 40.0);
                if dx * dx + dy * dy < 100.0 || (i, j) == (7, 70) {
                    z[j * nx + i] = f32::NAN;
                }
            }
        }
        let h = heights(&z, o, nx, ny);
        let tin = Rtin::new(h).mesh(0.5, whole(&h));
        check(&h, &tin, 0.5);
        // Every sample whose four cells all have data is covered.
        let ok = |i: usize, j: usize| z[j * nx + i].is_finite();
        let mut uncovered_inner = 0;
        let mut covered = vec![false; nx * ny];
        for t in &tin.triangles {
            for k in t {
                let g = (tin.vertices[*k as usize].truncate() - o).round();
                covered[g.y as usize * nx + g.x as usize] = true;
            }
        }
        for j in 1..ny - 1 {
            for i in 1..nx - 1 {
                let all = (j - 1..=j + 1).all(|b| (i - 1..=i + 1).all(|a| ok(a, b)));
                // A vertex or inside a triangle: checked through the areas below.
                if all && !covered[j * nx + i] {
                    uncovered_inner += 1;
                }
            }
        }
        // Samples inside big triangles are not vertices: count the area instead.
        let area: f64 = tin
            .triangles
            .iter()
            .map(|t| {
                let p = t.map(|k| tin.vertices[k as usize]);
                0.5 * cross2(p[0], p[1], p[2])
            })
            .sum();
        let full_cells = (0..ny - 1)
            .flat_map(|j| (0..nx - 1).map(move |i| (i, j)))
            .filter(|&(i, j)| ok(i, j) && ok(i + 1, j) && ok(i, j + 1) && ok(i + 1, j + 1))
            .count() as f64;
        assert!(area >= full_cells - 1e-6, "{area} < {full_cells}");
        assert!(area < (nx * ny) as f64, "{area}");
        let _ = uncovered_inner;
    }

    #[test]
    fn rectangles_that_share_an_edge_share_its_points() {
        let (nx, ny) = (400, 300);
        let (z, o) = grid(nx, ny, |x, y| {
            hill(x, y) + 0.3 * (x * 0.37).sin() * (y * 0.21).cos()
        });
        let h = heights(&z, o, nx, ny);
        let rtin = Rtin::new(h);
        // Cut lines off the samples, one through a block's edge.
        let xs = [o.x - 3.0, o.x + 137.4, o.x + 256.0, o.x + 500.0];
        let ys = [o.y - 3.0, o.y + 101.7, o.y + 400.0];
        let mut tiles = Vec::new();
        for wy in ys.windows(2) {
            for wx in xs.windows(2) {
                let r = Rect {
                    min: DVec2::new(wx[0], wy[0]),
                    max: DVec2::new(wx[1], wy[1]),
                };
                tiles.push((r, rtin.mesh(0.3, r)));
            }
        }
        let whole_tin = rtin.mesh(0.3, whole(&h));
        let area = |t: &Tin| -> f64 {
            t.triangles
                .iter()
                .map(|k| {
                    let p = k.map(|k| t.vertices[k as usize]);
                    0.5 * cross2(p[0], p[1], p[2])
                })
                .sum()
        };
        let sum: f64 = tiles.iter().map(|(_, t)| area(t)).sum();
        assert!(
            (sum - area(&whole_tin)).abs() < 1e-6,
            "{sum} vs {}",
            area(&whole_tin)
        );
        for (_, t) in &tiles {
            check(&h, t, 0.3);
        }
        // The points on each inner cut line, from either side, bit for bit.
        let on = |t: &Tin, x: Option<f64>, y: Option<f64>, r: &Rect| -> Vec<[u64; 3]> {
            let mut v: Vec<[u64; 3]> = t
                .vertices
                .iter()
                .filter(|p| x.is_none_or(|x| p.x == x) && y.is_none_or(|y| p.y == y))
                .filter(|p| p.x >= r.min.x && p.x <= r.max.x && p.y >= r.min.y && p.y <= r.max.y)
                .map(|p| [p.x.to_bits(), p.y.to_bits(), p.z.to_bits()])
                .collect();
            v.sort_unstable();
            v
        };
        let mut lines = 0;
        for (ra, ta) in &tiles {
            for (rb, tb) in &tiles {
                if ra.max.x == rb.min.x && ra.min.y == rb.min.y {
                    let x = Some(ra.max.x);
                    let a = on(ta, x, None, ra);
                    assert!(a.len() > 3);
                    assert_eq!(a, on(tb, x, None, rb), "x = {:?}", x);
                    lines += 1;
                }
                if ra.max.y == rb.min.y && ra.min.x == rb.min.x {
                    let y = Some(ra.max.y);
                    let a = on(ta, None, y, ra);
                    assert!(a.len() > 3);
                    assert_eq!(a, on(tb, None, y, rb), "y = {:?}", y);
                    lines += 1;
                }
            }
        }
        // Two vertical lines in each of two rows, three horizontal ones between them.
        assert_eq!(lines, 2 * 2 + 3);
    }

    #[test]
    fn two_grids_of_one_lattice_give_the_same_triangles_where_they_meet() {
        // A big grid, and a piece of it starting 300 samples east, each anchored
        // at the same block lattice: in the blocks the piece holds whole, one mesh.
        let (nx, ny) = (700, 300);
        let (z, o) = grid(nx, ny, |x, y| hill(x, y) + 0.2 * (x * 0.3).sin());
        let big = heights(&z, o, nx, ny);
        let (px, py, pnx, pny) = (300, 0, 400, 300);
        let zp: Vec<f32> = (0..pny)
            .flat_map(|j| (0..pnx).map(move |i| (i, j)))
            .map(|(i, j)| z[(j + py) * nx + i + px])
            .collect();
        let piece = Heights {
            origin: o + DVec2::new(px as f64, py as f64),
            nx: pnx,
            ny: pny,
            z: &zp,
            shift: (px % BLOCK, py % BLOCK),
            ..big
        };
        let r = Rect {
            min: o + DVec2::new(520.0, 60.3),
            max: o + DVec2::new(640.5, 250.0),
        };
        let a = Rtin::new(big).mesh(0.25, r);
        let b = Rtin::new(piece).mesh(0.25, r);
        assert!(a.triangles.len() > 20);
        assert_eq!(a, b);
        assert_eq!(block_shift(DVec2::new(-1.0, 513.0), 1.0), (255, 1));
    }

    #[test]
    fn a_cut_adds_points_on_the_rectangle_only() {
        // Every vertex of a mesh cut off the samples is a grid sample (its own height) or lies
        // on the rectangle's edge: a cut triangle fanned from its centre added points inside,
        // on the triangle's plane, metres off the grid on a hill (issue 44).
        let (nx, ny) = (300, 200);
        let (z, o) = grid(nx, ny, |x, y| hill(x, y) + 0.3 * (x * 0.37).sin());
        let h = heights(&z, o, nx, ny);
        let r = Rect {
            min: o + DVec2::new(13.3, 7.6),
            max: o + DVec2::new(271.2, 180.45),
        };
        let tin = Rtin::new(h).mesh(2.0, r);
        let mut cut = 0;
        for v in &tin.vertices {
            let g = v.truncate() - o;
            let on_edge = [v.x - r.min.x, r.max.x - v.x, v.y - r.min.y, r.max.y - v.y]
                .iter()
                .any(|d| d.abs() < 1e-9);
            if on_edge {
                cut += 1;
                continue;
            }
            assert_eq!(
                g,
                g.round(),
                "{v} is no sample and not on the rectangle's edge"
            );
            let sample = z[g.y as usize * nx + g.x as usize];
            assert_eq!(v.z, f64::from(sample), "{v}");
        }
        assert!(cut > 10 && tin.vertices.len() > 2 * cut, "{cut} cut points");
        check(&h, &tin, 2.0);
    }

    #[test]
    fn the_same_grid_gives_the_same_tin() {
        let (z, o) = grid(200, 150, hill);
        let h = heights(&z, o, 200, 150);
        let a = Rtin::new(h).mesh(0.2, whole(&h));
        let b = Rtin::new(h).mesh(0.2, whole(&h));
        assert_eq!(a, b);
    }

    #[test]
    fn an_extent_outside_the_grid_gives_nothing() {
        let (z, o) = grid(20, 20, hill);
        let h = heights(&z, o, 20, 20);
        let r = Rect {
            min: o - 100.0,
            max: o - 50.0,
        };
        assert!(Rtin::new(h).mesh(0.2, r).triangles.is_empty());
        let tiny = Heights {
            nx: 1,
            ny: 1,
            z: &z[..1],
            ..h
        };
        assert!(Rtin::new(tiny).mesh(0.2, whole(&tiny)).triangles.is_empty());
    }
}
