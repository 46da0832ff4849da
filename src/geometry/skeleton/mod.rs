//! Straight skeleton of a polygon with holes, by global wavefront propagation.
//!
//! Every edge of the polygon moves inwards at unit speed, parallel to itself. The wavefront is
//! kept as linked cycles of *wavefront vertices*; each vertex is the intersection of the offset
//! lines of its left edge (the edge arriving at it) and right edge (the edge leaving it) and so
//! moves on a straight line. The simulation jumps from event time to event time:
//!
//! * an **edge event**: a wavefront edge shrinks to zero length;
//! * a **split event**: a vertex hits a non-incident wavefront edge (also one of another ring:
//!   this is how rings of holes merge with the outer ring);
//! * a **vertex event**: two vertices meet.
//!
//! Instead of handling each kind with its own case analysis (which is where Felkel–Obdržálek
//! implementations usually break on simultaneous events), every event point is handled the same
//! way: everything of the wavefront that lies at the point at the event time is collected (runs
//! of consecutive vertices and edges passing through), the incoming and outgoing wavefront edges
//! are sorted by angle around the point, and every incoming edge is reconnected to the nearest
//! outgoing edge clockwise from it. Several events at one point (the apex of a square, the ridge
//! ends of a rectangle, the inner corners of a T meeting) therefore give one skeleton node.
//! Rings whose area has dropped to zero (the two sides of a ridge meeting) are retired and their
//! edges become skeleton edges (ridges).
//!
//! # Tolerances
//!
//! All tolerances scale with `size`, the larger side of the polygon's bounding box:
//!
//! * `DUPLICATE_REL`` × size`: consecutive vertices closer than this are merged (the edge
//!   between them owns no face);
//! * `COLLINEAR_REL`` × size`: a vertex closer than this to the line through its neighbours,
//!   with both edges running the same way, is removed before the propagation; the merged edge's
//!   face is cut back into one face per input edge afterwards (so the contract "one face per
//!   input edge" still holds, with the face's base moved by at most this distance);
//! * `EVENT_REL`` × size`: events closer than this in time and place are one event.
//!
//! Directions that differ by less than `ANGLE_TOL` radians are treated as equal.
//!
//! A vertex between edges within about 2e-4 rad of antiparallel (corridors one wall apart,
//! nearly rectangular footprints) would move at over 10⁴ times the wavefront speed; it is
//! instead slid along the edges' common line to the neighbour it meets first, at the meeting
//! time computed from its true velocity. A vertex's position at an event is trusted to the
//! event radius plus `speed × EVENT_REL × size` (the distance it covers in the time tolerance).
//!
//! # Failure modes
//!
//! [`straight_skeleton`] returns an error (never panics, never loops: the number of events is
//! capped by a linear function of the vertex count) for: non-finite coordinates, rings with fewer
//! than 3 distinct vertices, zero area, spikes (an edge folding back onto the previous one),
//! boundaries that cross or touch themselves or each other, holes outside the outer ring or
//! inside another hole, and numerical breakdowns (inconsistent wavefront, faces that do not
//! close, face areas that do not add up to the polygon's area within 1e-6 relative). Callers are
//! expected to fall back to a flat roof on error.

use glam::{DVec2, DVec3};
use thiserror::Error;

use super::{ring, ring_contains, ring_signed_area, Polygon};

mod sim;

use sim::*;

/// Consecutive vertices closer than `DUPLICATE_REL × size` are one vertex.
pub(crate) const DUPLICATE_REL: f64 = 1e-7;
/// Vertices closer than `COLLINEAR_REL × size` to the line through their neighbours are removed
/// (or closer than [`COLLINEAR_ABS`], whichever is larger: see [`collinear_tolerance`]).
pub(crate) const COLLINEAR_REL: f64 = 1e-6;
/// Vertices closer than this (metres) to the chord of their neighbours, going straight on, are
/// removed whatever the polygon's size: footprints on the millimetre grid carry straight walls
/// with a node a millimetre off the line (the rounding of a point that was on it), and nearly
/// straight vertices of real footprints (turning by hundredths of a degree, a few millimetres
/// off the chord) make events that are simultaneous in all but rounding, on which the
/// propagation used to stall.
pub const COLLINEAR_ABS: f64 = 0.005;

/// The distance under which a vertex going straight on is removed, for a polygon whose
/// bounding box's larger side is `size`: [`COLLINEAR_ABS`], but no more than a thousandth of the
/// size (a kiosk of 2 m keeps a 3 mm kink).
pub(crate) fn collinear_tolerance(size: f64) -> f64 {
    (COLLINEAR_REL * size).max(COLLINEAR_ABS.min(1e-3 * size))
}

/// Events closer than `EVENT_REL × size` (in time and in position) are simultaneous.
pub(crate) const EVENT_REL: f64 = 1e-9;
/// Wavefront vertices and edges within `RADIUS_REL × size` of an event point at its time take
/// part in it: two reflex corners that meet head-on on the exact footprint pass a few hundredths
/// of a millimetre apart once it is rounded to the grid, and must still be one event.
pub(crate) const RADIUS_REL: f64 = 5e-6;
/// Skeleton nodes closer than `NODE_MERGE_REL × size` (in place and time), and at most
/// [`NODE_MERGE_MAX`], are one node (see `Sim::merge_nodes`).
pub(crate) const NODE_MERGE_REL: f64 = 1e-4;
/// The most distance (metres) at which two skeleton nodes are merged: half the millimetre to
/// which footprints are cleaned and outputs written (two nodes closer would often be one point,
/// or a zero-length edge shared by four faces, once written), so a node's time stays within
/// 1 mm of its distance to its edges' lines; a merge tilts a 4 m face by under 0.01°. (The slide of a nearly
/// antiparallel vertex can place its node up to `distance × angle / 2` off, 0.45 mm on a 12 m
/// rectangle skewed by 0.01°: such ends are recognised by the gable rule instead, see
/// `derive::roof::shapes`.)
pub(crate) const NODE_MERGE_MAX: f64 = 5e-4;
/// Directions closer than this (radians) are parallel.
pub(crate) const ANGLE_TOL: f64 = 1e-9;

/// Two edges whose normals `n1`, `n2` have `1 + n1·n2` below this (an angle under about 2e-4
/// rad from antiparallel) meet in a *degenerate* vertex, resolved by sliding it along their
/// common line (see `Sim::resolve_degenerate`). Its exact speed, about 2 / angle (over 10⁴),
/// would make its position at an event uncertain by `speed × EVENT_REL × size`, while sliding
/// errs by at most `distance × angle / 2` in height (below 0.1 mm per metre slid).
const ANTIPARALLEL_DEN: f64 = 2e-8;

/// Most edges a skeleton is computed for. The propagation is cheap on real footprints (a
/// 1,500-edge star takes 40 ms in release) but some many-edged shapes make it cubic: a
/// 10,000-vertex footprint (5,688 edges once collinear runs merge) ran for hours. The samples'
/// largest footprints are far below the limit (tests/it/roofs.rs builds a roof on every one).
pub(crate) const MAX_EDGES: usize = 1000;

/// Why a straight skeleton could not be computed.
#[derive(Clone, Debug, Error, PartialEq)]
pub enum SkeletonError {
    /// A coordinate is NaN or infinite.
    #[error("ring {ring} vertex {vertex} has a non-finite coordinate")]
    NonFinite {
        /// The ring: 0 is the outer ring, 1.. the holes in their order.
        ring: usize,
        /// The vertex's index in the ring as given.
        vertex: usize,
    },
    /// A ring has fewer than three distinct, non-collinear vertices.
    #[error("ring {ring} has fewer than 3 distinct non-collinear vertices")]
    TooFewVertices {
        /// The ring: 0 is the outer ring, 1.. the holes.
        ring: usize,
    },
    /// The polygon (or a hole) has no area.
    #[error("ring {ring} has zero area")]
    ZeroArea {
        /// The ring: 0 is the outer ring, 1.. the holes.
        ring: usize,
    },
    /// An edge folds back onto the previous one.
    #[error("ring {ring} has a spike at vertex {vertex} (the boundary folds back on itself)")]
    Spike {
        /// The ring: 0 is the outer ring, 1.. the holes.
        ring: usize,
        /// The index (in the ring as given) of the vertex where it turns back.
        vertex: usize,
    },
    /// Two edges of the boundary cross or touch.
    #[error(
        "the boundary touches itself: ring {ring_a} edge {edge_a} meets ring {ring_b} edge {edge_b}"
    )]
    SelfIntersection {
        /// The ring of the first edge (0 outer, 1.. holes).
        ring_a: usize,
        /// The first edge, by the index (in the ring as given) of the vertex it starts at.
        edge_a: usize,
        /// The ring of the second edge.
        ring_b: usize,
        /// The second edge, by the index of the vertex it starts at.
        edge_b: usize,
    },
    /// A hole is not inside the outer ring, or is inside another hole.
    #[error("hole {hole} (ring {}) is not inside the outer ring or lies in another hole", hole + 1)]
    HoleOutside {
        /// The hole, 0-based among the holes (ring `hole + 1`).
        hole: usize,
    },
    /// Too many edges (after merging collinear ones) for the skeleton to finish quickly.
    #[error("{edges} edges (after merging collinear ones) exceed the skeleton's limit of {max}")]
    TooComplex {
        /// The polygon's edges after collinear runs are merged.
        edges: usize,
        /// The limit, `MAX_EDGES`.
        max: usize,
    },
    /// The propagation did not finish within its event budget.
    #[error("straight skeleton did not converge within {events} events")]
    NoConvergence {
        /// The event budget that ran out.
        events: usize,
    },
    /// The propagation reached a state that cannot be right (numerical breakdown).
    #[error("straight skeleton is inconsistent: {0}")]
    Inconsistent(&'static str),
}

/// The straight skeleton, as one face per input edge.
#[derive(Clone, Debug, PartialEq)]
pub struct Skeleton {
    /// Faces in ring order (outer ring first, then holes), then edge order. Edges shorter than
    /// the duplicate tolerance own no face; every other input edge owns exactly one.
    pub faces: Vec<SkeletonFace>,
}

/// The part of the polygon swept by one input edge's wavefront.
#[derive(Clone, Debug, PartialEq)]
pub struct SkeletonFace {
    /// (ring, edge): ring 0 is the outer ring, ring `k + 1` hole `k`; edge `i` runs from vertex
    /// `i` to vertex `i + 1` of that ring.
    pub edge: (usize, usize),
    /// The face, counter-clockwise seen from above, starting with the edge's two endpoints.
    /// `z` is the time the wavefront reached the vertex, i.e. its distance to the edge's line
    /// (0 for the edge's endpoints). Faces' ground projections tile the polygon.
    pub polygon: Vec<DVec3>,
}

/// One edge of the cleaned polygon.
#[derive(Clone, Debug)]
struct Edge {
    /// Start point (time 0).
    a: DVec2,
    /// Unit direction.
    d: DVec2,
    /// Unit inward normal (left of `d`).
    n: DVec2,
    ring: usize,
    /// Input edges covered by this edge (several when collinear vertices were removed), with the
    /// position along `d` (relative to `a`) where each input edge starts.
    inputs: Vec<(usize, f64)>,
}

#[derive(Clone, Debug)]
struct Vert {
    /// Edge arriving at the vertex (the wavefront edge before it).
    l: usize,
    /// Edge leaving the vertex.
    r: usize,
    /// Skeleton node where this vertex started.
    node: usize,
    t0: f64,
    p0: DVec2,
    vel: DVec2,
    /// The two edges are antiparallel: the vertex has no defined motion and must be resolved at
    /// the time it was created.
    degenerate: bool,
    prev: usize,
    next: usize,
    alive: bool,
}

#[derive(Clone, Copy, Debug)]
struct Node {
    p: DVec2,
    t: f64,
}

/// Computes the straight skeleton of `poly` (outer ring counter-clockwise, holes clockwise).
///
/// See the module documentation for the tolerances and the inputs that return errors.
///
/// ```
/// use citygen::geometry::{Polygon, skeleton::straight_skeleton};
/// use glam::DVec2;
/// let rect = Polygon::new(vec![DVec2::new(0., 0.), DVec2::new(10., 0.), DVec2::new(10., 4.),
///     DVec2::new(0., 4.)], vec![]);
/// let sk = straight_skeleton(&rect).unwrap();
/// assert_eq!(sk.faces.len(), 4);
/// ```
pub fn straight_skeleton(poly: &Polygon) -> Result<Skeleton, SkeletonError> {
    skeleton(poly, true)
}

/// [`straight_skeleton`] with one face per run of collinear input edges (the edges the
/// propagation merged, see the module documentation) instead of one per input edge: a face's
/// `edge` is the first input edge of its run, and the run's inner vertices lie on the face's
/// base. A roof plane over a footprint side with collinear vertices is one face.
pub(crate) fn straight_skeleton_merged(poly: &Polygon) -> Result<Skeleton, SkeletonError> {
    skeleton(poly, false)
}

fn skeleton(poly: &Polygon, split: bool) -> Result<Skeleton, SkeletonError> {
    let rings: Vec<&Vec<DVec2>> = poly.rings().collect();
    for (ri, r) in rings.iter().enumerate() {
        if let Some(vi) = r.iter().position(|p| !p.is_finite()) {
            return Err(SkeletonError::NonFinite {
                ring: ri,
                vertex: vi,
            });
        }
    }
    let (lo, hi) = poly.bounds();
    let size = (hi - lo).max_element();
    if !(size.is_finite() && size > 0.0) {
        return Err(SkeletonError::TooFewVertices { ring: 0 });
    }
    let mut edges = Vec::new();
    let mut ring_starts = Vec::new();
    for (ri, r) in rings.iter().enumerate() {
        ring_starts.push(edges.len());
        ring_edges(ri, r, size, &mut edges)?;
    }
    ring_starts.push(edges.len());
    // The propagation costs about O(n²) per event: past this many edges one skeleton would take
    // minutes (a 10,000-vertex footprint took hours), so such a footprint gets no skeleton.
    if edges.len() > MAX_EDGES {
        return Err(SkeletonError::TooComplex {
            edges: edges.len(),
            max: MAX_EDGES,
        });
    }
    check_simple(&edges, &ring_starts, size)?;
    check_holes(&edges, &ring_starts)?;
    // The faces tile the polygon the propagation runs on: the input without its collinear
    // vertices (which may lie up to the collinear tolerance off their chord; the faces cut back
    // to the input edges keep their bases on the chord).
    let expect: f64 = ring_starts
        .windows(2)
        .map(|w| {
            let pts: Vec<DVec2> = edges[w[0]..w[1]].iter().map(|e| e.a).collect();
            ring_signed_area(&pts)
        })
        .sum();
    // The propagation decides events that are simultaneous but for rounding (real footprints
    // are full of them: walls a hair off parallel, cells of nearly equal width) one after the
    // other, and on rare configurations it takes a wrong turn. A result that fails the checks
    // below is computed again on the polygon turned by a tiny angle about its first corner
    // (a different rounding of the same events), and turned back.
    let mut last = SkeletonError::Inconsistent("no attempt");
    for angle in RETRY_ANGLES {
        match attempt(&edges, &ring_starts, size, split, expect, angle) {
            Ok(faces) => return Ok(Skeleton { faces }),
            Err(e) => last = e,
        }
    }
    Err(last)
}

/// Turns by which a failed propagation is tried again (radians; see [`skeleton`]): at most
/// 3e-5 × the polygon's size in plan (0.6 mm on a 20 m footprint), undone on the result.
const RETRY_ANGLES: [f64; 4] = [0.0, 1e-5, -2e-5, 3e-5];

/// One propagation on `edges` turned by `angle` about the first corner, its faces turned back
/// (the footprint's corners exactly as given) and checked: the faces tile the polygon, every
/// face vertex lies in the polygon at a height (time) equal to its distance from its edge's
/// line.
fn attempt(
    edges: &[Edge],
    ring_starts: &[usize],
    size: f64,
    split: bool,
    expect: f64,
    angle: f64,
) -> Result<Vec<SkeletonFace>, SkeletonError> {
    let o = edges[0].a;
    let (sin, cos) = angle.sin_cos();
    let turn = |p: DVec2, s: f64| {
        let q = p - o;
        o + DVec2::new(cos * q.x - s * q.y, s * q.x + cos * q.y)
    };
    let turned: Vec<Edge> = if angle == 0.0 {
        edges.to_vec()
    } else {
        edges
            .iter()
            .map(|e| {
                let a = turn(e.a, sin);
                let d = DVec2::new(cos * e.d.x - sin * e.d.y, sin * e.d.x + cos * e.d.y);
                Edge {
                    a,
                    d,
                    n: d.perp(),
                    ..e.clone()
                }
            })
            .collect()
    };
    let corners: Vec<(DVec2, DVec2)> = turned.iter().zip(edges).map(|(t, e)| (t.a, e.a)).collect();
    let mut sim = Sim::new(turned, ring_starts, size);
    sim.run()?;
    sim.merge_nodes();
    let mut faces = sim.faces(split)?;
    if angle != 0.0 {
        for f in &mut faces {
            for p in &mut f.polygon {
                let g = match corners.iter().find(|c| c.0 == p.truncate() && p.z == 0.0) {
                    Some(c) => c.1,
                    None => turn(p.truncate(), -sin),
                };
                *p = g.extend(p.z);
            }
        }
    }
    // Area check: the faces must tile the polygon.
    let total: f64 = faces.iter().map(|f| area3(&f.polygon)).sum();
    if (total - expect).abs() > 1e-6 * expect.abs().max(size * size * 1e-9) {
        return Err(SkeletonError::Inconsistent(
            "face areas do not add up to the polygon area",
        ));
    }
    // Heights: a vertex of edge e's face is as high as it is far from e's line (up to the node
    // merge and the slide of a nearly antiparallel vertex), and within the polygon.
    let tol = 1e-3 + 1e-4 * size;
    let rings: Vec<Vec<DVec2>> = ring_starts
        .windows(2)
        .map(|w| edges[w[0]..w[1]].iter().map(|e| e.a).collect())
        .collect();
    let inside = |q: DVec2| {
        let within = ring_contains(&rings[0], q) && !rings[1..].iter().any(|h| ring_contains(h, q));
        within
            || rings
                .iter()
                .any(|r| (0..r.len()).any(|i| point_seg_dist(q, r[i], r[(i + 1) % r.len()]) <= tol))
    };
    // The first edge covering each input edge (ring, edge), and the points found inside (a
    // node is a vertex of several faces).
    let mut edge_of: std::collections::HashMap<(usize, usize), usize, super::CellHash> =
        Default::default();
    for (k, e) in edges.iter().enumerate() {
        for x in &e.inputs {
            edge_of.entry((e.ring, x.0)).or_insert(k);
        }
    }
    let mut known: std::collections::HashSet<(u64, u64), super::CellHash> = Default::default();
    let mut inside_known = |q: DVec2| {
        let b = (q.x.to_bits(), q.y.to_bits());
        known.contains(&b) || (inside(q) && known.insert(b))
    };
    for f in &faces {
        let Some(e) = edge_of.get(&f.edge).map(|&k| &edges[k]) else {
            return Err(SkeletonError::Inconsistent("a face has no edge"));
        };
        for p in &f.polygon {
            let d = (p.truncate() - e.a).dot(e.n);
            if !((d - p.z).abs() <= tol && p.z >= -tol && inside_known(p.truncate())) {
                return Err(SkeletonError::Inconsistent(
                    "a face vertex is outside the polygon, or not as high as it is far from its edge",
                ));
            }
        }
    }
    Ok(faces)
}

/// Ground-projected signed area of a 3D ring.
fn area3(r: &[DVec3]) -> f64 {
    let n = r.len();
    (0..n)
        .map(|i| {
            let (a, b) = (r[i], r[(i + 1) % n]);
            a.x * b.y - b.x * a.y
        })
        .sum::<f64>()
        * 0.5
}

/// Removes duplicate and collinear vertices of ring `ri` ([`super::ring::simplified_indices`])
/// and appends its edges.
fn ring_edges(
    ri: usize,
    ring: &[DVec2],
    size: f64,
    edges: &mut Vec<Edge>,
) -> Result<(), SkeletonError> {
    let n = ring.len();
    if n < 3 {
        return Err(SkeletonError::TooFewVertices { ring: ri });
    }
    let dup = DUPLICATE_REL * size;
    let col = collinear_tolerance(size);
    let keep = super::ring::simplified_indices(ring, dup, col, COLLINEAR_REL * size)
        .map_err(|vertex| SkeletonError::Spike { ring: ri, vertex })?;
    if keep.len() < 3 {
        return Err(SkeletonError::TooFewVertices { ring: ri });
    }
    let pts: Vec<DVec2> = keep.iter().map(|&i| ring[i]).collect();
    if ring_signed_area(&pts).abs() < dup * size {
        return Err(SkeletonError::ZeroArea { ring: ri });
    }
    let m = keep.len();
    for k in 0..m {
        let (i0, i1) = (keep[k], keep[(k + 1) % m]);
        let (a, b) = (ring[i0], ring[i1]);
        let d = (b - a).normalize();
        let mut inputs = Vec::new();

        let mut i = i0;
        loop {
            inputs.push((i, (ring[i] - a).dot(d)));

            i = (i + 1) % n;
            if i == i1 {
                break;
            }
        }
        edges.push(Edge {
            a,
            d,
            n: d.perp(),
            ring: ri,
            inputs,
        });
    }
    Ok(())
}

/// Distance between segments [a, b] and [c, d].
fn seg_seg_dist(a: DVec2, b: DVec2, c: DVec2, d: DVec2) -> f64 {
    let o = |p: DVec2, q: DVec2, r: DVec2| (q - p).perp_dot(r - p);
    let (d1, d2, d3, d4) = (o(a, b, c), o(a, b, d), o(c, d, a), o(c, d, b));
    if ((d1 > 0.0 && d2 < 0.0) || (d1 < 0.0 && d2 > 0.0))
        && ((d3 > 0.0 && d4 < 0.0) || (d3 < 0.0 && d4 > 0.0))
    {
        return 0.0;
    }
    point_seg_dist(a, c, d)
        .min(point_seg_dist(b, c, d))
        .min(point_seg_dist(c, a, b))
        .min(point_seg_dist(d, a, b))
}

fn point_seg_dist(p: DVec2, a: DVec2, b: DVec2) -> f64 {
    let ab = b - a;
    let l2 = ab.length_squared();
    let t = if l2 > 0.0 {
        ((p - a).dot(ab) / l2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    p.distance(a + ab * t)
}

/// Rejects boundaries whose edges cross or touch (other than consecutive edges at their shared
/// vertex).
fn check_simple(edges: &[Edge], ring_starts: &[usize], size: f64) -> Result<(), SkeletonError> {
    let tol = DUPLICATE_REL * size;
    let ends: Vec<(DVec2, DVec2)> = (0..edges.len())
        .map(|i| (edges[i].a, edges[next_in_ring(i, edges, ring_starts)].a))
        .collect();
    for i in 0..edges.len() {
        let (a, b) = ends[i];
        let (lo, hi) = (a.min(b) - tol, a.max(b) + tol);
        for j in i + 1..edges.len() {
            let (c, d) = ends[j];
            if c.max(d).cmple(lo).any() || c.min(d).cmpge(hi).any() {
                continue;
            }
            let adjacent = edges[i].ring == edges[j].ring
                && (next_in_ring(i, edges, ring_starts) == j
                    || next_in_ring(j, edges, ring_starts) == i);
            if adjacent {
                continue;
            }
            if seg_seg_dist(a, b, c, d) < tol {
                return Err(SkeletonError::SelfIntersection {
                    ring_a: edges[i].ring,
                    edge_a: edges[i].inputs[0].0,
                    ring_b: edges[j].ring,
                    edge_b: edges[j].inputs[0].0,
                });
            }
        }
    }
    Ok(())
}

fn next_in_ring(i: usize, edges: &[Edge], ring_starts: &[usize]) -> usize {
    let r = edges[i].ring;
    if i + 1 == ring_starts[r + 1] {
        ring_starts[r]
    } else {
        i + 1
    }
}

/// Holes must lie inside the outer ring and outside each other (their boundaries do not touch,
/// so one vertex decides).
fn check_holes(edges: &[Edge], ring_starts: &[usize]) -> Result<(), SkeletonError> {
    let ring_pts = |r: usize| -> Vec<DVec2> {
        edges[ring_starts[r]..ring_starts[r + 1]]
            .iter()
            .map(|e| e.a)
            .collect()
    };
    let outer = ring_pts(0);
    let holes: Vec<Vec<DVec2>> = (1..ring_starts.len() - 1).map(ring_pts).collect();
    for (h, pts) in holes.iter().enumerate() {
        let p = pts[0];
        if !ring_contains(&outer, p)
            || holes
                .iter()
                .enumerate()
                .any(|(k, o)| k != h && ring_contains(o, p))
        {
            return Err(SkeletonError::HoleOutside { hole: h });
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests;
