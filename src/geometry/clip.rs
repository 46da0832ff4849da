//! Clipping a polygon to a slab between two parallel lines, and mapping its vertices.

use geo::algorithm::bool_ops::FillRule;
use geo::BooleanOps;
use glam::DVec2;

use super::Polygon;

/// Lengths below this (metres) are treated as zero: empty split pieces, degenerate edges.
pub(crate) const EPS: f64 = 1e-9;
/// Pieces of a clipped footprint smaller than this (m²) are slivers and are dropped.
pub(crate) const MIN_AREA: f64 = 1e-6;

/// Whether a ring is convex (counter-clockwise, collinear vertices allowed).
fn is_convex(ring: &[DVec2]) -> bool {
    let n = ring.len();
    if n < 3 {
        return false;
    }
    (0..n).all(|i| {
        let (a, b, c) = (ring[i], ring[(i + 1) % n], ring[(i + 2) % n]);
        (b - a).perp_dot(c - b) >= -1e-12 * (b - a).length() * (c - b).length()
    })
}

/// The parts of `poly` whose points `p` satisfy `lo <= (p - origin)·axis <= hi` (`axis` unit).
///
/// Convex footprints without holes (most buildings) are clipped by Sutherland–Hodgman against
/// the two half-planes; anything else goes through `geo`'s boolean intersection with a large
/// rectangle, which is exact for concave outlines and holes and may return several polygons.
/// Slivers under [`MIN_AREA`] are dropped.
pub(crate) fn clip_slab(
    poly: &Polygon,
    origin: DVec2,
    axis: DVec2,
    lo: f64,
    hi: f64,
) -> Vec<Polygon> {
    let proj = |p: &DVec2| (*p - origin).dot(axis);
    let (mut pmin, mut pmax) = (f64::INFINITY, f64::NEG_INFINITY);
    for p in &poly.outer {
        let t = proj(p);
        pmin = pmin.min(t);
        pmax = pmax.max(t);
    }
    if pmin >= lo - EPS && pmax <= hi + EPS {
        return vec![poly.clone()];
    }
    if pmax <= lo + EPS || pmin >= hi - EPS {
        return Vec::new();
    }
    let out = if poly.holes.is_empty() && is_convex(&poly.outer) {
        let a = half_plane(&poly.outer, |p| proj(p) - lo);
        let b = half_plane(&a, |p| hi - proj(p));
        vec![Polygon::new(b, Vec::new())]
    } else {
        let perp = axis.perp();
        let (mut qmin, mut qmax) = (f64::INFINITY, f64::NEG_INFINITY);
        for p in &poly.outer {
            let t = (*p - origin).dot(perp);
            qmin = qmin.min(t);
            qmax = qmax.max(t);
        }
        let (qmin, qmax) = (qmin - 1.0, qmax + 1.0);
        let lo = lo.max(pmin - 1.0);
        let hi = hi.min(pmax + 1.0);
        let corner = |s: f64, t: f64| {
            let p = origin + axis * s + perp * t;
            geo::Coord { x: p.x, y: p.y }
        };
        let rect = geo::Polygon::new(
            geo::LineString::from(vec![
                corner(lo, qmin),
                corner(hi, qmin),
                corner(hi, qmax),
                corner(lo, qmax),
            ]),
            Vec::new(),
        );
        let g = to_geo(poly);
        g.intersection(&rect)
            .0
            .into_iter()
            .map(|gp| from_geo(&gp))
            .collect()
    };
    out.into_iter()
        .filter(|p| p.outer.len() >= 3 && p.area() > MIN_AREA)
        .collect()
}

/// One Sutherland–Hodgman pass: keeps the part of a ring where `f >= 0`.
fn half_plane(ring: &[DVec2], f: impl Fn(&DVec2) -> f64) -> Vec<DVec2> {
    let n = ring.len();
    let mut out = Vec::with_capacity(n + 2);
    for i in 0..n {
        let (a, b) = (ring[i], ring[(i + 1) % n]);
        let (fa, fb) = (f(&a), f(&b));
        if fa >= 0.0 {
            out.push(a);
        }
        if (fa >= 0.0) != (fb >= 0.0) {
            let t = fa / (fa - fb);
            out.push(a + (b - a) * t);
        }
    }
    out.dedup_by(|a, b| a.distance_squared(*b) < EPS * EPS);
    if out.len() > 1 && out[0].distance_squared(out[out.len() - 1]) < EPS * EPS {
        out.pop();
    }
    out
}

/// Up to this many cutters, [`difference`] removes them one at a time, as it always did (so
/// the bytes of ordinary buildings' outputs stay as they were); past it, their union in one
/// boolean operation, whose cost grows as n log n in the cutters' vertices where one at a time
/// grows as n² (each cut works on a rest holding every earlier cutter's hole).
pub(crate) const SEQUENTIAL_CUTTERS: usize = 32;

/// What of the polygons `a` lies outside every polygon of `b` (boolean difference), as
/// polygons with the orientation convention. Pieces under [`MIN_AREA`] are dropped; the caller
/// filters slivers by its own measure.
pub fn difference(a: &[Polygon], b: &[Polygon]) -> Vec<Polygon> {
    let subject = geo::MultiPolygon::new(a.iter().map(to_geo).collect());
    let rest = if b.len() <= SEQUENTIAL_CUTTERS {
        // One cutter at a time: a multipolygon whose members overlap is read even-odd by the
        // boolean operations, so two overlapping cutters would cancel where they overlap.
        let mut rest = subject;
        for cutter in b {
            rest = rest.difference(&geo::MultiPolygon::new(vec![to_geo(cutter)]));
        }
        rest
    } else {
        // All cutters in one operation, read non-zero: rings follow the orientation
        // convention (outer counter-clockwise, holes clockwise), so overlapping cutters add up
        // to their union instead of cancelling, and a hole stays a hole.
        let cutters = geo::MultiPolygon::new(b.iter().map(to_geo).collect());
        subject.difference_with_fill_rule(&cutters, FillRule::NonZero)
    };
    rest.0
        .iter()
        .map(from_geo)
        .filter(|p| p.outer.len() >= 3 && p.area() > MIN_AREA)
        .collect()
}

fn to_geo(poly: &Polygon) -> geo::Polygon<f64> {
    let ring = |r: &Vec<DVec2>| {
        geo::LineString::from(
            r.iter()
                .map(|p| geo::Coord { x: p.x, y: p.y })
                .collect::<Vec<_>>(),
        )
    };
    geo::Polygon::new(ring(&poly.outer), poly.holes.iter().map(ring).collect())
}

fn from_geo(p: &geo::Polygon<f64>) -> Polygon {
    let ring =
        |l: &geo::LineString<f64>| l.0.iter().map(|c| DVec2::new(c.x, c.y)).collect::<Vec<_>>();
    Polygon::new(ring(p.exterior()), p.interiors().iter().map(ring).collect())
}

/// Applies `f` to every vertex of a polygon, then restores the orientation convention.
pub(crate) fn map_polygon(poly: &Polygon, f: impl Fn(DVec2) -> DVec2) -> Polygon {
    Polygon::new(
        poly.outer.iter().map(|p| f(*p)).collect(),
        poly.holes
            .iter()
            .map(|h| h.iter().map(|p| f(*p)).collect())
            .collect(),
    )
}

#[cfg(test)]
mod tests;

#[cfg(test)]
mod difference_tests {
    use super::*;

    fn sq(x: f64, y: f64, w: f64, h: f64) -> Polygon {
        Polygon::new(
            vec![
                DVec2::new(x, y),
                DVec2::new(x + w, y),
                DVec2::new(x + w, y + h),
                DVec2::new(x, y + h),
            ],
            vec![],
        )
    }

    #[test]
    fn overlapping_cutters_remove_their_union() {
        // The second cutter lies inside the first: nothing is left, not the second's square.
        let a = vec![sq(0.0, 0.0, 20.0, 20.0)];
        assert!(difference(&a, &[sq(0.0, 0.0, 20.0, 20.0), sq(5.0, 5.0, 10.0, 10.0)]).is_empty());
        let rest = difference(&a, &[sq(0.0, 0.0, 10.0, 20.0), sq(5.0, 0.0, 10.0, 10.0)]);
        let area: f64 = rest.iter().map(Polygon::area).sum();
        assert!((area - 150.0).abs() < 1e-6, "{area}");
        assert!(difference(&a, &[]).len() == 1);
    }

    #[test]
    fn many_cutters_remove_their_union_in_one_operation() {
        // Past SEQUENTIAL_CUTTERS: 100 squares of 1 m in a 20 m square, each overlapped by a
        // second one shifted by half a metre, and one cutter with a hole (a ring around an
        // island that stays).
        let a = vec![sq(0.0, 0.0, 20.0, 20.0)];
        let mut cutters = Vec::new();
        for i in 0..100 {
            let (x, y) = (1.0 + 1.5 * (i % 10) as f64, 1.0 + 1.5 * (i / 10) as f64);
            cutters.push(sq(x, y, 1.0, 1.0));
            cutters.push(sq(x + 0.5, y, 1.0, 1.0));
        }
        assert!(cutters.len() > SEQUENTIAL_CUTTERS);
        let ring = Polygon::new(
            sq(16.5, 16.5, 3.0, 3.0).outer,
            vec![sq(17.5, 17.5, 1.0, 1.0).outer],
        );
        cutters.push(ring);
        let rest = difference(&a, &cutters);
        let area: f64 = rest.iter().map(Polygon::area).sum();
        // 400 - 100 × 1.5 (each pair's union) - (9 - 1) (the ring without its island).
        assert!((area - (400.0 - 150.0 - 8.0)).abs() < 1e-6, "{area}");
        // The same as one cutter at a time.
        let mut one_by_one = a.clone();
        for c in &cutters {
            one_by_one = difference(&one_by_one, std::slice::from_ref(c));
        }
        let again: f64 = one_by_one.iter().map(Polygon::area).sum();
        assert!((area - again).abs() < 1e-6, "{area} {again}");
        assert_eq!(rest.len(), 2, "the rest with its holes, and the island");
    }
}
