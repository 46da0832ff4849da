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

/// `c` moved by [`clear_shift`] (at most `reach`); when nothing within reach is clear (corners
/// closer together than twice `eps` all across the reach: a small stepped footprint under a
/// shallow slope), the place within reach farthest from every corner's projection
/// ([`farthest_within`]), so that the cut still misses the corners by as much as it can
/// rather than by whatever `c` happens to leave (a cut 6 mm beside a corner leaves the
/// corner out of the roof's outline).
pub(super) fn clear_cut(corners: &[DVec2], n: DVec2, c: f64, eps: f64, reach: f64) -> f64 {
    match clear_shift(corners, n, &[c], (eps, true), reach) {
        Some(d) => c + d,
        None => farthest_within(corners, n, c, reach),
    }
}

/// The point of `[c - reach, c + reach]` whose distance to the nearest projection `p·n` of a
/// corner is largest (the nearer to `c` on a tie): the middle of the widest gap between
/// projections, or an end of the interval.
pub(super) fn farthest_within(corners: &[DVec2], n: DVec2, c: f64, reach: f64) -> f64 {
    let (lo, hi) = (c - reach, c + reach);
    let mut proj: Vec<f64> = corners.iter().map(|p| p.dot(n)).collect();
    proj.sort_by(f64::total_cmp);
    let gap = |l: f64| {
        let i = proj.partition_point(|&t| t < l);
        let d1 = proj.get(i).map_or(f64::INFINITY, |t| t - l);
        let d0 = i.checked_sub(1).map_or(f64::INFINITY, |j| l - proj[j]);
        d0.min(d1)
    };
    let mut candidates = vec![c, lo, hi];
    candidates.extend(
        proj.windows(2)
            .map(|w| 0.5 * (w[0] + w[1]))
            .filter(|m| (lo..=hi).contains(m)),
    );
    candidates
        .into_iter()
        .map(|l| (gap(l), -(l - c).abs(), l))
        .max_by(|a, b| a.0.total_cmp(&b.0).then(a.1.total_cmp(&b.1)))
        .map_or(c, |(_, _, l)| l)
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn farthest_within_takes_the_widest_gap_or_an_end() {
        let corners = [
            DVec2::new(0.0, 5.0),
            DVec2::new(1.0, -2.0),
            DVec2::new(3.0, 0.0),
        ];
        // Within [-0.1, 1.9]: the end 1.9 is 0.9 from the nearest corner (1.0); the gap's
        // middle 0.5 only 0.5.
        assert_eq!(farthest_within(&corners, DVec2::X, 0.9, 1.0), 1.9);
        // Within [0.2, 2.8]: the middle of the gap (1, 3).
        assert_eq!(farthest_within(&corners, DVec2::X, 1.5, 1.3), 2.0);
        // A tie: in [-1, 2] with corners at 0 and 2, both -1 and 1 are 1 from a corner; 1 is
        // nearer to 0.5.
        let two = [DVec2::ZERO, DVec2::new(2.0, 0.0)];
        assert_eq!(farthest_within(&two, DVec2::X, 0.5, 1.5), 1.0);
        // Nothing to keep clear of: `c` itself.
        assert_eq!(farthest_within(&[], DVec2::X, 0.3, 1.0), 0.3);
    }
}
