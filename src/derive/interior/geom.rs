//! Planar helpers for the floor-plan layout: conversion to and from `geo`, half-plane areas by
//! ring clipping (cheap, for the bisection), half-plane cuts with `geo`'s boolean operations,
//! ring clean-up, shared boundary segments and axis-aligned rectangle containment.

use geo::{Area, BooleanOps, Validation};
use glam::DVec2;

use crate::geometry::{ring, ring_signed_area, Polygon};

/// A `geo` polygon (f64).
pub(crate) type GPoly = geo::Polygon<f64>;
/// A `geo` multipolygon (f64).
pub(crate) type GMulti = geo::MultiPolygon<f64>;

/// Distance under which two points or a point and a line count as coincident (metres).
/// Boolean operations snap coordinates to a grid much finer than this.
pub(crate) const EPS: f64 = 1e-3;

fn ring_to_geo(r: &[DVec2]) -> geo::LineString<f64> {
    geo::LineString::from(r.iter().map(|q| (q.x, q.y)).collect::<Vec<_>>())
}

/// Our polygon as a `geo` polygon.
pub(crate) fn to_geo(p: &Polygon) -> GPoly {
    GPoly::new(
        ring_to_geo(&p.outer),
        p.holes.iter().map(|h| ring_to_geo(h)).collect(),
    )
}

fn ring_from_geo(ls: &geo::LineString<f64>) -> Vec<DVec2> {
    straighten(ls.0.iter().map(|c| DVec2::new(c.x, c.y)).collect())
}

/// A `geo` polygon as ours: orientation normalised, rings cleaned, degenerate holes dropped.
pub(crate) fn from_geo(g: &GPoly) -> Polygon {
    let holes = g
        .interiors()
        .iter()
        .map(ring_from_geo)
        .filter(|h| h.len() >= 3 && ring_signed_area(h).abs() > 1e-6)
        .collect();
    Polygon::new(ring_from_geo(g.exterior()), holes)
}

/// Drops the closing vertex ([`ring::pop_closing_by`], 1 nm) and near-duplicate and straight
/// vertices ([`ring::remove_straight`], 0.1 µm and a sine of 1e-7), so that rings stay small
/// and shared-edge tests see straight edges as one edge.
pub(crate) fn straighten(mut r: Vec<DVec2>) -> Vec<DVec2> {
    ring::pop_closing_by(&mut r, |a, b| a.distance(b) < 1e-9);
    ring::remove_straight(&mut r, 1e-7, 1e-7);
    r
}

/// Unsigned area of a `geo` multipolygon.
pub(crate) fn garea(m: &GMulti) -> f64 {
    m.unsigned_area()
}

/// Axis-aligned bounds of a multipolygon (min, max); infinite when empty.
pub(crate) fn gbounds(m: &GMulti) -> (DVec2, DVec2) {
    let mut lo = DVec2::splat(f64::INFINITY);
    let mut hi = DVec2::splat(f64::NEG_INFINITY);
    for p in &m.0 {
        for c in p.exterior().0.iter() {
            lo = lo.min(DVec2::new(c.x, c.y));
            hi = hi.max(DVec2::new(c.x, c.y));
        }
    }
    (lo, hi)
}

/// The two axes of the plan frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Axis {
    /// Cut by lines x = t.
    X,
    /// Cut by lines y = t.
    Y,
}

fn coord(p: DVec2, axis: Axis) -> f64 {
    match axis {
        Axis::X => p.x,
        Axis::Y => p.y,
    }
}

/// Signed area of the part of a ring with `coord < t` (Sutherland-Hodgman against one
/// half-plane). On a concave ring the clip may keep zero-width bridges, which add no area, so
/// the sum over all rings (holes negative) is the exact area of the region below `t`.
fn ring_area_below(ring: &[DVec2], axis: Axis, t: f64) -> f64 {
    let n = ring.len();
    if n < 3 {
        return 0.0;
    }
    let mut out: Vec<DVec2> = Vec::with_capacity(n + 4);
    for i in 0..n {
        let a = ring[i];
        let b = ring[(i + 1) % n];
        let (ca, cb) = (coord(a, axis) - t, coord(b, axis) - t);
        if ca <= 0.0 {
            out.push(a);
        }
        if (ca < 0.0 && cb > 0.0) || (ca > 0.0 && cb < 0.0) {
            let s = ca / (ca - cb);
            out.push(a + (b - a) * s);
        }
    }
    ring_signed_area(&out)
}

/// The rings of a multipolygon as point lists, holes marked.
fn rings_of(m: &GMulti) -> Vec<(bool, Vec<DVec2>)> {
    let mut out = Vec::new();
    for p in &m.0 {
        let pts = |ls: &geo::LineString<f64>| ls.0.iter().map(|c| DVec2::new(c.x, c.y)).collect();
        out.push((false, pts(p.exterior())));
        for h in p.interiors() {
            out.push((true, pts(h)));
        }
    }
    out
}

fn rings_area_below(rings: &[(bool, Vec<DVec2>)], axis: Axis, t: f64) -> f64 {
    rings
        .iter()
        .map(|(hole, r)| {
            let a = ring_area_below(r, axis, t).abs();
            if *hole {
                -a
            } else {
                a
            }
        })
        .sum()
}

/// The cut position `t` on `axis` where the region below holds `frac` of the area (bisection).
pub(crate) fn cut_at_fraction(m: &GMulti, axis: Axis, frac: f64) -> f64 {
    let (lo, hi) = gbounds(m);
    let (mut a, mut b) = (coord(lo, axis), coord(hi, axis));
    if !(a.is_finite() && b.is_finite()) {
        return 0.0;
    }
    let rings = rings_of(m);
    let total = rings_area_below(&rings, axis, b + 1.0);
    let target = frac.clamp(0.0, 1.0) * total;
    for _ in 0..48 {
        let mid = 0.5 * (a + b);
        if rings_area_below(&rings, axis, mid) < target {
            a = mid;
        } else {
            b = mid;
        }
        if b - a < 1e-6 {
            break;
        }
    }
    0.5 * (a + b)
}

/// An axis-aligned rectangle as a `geo` polygon.
pub fn rect(lo: DVec2, hi: DVec2) -> GPoly {
    GPoly::new(
        geo::LineString::from(vec![
            (lo.x, lo.y),
            (hi.x, lo.y),
            (hi.x, hi.y),
            (lo.x, hi.y),
            (lo.x, lo.y),
        ]),
        vec![],
    )
}

/// The parts of `m` below and above `t` on `axis`.
pub fn split(m: &GMulti, axis: Axis, t: f64) -> (GMulti, GMulti) {
    let (lo, hi) = gbounds(m);
    let pad = DVec2::splat(1.0);
    let (lo, hi) = (lo - pad, hi + pad);
    let (below, above) = match axis {
        Axis::X => (rect(lo, DVec2::new(t, hi.y)), rect(DVec2::new(t, lo.y), hi)),
        Axis::Y => (rect(lo, DVec2::new(hi.x, t)), rect(DVec2::new(lo.x, t), hi)),
    };
    (
        m.intersection(&GMulti::new(vec![below])),
        m.intersection(&GMulti::new(vec![above])),
    )
}

/// The part of `m` between `a` and `b` on `axis`.
pub fn band(m: &GMulti, axis: Axis, a: f64, b: f64) -> GMulti {
    let (lo, hi) = gbounds(m);
    let pad = DVec2::splat(1.0);
    let (lo, hi) = (lo - pad, hi + pad);
    let r = match axis {
        Axis::X => rect(DVec2::new(a, lo.y), DVec2::new(b, hi.y)),
        Axis::Y => rect(DVec2::new(lo.x, a), DVec2::new(hi.x, b)),
    };
    m.intersection(&GMulti::new(vec![r]))
}

/// Whether a `geo` polygon is valid (simple rings, holes inside, no self-touching).
pub(crate) fn is_valid(p: &GPoly) -> bool {
    p.is_valid()
}

/// Whether the rectangle `[lo, hi]` lies inside `poly` (its interior may touch the boundary
/// only along edges): every corner inside or on the boundary, no ring vertex strictly inside
/// the rectangle, and no ring edge crossing a rectangle edge properly.
pub(crate) fn rect_inside(poly: &Polygon, lo: DVec2, hi: DVec2) -> bool {
    let corners = [lo, DVec2::new(hi.x, lo.y), hi, DVec2::new(lo.x, hi.y)];
    let centre = 0.5 * (lo + hi);
    // Corners shrunk a hair toward the centre, so that corners on the boundary count inside.
    for c in corners {
        let q = c + (centre - c) * 1e-6;
        if !poly.contains(q) {
            return false;
        }
    }
    let inside_strict =
        |p: DVec2| p.x > lo.x + 1e-9 && p.x < hi.x - 1e-9 && p.y > lo.y + 1e-9 && p.y < hi.y - 1e-9;
    for ring in poly.rings() {
        let n = ring.len();
        for i in 0..n {
            let a = ring[i];
            let b = ring[(i + 1) % n];
            if inside_strict(a) {
                return false;
            }
            // The segment's midpoint strictly inside means it cuts through.
            if inside_strict(0.5 * (a + b)) {
                return false;
            }
            for k in 0..4 {
                if segments_cross(a, b, corners[k], corners[(k + 1) % 4]) {
                    return false;
                }
            }
        }
    }
    true
}

/// Proper crossing of two segments (interiors intersect at one point, not at endpoints).
fn segments_cross(a: DVec2, b: DVec2, c: DVec2, d: DVec2) -> bool {
    let d1 = (b - a).perp_dot(c - a);
    let d2 = (b - a).perp_dot(d - a);
    let d3 = (d - c).perp_dot(a - c);
    let d4 = (d - c).perp_dot(b - c);
    let tol = 1e-9;
    ((d1 > tol && d2 < -tol) || (d1 < -tol && d2 > tol))
        && ((d3 > tol && d4 < -tol) || (d3 < -tol && d4 > tol))
}

/// Shared boundary of two rings: the overlaps of anti-parallel (or parallel) collinear edges,
/// each longer than [`EPS`]. Returns segments in the direction of `a`'s edges.
pub(crate) fn shared_segments(a: &[DVec2], b: &[DVec2]) -> Vec<(DVec2, DVec2)> {
    let mut out = Vec::new();
    let (na, nb) = (a.len(), b.len());
    for i in 0..na {
        let p0 = a[i];
        let p1 = a[(i + 1) % na];
        let d = p1 - p0;
        let len = d.length();
        if len < EPS {
            continue;
        }
        let dir = d / len;
        for j in 0..nb {
            let q0 = b[j];
            let q1 = b[(j + 1) % nb];
            // Both ends of b's edge on a's line.
            if dir.perp_dot(q0 - p0).abs() > EPS || dir.perp_dot(q1 - p0).abs() > EPS {
                continue;
            }
            let (s0, s1) = (dir.dot(q0 - p0), dir.dot(q1 - p0));
            let (lo, hi) = (s0.min(s1).max(0.0), s0.max(s1).min(len));
            if hi - lo > EPS {
                out.push((p0 + dir * lo, p0 + dir * hi));
            }
        }
    }
    out
}

/// Tolerance of [`simple_parts`]: a vertex this close to another vertex or to an edge touches it
/// (metres), as in [`crate::geometry::is_simple`].
const TOUCH: f64 = crate::geometry::TOUCH_TOLERANCE;

/// The simple rings a writer builds a solid from, for one polygon outer ring: the ring cleaned
/// as the writers clean it ([`crate::geometry::clean_ring`], counter-clockwise) and, when it
/// touches itself (two pieces joined at a vertex or by a zero-width seam, which `geo`'s boolean
/// operations produce and call valid), cut at every touching point into its pieces. Pieces that
/// run clockwise are holes pinched onto the ring: they are returned in the second list, for the
/// caller to cut the polygon through them. A ring that still crosses itself is returned as it
/// is (never seen from the planner's own cuts; the plan tests check it).
pub(crate) fn simple_parts(ring: &[DVec2]) -> (Vec<Vec<DVec2>>, Vec<Vec<DVec2>>) {
    let (mut outers, mut holes) = (Vec::new(), Vec::new());
    let Some(first) = crate::geometry::clean_ring(ring) else {
        return (outers, holes);
    };
    let mut stack = vec![first];
    let mut budget = 256usize;
    while let Some(r) = stack.pop() {
        if crate::geometry::is_simple(&r) || budget == 0 {
            outers.push(r);
            continue;
        }
        budget -= 1;
        let r = node_ring(r);
        let n = r.len();
        let pinch = (0..n).find_map(|i| {
            ((i + 2)..n)
                .find(|&j| r[i].distance(r[j]) <= TOUCH && !(i == 0 && j == n - 1))
                .map(|j| (i, j))
        });
        let Some((i, j)) = pinch else {
            outers.push(r);
            continue;
        };
        let a: Vec<DVec2> = r[i..j].to_vec();
        let b: Vec<DVec2> = r[j..].iter().chain(r[..i].iter()).copied().collect();
        for piece in [a, b] {
            let clockwise = ring_signed_area(&piece) < 0.0;
            if let Some(c) = crate::geometry::clean_ring(&piece) {
                if clockwise {
                    holes.push(c);
                } else {
                    stack.push(c);
                }
            }
        }
    }
    (outers, holes)
}

/// Inserts every vertex that lies on the inside of a non-adjacent edge into that edge, so that
/// a ring touching itself along an edge shares a vertex there.
fn node_ring(mut r: Vec<DVec2>) -> Vec<DVec2> {
    for _ in 0..64 {
        let n = r.len();
        let mut hit = None;
        'search: for k in 0..n {
            let p = r[k];
            for i in 0..n {
                let j = (i + 1) % n;
                if i == k || j == k {
                    continue;
                }
                let (a, b) = (r[i], r[j]);
                let ab = b - a;
                let len2 = ab.length_squared();
                if len2 <= TOUCH * TOUCH {
                    continue;
                }
                let t = (p - a).dot(ab) / len2;
                let near_end = p.distance(a) <= TOUCH || p.distance(b) <= TOUCH;
                if t > 0.0 && t < 1.0 && !near_end && (a + ab * t).distance(p) <= TOUCH {
                    hit = Some((i + 1, p));
                    break 'search;
                }
            }
        }
        match hit {
            Some((at, p)) => r.insert(at, p),
            None => break,
        }
    }
    r
}
