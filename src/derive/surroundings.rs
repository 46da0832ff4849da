//! What stands around a building: every other building's parts as derived (footprint and height
//! range), and the stretches of a wall that face one of them (`party_spans`).
//!
//! At LOD3 a wall that touches or faces a neighbour closer than `PARTY_REACH` is a party
//! wall up to the neighbour's top: `derive::frontage` cuts no window, door or balcony
//! there. The neighbours' heights are those of their own derivation: [`Surroundings`] is built
//! before the run by deriving every building that may touch one of the run's at LOD2
//! ([`crate::derive::Generator::surroundings`]), on each building's own random stream, so that
//! a building's neighbours are the same at any thread count, tile size or `--bbox`.

use glam::DVec2;
use rstar::primitives::{GeomWithData, Rectangle};
use rstar::{RTree, AABB};

use crate::model::{Part, SourceId};

/// How far outside a wall (metres) a neighbouring footprint makes it a party wall: a window
/// whose outside, up to this far, lies in another building opens into it.
pub(crate) const PARTY_REACH: f64 = 0.5;

/// Where the strip outside a wall starts (metres): a neighbour that only meets the wall's line
/// (a corner on it) is not in front of the wall.
const PARTY_NEAR: f64 = 0.02;

/// One derived part of another building.
#[derive(Clone, Debug, PartialEq)]
pub struct Neighbour {
    /// The building (lot) it belongs to: a building's own parts are not its neighbours.
    pub owner: SourceId,
    /// Its footprint rings (outer first), local frame.
    pub rings: Vec<Vec<DVec2>>,
    /// Its base, metres.
    pub z0: f64,
    /// Its top (roof included), metres.
    pub z1: f64,
}

impl Neighbour {
    /// The neighbour of building `owner` that part `p` makes.
    pub(crate) fn of_part(owner: SourceId, p: &Part) -> Neighbour {
        Neighbour {
            owner,
            rings: p.footprint.rings().cloned().collect(),
            z0: p.base_z,
            z1: p.top_z,
        }
    }
}

type Entry = GeomWithData<Rectangle<[f64; 2]>, usize>;

/// Every building's parts around a run's buildings, indexed by their bounds.
#[derive(Default)]
pub struct Surroundings {
    parts: Vec<Neighbour>,
    tree: RTree<Entry>,
}

impl Surroundings {
    /// An index of `parts`.
    pub fn new(parts: Vec<Neighbour>) -> Surroundings {
        let entries = parts
            .iter()
            .enumerate()
            .filter_map(|(i, n)| {
                let (lo, hi) = bounds(n.rings.first()?)?;
                Some(Entry::new(
                    Rectangle::from_corners(lo.to_array(), hi.to_array()),
                    i,
                ))
            })
            .collect();
        Surroundings {
            parts,
            tree: RTree::bulk_load(entries),
        }
    }

    /// How many parts it holds.
    pub fn len(&self) -> usize {
        self.parts.len()
    }

    /// Whether it holds none.
    pub fn is_empty(&self) -> bool {
        self.parts.is_empty()
    }

    /// The indices of the parts whose bounds meet `lo..hi`, whatever their building, in index
    /// order (for a building's own parts among themselves: [`Surroundings::part`]).
    pub(crate) fn indices_near(&self, lo: DVec2, hi: DVec2) -> Vec<usize> {
        let mut found: Vec<usize> = self
            .tree
            .locate_in_envelope_intersecting(AABB::from_corners(lo.to_array(), hi.to_array()))
            .map(|e| e.data)
            .collect();
        found.sort_unstable();
        found
    }

    /// Part `i` of the index.
    pub(crate) fn part(&self, i: usize) -> &Neighbour {
        &self.parts[i]
    }

    /// The parts of buildings other than `owner` whose bounds meet `lo..hi`, in index order.
    pub fn near(&self, owner: SourceId, lo: DVec2, hi: DVec2) -> Vec<&Neighbour> {
        let mut found: Vec<usize> = self
            .tree
            .locate_in_envelope_intersecting(AABB::from_corners(lo.to_array(), hi.to_array()))
            .map(|e| e.data)
            .filter(|&i| self.parts[i].owner != owner)
            .collect();
        found.sort_unstable();
        found.into_iter().map(|i| &self.parts[i]).collect()
    }
}

/// Bounds of a ring, `None` when empty or not finite.
fn bounds(ring: &[DVec2]) -> Option<(DVec2, DVec2)> {
    let mut lo = DVec2::splat(f64::INFINITY);
    let mut hi = DVec2::splat(f64::NEG_INFINITY);
    for p in ring {
        lo = lo.min(*p);
        hi = hi.max(*p);
    }
    (lo.is_finite() && hi.is_finite()).then_some((lo, hi))
}

/// A stretch of a wall in front of a neighbour: `u0..u1` along the wall from its start, and the
/// neighbour's height range `z0..z1`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Span {
    /// Start along the wall, metres.
    pub u0: f64,
    /// End along the wall, metres.
    pub u1: f64,
    /// The neighbour's base, metres.
    pub z0: f64,
    /// The neighbour's top, metres.
    pub z1: f64,
}

impl Span {
    /// Whether the rectangle `u0..u1` by `z0..z1` of the wall meets this span (touching is not
    /// meeting).
    pub fn meets(&self, u0: f64, u1: f64, z0: f64, z1: f64) -> bool {
        u0 < self.u1 && self.u0 < u1 && z0 < self.z1 && self.z0 < z1
    }
}

/// The stretches of the wall from `a` to `b` (outside on its right, as on a counter-clockwise
/// outer ring) in front of `n`: where some point up to [`PARTY_REACH`] outside the wall lies in
/// `n`'s footprint. Exact for any footprint: the strip's stretches crossed by an edge of `n`,
/// and those between where no edge crosses and the strip lies inside `n`. Appended to `out`,
/// merged where they touch.
pub(crate) fn party_spans(a: DVec2, b: DVec2, n: &Neighbour, out: &mut Vec<Span>) {
    strip_spans(a, b, n, PARTY_REACH, out);
}

/// The stretches of the wall from `a` to `b` where some point up to `reach` outside it lies in
/// `n`'s footprint, as [`party_spans`] (which is this at [`PARTY_REACH`]); what a balcony
/// `reach` deep would reach into (issue 45).
pub(crate) fn strip_spans(a: DVec2, b: DVec2, n: &Neighbour, reach: f64, out: &mut Vec<Span>) {
    let len = a.distance(b);
    if len.is_nan() || len <= 1e-9 || n.z1 <= n.z0 {
        return;
    }
    let d = (b - a) / len;
    let out_dir = DVec2::new(d.y, -d.x);
    let ut = |p: DVec2| DVec2::new((p - a).dot(d), (p - a).dot(out_dir));
    let mut hits: Vec<(f64, f64)> = Vec::new();
    for r in &n.rings {
        for i in 0..r.len() {
            let (p, q) = (ut(r[i]), ut(r[(i + 1) % r.len()]));
            if let Some((s, e)) = clip_to_strip(p, q, len, reach) {
                hits.push((s.min(e), s.max(e)));
            }
        }
    }
    // Between the crossings the strip is wholly in or wholly out of the neighbour.
    let mut cuts: Vec<f64> = vec![0.0, len];
    cuts.extend(hits.iter().flat_map(|&(s, e)| [s, e]));
    cuts.sort_by(f64::total_cmp);
    cuts.dedup_by(|x, y| (*x - *y).abs() < 1e-9);
    let mid_t = 0.5 * (PARTY_NEAR + reach);
    for w in cuts.windows(2) {
        let m = 0.5 * (w[0] + w[1]);
        if hits.iter().any(|&(s, e)| s <= m && m <= e) {
            continue;
        }
        let p = a + d * m + out_dir * mid_t;
        let inside = n
            .rings
            .iter()
            .filter(|r| crate::geometry::ring_contains(r, p))
            .count()
            % 2
            == 1;
        if inside {
            hits.push((w[0], w[1]));
        }
    }
    hits.sort_by(|x, y| x.0.total_cmp(&y.0));
    // An edge across the strip is a crossing, not a stretch: what lies beside it was tested.
    hits.retain(|(s, e)| e - s > 1e-6);
    let first = out.len();
    for (s, e) in hits {
        match out[first..].last_mut() {
            Some(last) if s <= last.u1 + 1e-9 => last.u1 = last.u1.max(e),
            _ => out.push(Span {
                u0: s,
                u1: e,
                z0: n.z0,
                z1: n.z1,
            }),
        }
    }
}

/// The part of segment `p`-`q` (wall coordinates: u along, t out) inside the strip
/// `0..=len` by `PARTY_NEAR..=reach`, as its two ends' u (Liang-Barsky).
fn clip_to_strip(p: DVec2, q: DVec2, len: f64, reach: f64) -> Option<(f64, f64)> {
    let d = q - p;
    let (mut t0, mut t1) = (0.0f64, 1.0f64);
    for (den, num) in [
        (-d.x, p.x),
        (d.x, len - p.x),
        (-d.y, p.y - PARTY_NEAR),
        (d.y, reach - p.y),
    ] {
        if den == 0.0 {
            if num < 0.0 {
                return None;
            }
        } else {
            let r = num / den;
            if den < 0.0 {
                t0 = t0.max(r);
            } else {
                t1 = t1.min(r);
            }
        }
    }
    (t0 <= t1).then_some((p.x + d.x * t0, p.x + d.x * t1))
}

/// The union area of `spans` over the rectangle `0..len` by `z0..z1`, divided by its area.
pub fn share(spans: &[Span], len: f64, z0: f64, z1: f64) -> f64 {
    let area = len * (z1 - z0);
    if area.is_nan() || area <= 0.0 || spans.is_empty() {
        return 0.0;
    }
    let mut us: Vec<f64> = vec![0.0, len];
    us.extend(
        spans
            .iter()
            .flat_map(|s| [s.u0.clamp(0.0, len), s.u1.clamp(0.0, len)]),
    );
    us.sort_by(f64::total_cmp);
    us.dedup();
    let mut covered = 0.0;
    for w in us.windows(2) {
        let m = 0.5 * (w[0] + w[1]);
        let mut zs: Vec<(f64, f64)> = spans
            .iter()
            .filter(|s| s.u0 <= m && m <= s.u1)
            .map(|s| (s.z0.max(z0), s.z1.min(z1)))
            .filter(|(a, b)| b > a)
            .collect();
        zs.sort_by(|x, y| x.0.total_cmp(&y.0));
        let (mut h, mut top) = (0.0, f64::NEG_INFINITY);
        for (a, b) in zs {
            let a = a.max(top);
            if b > a {
                h += b - a;
            }
            top = top.max(b);
        }
        covered += (w[1] - w[0]) * h;
    }
    (covered / area).clamp(0.0, 1.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn square(x0: f64, y0: f64, s: f64, z1: f64) -> Neighbour {
        let v = DVec2::new;
        Neighbour {
            owner: SourceId::Way(9),
            rings: vec![vec![
                v(x0, y0),
                v(x0 + s, y0),
                v(x0 + s, y0 + s),
                v(x0, y0 + s),
            ]],
            z0: 0.0,
            z1,
        }
    }

    #[test]
    fn a_touching_neighbour_covers_the_shared_stretch_only() {
        // A wall a -> b has its outside on its right: from (0,10) to (0,0) that is x < 0.
        let (a, b) = (DVec2::new(0.0, 10.0), DVec2::new(0.0, 0.0));
        // A neighbour west of the wall, sharing y 2..6 of it.
        let n = square(-4.0, 2.0, 4.0, 12.0);
        let mut s = Vec::new();
        party_spans(a, b, &n, &mut s);
        assert_eq!(s.len(), 1, "{s:?}");
        assert!(
            (s[0].u0 - 4.0).abs() < 1e-9 && (s[0].u1 - 8.0).abs() < 1e-9,
            "{s:?}"
        );
        assert_eq!((s[0].z0, s[0].z1), (0.0, 12.0));
        // 4 of 10 m, and the neighbour is taller than the wall.
        assert!((share(&s, 10.0, 0.0, 9.0) - 0.4).abs() < 1e-9);
        // Half as tall as the wall: a fifth.
        assert!((share(&s, 10.0, 0.0, 24.0) - 0.2).abs() < 1e-9);
    }

    #[test]
    fn a_neighbour_behind_the_wall_or_far_away_is_not_in_front() {
        let (a, b) = (DVec2::new(0.0, 10.0), DVec2::new(0.0, 0.0));
        let mut s = Vec::new();
        // East of the wall: inside our own building's side.
        party_spans(a, b, &square(0.0, 2.0, 4.0, 9.0), &mut s);
        // 0.6 m west: beyond the reach.
        party_spans(a, b, &square(-4.6, 2.0, 4.0, 9.0), &mut s);
        // Meets the wall's line at one corner only.
        party_spans(a, b, &square(-4.0, 10.0, 4.0, 9.0), &mut s);
        assert!(s.is_empty(), "{s:?}");
        // 0.3 m west: within reach.
        party_spans(a, b, &square(-4.3, 2.0, 4.0, 9.0), &mut s);
        assert_eq!(s.len(), 1);
    }

    #[test]
    fn a_neighbour_that_wraps_the_strip_covers_it_without_crossing() {
        // A big neighbour whose edges do not cross the strip in its middle: the whole wall.
        let (a, b) = (DVec2::new(0.0, 10.0), DVec2::new(0.0, 0.0));
        let mut s = Vec::new();
        party_spans(a, b, &square(-50.0, -20.0, 50.0, 30.0), &mut s);
        assert_eq!(s.len(), 1);
        assert!(
            (s[0].u0).abs() < 1e-9 && (s[0].u1 - 10.0).abs() < 1e-9,
            "{s:?}"
        );
    }

    #[test]
    fn the_index_leaves_out_the_owner() {
        let mut own = square(-4.0, 2.0, 4.0, 9.0);
        own.owner = SourceId::Way(1);
        let other = square(-4.0, 2.0, 4.0, 9.0);
        let s = Surroundings::new(vec![own, other]);
        let near = s.near(
            SourceId::Way(1),
            DVec2::new(-1.0, 0.0),
            DVec2::new(1.0, 10.0),
        );
        assert_eq!(near.len(), 1);
        assert_eq!(near[0].owner, SourceId::Way(9));
    }
}
