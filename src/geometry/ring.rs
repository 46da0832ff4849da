//! Ring cleaning, one family for every stage. A ring is a closed sequence of points, not closed
//! explicitly (the first point is not repeated at the end). Each member has one contract,
//! stated on it; the stages compose them:
//!
//! | stage | what it calls | tolerance |
//! |---|---|---|
//! | readers (`input::rings`) | [`dedup_by`] with exact equality | none |
//! | prepare (`prepare`) | [`dedup_within`], then [`remove_spikes_by`] | `MERGE_TOLERANCE` |
//! | prepare, per lot (`prepare::straighten_lot`) | [`straighten`] | `STRAIGHTEN_TOLERANCE`, 1° |
//! | massing (welded parts) | [`dedup_by`] and [`remove_spikes_by`], exact, on 3D rings | none |
//! | straight skeleton | [`simplified_indices`]; [`dedup_within`] on its faces | relative to the footprint size |
//! | LOD4 floor plans | [`pop_closing_by`], then [`remove_straight`] | 1e-9 / 1e-7 m |
//! | writers | [`clean_ring`] (IFC also [`dedup_within`]) | 0.1 mm |
//!
//! The members never move a point: they only drop points, so every output point is an input
//! point and the order is kept.

use glam::{DVec2, DVec3};

use super::ring_signed_area;

/// A point whose distance to another can be measured (the 2D and 3D points of the model).
pub trait Point: Copy {
    /// The Euclidean distance to `other`.
    fn dist(self, other: Self) -> f64;
}

impl Point for DVec2 {
    fn dist(self, other: Self) -> f64 {
        self.distance(other)
    }
}

impl Point for DVec3 {
    fn dist(self, other: Self) -> f64 {
        self.distance(other)
    }
}

/// Drops the points at the end of the ring that `same` calls equal to the first one (a
/// closing vertex, repeated or not), keeping at least one point.
pub(crate) fn pop_closing_by<T: Copy>(ring: &mut Vec<T>, same: impl Fn(T, T) -> bool) {
    while ring.len() > 1 && same(ring[0], ring[ring.len() - 1]) {
        ring.pop();
    }
}

/// Drops every point that `same` calls equal to the last point kept before it (of a run of
/// equal points the first stays), then the closing points ([`pop_closing_by`]). With exact
/// equality (`|a, b| a == b`) this is `Vec::dedup` plus the closing vertex.
pub(crate) fn dedup_by<T: Copy>(ring: &mut Vec<T>, same: impl Fn(T, T) -> bool) {
    ring.dedup_by(|a, b| same(*b, *a));
    pop_closing_by(ring, same);
}

/// [`dedup_by`] within a distance: a point is kept when it is farther than `tol` from the last
/// point kept, and the closing points within `tol` of the first are dropped. A point at a
/// non-finite distance (NaN) from the last one kept is dropped; at the end it is kept.
pub(crate) fn dedup_within<P: Point>(ring: &mut Vec<P>, tol: f64) {
    let mut kept = 0;
    for i in 0..ring.len() {
        let p = ring[i];
        if kept == 0 || ring[kept - 1].dist(p) > tol {
            ring[kept] = p;
            kept += 1;
        }
    }
    ring.truncate(kept);
    pop_closing_by(ring, |a, b| a.dist(b) <= tol);
}

/// Removes spikes: a vertex whose two neighbours `same` calls equal (the ring runs out along an
/// edge and back, `x, y, x`). The tip and the neighbour after it go, and the search starts again
/// from the first vertex, until no spike is left or fewer than 3 vertices remain. Returns the
/// number of spikes removed. On a ring without consecutive duplicates (after [`dedup_by`] with
/// the same exact equality) no removal creates one.
pub(crate) fn remove_spikes_by<T: Copy>(ring: &mut Vec<T>, same: impl Fn(T, T) -> bool) -> usize {
    let mut spikes = 0;
    while ring.len() >= 3 {
        let n = ring.len();
        let Some(i) = (0..n).find(|&i| same(ring[(i + n - 1) % n], ring[(i + 1) % n])) else {
            break;
        };
        let j = (i + 1) % n;
        ring.remove(i.max(j));
        ring.remove(i.min(j));
        spikes += 1;
    }
    spikes
}

/// Removes collinear vertices one at a time, the first in ring order each time: a vertex whose
/// distance to the line through its two neighbours is at most `tol`, or whose neighbours are
/// within `degenerate` of each other. Stops when none is left or fewer than 3 vertices remain.
pub(crate) fn remove_collinear(ring: &mut Vec<DVec2>, tol: f64, degenerate: f64) {
    let mut changed = true;
    while changed && ring.len() >= 3 {
        changed = false;
        let n = ring.len();
        for i in 0..n {
            let (a, p, b) = (ring[(i + n - 1) % n], ring[i], ring[(i + 1) % n]);
            let ab = b - a;
            let len = ab.length();
            if len <= degenerate || (p - a).perp_dot(ab).abs() / len <= tol {
                ring.remove(i);
                changed = true;
                break;
            }
        }
    }
}

/// Removes straight vertices in rounds: each round judges every vertex against its neighbours
/// in the ring as the round found it, and drops those closer than `near` to the previous vertex
/// or whose turn has a sine below `sine` (straight on, or a zero-width spike). Rounds repeat
/// until one drops nothing; a round that would leave fewer than 3 vertices leaves what it kept.
pub(crate) fn remove_straight(ring: &mut Vec<DVec2>, near: f64, sine: f64) {
    let mut changed = true;
    while changed && ring.len() >= 3 {
        changed = false;
        let n = ring.len();
        let mut keep = Vec::with_capacity(n);
        for i in 0..n {
            let (prev, cur, next) = (ring[(i + n - 1) % n], ring[i], ring[(i + 1) % n]);
            let (e1, e2) = (cur - prev, next - cur);
            let len = e1.length() * e2.length();
            let straight = len > 0.0 && e1.perp_dot(e2).abs() / len < sine;
            if cur.distance(prev) < near || straight {
                changed = true;
            } else {
                keep.push(cur);
            }
        }
        *ring = keep;
        if ring.len() < 3 {
            return;
        }
    }
}

/// Drops the vertices where the ring bends by less than `max_turn_deg` degrees (going on, not
/// turning back) and whose removal keeps every dropped vertex within `tol` of the chord that
/// replaces it — a straight wall drawn with an extra node a little off the line — except those
/// `keep` holds (a corner another ring shares). The least bent vertex goes first, one at a
/// time; a ring is never left with fewer than 3 vertices. Returns the ring's kept points.
pub(crate) fn straighten(
    ring: &[DVec2],
    tol: f64,
    max_turn_deg: f64,
    keep: impl Fn(DVec2) -> bool,
) -> Vec<DVec2> {
    let n = ring.len();
    let mut kept: Vec<usize> = (0..n).collect();
    let max_sine = max_turn_deg.to_radians().sin();
    let held: Vec<bool> = ring.iter().map(|p| keep(*p)).collect();
    // Distance of every original vertex between kept positions i and k (exclusive) to the chord.
    let fits = |i: usize, k: usize| -> bool {
        let (a, c) = (ring[i], ring[k]);
        let ac = c - a;
        let len = ac.length();
        if len <= 0.0 {
            return false;
        }
        let mut j = (i + 1) % n;
        while j != k {
            if (ring[j] - a).perp_dot(ac).abs() / len > tol {
                return false;
            }
            j = (j + 1) % n;
        }
        true
    };
    while kept.len() > 3 {
        let m = kept.len();
        let mut best: Option<(f64, usize)> = None;
        for k in 0..m {
            let (i, j, l) = (kept[(k + m - 1) % m], kept[k], kept[(k + 1) % m]);
            if held[j] {
                continue;
            }
            let (e1, e2) = (ring[j] - ring[i], ring[l] - ring[j]);
            let len = e1.length() * e2.length();
            if len.is_nan() || len <= 0.0 || e1.dot(e2) <= 0.0 {
                continue;
            }
            let sine = e1.perp_dot(e2).abs() / len;
            if sine < max_sine && best.is_none_or(|(b, _)| sine < b) && fits(i, l) {
                best = Some((sine, k));
            }
        }
        let Some((_, k)) = best else { break };
        kept.remove(k);
    }
    kept.into_iter().map(|i| ring[i]).collect()
}

/// The indices of the vertices of `ring` that remain when duplicates and collinear vertices are
/// removed without moving any (the straight skeleton's input): a vertex closer than `dup` to
/// the previous kept one goes; a vertex going straight on whose distance to the chord of its
/// neighbours is under `col` goes. A vertex where the ring turns back on itself, the far end
/// of the shorter edge less than `spike` off the longer one's line, is an error (a spike):
/// `Err(index)`. One removal at a time, the first in ring order.
pub(crate) fn simplified_indices(
    ring: &[DVec2],
    dup: f64,
    col: f64,
    spike: f64,
) -> Result<Vec<usize>, usize> {
    let n = ring.len();
    let mut keep: Vec<usize> = (0..n).collect();
    let mut changed = true;
    while changed && keep.len() >= 3 {
        changed = false;
        let m = keep.len();
        for k in 0..m {
            let (a, b, c) = (
                ring[keep[(k + m - 1) % m]],
                ring[keep[k]],
                ring[keep[(k + 1) % m]],
            );
            let (ab, bc) = (b - a, c - b);
            let remove = if ab.length() < dup {
                true
            } else if bc.length() < dup {
                false // handled when the next vertex is visited
            } else {
                let cross = ab.perp_dot(bc);
                if ab.dot(bc) > 0.0 {
                    let ac = c - a;
                    cross.abs() / ac.length() < col
                } else if cross.abs() / ab.length().max(bc.length()) < spike {
                    return Err(keep[k]);
                } else {
                    false
                }
            };
            if remove {
                keep.remove(k);
                changed = true;
                break;
            }
        }
    }
    Ok(keep)
}

/// Lengths below this are zero in [`clean_ring`] (metres).
const RING_EPS: f64 = 1e-6;

/// The writers' ring: without repeated (closer than 0.1 mm), closing or collinear (within
/// 1 µm) vertices, counter-clockwise; `None` when a point is not finite, or fewer than 3
/// vertices or no area remain.
pub(crate) fn clean_ring(ring: &[DVec2]) -> Option<Vec<DVec2>> {
    if ring.iter().any(|p| !p.is_finite()) {
        return None;
    }
    let mut r = ring.to_vec();
    dedup_within(&mut r, 1e-4);
    remove_collinear(&mut r, 1e-6, RING_EPS);
    if r.len() < 3 {
        return None;
    }
    let area = ring_signed_area(&r);
    if area.abs() <= 1e-8 {
        return None;
    }
    if area < 0.0 {
        r.reverse();
    }
    Some(r)
}

#[cfg(test)]
mod tests;
