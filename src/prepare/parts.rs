//! A lot's outline and parts made consistent: nearly straight vertices dropped, vertices
//! shared along common boundaries, parts cut out of their outline.

use glam::DVec2;
use rstar::primitives::{GeomWithData, Rectangle};
use rstar::{RTree, RTreeObject, AABB};

use super::clean::{clean_polygons_quietly, is_valid, Least};
use super::fronts::nearest_on_segment;
use super::{
    interior_point, ring_perimeter, Lot, LotPiece, STRAIGHTEN_MAX_TURN_DEG, STRAIGHTEN_TOLERANCE,
};
use crate::geometry::{ring, Polygon};
use crate::model::SourceId;
use crate::report::{Outcome, Report};

/// An edge of a lot's ring in an R-tree: (owner, start, end).
type OwnedEdge = GeomWithData<Rectangle<[f64; 2]>, (usize, DVec2, DVec2)>;

/// Straightens the rings of a lot ([`ring::straighten`] within [`STRAIGHTEN_TOLERANCE`]): the
/// outline, its drawn rest and its parts. A vertex within 1 cm of another of the lot's rings
/// stays (a part's corner on the outline, an outline's corner on a part), so that what shares a
/// boundary still does; the outline and its drawn rest, which share theirs by construction, are
/// not each other's keepers. A polygon that straightening would make touch itself stays as it
/// was.
pub(super) fn straighten_lot(lot: &mut Lot) {
    const NEAR: f64 = 0.01;
    let rings_of = |ps: &[Polygon]| -> Vec<Vec<DVec2>> {
        ps.iter().flat_map(|p| p.rings().cloned()).collect()
    };
    // The drawn rest as its own copy while it is straightened; kept apart afterwards only
    // where it differs from the outline.
    let mut drawn_polygons = lot.drawn.take().unwrap_or_else(|| lot.polygons.clone());
    let outline = rings_of(&lot.polygons);
    let drawn = rings_of(&drawn_polygons);
    let parts: Vec<Vec<Vec<DVec2>>> = lot.parts.iter().map(|p| rings_of(&p.polygons)).collect();
    // Every edge of the lot's rings, by owner (0 the outline, 1 its drawn rest, 2 + k part
    // k), in an R-tree: a lot of 10,000 parts asks each vertex about the few edges near it,
    // not about every ring of the lot.
    let owners = [&outline, &drawn].into_iter().chain(&parts);
    let edges: Vec<OwnedEdge> = owners
        .enumerate()
        .flat_map(|(owner, rings)| {
            rings
                .iter()
                .flat_map(move |r| (0..r.len()).map(move |i| (owner, r[i], r[(i + 1) % r.len()])))
        })
        .filter(|(_, a, b)| a.is_finite() && b.is_finite())
        .map(|(owner, a, b)| {
            let (lo, hi) = (a.min(b), a.max(b));
            GeomWithData::new(
                Rectangle::from_corners([lo.x, lo.y], [hi.x, hi.y]),
                (owner, a, b),
            )
        })
        .collect();
    let tree = RTree::bulk_load(edges);
    // Whether q lies within NEAR of an edge of an owner that `keeps` accepts.
    let near = |q: DVec2, keeps: &dyn Fn(usize) -> bool| {
        let r = NEAR + 1e-9;
        let env = AABB::from_corners([q.x - r, q.y - r], [q.x + r, q.y + r]);
        tree.locate_in_envelope_intersecting(env).any(|e| {
            let (owner, a, b) = e.data;
            keeps(owner) && nearest_on_segment(a, b, q).distance(q) <= NEAR
        })
    };
    let fix = |ps: &mut Vec<Polygon>, keeps: &dyn Fn(usize) -> bool| {
        for p in ps.iter_mut() {
            let straight = |r: &Vec<DVec2>| {
                ring::straighten(r, STRAIGHTEN_TOLERANCE, STRAIGHTEN_MAX_TURN_DEG, |q| {
                    near(q, keeps)
                })
            };
            let candidate =
                Polygon::new(straight(&p.outer), p.holes.iter().map(straight).collect());
            if candidate != *p && candidate.outer.len() >= 3 && is_valid(&candidate) {
                *p = candidate;
            }
        }
    };
    // The outline and its drawn rest keep what is near a part; a part what is near the
    // outline, the drawn rest or another part.
    fix(&mut lot.polygons, &|owner| owner >= 2);
    fix(&mut drawn_polygons, &|owner| owner >= 2);
    for (k, part) in lot.parts.iter_mut().enumerate() {
        fix(&mut part.polygons, &|owner| owner != k + 2);
    }
    share_vertices(lot, &mut drawn_polygons);
    lot.drawn = (drawn_polygons != lot.polygons).then_some(drawn_polygons);
}

/// How far (metres) a vertex of one of a lot's drawn rings may lie from another ring's edge
/// and be put into that edge: two rings that share a boundary then have the same vertices along
/// it, and their walls meet edge to edge (a vertex on one side only leaves a sliver between the
/// two solids, a volume overlap to a solid validator, and a T-junction in the shell).
const SHARED_VERTEX_TOLERANCE: f64 = 0.002;

/// Puts every vertex of the lot's drawn rings (the outline's rest and the parts) into the
/// edges of the others that pass within [`SHARED_VERTEX_TOLERANCE`] of it, strictly between
/// their ends (at least [`crate::model::MIN_VERTEX_GAP`] from each). A polygon that the
/// insertion would make invalid stays as it was.
fn share_vertices(lot: &mut Lot, drawn: &mut Vec<Polygon>) {
    if lot.parts.is_empty() {
        return;
    }
    let gap = crate::model::MIN_VERTEX_GAP;
    // Every vertex of each piece, with the piece it belongs to.
    let mut verts: Vec<(usize, DVec2)> = Vec::new();
    let pieces = std::iter::once(&*drawn).chain(lot.parts.iter().map(|p| &p.polygons));
    for (k, ps) in pieces.enumerate() {
        for p in ps {
            verts.extend(p.rings().flatten().map(|&v| (k, v)));
        }
    }
    // The vertices in an R-tree (those that are not finite never lie near an edge): each edge
    // looks at the vertices in its box, not at every vertex of the lot.
    let tree = RTree::bulk_load(
        verts
            .iter()
            .filter(|(_, v)| v.is_finite())
            .map(|&(k, v)| GeomWithData::new([v.x, v.y], (k, v)))
            .collect(),
    );
    let insert = |k: usize, r: &Vec<DVec2>| -> Vec<DVec2> {
        let n = r.len();
        let mut out = Vec::with_capacity(n);
        for i in 0..n {
            let (a, b) = (r[i], r[(i + 1) % n]);
            out.push(a);
            let (lo, hi) = (a.min(b), a.max(b));
            let d = b - a;
            let l2 = d.length_squared();
            let t = SHARED_VERTEX_TOLERANCE;
            let env = AABB::from_corners([lo.x - t, lo.y - t], [hi.x + t, hi.y + t]);
            let mut on: Vec<(f64, DVec2)> = tree
                .locate_in_envelope(env)
                .map(|g| &g.data)
                .filter(|(j, v)| {
                    *j != k
                        && v.x >= lo.x - SHARED_VERTEX_TOLERANCE
                        && v.x <= hi.x + SHARED_VERTEX_TOLERANCE
                        && v.y >= lo.y - SHARED_VERTEX_TOLERANCE
                        && v.y <= hi.y + SHARED_VERTEX_TOLERANCE
                })
                .filter(|&&(_, v)| {
                    v.distance(a) >= gap
                        && v.distance(b) >= gap
                        && nearest_on_segment(a, b, v).distance(v) <= SHARED_VERTEX_TOLERANCE
                })
                // Along the edge; a vertex at least `gap` from both ends of an edge it lies
                // within 2 mm of is strictly inside it, so the edge has a length.
                .map(|&(_, v)| ((v - a).dot(d) / l2, v))
                .collect();
            on.sort_by(|x, y| {
                x.0.total_cmp(&y.0)
                    .then(x.1.x.total_cmp(&y.1.x))
                    .then(x.1.y.total_cmp(&y.1.y))
            });
            on.dedup_by(|x, y| x.1.distance(y.1) < gap);
            out.extend(on.into_iter().map(|x| x.1));
        }
        out
    };
    let fix = |k: usize, ps: &mut Vec<Polygon>| {
        for p in ps.iter_mut() {
            let candidate = Polygon::new(
                insert(k, &p.outer),
                p.holes.iter().map(|h| insert(k, h)).collect(),
            );
            if candidate != *p && is_valid(&candidate) {
                *p = candidate;
            }
        }
    };
    fix(0, drawn);
    for (i, part) in lot.parts.iter_mut().enumerate() {
        fix(i + 1, &mut part.polygons);
    }
}

/// An outline's bounding box in the part-assignment index.
struct OutlineBox {
    index: usize,
    aabb: AABB<[f64; 2]>,
}

impl RTreeObject for OutlineBox {
    type Envelope = AABB<[f64; 2]>;
    fn envelope(&self) -> Self::Envelope {
        self.aabb
    }
}

/// The smallest piece of an outline left over by its parts that is still drawn (m²), and the
/// least mean width (area / half perimeter, metres): what the parts leave of an outline is
/// mostly the slivers between nearly shared edges.
const MIN_REST_AREA: f64 = 2.0;
const MIN_REST_WIDTH: f64 = 0.25;

/// Groups parts under outlines (Simple 3D Buildings). Each part goes under the smallest
/// outline containing its representative point. A part that lies in no outline but is tagged
/// `building=*` too (a church mapped as its nave with `building=church` + `building:part=yes`,
/// domes and towers as parts inside it) holds the unowned parts inside it, the largest such
/// part first, and is drawn as a part of itself; any other part that lies in no outline is a
/// building of its own (with a note). An outline with parts is a container: only what its
/// parts leave uncovered is drawn with its own tags ([`Lot::drawn_outline`]), so that outline
/// and parts never both fill one volume.
pub(super) fn group_parts(
    mut outlines: Vec<Lot>,
    pieces: Vec<(LotPiece, (f64, f64))>,
    report: &mut Report,
) -> Vec<Lot> {
    let tree = outline_index(&outlines);
    let area = |polys: &[Polygon]| polys.iter().map(Polygon::area).sum::<f64>();
    let owner_in =
        |lots: &[Lot], tree: &RTree<OutlineBox>, piece: &LotPiece, skip: Option<SourceId>| {
            let probe = interior_point(&piece.polygons[0]);
            tree.locate_in_envelope_intersecting(AABB::from_point([probe.x, probe.y]))
                .filter(|b| Some(lots[b.index].id) != skip)
                .filter(|b| lots[b.index].polygons.iter().any(|p| p.contains(probe)))
                .min_by(|a, b| {
                    area(&lots[a.index].polygons)
                        .total_cmp(&area(&lots[b.index].polygons))
                        .then(a.index.cmp(&b.index))
                })
                .map(|b| b.index)
        };
    let mut unowned = Vec::new();
    for (piece, lonlat) in pieces {
        match owner_in(&outlines, &tree, &piece, None) {
            Some(i) => outlines[i].parts.push(piece),
            None => unowned.push((piece, lonlat)),
        }
    }
    // Unowned parts tagged building=* too are candidate containers; each unowned part goes into
    // the largest candidate containing it (a dome into the nave, not into a tower).
    let is_building = |p: &LotPiece| p.tags.has_building;
    let mut containers: Vec<Lot> = unowned
        .iter()
        .filter(|(p, _)| is_building(p))
        .map(|(p, lonlat)| Lot {
            id: p.id,
            tags: p.tags.clone(),
            polygons: p.polygons.clone(),
            parts: Vec::new(),
            drawn: None,
            rest_tags: None,
            lonlat: *lonlat,
            front: None,
            ground: 0.0,
            terrain: None,
        })
        .collect();
    let ctree = outline_index(&containers);
    let largest_container = |piece: &LotPiece| {
        let probe = interior_point(&piece.polygons[0]);
        ctree
            .locate_in_envelope_intersecting(AABB::from_point([probe.x, probe.y]))
            .filter(|b| containers[b.index].id != piece.id)
            .filter(|b| {
                containers[b.index]
                    .polygons
                    .iter()
                    .any(|p| p.contains(probe))
            })
            .filter(|b| area(&containers[b.index].polygons) > area(&piece.polygons))
            .max_by(|a, b| {
                area(&containers[a.index].polygons)
                    .total_cmp(&area(&containers[b.index].polygons))
                    .then(b.index.cmp(&a.index))
            })
            .map(|b| b.index)
    };
    let homes: Vec<Option<usize>> = unowned.iter().map(|(p, _)| largest_container(p)).collect();
    let mut orphans = Vec::new();
    let mut contained = vec![false; containers.len()];
    for ((piece, lonlat), home) in unowned.into_iter().zip(homes) {
        match home {
            Some(c) => {
                if let Some(k) = containers.iter().position(|l| l.id == piece.id) {
                    contained[k] = true;
                }
                containers[c].parts.push(piece);
            }
            None if is_building(&piece) => {}
            None => {
                report.add(
                    Some(piece.id),
                    Outcome::Note,
                    "building:part lies in no building outline; generated as a building of its own",
                );
                orphans.push(Lot {
                    id: piece.id,
                    tags: piece.tags.clone(),
                    polygons: piece.polygons,
                    parts: Vec::new(),
                    drawn: None,
                    rest_tags: None,
                    lonlat,
                    front: None,
                    ground: 0.0,
                    terrain: None,
                });
            }
        }
    }
    // A container inside a larger one is one of its parts, not a building of its own.
    let containers: Vec<Lot> = containers
        .into_iter()
        .zip(contained)
        .filter(|(_, inside)| !inside)
        .map(|(l, _)| l)
        .collect();
    for lot in &mut outlines {
        if lot.parts.is_empty() {
            continue;
        }
        let parts: Vec<Polygon> = lot
            .parts
            .iter()
            .flat_map(|p| p.polygons.iter().cloned())
            .collect();
        let outline_area = area(&lot.polygons);
        let drawn = cut_out(&lot.polygons, &parts);
        lot.rest_tags = Some(lot.tags.clone());
        if !drawn.is_empty() {
            report.add(
                Some(lot.id),
                Outcome::Note,
                format!(
                    "building:parts cover {:.0} % of the outline; the rest ({:.0} m²) is drawn with the outline's own tags (traced as its outline-rest)",
                    100.0 * (1.0 - area(&drawn) / outline_area.max(1e-9)),
                    area(&drawn)
                ),
            );
        }
        lot.drawn = Some(drawn);
    }
    outlines.extend(containers);
    outlines.extend(orphans);
    for lot in &mut outlines {
        lot.parts.sort_by_key(|p| p.id);
    }
    outlines.sort_by_key(|l| l.id);
    outlines
}

/// What of `polygons` lies outside every polygon of `cutters`, cleaned as footprints are, and
/// without the slivers that nearly shared edges leave (pieces under 2 m² or 0.25 m of mean
/// width).
fn cut_out(polygons: &[Polygon], cutters: &[Polygon]) -> Vec<Polygon> {
    let rest: Vec<Polygon> = crate::geometry::clip::difference(polygons, cutters)
        .into_iter()
        .filter(|p| p.area() >= MIN_REST_AREA && mean_width(p) >= MIN_REST_WIDTH)
        .collect();
    clean_polygons_quietly(rest, Least::OUTLINE)
        .0
        .unwrap_or_default()
}

/// What of a tagged part's `polygons` lies outside every polygon of `cutters` (issue 45: a
/// part is drawn at any size): the slivers [`cut_out`] drops are measured against the part
/// itself, pieces under a twentieth of its area (at most 2 m²) or under a twentieth of its
/// mean width (at most 0.25 m) dropped, so that a column of 0.3 m² keeps what a neighbour leaves of
/// it and a ring around a shaft keeps the few centimetres it stands out; a part as large as an
/// outline is cut as [`cut_out`] cuts.
pub(crate) fn cut_part(polygons: &[Polygon], cutters: &[Polygon]) -> Vec<Polygon> {
    let area: f64 = polygons.iter().map(Polygon::area).sum();
    let width = polygons.iter().map(mean_width).fold(0.0, f64::max);
    let least_area = MIN_REST_AREA.min(0.05 * area);
    let least_width = MIN_REST_WIDTH.min(0.05 * width);
    let rest: Vec<Polygon> = crate::geometry::clip::difference(polygons, cutters)
        .into_iter()
        .filter(|p| p.area() >= least_area && mean_width(p) >= least_width)
        .collect();
    clean_polygons_quietly(rest, Least::PART)
        .0
        .unwrap_or_default()
}

/// A polygon's mean width: twice its area over its perimeter (metres; the width of a long
/// strip, the radius of the circle inscribed in a regular polygon).
fn mean_width(p: &Polygon) -> f64 {
    let perimeter: f64 = p.rings().map(|r| ring_perimeter(r)).sum();
    if perimeter > 0.0 {
        2.0 * p.area() / perimeter
    } else {
        0.0
    }
}

/// The bounding boxes of lots' outlines, for finding the outlines around a point.
fn outline_index(lots: &[Lot]) -> RTree<OutlineBox> {
    let boxes: Vec<OutlineBox> = lots
        .iter()
        .enumerate()
        .map(|(index, l)| {
            let (mut lo, mut hi) = (DVec2::splat(f64::INFINITY), DVec2::splat(f64::NEG_INFINITY));
            for p in &l.polygons {
                let (a, b) = p.bounds();
                lo = lo.min(a);
                hi = hi.max(b);
            }
            OutlineBox {
                index,
                aabb: AABB::from_corners([lo.x, lo.y], [hi.x, hi.y]),
            }
        })
        .collect();
    RTree::bulk_load(boxes)
}
