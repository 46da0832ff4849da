//! The street front of each lot: the edge facing the nearest street, unless another building
//! stands against it.

use glam::DVec2;
use rayon::prelude::*;
use rstar::{RTree, RTreeObject, AABB};

use super::{Site, MERGE_TOLERANCE};
use crate::crs::Crs;
use crate::geometry::Polygon;
use crate::input::{StreetKind, Streets};

/// A street farther than this (metres) from every facing outline edge does not make a front:
/// beyond it a building stands in a park, a compound or behind other buildings, and the nearest
/// street says little about where its door is.
pub const FRONT_MAX_DISTANCE: f64 = 50.0;
/// Outline edges shorter than this (metres) are passed over for the front when the outline has
/// longer ones: a chamfered corner or a small recess would get the door otherwise, and a door
/// bay does not fit on it.
const FRONT_MIN_EDGE: f64 = 2.0;
/// Edges whose distance to the street is within this (metres) of the nearest one count as
/// equally near; the longest of them is the front (the main facade over a slightly closer
/// recess).
const FRONT_TIE: f64 = 1.0;
/// An edge faces a street when the direction from its midpoint to the street's nearest point is
/// within 60° of its outward normal.
const FRONT_COS_CONE: f64 = 0.5;

/// How much farther (metres) a street of each kind counts than a road when the front is
/// chosen (issue 45): a building faces its road rather than the back lane, drive or footpath
/// behind it, unless the road is that much farther away. Sidewalks run in front of the facades
/// anyway, and a house in an old town that opens only onto stepped lanes still faces them.
fn kind_penalty(kind: StreetKind) -> f64 {
    match kind {
        StreetKind::Road => 0.0,
        StreetKind::Service | StreetKind::Foot => 4.0,
        StreetKind::Lane => 20.0,
    }
}

/// A street segment in the front index, local metres, with its kind and name (an index into
/// [`Streets::names`], [`Streets::NO_NAME`] for none).
pub(super) struct StreetSegment(
    pub(super) [f64; 2],
    pub(super) [f64; 2],
    pub(super) StreetKind,
    pub(super) u32,
);

impl StreetSegment {
    /// A nameless road from `a` to `b`.
    #[cfg(test)]
    pub(super) fn road(a: [f64; 2], b: [f64; 2]) -> StreetSegment {
        StreetSegment(a, b, StreetKind::Road, Streets::NO_NAME)
    }
}

impl RTreeObject for StreetSegment {
    type Envelope = AABB<[f64; 2]>;
    fn envelope(&self) -> Self::Envelope {
        AABB::from_corners(self.0, self.1)
    }
}

/// Sets [`Lot::front`](super::Lot::front) of every lot from the street centre lines the reader
/// gave (in the same source coordinates as the footprints, `source_crs` as for
/// [`prepare`](super::prepare)).
///
/// For each outer edge of the outline (edges shorter than 2 m are passed over when longer ones
/// exist) and each street segment near the lot (an rstar index over the segments), the edge
/// *faces* the segment when the segment's point nearest to the edge's midpoint lies within 60°
/// of the edge's outward normal; its distance is that of the midpoint (so the long side of a
/// building whose corner touches a street does not win over the end wall that faces it). The
/// nearest facing edge within [`FRONT_MAX_DISTANCE`] — the longest of those within 1 m of the
/// nearest — gives the front: its outward normal. Issue 45: an outline with an `addr:street`
/// ([`Streets::address`]; without one, the street most of its address and entrance nodes
/// name, [`Streets::address_points`] inside it or within `ADDRESS_NODE_REACH` of it) that
/// has an edge facing a street of that name takes its front among
/// those edges only; otherwise each street's distance counts its kind's penalty
/// (`kind_penalty`: a back lane or drive 20 m, a footway or other service road 4 m), so a
/// row of houses between its street and a nearer alley faces the street. Pure per lot, so it runs in parallel and the
/// result does not depend on the thread count. Street vertices that cannot be projected break
/// their line.
///
/// An edge whose outside is another building's (probes a quarter, half and three quarters
/// along it, [`FRONT_PARTY_PROBE`] out, all inside another lot's outline) is no front: a
/// party wall does not face the street beyond its neighbour.
///
/// Not handled: a street hidden behind another building still counts (no visibility test).
pub fn assign_fronts(site: &mut Site, streets: &Streets, source_crs: Option<Crs>) {
    if streets.is_empty() {
        return;
    }
    let crs = site.crs;
    let origin = site.origin;
    let local = |x: f64, y: f64| -> Option<DVec2> {
        let (lon, lat) = match source_crs {
            None | Some(Crs::Wgs84) => (x, y),
            Some(c) if c == crs => return finite(DVec2::new(x, y) * c.unit().metres - origin),
            Some(c) => c.file_to_lonlat(x, y),
        };
        let (px, py) = crs.from_lonlat(lon, lat);
        finite(DVec2::new(px, py) - origin)
    };
    let mut segments = Vec::new();
    for (i, line) in streets.lines().enumerate() {
        let (kind, name) = streets.line_info(i);
        let pts: Vec<Option<DVec2>> = line.iter().map(|&(x, y)| local(x, y)).collect();
        for w in pts.windows(2) {
            if let [Some(a), Some(b)] = *w {
                if a.distance(b) > MERGE_TOLERANCE {
                    segments.push(StreetSegment([a.x, a.y], [b.x, b.y], kind, name));
                }
            }
        }
    }
    let tree = RTree::bulk_load(segments);
    let points = RTree::bulk_load(
        streets
            .address_points
            .iter()
            .filter_map(|&(x, y, n)| Some(AddressPoint::new(local(x, y)?.to_array(), n)))
            .collect(),
    );
    let outlines: Vec<OutlineEntry> = site
        .lots
        .iter()
        .enumerate()
        .flat_map(|(i, l)| {
            l.polygons.iter().enumerate().map(move |(j, p)| {
                let (lo, hi) = p.bounds();
                OutlineEntry::new(
                    rstar::primitives::Rectangle::from_corners(lo.to_array(), hi.to_array()),
                    (i, j),
                )
            })
        })
        .collect();
    let outlines = RTree::bulk_load(outlines);
    let lots = &site.lots;
    let fronts: Vec<Option<DVec2>> = lots
        .par_iter()
        .enumerate()
        .map(|(i, lot)| {
            let others = |p: DVec2| {
                outlines
                    .locate_all_at_point(p.to_array())
                    .any(|e| e.data.0 != i && lots[e.data.0].polygons[e.data.1].contains(p))
            };
            let address = streets
                .address(lot.id)
                .or_else(|| address_of_points(&lot.polygons, &points));
            front_of(&lot.polygons, &tree, address, &others)
        })
        .collect();
    for (lot, f) in site.lots.iter_mut().zip(fronts) {
        lot.front = f;
    }
}

/// An address node (`addr:street` on a node, issue 45) in the index of [`assign_fronts`]: its
/// local position and its street's name index.
type AddressPoint = rstar::primitives::GeomWithData<[f64; 2], u32>;

/// How far outside an outline (metres) an address node still belongs to it: an entrance
/// node sits on the outline, and a mapper's address node just outside its wall is the
/// building's.
pub const ADDRESS_NODE_REACH: f64 = 1.0;

/// The street an outline's address nodes name (issue 45): those inside its polygons or within
/// [`ADDRESS_NODE_REACH`] of their outer rings; the name most of them give (the first in
/// name order on a tie), `None` without any.
pub(super) fn address_of_points(polygons: &[Polygon], points: &RTree<AddressPoint>) -> Option<u32> {
    let mut counts: std::collections::BTreeMap<u32, usize> = Default::default();
    let m = DVec2::splat(ADDRESS_NODE_REACH);
    for p in polygons {
        let (lo, hi) = p.bounds();
        let r = &p.outer;
        for a in
            points.locate_in_envelope(AABB::from_corners((lo - m).to_array(), (hi + m).to_array()))
        {
            let q = DVec2::from(*a.geom());
            let near = p.contains(q)
                || (0..r.len()).any(|i| {
                    nearest_on_segment(r[i], r[(i + 1) % r.len()], q).distance(q)
                        <= ADDRESS_NODE_REACH
                });
            if near {
                *counts.entry(a.data).or_default() += 1;
            }
        }
    }
    counts
        .into_iter()
        .rev()
        .max_by_key(|&(_, c)| c)
        .map(|(n, _)| n)
}

/// How far outside an edge [`assign_fronts`] looks for another building (metres).
pub const FRONT_PARTY_PROBE: f64 = 0.25;

/// A lot's outline polygon in the index of [`assign_fronts`]: (lot, polygon).
type OutlineEntry =
    rstar::primitives::GeomWithData<rstar::primitives::Rectangle<[f64; 2]>, (usize, usize)>;

fn finite(p: DVec2) -> Option<DVec2> {
    p.is_finite().then_some(p)
}

/// The point of segment `a`-`b` nearest to `p`.
pub(super) fn nearest_on_segment(a: DVec2, b: DVec2, p: DVec2) -> DVec2 {
    let d = b - a;
    let l2 = d.length_squared();
    if l2 <= 0.0 {
        return a;
    }
    a + d * ((p - a).dot(d) / l2).clamp(0.0, 1.0)
}

/// The front of one outline (see [`assign_fronts`]), whose `addr:street` is `address` (an
/// index into [`Streets::names`]).
pub(super) fn front_of(
    polygons: &[Polygon],
    tree: &RTree<StreetSegment>,
    address: Option<u32>,
    in_another: &dyn Fn(DVec2) -> bool,
) -> Option<DVec2> {
    let (mut lo, mut hi) = (DVec2::splat(f64::INFINITY), DVec2::splat(f64::NEG_INFINITY));
    for p in polygons {
        let (a, b) = p.bounds();
        lo = lo.min(a);
        hi = hi.max(b);
    }
    if !(lo.is_finite() && hi.is_finite()) {
        return None;
    }
    let m = DVec2::splat(FRONT_MAX_DISTANCE);
    let near: Vec<(DVec2, DVec2, StreetKind, u32)> = tree
        .locate_in_envelope_intersecting(AABB::from_corners(
            (lo - m).to_array(),
            (hi + m).to_array(),
        ))
        .map(|s| (DVec2::from(s.0), DVec2::from(s.1), s.2, s.3))
        .collect();
    if near.is_empty() {
        return None;
    }
    // (score, length, outward normal, faces the addressed street) of every edge that faces a
    // street: its best score, distance plus the street kind's penalty (the addressed street's
    // distance alone where it faces that).
    let edges = || {
        polygons.iter().flat_map(|p| {
            let r = &p.outer;
            (0..r.len()).map(move |i| (r[i], r[(i + 1) % r.len()]))
        })
    };
    let long_exists = edges().any(|(a, b)| a.distance(b) >= FRONT_MIN_EDGE);
    let mut facing: Vec<(f64, f64, DVec2, bool)> = Vec::new();
    for (a, b) in edges() {
        let len = a.distance(b);
        if len <= MERGE_TOLERANCE || (long_exists && len < FRONT_MIN_EDGE) {
            continue;
        }
        let d = (b - a) / len;
        // Outer rings are counter-clockwise: the outside is on the right.
        let normal = DVec2::new(d.y, -d.x);
        let mid = (a + b) * 0.5;
        let party = [0.25, 0.5, 0.75]
            .iter()
            .all(|t| in_another(a + (b - a) * *t + normal * FRONT_PARTY_PROBE));
        if party {
            continue;
        }
        let mut best: Option<(f64, bool)> = None;
        for &(s0, s1, kind, name) in &near {
            let v = nearest_on_segment(s0, s1, mid) - mid;
            let dist = v.length();
            let faces = dist <= MERGE_TOLERANCE || normal.dot(v) >= FRONT_COS_CONE * dist;
            if !faces || dist > FRONT_MAX_DISTANCE {
                continue;
            }
            let addressed = address.is_some_and(|n| n == name);
            let score = if addressed {
                dist
            } else {
                dist + kind_penalty(kind)
            };
            // The addressed street first, then the lowest score.
            if best.is_none_or(|(s, ad)| (addressed, -score) > (ad, -s)) {
                best = Some((score, addressed));
            }
        }
        if let Some((score, addressed)) = best {
            facing.push((score, len, normal, addressed));
        }
    }
    // An outline facing the street of its address faces it, whatever is nearer.
    let addressed = facing.iter().any(|f| f.3);
    facing.retain(|f| f.3 == addressed);
    let nearest = facing.iter().map(|f| f.0).min_by(f64::total_cmp)?;
    facing
        .iter()
        .filter(|f| f.0 <= nearest + FRONT_TIE)
        // The longest; on equal lengths the first in ring order (max_by keeps the last).
        .rev()
        .max_by(|x, y| x.1.total_cmp(&y.1))
        .map(|f| f.2)
}
