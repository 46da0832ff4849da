//! The convex hull of a point set, and what is measured on it: the minimum-area bounding
//! rectangle (rotating calipers) and the deterministic directions of a footprint's scope.

use glam::DVec2;

use super::Polygon;

/// A deterministic X direction for a footprint's scope: the longer side of its minimum-area
/// bounding rectangle (rotating calipers over the convex hull of the outer ring). Of the four
/// directions along that side, the one closest to world +X is taken (ties: closest to +Y), so
/// that an east-west rectangle gets X = east, Y = north and its south facade is `front`.
pub(crate) fn dominant_direction(poly: &Polygon) -> DVec2 {
    let Some((d, square)) = min_area_rectangle(poly) else {
        return DVec2::X;
    };
    // Only the two directions along the long side compete, all four for a square.
    let cands = [d, -d, d.perp(), -d.perp()];
    let cands = if square { &cands[..] } else { &cands[..2] };
    let r = cands
        .iter()
        .copied()
        .max_by(|a, b| {
            (a.x, a.y)
                .partial_cmp(&(b.x, b.y))
                .unwrap_or(std::cmp::Ordering::Equal)
        })
        .unwrap_or(DVec2::X);
    // Snap tiny numerical noise so that axis-aligned footprints get exact axes.
    DVec2::new(snap(r.x), snap(r.y))
}

/// The X direction of a footprint's scope when the building's front is known: the scope's −Y
/// (the `front` of `comp`) is the one of the four directions along the sides of the minimum-area
/// rectangle closest to `front` (a unit vector pointing from the building to its street), and
/// X = that direction turned a quarter counter-clockwise. Without `front`, or when that choice
/// is the thesis one, this is exactly [`dominant_direction`].
///
/// Why the rectangle's directions and not the street edge's own normal: the closest of four
/// directions 90° apart is within 45° of `front`, so the edge that faces the street is always a
/// `front` face of `comp` (ties at 45° go to front, see `grammar::interp`), while the scope stays
/// aligned with the building's main axes, so that X/Y splits of rule files, `repeat`s and top
/// faces keep following the mass and differ from the thesis only by a quarter or half turn.
pub(crate) fn scope_direction(poly: &Polygon, front: Option<DVec2>) -> DVec2 {
    let thesis = dominant_direction(poly);
    let Some(front) = front.and_then(DVec2::try_normalize) else {
        return thesis;
    };
    let Some((d, _)) = min_area_rectangle(poly) else {
        return thesis;
    };
    // −Y of the thesis scope first, so that a tie keeps the thesis front.
    let thesis_front = -thesis.perp();
    let cands = [thesis_front, d, -d, d.perp(), -d.perp()];
    let best = cands
        .iter()
        .copied()
        .rev()
        .max_by(|a, b| a.dot(front).total_cmp(&b.dot(front)))
        .unwrap_or(thesis_front);
    if best.dot(front) <= thesis_front.dot(front) + 1e-12 {
        return thesis;
    }
    // −Y = best  ⇔  Y = −best  ⇔  X = best turned a quarter counter-clockwise.
    let x = best.perp();
    DVec2::new(snap(x.x), snap(x.y))
}

/// The direction of one side of the minimum-area bounding rectangle of the outer ring
/// (rotating calipers over its convex hull): the longer side, and whether the rectangle is a
/// square. `None` for fewer than two distinct points.
pub(crate) fn min_area_rectangle(poly: &Polygon) -> Option<(DVec2, bool)> {
    let hull = convex_hull(&poly.outer);
    if hull.len() < 2 {
        return None;
    }
    let mut best: Option<(f64, DVec2, bool)> = None;
    for i in 0..hull.len() {
        let Some(u) = (hull[(i + 1) % hull.len()] - hull[i]).try_normalize() else {
            continue;
        };
        let v = u.perp();
        let (mut lu, mut hu, mut lv, mut hv) = (
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::INFINITY,
            f64::NEG_INFINITY,
        );
        for p in &hull {
            let (a, b) = (p.dot(u), p.dot(v));
            lu = lu.min(a);
            hu = hu.max(a);
            lv = lv.min(b);
            hv = hv.max(b);
        }
        let (wu, wv) = (hu - lu, hv - lv);
        let area = wu * wv;
        let square = (wu - wv).abs() <= 1e-9 * wu.max(wv);
        let long = if wv > wu { v } else { u };
        if best.is_none_or(|(a, _, _)| area < a * (1.0 - 1e-9)) {
            best = Some((area, long, square));
        }
    }
    best.map(|(_, d, square)| (d, square))
}

fn snap(v: f64) -> f64 {
    if v.abs() < 1e-12 {
        0.0
    } else if (v.abs() - 1.0).abs() < 1e-12 {
        v.signum()
    } else {
        v
    }
}

/// Andrew's monotone chain; counter-clockwise, without collinear points.
pub(crate) fn convex_hull(pts: &[DVec2]) -> Vec<DVec2> {
    let mut p: Vec<DVec2> = pts.iter().copied().filter(|q| q.is_finite()).collect();
    p.sort_by(|a, b| {
        (a.x, a.y)
            .partial_cmp(&(b.x, b.y))
            .unwrap_or(std::cmp::Ordering::Equal)
    });
    p.dedup();
    if p.len() < 3 {
        return p;
    }
    let cross = |o: DVec2, a: DVec2, b: DVec2| (a - o).perp_dot(b - o);
    let mut h: Vec<DVec2> = Vec::with_capacity(p.len() * 2);
    for &q in &p {
        while h.len() >= 2 && cross(h[h.len() - 2], h[h.len() - 1], q) <= 0.0 {
            h.pop();
        }
        h.push(q);
    }
    let lower = h.len() + 1;
    for &q in p.iter().rev().skip(1) {
        while h.len() >= lower && cross(h[h.len() - 2], h[h.len() - 1], q) <= 0.0 {
            h.pop();
        }
        h.push(q);
    }
    h.pop();
    h
}

#[cfg(test)]
mod tests;
