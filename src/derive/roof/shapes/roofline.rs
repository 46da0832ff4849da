//! The roof line over a footprint edge, read from a roof's faces.

use std::collections::HashSet;

use glam::{DVec2, DVec3};

use crate::geometry::{CellHash, Polygon};
use crate::model::Face;

/// Where the walls meet a roof: the vertices of the roof's boundary (those of the roof faces'
/// edges that no other face runs back along: the eaves, gable lines and the points on them),
/// each with the footprint edge it stands on.
pub(crate) struct RoofLine<'a> {
    footprint: &'a Polygon,
    /// Boundary vertices above the eave with the footprint edge (ring, edge) nearest to them
    /// in plan, within [`RoofLine::TOL`].
    above: Vec<(DVec3, (usize, usize))>,
    /// Boundary vertices on the eave (z = 0) the same way: the foot of a valley that comes
    /// down to the eave in the middle of a wall (a butterfly's end wall, a sawtooth's side).
    low: Vec<(DVec3, (usize, usize))>,
    /// Every boundary vertex (for the heights at the footprint's corners), sorted by x.
    boundary: Vec<DVec3>,
    /// No x is NaN, so that `boundary` is ordered by `<` on x too.
    sorted: bool,
}

impl<'a> RoofLine<'a> {
    /// How far in plan (metres) a roof boundary vertex may lie from its footprint edge: twice
    /// the skeleton's collinear tolerance ([`crate::geometry::skeleton::COLLINEAR_ABS`]), since
    /// a roof built on a side with a vertex a few millimetres off straight puts the side's
    /// gable point on the side's chord.
    pub(crate) const TOL: f64 = 2.0 * crate::geometry::skeleton::COLLINEAR_ABS;

    /// The boundary of `faces` (edges compared on exact coordinates) over `footprint`.
    pub(crate) fn new(faces: &[Face], footprint: &'a Polygon) -> RoofLine<'a> {
        type K = (u64, u64, u64);
        let key = |p: DVec3| (p.x.to_bits(), p.y.to_bits(), p.z.to_bits());
        let rings = || {
            faces
                .iter()
                .flat_map(|f| std::iter::once(&f.outer).chain(f.holes.iter()))
        };
        let mut edges: HashSet<(K, K), CellHash> =
            HashSet::with_capacity_and_hasher(rings().map(Vec::len).sum(), CellHash);
        for r in rings() {
            for i in 0..r.len() {
                edges.insert((key(r[i]), key(r[(i + 1) % r.len()])));
            }
        }
        let mut boundary: Vec<DVec3> = Vec::new();
        for r in rings() {
            for i in 0..r.len() {
                let (u, v) = (r[i], r[(i + 1) % r.len()]);
                if !edges.contains(&(key(v), key(u))) {
                    boundary.push(u);
                    boundary.push(v);
                }
            }
        }
        boundary.sort_by(|p, q| {
            p.x.total_cmp(&q.x)
                .then(p.y.total_cmp(&q.y))
                .then(p.z.total_cmp(&q.z))
        });
        boundary.dedup();
        let mut above = Vec::new();
        let mut low = Vec::new();
        for p in &boundary {
            let g = p.truncate();
            let mut best: Option<(f64, (usize, usize))> = None;
            for (ri, r) in footprint.rings().enumerate() {
                let n = r.len();
                for i in 0..n {
                    let (a, b) = (r[i], r[(i + 1) % n]);
                    let d = b - a;
                    let l2 = d.length_squared();
                    if l2 <= 0.0 {
                        continue;
                    }
                    let s = ((g - a).dot(d) / l2).clamp(0.0, 1.0);
                    let dist = g.distance(a + d * s);
                    if dist <= Self::TOL && best.is_none_or(|(bd, _)| dist < bd) {
                        best = Some((dist, (ri, i)));
                    }
                }
            }
            if let Some((_, e)) = best {
                if p.z > 1e-6 {
                    above.push((*p, e));
                } else {
                    low.push((*p, e));
                }
            }
        }
        let sorted = boundary.iter().all(|p| !p.x.is_nan());
        RoofLine {
            footprint,
            above,
            low,
            boundary,
            sorted,
        }
    }

    /// The roof line over edge `i` of ring `ring` of the footprint (`a → b`), relative to the
    /// eave (z = 0): the roof boundary's vertices standing on that edge (nearer to it than to
    /// any other), ordered from `b` back to `a`, with `b` and `a` first and last (at the
    /// highest roof vertex there, 0 if none is higher). A wall on this edge closes the roof when
    /// its outline is `a(base), b(base), then these points`. A vertex on the eave is one of them
    /// only between two above it (a valley coming down to the eave in the middle of the wall).
    pub(crate) fn over(&self, ring: usize, i: usize) -> Vec<DVec3> {
        let Some(r) = self.footprint.rings().nth(ring) else {
            return Vec::new();
        };
        let (a, b) = (r[i], r[(i + 1) % r.len()]);
        let d = b - a;
        let len2 = d.length_squared();
        if len2 <= 0.0 || !len2.is_finite() {
            return vec![b.extend(0.0), a.extend(0.0)];
        }
        let tol = 1e-6 * len2.sqrt().max(1.0);
        // The roof at the corners: its boundary vertices standing there, within a grid step
        // (the footprint's corner rounded to the grid: the roof was built on it before); else
        // those within the grid's vertex gap (a vertex the grid moved farther). Near ones win,
        // so that a roof vertex a few millimetres from a corner (a gable point just past a
        // kink of the side) stays a vertex of the line instead of being pulled onto the
        // corner, which would leave the wall short of the roof.
        let snap = tol.max(1.0 / crate::model::GRID_STEPS_PER_M);
        let gap = tol.max(crate::model::MIN_VERTEX_GAP);
        // The boundary is sorted by x: only the points within (a little more than) `gap` of a
        // corner in x can be within `gap` of it.
        let near = |c: DVec2| -> &[DVec3] {
            if !self.sorted {
                return &self.boundary;
            }
            let m = gap * (1.0 + 1e-6) + 1e-6;
            let lo = self.boundary.partition_point(|p| p.x < c.x - m);
            let hi = self.boundary.partition_point(|p| p.x <= c.x + m);
            &self.boundary[lo..hi.max(lo)]
        };
        // The highest z within `r` of corner `c` (not within `r` of `other`), if any.
        let top_at = |c: DVec2, other: Option<DVec2>, r: f64| -> Option<f64> {
            near(c)
                .iter()
                .filter(|p| {
                    let g = p.truncate();
                    g.distance(c) <= r && other.is_none_or(|o| g.distance(o) > r)
                })
                .map(|p| p.z)
                .reduce(f64::max)
        };
        // Exactly at a corner, only a vertex above the eave counts: the eave's own corner is
        // always there.
        let raised = |z: Option<f64>| z.filter(|&z| z > 1e-6);
        let (za, ca) = match raised(top_at(a, None, snap)) {
            Some(z) => (z, snap),
            None => (top_at(a, None, gap).unwrap_or(0.0).max(0.0), gap),
        };
        let (zb, cb) = match raised(top_at(b, Some(a), snap)) {
            Some(z) => (z, snap),
            None => (top_at(b, Some(a), gap).unwrap_or(0.0).max(0.0), gap),
        };
        let mut mid: Vec<(f64, DVec3)> = Vec::new();
        for &(p, e) in self.above.iter().chain(&self.low) {
            let g = p.truncate();
            if e != (ring, i) || g.distance(a) <= ca || g.distance(b) <= cb {
                continue;
            }
            let s = (g - a).dot(d) / len2;
            if s > 0.0 && s < 1.0 {
                mid.push((s, p));
            }
        }
        mid.sort_by(|x, y| y.0.total_cmp(&x.0).then(x.1.z.total_cmp(&y.1.z)));
        mid.dedup_by(|x, y| x.1.distance(y.1) <= tol);
        // Eave vertices only between raised ones (the corners count).
        let raised: Vec<bool> = mid.iter().map(|m| m.1.z > 1e-6).collect();
        let keep: Vec<bool> = (0..mid.len())
            .map(|i| {
                raised[i]
                    || ((zb > 1e-6 || raised[..i].iter().any(|&r| r))
                        && (za > 1e-6 || raised[i + 1..].iter().any(|&r| r)))
            })
            .collect();
        let mut k = keep.iter();
        mid.retain(|_| k.next().copied().unwrap_or(false));
        let mut out = vec![b.extend(zb)];
        out.extend(mid.into_iter().map(|m| m.1));
        out.push(a.extend(za));
        out
    }
}
