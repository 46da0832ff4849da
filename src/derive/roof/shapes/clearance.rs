//! Cuts and ridges kept clear of the footprint's corners (issue 45): a cut a hair beside a
//! corner leaves slivers and heights the millimetre grid cannot keep apart. Shared by the cut
//! roofs (`cut`) and the ridge roofs (`ridge`).

use glam::DVec2;

use crate::geometry::Polygon;

/// Every vertex of the footprint (all rings).
pub(super) fn corners(poly: &Polygon) -> Vec<DVec2> {
    poly.rings().flatten().copied().collect()
}

/// The smallest shift `d` (0, then ±`eps`, ±2·`eps`, … up to `reach` away) such that every
/// `at[i] + d` lies exactly on, or more than `eps` from, the projection `p·n` of every
/// footprint corner: a cut a hair beside a corner leaves slivers and heights that the
/// millimetre grid cannot keep apart (a corner a centimetre beside a shallow valley stands a
/// millimetre above it), while a cut exactly through a corner gives it the cut's own height.
/// `eps` comes from [`cut_clearance`]; `through`: whether a cut exactly through a corner is
/// clear (a sawtooth's are not: its teeth keep off the corners). `None` when no shift within
/// reach is clear.
pub(super) fn clear_shift(
    corners: &[DVec2],
    n: DVec2,
    at: &[f64],
    (eps, through): (f64, bool),
    reach: f64,
) -> Option<f64> {
    let mut proj: Vec<f64> = corners.iter().map(|p| p.dot(n)).collect();
    proj.sort_by(f64::total_cmp);
    let scale = proj.iter().fold(1.0_f64, |m, t| m.max(t.abs()));
    let exact = 1e-12 * scale;
    let clear = |l: f64| {
        let i = proj.partition_point(|&t| t < l - exact);
        let d1 = proj.get(i).map_or(f64::INFINITY, |t| t - l);
        let d0 = i.checked_sub(1).map_or(f64::INFINITY, |j| l - proj[j]);
        let d = d0.min(d1.abs());
        d > eps || through && d <= exact
    };
    (0..4000)
        .map(|j| (j / 2 + j % 2) as f64 * eps * if j % 2 == 0 { 1.0 } else { -1.0 })
        .take_while(|d| d.abs() <= reach)
        .find(|&d| at.iter().all(|&c| clear(c + d)))
}

/// `c` moved by [`clear_shift`] (at most `reach`), or `c` itself when nothing within reach is
/// clear.
pub(super) fn clear_cut(corners: &[DVec2], n: DVec2, c: f64, eps: f64, reach: f64) -> f64 {
    c + clear_shift(corners, n, &[c], (eps, true), reach).unwrap_or(0.0)
}

/// How high (metres) a corner beside a cut at least stands apart from the cut's height, so
/// that the millimetre grid keeps them apart: see [`cut_clearance`].
const MIN_RISE_M: f64 = 0.01;

/// How far (metres) a cut keeps from the footprint's corners when the roof beside it rises
/// `slope` per metre (the shallowest slope meeting the cut): 1e-3 of the footprint's `size`,
/// at least three times [`crate::model::MIN_VERTEX_GAP`], and at least [`MIN_RISE_M`] of
/// height.
pub(super) fn cut_clearance(size: f64, slope: f64) -> f64 {
    let rise = if slope.is_finite() && slope > 0.0 {
        MIN_RISE_M / slope
    } else {
        0.0
    };
    (1e-3 * size)
        .max(3.0 * crate::model::MIN_VERTEX_GAP)
        .max(rise)
}

/// The footprint's size: the larger side of its bounding box.
pub(super) fn size_of(poly: &Polygon) -> f64 {
    let (lo, hi) = poly.bounds();
    (hi - lo).max_element()
}
