//! Polygons cleaned as they are read: rings merged, validity checked, self-intersections
//! repaired, each repair or skip reported.

use geo::BooleanOps;
use glam::DVec2;
use rstar::primitives::{GeomWithData, Rectangle};
use rstar::{RTree, RTreeObject};

use super::{MAX_CHECKED_VERTICES, MERGE_TOLERANCE, MIN_AREA, MIN_PART_AREA, MIN_PART_WIDTH};
use crate::geometry::{ring, Polygon};
use crate::model::SourceId;
use crate::report::{Outcome, Report};

/// Cleans polygons: merges near-duplicate vertices, drops spikes and degenerate rings,
/// repairs self-intersections and stray holes with a boolean union, drops slivers.
/// `None` (with a report entry) when nothing usable is left.
pub(super) fn clean_polygons(
    id: SourceId,
    polys: Vec<Polygon>,
    report: &mut Report,
) -> Option<Vec<Polygon>> {
    let (polygons, entry) = clean_polygons_quietly(polys, Least::OUTLINE);
    if let Some((outcome, text)) = entry {
        report.add(Some(id), outcome, text);
    }
    polygons
}

/// What [`clean_polygons_quietly`] gives: the cleaned polygons (`None`: skipped) and the report
/// entry for the footprint, if any.
pub(super) type Cleaned = (Option<Vec<Polygon>>, Option<(Outcome, String)>);

/// The least a cleaned polygon keeps to be drawn: its area (m²) and its mean width (metres,
/// twice the area over the perimeter).
#[derive(Clone, Copy, Debug)]
pub(super) struct Least {
    area: f64,
    width: f64,
}

impl Least {
    /// An outline's polygons: [`MIN_AREA`].
    pub(super) const OUTLINE: Least = Least {
        area: MIN_AREA,
        width: 0.0,
    };
    /// A tagged `building:part`'s: drawn at any size, dropped only with no area
    /// ([`MIN_PART_AREA`], [`MIN_PART_WIDTH`]).
    pub(super) const PART: Least = Least {
        area: MIN_PART_AREA,
        width: MIN_PART_WIDTH,
    };

    fn keeps(&self, p: &Polygon) -> bool {
        let area = p.area();
        let perimeter: f64 = p.rings().map(|r| super::ring_perimeter(r)).sum();
        area >= self.area && 2.0 * area >= self.width * perimeter
    }

    /// What a polygon under it is, for the report.
    fn describe(&self) -> String {
        if self.width > 0.0 {
            format!(
                "with no area (under {} m², or under {} m wide)",
                self.area, self.width
            )
        } else {
            format!("smaller than {} m²", self.area)
        }
    }
}

/// [`clean_polygons`] without a report, keeping what `least` keeps: the cleaned polygons
/// (`None`: the footprint is skipped) and the report entry to add for it, if any.
pub(super) fn clean_polygons_quietly(
    polys: Vec<Polygon>,
    least: Least,
) -> (Option<Vec<Polygon>>, Option<(Outcome, String)>) {
    let mut out = Vec::with_capacity(polys.len());
    let mut repaired = Vec::new();
    for p in polys {
        let Some((outer, spikes)) = merge_ring(&p.outer) else {
            repaired.push("dropped an outer ring with fewer than 3 distinct vertices".to_string());
            continue;
        };
        let mut spikes_removed = spikes;
        let mut holes = Vec::with_capacity(p.holes.len());
        for h in &p.holes {
            match merge_ring(h) {
                Some((r, spikes)) => {
                    spikes_removed += spikes;
                    holes.push(r);
                }
                None => repaired.push("dropped a degenerate inner ring".to_string()),
            }
        }
        if spikes_removed > 0 {
            repaired.push(format!(
                "removed {spikes_removed} spike(s) (an edge going out and straight back)"
            ));
        }
        let poly = Polygon::new(outer, holes);
        if is_valid(&poly) {
            out.push(poly);
        } else {
            let fixed = repair(&poly);
            repaired.push(format!(
                "self-intersecting or inconsistent rings resolved into {} polygon(s)",
                fixed.len()
            ));
            out.extend(fixed);
        }
    }
    let before = out.len();
    out.retain(|p| least.keeps(p));
    if out.len() < before {
        repaired.push(format!(
            "dropped {} polygon(s) {}",
            before - out.len(),
            least.describe()
        ));
    }
    if out.is_empty() {
        let why = if repaired.is_empty() {
            "no usable polygon".to_string()
        } else {
            repaired.join("; ")
        };
        return (
            None,
            Some((Outcome::Skipped, format!("degenerate footprint: {why}"))),
        );
    }
    let entry = (!repaired.is_empty()).then(|| (Outcome::Repaired, repaired.join("; ")));
    (Some(out), entry)
}

/// Merges vertices closer than the tolerance and removes zero-width spikes (a, b, a)
/// ([`ring::dedup_within`], [`ring::remove_spikes_by`]); returns the ring and the number of
/// spikes. `None` when fewer than 3 vertices are left. (A ring can still have zero area, e.g. a
/// bow-tie: the validity check and the repair handle that.)
pub(super) fn merge_ring(r: &[DVec2]) -> Option<(Vec<DVec2>, usize)> {
    let mut v = r.to_vec();
    ring::dedup_within(&mut v, MERGE_TOLERANCE);
    let spikes = ring::remove_spikes_by(&mut v, |a, b| a.distance(b) <= MERGE_TOLERANCE);
    (v.len() >= 3).then_some((v, spikes))
}

/// The most segments [`is_valid`] checks pairwise.
const SMALL_CHECK: usize = 64;

/// Whether rings are simple, do not cross each other, and holes lie inside the outer ring.
/// Past [`SMALL_CHECK`] segments, the segments in an R-tree: each is tested against those
/// whose box meets its own (two segments that touch do), so that a polygon of many rings (an
/// outline with the holes of thousands of parts) costs O(n log n), not O(n²).
pub(super) fn is_valid(p: &Polygon) -> bool {
    let total: usize = p.rings().map(Vec::len).sum();
    if total > MAX_CHECKED_VERTICES {
        return true; // too large to check; the writers cope with it
    }
    let segs: Vec<Segment> = p
        .rings()
        .enumerate()
        .flat_map(|(ri, r)| (0..r.len()).map(move |i| (r[i], r[(i + 1) % r.len()], ri, i)))
        .collect();
    let lens: Vec<usize> = p.rings().map(Vec::len).collect();
    // Whether segments i < j of `segs` touch, neighbours along one ring excepted.
    let touch = |i: usize, j: usize| {
        let (a, b) = (&segs[i], &segs[j]);
        let adjacent =
            a.2 == b.2 && (b.3 == a.3 + 1 || (a.3 == 0 && b.3 == lens[a.2].saturating_sub(1)));
        !adjacent && segments_touch(a.0, a.1, b.0, b.1)
    };
    // Small rings pairwise (an index costs more than it saves under a few dozen segments,
    // and nearly every footprint is small); large ones through an R-tree of the segments'
    // boxes (issue 43: a relation's outline with thousands of vertices). The same answer.
    let indexed =
        segs.len() > SMALL_CHECK && segs.iter().all(|s| s.0.is_finite() && s.1.is_finite());
    let crossing = if indexed {
        let boxes: Vec<GeomWithData<Rectangle<[f64; 2]>, usize>> = segs
            .iter()
            .enumerate()
            .map(|(i, s)| {
                let (lo, hi) = (s.0.min(s.1), s.0.max(s.1));
                GeomWithData::new(Rectangle::from_corners(lo.to_array(), hi.to_array()), i)
            })
            .collect();
        let tree = RTree::bulk_load(boxes.clone());
        boxes.iter().any(|b| {
            tree.locate_in_envelope_intersecting(b.envelope())
                .any(|o| o.data > b.data && touch(b.data, o.data))
        })
    } else {
        // Small, or not finite: no box to index (such a segment may still cross a finite one).
        (0..segs.len()).any(|i| (i + 1..segs.len()).any(|j| touch(i, j)))
    };
    !crossing
        && p.holes.iter().all(|h| {
            h.iter()
                .all(|q| crate::geometry::ring_contains(&p.outer, *q))
        })
}

/// A segment of a polygon's ring: its ends, the ring's index and the segment's.
type Segment = (DVec2, DVec2, usize, usize);

fn segments_touch(a: DVec2, b: DVec2, c: DVec2, d: DVec2) -> bool {
    let orient = |p: DVec2, q: DVec2, r: DVec2| (q - p).perp_dot(r - p);
    let (d1, d2, d3, d4) = (
        orient(c, d, a),
        orient(c, d, b),
        orient(a, b, c),
        orient(a, b, d),
    );
    if ((d1 > 0.0 && d2 < 0.0) || (d1 < 0.0 && d2 > 0.0))
        && ((d3 > 0.0 && d4 < 0.0) || (d3 < 0.0 && d4 > 0.0))
    {
        return true;
    }
    let on = |p: DVec2, q: DVec2, r: DVec2, o: f64| {
        o.abs() <= 1e-12 * (1.0 + (q - p).length_squared())
            && r.x >= p.x.min(q.x)
            && r.x <= p.x.max(q.x)
            && r.y >= p.y.min(q.y)
            && r.y <= p.y.max(q.y)
    };
    on(c, d, a, d1) || on(c, d, b, d2) || on(a, b, c, d3) || on(a, b, d, d4)
}

/// Resolves self-intersections with a boolean union of the polygon with nothing.
fn repair(p: &Polygon) -> Vec<Polygon> {
    let to_ring =
        |r: &Vec<DVec2>| geo::LineString::from(r.iter().map(|q| (q.x, q.y)).collect::<Vec<_>>());
    let g = geo::Polygon::new(to_ring(&p.outer), p.holes.iter().map(to_ring).collect());
    let fixed = g.union(&geo::MultiPolygon::<f64>::new(Vec::new()));
    fixed
        .0
        .into_iter()
        .filter_map(|gp| {
            let ring = |ls: &geo::LineString<f64>| -> Vec<DVec2> {
                ls.0.iter().map(|c| DVec2::new(c.x, c.y)).collect()
            };
            let (outer, _) = merge_ring(&ring(gp.exterior()))?;
            let holes = gp
                .interiors()
                .iter()
                .filter_map(|h| merge_ring(&ring(h)).map(|(r, _)| r))
                .collect();
            Some(Polygon::new(outer, holes))
        })
        .collect()
}
