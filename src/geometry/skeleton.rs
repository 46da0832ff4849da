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
//! * [`DUPLICATE_REL`]` × size`: consecutive vertices closer than this are merged (the edge
//!   between them owns no face);
//! * [`COLLINEAR_REL`]` × size`: a vertex closer than this to the line through its neighbours,
//!   with both edges running the same way, is removed before the propagation; the merged edge's
//!   face is cut back into one face per input edge afterwards (so the contract "one face per
//!   input edge" still holds, with the face's base moved by at most this distance);
//! * [`EVENT_REL`]` × size`: events closer than this in time and place are one event.
//!
//! Directions that differ by less than [`ANGLE_TOL`] radians are treated as equal.
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

use super::{ring_contains, ring_signed_area, Polygon};

/// Consecutive vertices closer than `DUPLICATE_REL × size` are one vertex.
pub const DUPLICATE_REL: f64 = 1e-7;
/// Vertices closer than `COLLINEAR_REL × size` to the line through their neighbours are removed.
pub const COLLINEAR_REL: f64 = 1e-6;
/// Events closer than `EVENT_REL × size` (in time and in position) are simultaneous.
pub const EVENT_REL: f64 = 1e-9;
/// Directions closer than this (radians) are parallel.
pub const ANGLE_TOL: f64 = 1e-9;

/// Two edges whose normals `n1`, `n2` have `1 + n1·n2` below this (an angle under about 2e-4
/// rad from antiparallel) meet in a *degenerate* vertex, resolved by sliding it along their
/// common line (see `Sim::resolve_degenerate`). Its exact speed, about 2 / angle (over 10⁴),
/// would make its position at an event uncertain by `speed × EVENT_REL × size`, while sliding
/// errs by at most `distance × angle / 2` in height (below 0.1 mm per metre slid).
const ANTIPARALLEL_DEN: f64 = 2e-8;

/// Most edges a skeleton is computed for. The propagation is cheap on real footprints (a
/// 1,500-edge star takes 40 ms in release) but some many-edged shapes make it cubic: a
/// 10,000-vertex footprint (5,688 edges once collinear runs merge) ran for hours. The samples'
/// largest footprints are far below the limit (tests/roofs.rs builds a roof on every one).
pub const MAX_EDGES: usize = 1000;

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
        /// The limit, [`MAX_EDGES`].
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
    let mut sim = Sim::new(edges, &ring_starts, size);
    sim.run()?;
    let faces = sim.faces()?;
    // Area check: the faces must tile the polygon.
    let total: f64 = faces.iter().map(|f| area3(&f.polygon)).sum();
    let expect = poly.area();
    if (total - expect).abs() > 1e-6 * expect.abs().max(size * size * 1e-9) {
        return Err(SkeletonError::Inconsistent(
            "face areas do not add up to the polygon area",
        ));
    }
    Ok(Skeleton { faces })
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
    let col = COLLINEAR_REL * size;
    let keep = super::ring::simplified_indices(ring, dup, col)
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

/// A wavefront edge or a run of vertices meeting at an event point.
#[derive(Clone, Copy, Debug)]
struct Pass {
    /// Vertex before the pass (not at the point).
    entry: usize,
    /// Vertex after the pass.
    exit: usize,
    in_edge: usize,
    out_edge: usize,
    /// First and last vertex of the run; `None` for an edge passing through the point.
    run: Option<(usize, usize)>,
}

struct Sim {
    edges: Vec<Edge>,
    nodes: Vec<Node>,
    verts: Vec<Vert>,
    /// Directed boundary segments (node ids) of each edge's face.
    segs: Vec<Vec<(usize, usize)>>,
    /// Base segment (start node, end node) of each edge.
    base: Vec<(usize, usize)>,
    eps: f64,
    t: f64,
    size: f64,
}

impl Sim {
    fn new(edges: Vec<Edge>, ring_starts: &[usize], size: f64) -> Sim {
        let ne = edges.len();
        let mut sim = Sim {
            nodes: Vec::with_capacity(4 * ne),
            verts: Vec::with_capacity(4 * ne),
            segs: vec![Vec::new(); ne],
            base: vec![(0, 0); ne],
            eps: EVENT_REL * size,
            t: 0.0,
            size,
            edges,
        };
        for r in 0..ring_starts.len() - 1 {
            let (s, e) = (ring_starts[r], ring_starts[r + 1]);
            for i in s..e {
                let prev = if i == s { e - 1 } else { i - 1 };
                let next = if i + 1 == e { s } else { i + 1 };
                let node = sim.nodes.len();
                sim.nodes.push(Node {
                    p: sim.edges[i].a,
                    t: 0.0,
                });
                let (vel, degenerate) = sim.velocity(prev, i);
                sim.verts.push(Vert {
                    l: prev,
                    r: i,
                    node,
                    t0: 0.0,
                    p0: sim.edges[i].a,
                    vel,
                    degenerate,
                    prev,
                    next,
                    alive: true,
                });
            }
            for i in s..e {
                let next = if i + 1 == e { s } else { i + 1 };
                sim.base[i] = (i, next);
                sim.segs[i].push((i, next));
            }
        }
        sim
    }

    fn velocity(&self, l: usize, r: usize) -> (DVec2, bool) {
        let (nl, nr) = (self.edges[l].n, self.edges[r].n);
        let den = 1.0 + nl.dot(nr);
        if den < ANTIPARALLEL_DEN {
            (DVec2::ZERO, true)
        } else {
            ((nl + nr) / den, false)
        }
    }

    fn pos(&self, v: usize, t: f64) -> DVec2 {
        let v = &self.verts[v];
        v.p0 + v.vel * (t - v.t0)
    }

    fn alive(&self) -> Vec<usize> {
        (0..self.verts.len())
            .filter(|&i| self.verts[i].alive)
            .collect()
    }

    fn run(&mut self) -> Result<(), SkeletonError> {
        let budget = 40 * self.edges.len() + 100;
        for _ in 0..budget {
            let alive = self.alive();
            if alive.is_empty() {
                return Ok(());
            }
            let points = self.next_events(&alive)?;
            for p in points {
                self.handle_point(p)?;
            }
            self.resolve_degenerate()?;
        }
        Err(SkeletonError::NoConvergence { events: budget })
    }

    /// Finds the earliest event time, advances to it and returns the event points.
    fn next_events(&mut self, alive: &[usize]) -> Result<Vec<DVec2>, SkeletonError> {
        let t = self.t;
        let eps = self.eps;
        let mut best = f64::INFINITY;
        let mut cands: Vec<(f64, usize)> = Vec::new();
        let pos_now: Vec<DVec2> = self
            .verts
            .iter()
            .enumerate()
            .map(|(i, _)| self.pos(i, t))
            .collect();
        for &v in alive {
            let vv = &self.verts[v];
            if vv.degenerate {
                continue;
            }
            let w = vv.next;
            // Edge event on v -> w.
            let e = &self.edges[vv.r];
            let len = (pos_now[w] - pos_now[v]).dot(e.d);
            let rate = (self.verts[w].vel - vv.vel).dot(e.d);
            if rate < -1e-12 {
                let dt = (len / -rate).max(0.0);
                if t + dt <= best + eps {
                    best = best.min(t + dt);
                    cands.push((t + dt, v));
                }
            }
            // Split events of v against every non-incident edge.
            for &u in alive {
                let uu = &self.verts[u];
                if u == v || uu.next == v {
                    continue;
                }
                let f = &self.edges[uu.r];
                let h = (pos_now[v] - f.a).dot(f.n) - t;
                let rate = vv.vel.dot(f.n) - 1.0;
                if rate >= -1e-12 || h < -eps {
                    continue;
                }
                let dt = h.max(0.0) / -rate;
                let te = t + dt;
                if te > best + eps {
                    continue;
                }
                let pv = self.pos(v, te);
                let pa = self.pos(u, te);
                let pb = self.pos(uu.next, te);
                let s = (pv - pa).dot(f.d);
                let l = (pb - pa).dot(f.d);
                // At an end of the edge, the vertex must be moving onto the edge, not away
                // from it (two vertices born at one point and moving apart are no event).
                let vb = self.verts[uu.next].vel;
                let onto_start = s > eps || (vv.vel - uu.vel).dot(f.d) >= -1e-9;
                let onto_end = s < l - eps || (vv.vel - vb).dot(f.d) <= 1e-9;
                // A vertex already on the line at an end of the edge met that end at this
                // very time, and that point has been handled.
                let rad = 4.0 * eps;
                let stale = h <= eps && (s <= rad || s >= l - rad);
                if s >= -eps && s <= l + eps && onto_start && onto_end && !stale {
                    best = best.min(te);
                    cands.push((te, v));
                }
            }
        }
        if !best.is_finite() {
            return Err(SkeletonError::Inconsistent(
                "a wavefront ring has no further event",
            ));
        }
        self.t = best.max(t);
        // Cluster the event vertices; the slowest vertex of a cluster gives its point, as its
        // position is the most precise (see `Sim::tol`).
        let mut cands: Vec<usize> = cands
            .into_iter()
            .filter(|&(te, _)| te <= best + eps)
            .map(|(_, v)| v)
            .collect();
        cands.sort_by(|&a, &b| {
            let (sa, sb) = (self.verts[a].vel.length(), self.verts[b].vel.length());
            sa.total_cmp(&sb).then(a.cmp(&b))
        });
        let mut pts: Vec<DVec2> = Vec::new();
        for v in cands {
            let p = self.pos(v, self.t);
            if !pts.iter().any(|q| q.distance(p) <= self.tol(v)) {
                pts.push(p);
            }
        }
        Ok(pts)
    }

    /// Cluster radius: a little larger than the event tolerance to absorb rounding.
    fn radius(&self) -> f64 {
        4.0 * self.eps
    }

    /// Distance within which vertex `v` is at an event point. Events closer than `eps` in time
    /// are simultaneous, and in that time a vertex moves `eps × speed`: a vertex between nearly
    /// antiparallel edges moves at about 2 / angle (10⁴ or more on real footprints), so its
    /// position at an event is only known to that precision.
    fn tol(&self, v: usize) -> f64 {
        self.radius() + self.verts[v].vel.length() * self.eps
    }

    /// Handles everything at point `x` at the current time.
    fn handle_point(&mut self, x: DVec2) -> Result<bool, SkeletonError> {
        self.handle_point_at(x, None)
    }

    /// [`Sim::handle_point`], with the node of the event given (a slid vertex's meeting node).
    /// Returns whether the wavefront changed.
    fn handle_point_at(&mut self, x: DVec2, at: Option<usize>) -> Result<bool, SkeletonError> {
        let t = self.t;
        let rad = self.radius();
        let alive = self.alive();
        let member: Vec<bool> = {
            let mut m = vec![false; self.verts.len()];
            for &v in &alive {
                m[v] = self.pos(v, t).distance(x) <= self.tol(v);
            }
            m
        };
        let members: Vec<usize> = alive.iter().copied().filter(|&v| member[v]).collect();
        if members.is_empty() {
            return Ok(false);
        }
        let mut passes: Vec<Pass> = Vec::new();
        let mut visited = vec![false; self.verts.len()];
        for &m in &members {
            if member[self.verts[m].prev] {
                continue;
            }
            let mut last = m;
            visited[m] = true;
            let mut guard = 0;
            while member[self.verts[last].next] {
                last = self.verts[last].next;
                visited[last] = true;
                guard += 1;
                if guard > self.verts.len() {
                    return Err(SkeletonError::Inconsistent("wavefront ring is not a cycle"));
                }
            }
            passes.push(Pass {
                entry: self.verts[m].prev,
                exit: self.verts[last].next,
                in_edge: self.verts[m].l,
                out_edge: self.verts[last].r,
                run: Some((m, last)),
            });
        }
        // Rings that lie entirely at the point vanish there.
        let vanished: Vec<usize> = members.iter().copied().filter(|&m| !visited[m]).collect();
        for &u in &alive {
            let w = self.verts[u].next;
            if member[u] || member[w] {
                continue;
            }
            if point_seg_dist(x, self.pos(u, t), self.pos(w, t)) <= rad {
                let e = self.verts[u].r;
                passes.push(Pass {
                    entry: u,
                    exit: w,
                    in_edge: e,
                    out_edge: e,
                    run: None,
                });
            }
        }
        let trivial = vanished.is_empty()
            && passes
                .iter()
                .all(|p| matches!(p.run, Some((a, b)) if a == b))
            && passes.len() <= 1;
        if trivial {
            return Ok(false);
        }
        let pairs = self.match_passes(&passes)?;
        let changed = !vanished.is_empty()
            || pairs
                .iter()
                .enumerate()
                .any(|(i, &j)| i != j || matches!(passes[i].run, Some((a, b)) if a != b));
        if !changed {
            return Ok(false);
        }
        // The node: reuse one already at this place and time, unless the caller gives it.
        let node = match at {
            Some(n) => n,
            None => self.node_at(x, &members),
        };
        // Retire the vertices of runs that change and of vanished rings.
        for (i, p) in passes.iter().enumerate() {
            if let Some((a, b)) = p.run {
                if pairs[i] == i && a == b {
                    continue;
                }
                let mut v = a;
                loop {
                    self.retire(v, node);
                    if v == b {
                        break;
                    }
                    v = self.verts[v].next;
                }
            }
        }
        for &v in &vanished {
            self.retire(v, node);
        }
        // Reconnect.
        let mut touched = Vec::new();
        for (i, &j) in pairs.iter().enumerate() {
            if i == j && passes[i].run.is_none_or(|(a, b)| a == b) {
                continue;
            }
            let (pi, pj) = (passes[i], passes[j]);
            if pi.in_edge == pj.out_edge {
                self.verts[pi.entry].next = pj.exit;
                self.verts[pj.exit].prev = pi.entry;
                touched.push(pi.entry);
            } else {
                let (vel, degenerate) = self.velocity(pi.in_edge, pj.out_edge);
                let id = self.verts.len();
                self.verts.push(Vert {
                    l: pi.in_edge,
                    r: pj.out_edge,
                    node,
                    t0: self.nodes[node].t,
                    p0: self.nodes[node].p,
                    vel,
                    degenerate,
                    prev: pi.entry,
                    next: pj.exit,
                    alive: true,
                });
                self.verts[pi.entry].next = id;
                self.verts[pj.exit].prev = id;
                touched.push(id);
            }
        }
        for v in touched {
            if self.verts[v].alive {
                self.check_ring(v)?;
            }
        }
        Ok(true)
    }

    /// A node at `x` at the current time, reusing a member's start node when it is there.
    fn node_at(&mut self, x: DVec2, members: &[usize]) -> usize {
        let rad = self.radius();
        for &m in members {
            let n = self.nodes[self.verts[m].node];
            if (n.t - self.t).abs() <= self.eps && n.p.distance(x) <= rad {
                return self.verts[m].node;
            }
        }
        self.nodes.push(Node { p: x, t: self.t });
        self.nodes.len() - 1
    }

    /// Ends vertex `v` at `node`, recording its trace for the faces of its two edges.
    fn retire(&mut self, v: usize, node: usize) {
        let vv = &mut self.verts[v];
        vv.alive = false;
        if vv.node != node {
            self.segs[vv.l].push((vv.node, node));
            self.segs[vv.r].push((node, vv.node));
        }
    }

    /// Pairs each pass's incoming edge with the outgoing edge nearest clockwise from it.
    /// Returns, for each pass `i`, the pass whose outgoing edge continues it.
    fn match_passes(&self, passes: &[Pass]) -> Result<Vec<usize>, SkeletonError> {
        // (angle, is_in, pass)
        let mut rays: Vec<(f64, bool, usize)> = Vec::with_capacity(2 * passes.len());
        for (i, p) in passes.iter().enumerate() {
            let din = -self.edges[p.in_edge].d;
            let dout = self.edges[p.out_edge].d;
            rays.push((din.y.atan2(din.x), true, i));
            rays.push((dout.y.atan2(dout.x), false, i));
        }
        rays.sort_by(|a, b| a.0.total_cmp(&b.0));
        // Start after the largest angular gap so that groups of equal angles are not cut.
        let k = rays.len();
        let mut cut = 0;
        let mut gap = -1.0;
        for i in 0..k {
            let g = if i + 1 < k {
                rays[i + 1].0 - rays[i].0
            } else {
                rays[0].0 + std::f64::consts::TAU - rays[i].0
            };
            if g > gap {
                gap = g;
                cut = (i + 1) % k;
            }
        }
        rays.rotate_left(cut);
        // Group equal directions; within a group outgoing rays come first (counter-clockwise),
        // so an incoming edge pairs with an antiparallel outgoing one (two wavefronts meeting).
        let mut group = vec![0usize; k];
        for i in 1..k {
            let mut d = rays[i].0 - rays[i - 1].0;
            if d < 0.0 {
                d += std::f64::consts::TAU;
            }
            group[i] = group[i - 1] + usize::from(d > ANGLE_TOL);
        }
        let mut order: Vec<usize> = (0..k).collect();
        order.sort_by_key(|&i| (group[i], rays[i].1));
        let seq: Vec<(bool, usize)> = order.iter().map(|&i| (rays[i].1, rays[i].2)).collect();
        // Parenthesis matching (out opens, in closes), from a rotation with no deficit.
        let mut bal = 0i64;
        let mut min_bal = 0i64;
        let mut start = 0;
        for (i, &(is_in, _)) in seq.iter().enumerate() {
            bal += if is_in { -1 } else { 1 };
            if bal < min_bal {
                min_bal = bal;
                start = i + 1;
            }
        }
        if bal != 0 {
            return Err(SkeletonError::Inconsistent("unbalanced event point"));
        }
        let mut pairs = vec![usize::MAX; passes.len()];
        let mut stack = Vec::new();
        for s in 0..k {
            let (is_in, p) = seq[(start + s) % k];
            if is_in {
                let o = stack
                    .pop()
                    .ok_or(SkeletonError::Inconsistent("unmatched edge"))?;
                pairs[p] = o;
            } else {
                stack.push(p);
            }
        }
        if pairs.contains(&usize::MAX) {
            return Err(SkeletonError::Inconsistent("unmatched edge"));
        }
        Ok(pairs)
    }

    /// Retires the ring through `v` if it has collapsed (fewer than 3 vertices or no area):
    /// its edges become skeleton edges.
    fn check_ring(&mut self, v: usize) -> Result<(), SkeletonError> {
        let t = self.t;
        let mut ring = vec![v];
        let mut u = self.verts[v].next;
        while u != v {
            ring.push(u);
            if ring.len() > self.verts.len() {
                return Err(SkeletonError::Inconsistent("wavefront ring is not a cycle"));
            }
            u = self.verts[u].next;
        }
        let pts: Vec<DVec2> = ring.iter().map(|&u| self.pos(u, t)).collect();
        let area = ring_signed_area(&pts);
        let perim: f64 = (0..pts.len())
            .map(|i| pts[i].distance(pts[(i + 1) % pts.len()]))
            .sum();
        // Rings of holes that have not met the outer ring yet run clockwise: only the size of
        // the area tells a collapsed ring.
        if ring.len() >= 3 && area.abs() > self.radius() * perim {
            return Ok(());
        }
        // End nodes, shared between vertices at the same place.
        let rad = self.radius();
        let mut ends = Vec::with_capacity(ring.len());
        let mut fresh: Vec<usize> = Vec::new();
        for (k, &u) in ring.iter().enumerate() {
            let p = pts[k];
            let n0 = self.nodes[self.verts[u].node];
            let id = if (n0.t - t).abs() <= self.eps && n0.p.distance(p) <= rad {
                self.verts[u].node
            } else if let Some(&f) = fresh.iter().find(|&&f| self.nodes[f].p.distance(p) <= rad) {
                f
            } else {
                self.nodes.push(Node { p, t });
                fresh.push(self.nodes.len() - 1);
                self.nodes.len() - 1
            };
            ends.push(id);
        }
        for (k, &u) in ring.iter().enumerate() {
            self.retire(u, ends[k]);
        }
        for k in 0..ring.len() {
            let k1 = (k + 1) % ring.len();
            let e = self.verts[ring[k]].r;
            if self.verts[ring[k1]].l != e {
                return Err(SkeletonError::Inconsistent(
                    "wavefront edge labels disagree",
                ));
            }
            if ends[k] != ends[k1] {
                self.segs[e].push((ends[k1], ends[k]));
            }
        }
        Ok(())
    }

    /// Vertices between antiparallel edges must disappear at the time they were made (the two
    /// wavefronts annihilate along their overlap). First every point where a vertex lies on a
    /// non-incident wavefront edge or another vertex is handled; a degenerate vertex still left
    /// then slides along the common line of its two edges to the nearer of its neighbours (the
    /// end of the overlap, which a nearly antiparallel vertex reaches almost at once, moving at
    /// a speed of about 2 / angle) and that point is handled as an edge event.
    fn resolve_degenerate(&mut self) -> Result<(), SkeletonError> {
        let limit = 4 * self.verts.len() + 16;
        for _ in 0..limit {
            let alive = self.alive();
            let Some(&v) = alive.iter().find(|&&v| self.verts[v].degenerate) else {
                return Ok(());
            };
            let t = self.t;
            let rad = self.radius();
            let mut pts: Vec<DVec2> = Vec::new();
            for &v in &alive {
                let p = self.pos(v, t);
                for &u in &alive {
                    let w = self.verts[u].next;
                    if u == v || w == v {
                        continue;
                    }
                    if point_seg_dist(p, self.pos(u, t), self.pos(w, t)) <= rad
                        && !pts.iter().any(|q| q.distance(p) <= rad)
                    {
                        pts.push(p);
                    }
                }
            }
            let mut changed = false;
            for p in pts {
                changed |= self.handle_point(p)?;
            }
            if !changed {
                self.slide(v)?;
            }
        }
        Err(SkeletonError::Inconsistent(
            "unresolved antiparallel wavefront vertex",
        ))
    }

    /// Moves degenerate vertex `v` to the neighbour it meets first along the line of its edges
    /// and handles that point (see [`Sim::resolve_degenerate`]). When the edges are not exactly
    /// antiparallel the meeting time is computed from the vertex's true (large) velocity and
    /// the node placed on the neighbour's trajectory at that time, so that the node lies on
    /// all the planes involved however far the vertex slides.
    fn slide(&mut self, v: usize) -> Result<(), SkeletonError> {
        let t = self.t;
        let vv = self.verts[v].clone();
        let p = self.pos(v, t);
        let (nl, nr) = (self.edges[vv.l].n, self.edges[vv.r].n);
        let den = 1.0 + nl.dot(nr);
        let vel = if den > 0.0 {
            (nl + nr) / den
        } else {
            DVec2::ZERO
        };
        // Time to meet the next vertex (edge r collapses) and the previous one (edge l).
        let meet = |w: usize, d: DVec2, sign: f64| -> f64 {
            let len = sign * (self.pos(w, t) - p).dot(d);
            let rate = sign * (self.verts[w].vel - vel).dot(d);
            if rate < 0.0 {
                (len / -rate).max(0.0)
            } else {
                f64::INFINITY
            }
        };
        let tw = meet(vv.next, self.edges[vv.r].d, 1.0);
        let tu = meet(vv.prev, self.edges[vv.l].d, -1.0);
        // Both neighbours lie ahead along the right edge's direction (the ring folds back).
        let d = self.edges[vv.r].d;
        let (pu, pw) = (self.pos(vv.prev, t), self.pos(vv.next, t));
        let (w, dt) = if tw.is_finite() || tu.is_finite() {
            if tw <= tu {
                (vv.next, tw)
            } else {
                (vv.prev, tu)
            }
        } else if (pw - p).dot(d) <= (pu - p).dot(d) {
            (vv.next, 0.0)
        } else {
            (vv.prev, 0.0)
        };
        // A slide is instantaneous up to the angle: a long wait means it is no slide.
        let dt = if dt * self.verts[w].vel.length() > 1e-3 * self.size {
            0.0
        } else {
            dt
        };
        let x = self.pos(w, t);
        let target = self.pos(w, t + dt);
        let node = self.nodes.len();
        self.nodes.push(Node {
            p: target,
            t: t + dt,
        });
        self.retire(v, node);
        let id = self.verts.len();
        // The slid vertex rides on its neighbour's trajectory, so it is at the event point now.
        self.verts.push(Vert {
            node,
            t0: t + dt,
            p0: target,
            vel: self.verts[w].vel,
            alive: true,
            ..vv
        });
        self.verts[vv.prev].next = id;
        self.verts[vv.next].prev = id;
        self.handle_point_at(x, Some(node))?;
        if self.verts[id].alive {
            return Err(SkeletonError::Inconsistent(
                "unresolved antiparallel wavefront vertex",
            ));
        }
        Ok(())
    }

    /// Chains each edge's boundary segments into its face and splits faces of merged edges back
    /// into one face per input edge.
    fn faces(&self) -> Result<Vec<SkeletonFace>, SkeletonError> {
        let mut out = Vec::new();
        for (e, edge) in self.edges.iter().enumerate() {
            let ring = self.chain(e)?;
            let poly: Vec<DVec3> = ring
                .iter()
                .map(|&n| {
                    let nd = self.nodes[n];
                    DVec3::new(nd.p.x, nd.p.y, nd.t)
                })
                .collect();
            if edge.inputs.len() == 1 {
                out.push(SkeletonFace {
                    edge: (edge.ring, edge.inputs[0].0),
                    polygon: poly,
                });
                continue;
            }
            // Cut the (edge-monotone) face into slabs across the edge, one per input edge.
            for (k, &(input, s0)) in edge.inputs.iter().enumerate() {
                let lo = if k == 0 { f64::NEG_INFINITY } else { s0 };
                let hi = edge.inputs.get(k + 1).map_or(f64::INFINITY, |x| x.1);
                if hi - lo <= DUPLICATE_REL * self.size {
                    continue;
                }
                let mut piece = clip(&poly, edge.a, edge.d, lo, false);
                piece = clip(&piece, edge.a, edge.d, hi, true);
                piece = dedup(piece, self.radius());
                // Start at the base edge: the first vertex at time 0 followed by another.
                let m = piece.len();
                if m < 3 {
                    return Err(SkeletonError::Inconsistent("empty face piece"));
                }
                let tol = self.radius();
                let st = (0..m).find(|&i| piece[i].z <= tol && piece[(i + 1) % m].z <= tol);
                let st = st.ok_or(SkeletonError::Inconsistent("face piece lost its base"))?;
                piece.rotate_left(st);
                out.push(SkeletonFace {
                    edge: (edge.ring, input),
                    polygon: piece,
                });
            }
        }
        out.sort_by_key(|f| f.edge);
        Ok(out)
    }

    /// The cycle of nodes bounding edge `e`'s face, starting with the base edge.
    fn chain(&self, e: usize) -> Result<Vec<usize>, SkeletonError> {
        let mut segs: Vec<(usize, usize)> = self.segs[e]
            .iter()
            .copied()
            .filter(|s| s.0 != s.1)
            .collect();
        segs.sort_unstable();
        segs.dedup();
        // Cancel segments traversed both ways (slits of zero width).
        let mut keep = vec![true; segs.len()];
        for i in 0..segs.len() {
            if let Ok(j) = segs.binary_search(&(segs[i].1, segs[i].0)) {
                keep[i] = false;
                keep[j] = false;
            }
        }
        let segs: Vec<(usize, usize)> = segs
            .iter()
            .zip(&keep)
            .filter(|(_, k)| **k)
            .map(|(s, _)| *s)
            .collect();
        let mut used = vec![false; segs.len()];
        let (start, second) = self.base[e];
        let mut ring = vec![start];
        let mut cur = start;
        let mut prev_dir = self.nodes[second].p - self.nodes[start].p;
        let mut first = true;
        loop {
            // Outgoing candidates from `cur`.
            let cands: Vec<usize> = (0..segs.len())
                .filter(|&i| !used[i] && segs[i].0 == cur)
                .collect();
            let pick = if first {
                cands.iter().copied().find(|&i| segs[i].1 == second)
            } else if cands.len() <= 1 {
                cands.first().copied()
            } else {
                // Face touching itself: take the rightmost turn.
                cands.iter().copied().max_by(|&i, &j| {
                    let ti = turn(prev_dir, self.nodes[segs[i].1].p - self.nodes[cur].p);
                    let tj = turn(prev_dir, self.nodes[segs[j].1].p - self.nodes[cur].p);
                    tj.total_cmp(&ti)
                })
            };
            let i = pick.ok_or(SkeletonError::Inconsistent("face boundary does not close"))?;
            first = false;
            used[i] = true;
            prev_dir = self.nodes[segs[i].1].p - self.nodes[cur].p;
            cur = segs[i].1;
            if cur == start {
                break;
            }
            ring.push(cur);
            if ring.len() > segs.len() + 1 {
                return Err(SkeletonError::Inconsistent("face boundary does not close"));
            }
        }
        if used.iter().any(|u| !u) {
            return Err(SkeletonError::Inconsistent(
                "face boundary has extra pieces",
            ));
        }
        if ring.len() < 3 {
            return Err(SkeletonError::Inconsistent(
                "face with fewer than 3 vertices",
            ));
        }
        Ok(ring)
    }
}

/// Signed turn angle from direction `a` to direction `b` (counter-clockwise positive).
fn turn(a: DVec2, b: DVec2) -> f64 {
    a.perp_dot(b).atan2(a.dot(b))
}

/// Sutherland–Hodgman clip of a ring against `s >= c` (or `s <= c` when `upper`), where `s` is
/// the ground position along `d` measured from `a`. `z` is interpolated linearly.
fn clip(poly: &[DVec3], a: DVec2, d: DVec2, c: f64, upper: bool) -> Vec<DVec3> {
    if !c.is_finite() {
        return poly.to_vec();
    }
    let f = |p: DVec3| {
        let s = (p.truncate() - a).dot(d) - c;
        if upper {
            -s
        } else {
            s
        }
    };
    let n = poly.len();
    let mut out = Vec::with_capacity(n + 2);
    for i in 0..n {
        let (p, q) = (poly[i], poly[(i + 1) % n]);
        let (fp, fq) = (f(p), f(q));
        if fp >= 0.0 {
            out.push(p);
        }
        if (fp >= 0.0) != (fq >= 0.0) {
            let t = fp / (fp - fq);
            out.push(p + (q - p) * t);
        }
    }
    out
}

/// Removes consecutive vertices closer than `tol` (ground plus height).
fn dedup(poly: Vec<DVec3>, tol: f64) -> Vec<DVec3> {
    let mut out: Vec<DVec3> = Vec::with_capacity(poly.len());
    for p in poly {
        if out.last().is_none_or(|q| q.distance(p) > tol) {
            out.push(p);
        }
    }
    while out.len() > 1 && out[0].distance(out[out.len() - 1]) <= tol {
        out.pop();
    }
    out
}

#[cfg(test)]
mod tests {

    #[test]
    fn a_footprint_with_too_many_edges_is_refused_at_once() {
        // 4,000 vertices on a wavy circle: no run of them is collinear.
        let n = 4000;
        let ring: Vec<DVec2> = (0..n)
            .map(|i| {
                let a = i as f64 / n as f64 * std::f64::consts::TAU;
                let r = 20.0 + if i % 2 == 0 { 0.0 } else { 0.5 };
                DVec2::new(r * a.cos(), r * a.sin())
            })
            .collect();
        let t = std::time::Instant::now();
        let err = straight_skeleton(&Polygon::new(ring, vec![])).unwrap_err();
        assert!(
            matches!(
                err,
                SkeletonError::TooComplex {
                    edges: 4000,
                    max: MAX_EDGES
                }
            ),
            "{err}"
        );
        assert!(t.elapsed().as_secs() < 5, "refused quickly");
    }
    use super::*;

    fn poly(pts: &[(f64, f64)]) -> Polygon {
        Polygon::new(pts.iter().map(|&(x, y)| DVec2::new(x, y)).collect(), vec![])
    }

    fn square(x: f64, y: f64) -> Vec<DVec2> {
        vec![
            DVec2::new(x, y),
            DVec2::new(x, y + 1.),
            DVec2::new(x + 1., y + 1.),
            DVec2::new(x + 1., y),
        ]
    }

    #[test]
    fn rectangle_faces() {
        let sk = straight_skeleton(&poly(&[(0., 0.), (10., 0.), (10., 4.), (0., 4.)])).unwrap();
        let sizes: Vec<usize> = sk.faces.iter().map(|f| f.polygon.len()).collect();
        assert_eq!(sizes, vec![4, 3, 4, 3]);
        assert_eq!(sk.faces[1].polygon[2], DVec3::new(8., 2., 2.));
    }

    #[test]
    fn collinear_vertices_keep_one_face_per_edge() {
        let sk = straight_skeleton(&poly(&[(0., 0.), (4., 0.), (10., 0.), (10., 4.), (0., 4.)]))
            .unwrap();
        assert_eq!(sk.faces.len(), 5);
        let e0 = &sk.faces[0].polygon;
        assert_eq!(
            (e0[0].truncate(), e0[1].truncate()),
            (DVec2::ZERO, DVec2::new(4., 0.))
        );
    }

    /// Regressions found by the property tests.
    #[test]
    fn regressions() {
        let stars: [&[(f64, f64)]; 2] = [
            &[
                (0.39838971759809566, 0.035855723561373405),
                (0.33404937147622477, 0.5060631665136619),
                (-0.8479026993284455, 0.9485935222440922),
                (-0.37547005695450164, -0.13792112358367487),
                (-0.3433795174407466, -0.2051597109623623),
                (-0.11857819031895019, -0.8753793534834874),
                (0.603122373712497, -0.1318777078045141),
            ],
            &[
                (1.735785639633616, 0.08395971628638865),
                (1.1675437242486026, 1.5053175665116583),
                (0.24598550744084619, 0.7620072262379639),
                (0.11391485177964451, 1.5685225093791306),
                (-0.2791213097346702, 0.6407584669289865),
                (-0.7847381485905126, 0.6302521174771831),
                (-0.3925480504557654, 0.07685068694148345),
                (-1.2180783529680586, -0.3634810926398813),
                (-0.2862395842976485, -0.27940454609957477),
                (-0.12360679774997903, -0.3804226065180614),
                (0.06734281653881553, -0.39429043237266037),
                (0.24286500312748444, -0.31783107188550175),
                (0.3627497443402183, -0.16856044310901153),
            ],
        ];
        for s in stars {
            assert!(straight_skeleton(&poly(s)).is_ok());
        }
        // Two courtyards whose wavefronts meet each other before the outer one.
        let outer = vec![
            DVec2::new(0., 0.),
            DVec2::new(7., 0.),
            DVec2::new(7., 7.),
            DVec2::new(0., 7.),
        ];
        let p = Polygon::new(outer, vec![square(2., 2.), square(2., 4.)]);
        assert_eq!(straight_skeleton(&p).unwrap().faces.len(), 12);
    }

    #[test]
    fn invalid_inputs_are_errors() {
        let bow = poly(&[(0., 0.), (6., 4.), (6., 0.), (0., 2.)]);
        assert!(matches!(
            straight_skeleton(&bow),
            Err(SkeletonError::SelfIntersection { .. })
        ));
        let spike = poly(&[
            (0., 0.),
            (4., 0.),
            (4., 4.),
            (2., 4.),
            (2., 8.),
            (2., 4.),
            (0., 4.),
        ]);
        assert!(matches!(
            straight_skeleton(&spike),
            Err(SkeletonError::Spike { .. })
        ));
        let nan = poly(&[(0., 0.), (f64::NAN, 0.), (4., 4.)]);
        assert!(matches!(
            straight_skeleton(&nan),
            Err(SkeletonError::NonFinite { .. })
        ));
        assert!(straight_skeleton(&poly(&[(0., 0.), (1., 0.)])).is_err());
        assert!(straight_skeleton(&poly(&[(0., 0.), (1., 0.), (2., 0.)])).is_err());
        let outside = Polygon::new(square(0., 0.), vec![square(5., 5.)]);
        assert!(matches!(
            straight_skeleton(&outside),
            Err(SkeletonError::HoleOutside { .. })
        ));
    }
}
