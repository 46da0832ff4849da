//! The OSM roof catalogue on any simple footprint, holes included, built on the straight
//! skeleton.
//!
//! # Method
//!
//! Every roof except flat, skillion and the pyramid/cone apex roofs is a *profile roof*: the
//! skeleton gives, for each footprint edge, the face swept by that edge's wavefront, and every
//! point of a face carries `t`, its distance to the edge's line. The roof height is a
//! piecewise-linear function `z = h(t)`, the same for every face (the *profile*):
//!
//! * hipped: `h(t) = t·tan(pitch)`;
//! * mansard: steep ([`MANSARD_LOWER_DEG`]) up to the break distance `t0`, then shallow
//!   ([`MANSARD_UPPER_DEG`]); gambrel the same with gable ends ([`GAMBREL_LOWER_DEG`],
//!   [`GAMBREL_UPPER_DEG`]);
//! * dome: a quarter circle of radius `T` (the largest `t`, the inscribed radius) in
//!   [`CURVE_BANDS`] chords; round (a barrel vault): the same circle with gable ends; onion: a
//!   bulb profile ([`ONION_PROFILE`]) that rises almost vertically from the eave, bulges and
//!   ends in a concave spire, kept inside the footprint (a skeleton roof cannot overhang).
//!
//! Each face is cut at the profile's break distances into bands; within a band `t` is affine on
//! the face and `h` is linear, so every band is planar. Two faces meet along a skeleton arc on
//! which both have the same `t`, so their bands meet at the same points: the roof stays closed.
//! Break distances that fall within a tolerance of some vertex's `t` are nudged so that no
//! vertex lies on a cut (the cut then never runs along an edge or touches a vertex, and the
//! crossings along the cut pair up exactly).
//!
//! Why offsets and not the thesis's "top polygon shrunk to 80 %" for the mansard: scaling a
//! polygon about its centroid keeps it inside itself only for star-shaped outlines, and even
//! then gives eaves of unequal depth (a long wing gets a deep lower slope, a short one a thin
//! one) and, on an L or a courtyard, an upper polygon that crosses the walls. The inward offset
//! at distance `t0` (which the skeleton gives exactly) is inside the footprint for every simple
//! polygon, has the same depth on every side, and handles holes and wings narrower than `2·t0`
//! (they simply never reach the upper slope).
//!
//! # Gables (after Laycock and Day)
//!
//! A *hip end* is a triangular skeleton face (edge `a → b`, apex `m`) whose apex lies on
//! exactly three faces — its own and those of the two edges next to it — and whose two
//! neighbouring edges run roughly opposite (more than [`GABLE_MIN_OPPOSITE_DEG`] apart: the end
//! of a wing, not a chamfered corner). The apex is moved along the ridge (the line where the
//! two neighbouring planes meet) onto the vertical plane of the edge: the point `p` of `a b`
//! equidistant from the two neighbouring edges' lines. The neighbours take over the two halves of
//! the end triangle; `p` lies on both their planes, so they stay planar and the roof stays
//! closed. The wall under the edge is then closed by the roof line `b → p → a` (see
//! [`RoofLine::over`]). On an L, T, U, H or a courtyard block each wing ends in its own gable
//! and the wings' ridges meet in valleys and hips, as a carpenter frames them. An end whose
//! side has a vertex a little off straight (more than the skeleton's collinear tolerance, less
//! than [`GABLE_MAX_KINK_DEG`]) is made of two or three faces and is still one end; a square's
//! four hips meet in one apex, and two opposite ones become gables. An end that is no hip end
//! (an irregular junction) stays hipped, which is still a closed roof.
//!
//! A half-hip cuts the gable at the fraction [`HALF_HIP_FRACTION`] of its height: the wall stops
//! at a horizontal line there, and a small hip rises from it to the ridge.

use std::collections::HashSet;

use glam::{DVec2, DVec3};

use super::{RoofError, RoofGeometry};
use crate::geometry::hull::convex_hull;
use crate::geometry::skeleton::{collinear_tolerance, straight_skeleton, straight_skeleton_merged};
use crate::geometry::{CellHash, Polygon};
use crate::model::Face;

/// Pitch of the mansard's lower (steep) slope, degrees.
pub const MANSARD_LOWER_DEG: f64 = 70.0;
/// Pitch of the mansard's upper (shallow) slope, degrees.
pub const MANSARD_UPPER_DEG: f64 = 25.0;
/// Horizontal depth of the mansard's lower slope, metres (about one storey at 70°), at most
/// [`MANSARD_BREAK_REL`] of the inscribed radius.
pub const MANSARD_BREAK_M: f64 = 1.0;
/// Upper bound of the mansard break as a fraction of the inscribed radius `T`.
pub const MANSARD_BREAK_REL: f64 = 0.35;
/// Gambrel (barn) lower slope, degrees.
pub const GAMBREL_LOWER_DEG: f64 = 60.0;
/// Gambrel upper slope, degrees.
pub const GAMBREL_UPPER_DEG: f64 = 30.0;
/// Gambrel break as a fraction of the inscribed radius `T` (a barn's lower slope covers
/// about 40 % of its half-width).
pub const GAMBREL_BREAK_REL: f64 = 0.4;
/// Number of chords of the dome and barrel-vault quarter circles.
pub const CURVE_BANDS: usize = 6;
/// Onion profile as (t / T, z / H) points, H = [`ONION_HEIGHT_REL`] · T.
pub const ONION_PROFILE: [(f64, f64); 8] = [
    (0.0, 0.0),
    (0.03, 0.2),
    (0.12, 0.38),
    (0.3, 0.52),
    (0.55, 0.62),
    (0.75, 0.72),
    (0.88, 0.84),
    (1.0, 1.0),
];
/// Onion height over the inscribed radius.
pub const ONION_HEIGHT_REL: f64 = 1.6;
/// Two edges next to a triangular end face must differ in direction by more than this for the
/// end to become a gable.
pub const GABLE_MIN_OPPOSITE_DEG: f64 = 135.0;
/// The top of a hip end (its vertices off the base) may spread over this fraction of the
/// base's length and still be one apex (see `make_gables`).
pub const GABLE_APEX_CLUSTER: f64 = 0.05;
/// A footprint's skeleton whose inner nodes all lie within this fraction of its largest `t`
/// (in plan) of the deepest node rises to that one apex (see `to_one_apex`).
pub const ONE_APEX_SPREAD: f64 = 0.1;
/// Fewest sides of an outline that `to_one_apex` takes for round (an octagonal tower).
pub const ONE_APEX_MIN_SIDES: usize = 8;
/// Height fraction of the gable wall under a half-hip.
pub const HALF_HIP_FRACTION: f64 = 0.6;

/// What happens to the hip ends of a profile roof.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Ends {
    /// Keep every hip.
    Hipped,
    /// Every hip end becomes a gable.
    Gabled,
    /// Every hip end but the first (in ring and edge order) becomes a gable.
    AllButOne,
    /// Every hip end becomes a gable up to the given fraction of its height, then a small hip.
    HalfHipped(f64),
}

/// A piecewise-linear height profile `z = h(t)`: points `(t, z)` with increasing `t`, starting
/// at (0, 0); beyond the last point the last slope continues.
#[derive(Clone, Debug, PartialEq)]
pub struct Profile(pub Vec<(f64, f64)>);

impl Profile {
    /// `z = t·tan(pitch)`.
    pub fn linear(slope: f64) -> Profile {
        Profile(vec![(0.0, 0.0), (1.0, slope)])
    }

    /// Steep `lower` slope up to `t0`, then `upper`.
    pub fn broken(lower: f64, upper: f64, t0: f64) -> Profile {
        Profile(vec![
            (0.0, 0.0),
            (t0, lower * t0),
            (t0 + 1.0, lower * t0 + upper),
        ])
    }

    /// A quarter circle of radius `r` (a dome or a barrel vault), in [`CURVE_BANDS`] chords.
    pub fn circle(r: f64) -> Profile {
        Profile(
            (0..=CURVE_BANDS)
                .map(|i| {
                    let a = i as f64 / CURVE_BANDS as f64 * std::f64::consts::FRAC_PI_2;
                    (r * (1.0 - a.cos()), r * a.sin())
                })
                .collect(),
        )
    }

    /// The onion bulb over inscribed radius `r`.
    pub fn onion(r: f64) -> Profile {
        let h = ONION_HEIGHT_REL * r;
        Profile(ONION_PROFILE.iter().map(|&(t, z)| (t * r, z * h)).collect())
    }

    /// Evaluates `h(t)`.
    pub fn eval(&self, t: f64) -> f64 {
        let p = &self.0;
        let n = p.len();
        if n < 2 {
            return 0.0;
        }
        let i = (1..n - 1).find(|&i| t < p[i].0).unwrap_or(n - 1);
        let (a, b) = (p[i - 1], p[i]);
        let dt = b.0 - a.0;
        if dt <= 0.0 {
            return b.1;
        }
        a.1 + (t - a.0) * (b.1 - a.1) / dt
    }
}

/// A roof face in plan: points `(x, y, t)` where `t` is affine on the face and the height is
/// `h(t)`.
#[derive(Clone, Debug)]
struct TFace {
    /// The face's edge (ring, first input edge): faces of one ring are consecutive in ring
    /// order.
    edge: (usize, usize),
    pts: Vec<DVec3>,
}

/// Builds a profile roof (see the module documentation) with the eave at z = 0.
///
/// `profile` receives `T`, the largest skeleton distance (the inscribed radius), and returns
/// the height profile. Errors: any straight-skeleton error (an invalid footprint).
pub fn profile_roof(
    poly: &Polygon,
    ends: Ends,
    profile: impl Fn(f64) -> Profile,
) -> Result<RoofGeometry, RoofError> {
    // One face per side, collinear vertices included: a gable end or a roof plane over a side
    // with an extra vertex is one face, as it is one plane.
    let sk = straight_skeleton_merged(poly)?;
    let (lo, hi) = poly.bounds();
    let size = (hi - lo).max_element();
    let mut faces: Vec<Option<TFace>> = sk
        .faces
        .iter()
        .map(|f| {
            Some(TFace {
                edge: f.edge,
                pts: f.polygon.clone(),
            })
        })
        .collect();
    if !to_one_apex(poly, &mut faces, size) && ends != Ends::Hipped {
        make_gables(&mut faces, ends, 1e-7 * size);
    }
    let tmax = faces
        .iter()
        .flatten()
        .flat_map(|f| f.pts.iter())
        .map(|p| p.z)
        .fold(0.0, f64::max);
    let prof = profile(tmax);
    // Break levels, nudged away from every vertex's t.
    let mut ts: Vec<f64> = faces
        .iter()
        .flatten()
        .flat_map(|f| f.pts.iter().map(|p| p.z))
        .collect();
    ts.sort_by(f64::total_cmp);
    // A cut closer than `eps` to a vertex would leave a sliver band: the break moves instead
    // (by at most 200 steps of `eps`), trying a clearance of 1e-3, then 1e-5, then 1e-7 of the
    // footprint size. The profile keeps its slopes (its heights shift a little); a break that
    // cannot be placed is dropped (the next segment takes the previous slope).
    let clear = |l: f64, eps: f64| {
        let i = ts.partition_point(|&t| t < l);
        let d1 = ts.get(i).map_or(f64::INFINITY, |t| t - l);
        let d0 = i.checked_sub(1).map_or(f64::INFINITY, |j| l - ts[j]);
        d0.min(d1) > eps && l > eps && l < tmax - eps
    };
    let pts = &prof.0;
    let mut placed: Vec<(f64, f64)> = vec![(0.0, 0.0)];
    let mut slope = if pts.len() >= 2 && pts[1].0 > pts[0].0 {
        (pts[1].1 - pts[0].1) / (pts[1].0 - pts[0].0)
    } else {
        0.0
    };
    let mut levels = Vec::new();
    for i in 1..pts.len() {
        let b = pts[i].0;
        let next_slope = match pts.get(i + 1) {
            Some(q) if q.0 > b => (q.1 - pts[i].1) / (q.0 - b),
            _ => slope,
        };
        if i + 1 == pts.len() {
            break;
        }
        let last = placed[placed.len() - 1].0;
        let found = [1e-3, 1e-5, 1e-7].iter().find_map(|rel| {
            let eps = rel * size;
            (0..400)
                .map(|j| b + (j / 2) as f64 * eps * if j % 2 == 0 { 1.0 } else { -1.0 })
                .find(|&l| l > last + eps && clear(l, eps))
        });
        if let Some(l) = found {
            let (t0, h0) = placed[placed.len() - 1];
            placed.push((l, h0 + slope * (l - t0)));
            levels.push(l);
            slope = next_slope;
        }
    }
    let (t0, h0) = placed[placed.len() - 1];
    placed.push((t0 + 1.0, h0 + slope));
    let prof = Profile(placed);
    levels.sort_by(f64::total_cmp);
    let mut out = Vec::new();
    for f in faces.into_iter().flatten() {
        let mut rest = vec![f.pts];
        for &l in &levels {
            let mut next = Vec::new();
            for r in rest {
                let (below, above) = split_ring(&r, l);
                out.extend(below);
                next.extend(above);
            }
            rest = next;
        }
        out.extend(rest);
    }
    let faces = out
        .into_iter()
        .filter(|r| r.len() >= 3)
        .map(|r| {
            Face::new(
                r.into_iter()
                    .map(|p| DVec3::new(p.x, p.y, prof.eval(p.z)))
                    .collect(),
            )
        })
        .collect::<Vec<_>>();
    let mut faces = faces;
    insert_footprint_vertices(&mut faces, poly, 2.0 * collinear_tolerance(size));
    let walls = gable_walls(poly, &faces);
    Ok(RoofGeometry::from_parts(faces, walls))
}

/// Makes the faces of a footprint whose skeleton nearly closes in one point (a round tower drawn
/// as a polygon of many sides, a regular octagon) rise to one apex: each face becomes its base
/// (the footprint side, collinear vertices included) and the deepest skeleton node, at the
/// largest `t`. Returns whether it did.
///
/// The skeleton of such a footprint, drawn by hand, does not meet in one point: its inner nodes
/// scatter over a few centimetres, joined by edges of millimetres, and the faces there are
/// needles that the millimetre rounding tilts by tens of degrees (a validator's sliver). A
/// triangle is planar whatever its apex; the apex is at most [`ONE_APEX_SPREAD`] of the
/// largest `t` from where each face's own top was, so a face's pitch changes by a few degrees
/// at most (2.5° at 35°).
///
/// Applies to round outlines: without holes, of [`ONE_APEX_MIN_SIDES`] sides or more, convex,
/// every corner within [`ONE_APEX_SPREAD`] of the mean distance from the deepest node, and all
/// inner nodes within [`ONE_APEX_SPREAD`] · `T` (in plan) of it; every face must have one run
/// of base vertices.
fn to_one_apex(poly: &Polygon, faces: &mut [Option<TFace>], size: f64) -> bool {
    if !poly.holes.is_empty() || poly.outer.len() < ONE_APEX_MIN_SIDES {
        return false;
    }
    let eps = 1e-9 * size;
    let Some(apex) = faces
        .iter()
        .flatten()
        .flat_map(|f| f.pts.iter())
        .copied()
        .max_by(|a, b| a.z.total_cmp(&b.z))
    else {
        return false;
    };
    let t = apex.z;
    let spread = ONE_APEX_SPREAD * t;
    let inner_close = faces
        .iter()
        .flatten()
        .flat_map(|f| f.pts.iter())
        .filter(|p| p.z > eps)
        .all(|p| p.truncate().distance(apex.truncate()) <= spread);
    // Round: convex, every corner about as far from the apex as the others.
    let n = poly.outer.len();
    let c = apex.truncate();
    let convex = (0..n).all(|i| {
        let (a, b, d) = (
            poly.outer[i],
            poly.outer[(i + 1) % n],
            poly.outer[(i + 2) % n],
        );
        (b - a).perp_dot(d - b) >= 0.0 && (b - a).perp_dot(c - a) > 0.05 * t * (b - a).length()
    });
    let radii: Vec<f64> = poly.outer.iter().map(|p| p.distance(c)).collect();
    let mean = radii.iter().sum::<f64>() / n as f64;
    let round = radii
        .iter()
        .all(|r| (r - mean).abs() <= ONE_APEX_SPREAD * mean);
    if !(t > eps && inner_close && convex && round) {
        return false;
    }
    let mut out = Vec::with_capacity(faces.len());
    for f in faces.iter().flatten() {
        let m = f.pts.len();
        // The base run: from the base vertex after an inner one, while on the base.
        let Some(s) = (0..m).find(|&i| f.pts[i].z <= eps && f.pts[(i + m - 1) % m].z > eps) else {
            return false;
        };
        let base: Vec<DVec3> = (0..m)
            .map(|k| f.pts[(s + k) % m])
            .take_while(|p| p.z <= eps)
            .collect();
        let rest_on_base = (base.len()..m).any(|k| f.pts[(s + k) % m].z <= eps);
        if base.len() < 2 || rest_on_base {
            return false;
        }
        let mut pts = base;
        pts.push(apex);
        out.push(TFace { edge: f.edge, pts });
    }
    for (slot, f) in faces.iter_mut().filter(|f| f.is_some()).zip(out) {
        *slot = Some(f);
    }
    true
}

/// Puts every footprint vertex that an edge of the roof's boundary passes over into that edge,
/// at the edge's height there, so that the wall on each side of it meets the roof at its
/// corner (a gable over a side with a collinear vertex rises to the roof line at that vertex,
/// not to the eave). A boundary edge runs along the footprint in the ring's direction from
/// the place of its start to the place of its end (each within `tol` of the footprint: the
/// collinear vertices the skeleton merged away lie up to its collinear tolerance off the
/// chord); the vertices it passes over are the ring's vertices between those places. Edges
/// inside the roof (two faces meeting) are left alone.
fn insert_footprint_vertices(faces: &mut [Face], poly: &Polygon, tol: f64) {
    type K = (u64, u64, u64);
    let key = |p: DVec3| (p.x.to_bits(), p.y.to_bits(), p.z.to_bits());
    let n_edges = faces
        .iter()
        .map(|f| f.outer.len() + f.holes.iter().map(Vec::len).sum::<usize>())
        .sum();
    let mut edges: HashSet<(K, K), CellHash> = HashSet::with_capacity_and_hasher(n_edges, CellHash);
    for f in faces.iter() {
        for r in std::iter::once(&f.outer).chain(f.holes.iter()) {
            for i in 0..r.len() {
                edges.insert((key(r[i]), key(r[(i + 1) % r.len()])));
            }
        }
    }
    let rings: Vec<&Vec<DVec2>> = poly.rings().collect();
    // The place of a point on the footprint: (ring, edge index + fraction along the edge).
    let place = |q: DVec2| -> Option<(usize, f64)> {
        let mut best: Option<(f64, usize, f64)> = None;
        for (ri, r) in rings.iter().enumerate() {
            let n = r.len();
            for i in 0..n {
                let (a, b) = (r[i], r[(i + 1) % n]);
                if q == a {
                    return Some((ri, i as f64));
                }
                let d = b - a;
                let l2 = d.length_squared();
                if l2 <= 0.0 {
                    continue;
                }
                let s = ((q - a).dot(d) / l2).clamp(0.0, 1.0);
                let dist = q.distance(a + d * s);
                if dist <= tol && best.is_none_or(|(bd, ..)| dist < bd) {
                    best = Some((dist, ri, i as f64 + s));
                }
            }
        }
        best.map(|(_, ri, p)| (ri, p))
    };
    // The places of a ring's vertices, each found once (an edge's end is the next one's start).
    let mut places: Vec<Option<Option<(usize, f64)>>> = Vec::new();
    for f in faces.iter_mut() {
        for r in std::iter::once(&mut f.outer).chain(f.holes.iter_mut()) {
            let n = r.len();
            let mut out = Vec::with_capacity(n);
            places.clear();
            places.resize(n, None);
            for i in 0..n {
                let (u, v) = (r[i], r[(i + 1) % n]);
                out.push(u);
                let d = (v - u).truncate();
                let l2 = d.length_squared();
                if l2 <= 1e-12 || edges.contains(&(key(v), key(u))) {
                    continue;
                }
                let pu = *places[i].get_or_insert_with(|| place(u.truncate()));
                let j = (i + 1) % n;
                let pv = *places[j].get_or_insert_with(|| place(v.truncate()));
                let (Some((ru, pu)), Some((rv, pv))) = (pu, pv) else {
                    continue;
                };
                if ru != rv {
                    continue;
                }
                let ring = rings[ru];
                let m = ring.len();
                // Ring vertices k with pu < k < pv, going forward (around the end if need be);
                // a boundary edge never passes over the whole ring, and runs along the
                // footprint (its middle on it too: a ridge between two gable points that only
                // looks open, for a vertex on it the other side has, does not).
                let span = if pv > pu { pv - pu } else { pv + m as f64 - pu };
                if span >= (m - 1) as f64 {
                    continue;
                }
                let along = place(0.5 * (u + v).truncate()).is_some_and(|(rm, pm)| {
                    let from_u = if pm >= pu {
                        pm - pu
                    } else {
                        pm + m as f64 - pu
                    };
                    rm == ru && from_u <= span
                });
                if !along {
                    continue;
                }
                let first = pu.floor() as usize + 1;
                let mut k = first;
                while (k as f64) < pu + span {
                    let c = ring[k % m];
                    let s = (c - u.truncate()).dot(d) / l2;
                    if s > 0.0 && s < 1.0 {
                        out.push(c.extend(u.z + s * (v.z - u.z)));
                    }
                    k += 1;
                }
            }
            *r = out;
        }
    }
}

/// Vertical faces closing the roof above the eave on each footprint edge whose roof line rises
/// above it (gables, half-hips): `a, b, then the roof line from b back to a` (see
/// [`RoofLine::over`]), counter-clockwise seen from outside.
fn gable_walls(poly: &Polygon, faces: &[Face]) -> Vec<Face> {
    let line = RoofLine::new(faces, poly);
    let mut out = Vec::new();
    for (ri, r) in poly.rings().enumerate() {
        for i in 0..r.len() {
            let (a, b) = (r[i], r[(i + 1) % r.len()]);
            let top = line.over(ri, i);
            if top.iter().any(|p| p.z > 0.0) {
                let mut ring = vec![a.extend(0.0), b.extend(0.0)];
                ring.extend(top.iter().filter(|p| p.z > 0.0));
                out.push(Face::new(ring));
            }
        }
    }
    out
}

/// Where the walls meet a roof: the vertices of the roof's boundary (those of the roof faces'
/// edges that no other face runs back along: the eaves, gable lines and the points on them),
/// each with the footprint edge it stands on.
pub struct RoofLine<'a> {
    footprint: &'a Polygon,
    /// Boundary vertices above the eave with the footprint edge (ring, edge) nearest to them
    /// in plan, within [`RoofLine::TOL`].
    above: Vec<(DVec3, (usize, usize))>,
    /// Every boundary vertex (for the heights at the footprint's corners), sorted by x.
    boundary: Vec<DVec3>,
    /// No x is NaN, so that `boundary` is ordered by `<` on x too.
    sorted: bool,
}

impl<'a> RoofLine<'a> {
    /// How far in plan (metres) a roof boundary vertex may lie from its footprint edge: twice
    /// the skeleton's collinear tolerance ([`crate::geometry::skeleton::COLLINEAR_ABS`]), since
    /// a roof built on a side with a vertex a few millimetres off straight puts the side's
    /// gable point on the side's chord.
    pub const TOL: f64 = 2.0 * crate::geometry::skeleton::COLLINEAR_ABS;

    /// The boundary of `faces` (edges compared on exact coordinates) over `footprint`.
    pub fn new(faces: &[Face], footprint: &'a Polygon) -> RoofLine<'a> {
        type K = (u64, u64, u64);
        let key = |p: DVec3| (p.x.to_bits(), p.y.to_bits(), p.z.to_bits());
        let rings = || {
            faces
                .iter()
                .flat_map(|f| std::iter::once(&f.outer).chain(f.holes.iter()))
        };
        let mut edges: HashSet<(K, K), CellHash> =
            HashSet::with_capacity_and_hasher(rings().map(Vec::len).sum(), CellHash);
        for r in rings() {
            for i in 0..r.len() {
                edges.insert((key(r[i]), key(r[(i + 1) % r.len()])));
            }
        }
        let mut boundary: Vec<DVec3> = Vec::new();
        for r in rings() {
            for i in 0..r.len() {
                let (u, v) = (r[i], r[(i + 1) % r.len()]);
                if !edges.contains(&(key(v), key(u))) {
                    boundary.push(u);
                    boundary.push(v);
                }
            }
        }
        boundary.sort_by(|p, q| {
            p.x.total_cmp(&q.x)
                .then(p.y.total_cmp(&q.y))
                .then(p.z.total_cmp(&q.z))
        });
        boundary.dedup();
        let mut above = Vec::new();
        for p in &boundary {
            if p.z <= 1e-6 {
                continue;
            }
            let g = p.truncate();
            let mut best: Option<(f64, (usize, usize))> = None;
            for (ri, r) in footprint.rings().enumerate() {
                let n = r.len();
                for i in 0..n {
                    let (a, b) = (r[i], r[(i + 1) % n]);
                    let d = b - a;
                    let l2 = d.length_squared();
                    if l2 <= 0.0 {
                        continue;
                    }
                    let s = ((g - a).dot(d) / l2).clamp(0.0, 1.0);
                    let dist = g.distance(a + d * s);
                    if dist <= Self::TOL && best.is_none_or(|(bd, _)| dist < bd) {
                        best = Some((dist, (ri, i)));
                    }
                }
            }
            if let Some((_, e)) = best {
                above.push((*p, e));
            }
        }
        let sorted = boundary.iter().all(|p| !p.x.is_nan());
        RoofLine {
            footprint,
            above,
            boundary,
            sorted,
        }
    }

    /// The roof line over edge `i` of ring `ring` of the footprint (`a → b`), relative to the
    /// eave (z = 0): the roof boundary's vertices standing on that edge (nearer to it than to
    /// any other), ordered from `b` back to `a`, with `b` and `a` first and last (at the
    /// highest roof vertex there, 0 if none is higher). A wall on this edge closes the roof when
    /// its outline is `a(base), b(base), then these points`.
    pub fn over(&self, ring: usize, i: usize) -> Vec<DVec3> {
        let Some(r) = self.footprint.rings().nth(ring) else {
            return Vec::new();
        };
        let (a, b) = (r[i], r[(i + 1) % r.len()]);
        let d = b - a;
        let len2 = d.length_squared();
        if len2 <= 0.0 || !len2.is_finite() {
            return vec![b.extend(0.0), a.extend(0.0)];
        }
        let tol = 1e-6 * len2.sqrt().max(1.0);
        // The roof at the corners: its boundary vertices standing there, within a grid step
        // (the footprint's corner rounded to the grid: the roof was built on it before); else
        // those within the grid's vertex gap (a vertex the grid moved farther). Near ones win,
        // so that a roof vertex a few millimetres from a corner (a gable point just past a
        // kink of the side) stays a vertex of the line instead of being pulled onto the
        // corner, which would leave the wall short of the roof.
        let snap = tol.max(1.0 / crate::model::GRID_STEPS_PER_M);
        let gap = tol.max(crate::model::MIN_VERTEX_GAP);
        // The boundary is sorted by x: only the points within (a little more than) `gap` of a
        // corner in x can be within `gap` of it.
        let near = |c: DVec2| -> &[DVec3] {
            if !self.sorted {
                return &self.boundary;
            }
            let m = gap * (1.0 + 1e-6) + 1e-6;
            let lo = self.boundary.partition_point(|p| p.x < c.x - m);
            let hi = self.boundary.partition_point(|p| p.x <= c.x + m);
            &self.boundary[lo..hi.max(lo)]
        };
        // The highest z within `r` of corner `c` (not within `r` of `other`), if any.
        let top_at = |c: DVec2, other: Option<DVec2>, r: f64| -> Option<f64> {
            near(c)
                .iter()
                .filter(|p| {
                    let g = p.truncate();
                    g.distance(c) <= r && other.is_none_or(|o| g.distance(o) > r)
                })
                .map(|p| p.z)
                .reduce(f64::max)
        };
        // Exactly at a corner, only a vertex above the eave counts: the eave's own corner is
        // always there.
        let raised = |z: Option<f64>| z.filter(|&z| z > 1e-6);
        let (za, ca) = match raised(top_at(a, None, snap)) {
            Some(z) => (z, snap),
            None => (top_at(a, None, gap).unwrap_or(0.0).max(0.0), gap),
        };
        let (zb, cb) = match raised(top_at(b, Some(a), snap)) {
            Some(z) => (z, snap),
            None => (top_at(b, Some(a), gap).unwrap_or(0.0).max(0.0), gap),
        };
        let mut mid: Vec<(f64, DVec3)> = Vec::new();
        for &(p, e) in &self.above {
            let g = p.truncate();
            if e != (ring, i) || g.distance(a) <= ca || g.distance(b) <= cb {
                continue;
            }
            let s = (g - a).dot(d) / len2;
            if s > 0.0 && s < 1.0 {
                mid.push((s, p));
            }
        }
        mid.sort_by(|x, y| y.0.total_cmp(&x.0).then(x.1.z.total_cmp(&y.1.z)));
        mid.dedup_by(|x, y| x.1.distance(y.1) <= tol);
        let mut out = vec![b.extend(zb)];
        out.extend(mid.into_iter().map(|m| m.1));
        out.push(a.extend(za));
        out
    }
}

/// Most faces one end of a wing may be made of: a side whose vertex is a little off straight
/// (beyond the skeleton's collinear tolerance, within [`GABLE_MAX_KINK_DEG`]) has a face on
/// each part, and the two together are the end.
pub const GABLE_MAX_CHAIN: usize = 3;

/// Most turn (degrees) between the parts of one end of a wing (see [`GABLE_MAX_CHAIN`]).
pub const GABLE_MAX_KINK_DEG: f64 = 1.0;

/// Turns hip ends into gables or half-hips in place (see the module documentation).
///
/// A hip end is a face — or a run of up to [`GABLE_MAX_CHAIN`] faces of consecutive sides that
/// turn by less than [`GABLE_MAX_KINK_DEG`] from each other (one side with a vertex a little
/// off straight) — whose vertices other than its base `a → … → b` (its *top*) lie within
/// [`GABLE_APEX_CLUSTER`] of the base's length of each other — one apex, or the few nodes a
/// nearly antiparallel pair of sides leaves where the exact skeleton has one (a rectangle
/// skewed by hundredths of a degree) — and touch no face but the end's two neighbours, whose
/// sides run roughly opposite. Each neighbour's run of top vertices is replaced by the gable
/// point `p` (or the half-hip's points), which lies exactly on both neighbours' planes, so they
/// stay planar and share their new ridge end; a kink of the base between `a` and `p` is lifted
/// onto the first neighbour's plane (the roof line over it), one between `p` and `b` onto the
/// second's. A square's four hips meet in one apex: two opposite ones become the gables.
fn make_gables(faces: &mut [Option<TFace>], ends: Ends, tol: f64) {
    let mut skipped_first = false;
    // The next face of the same ring, in ring order.
    let next_of = |faces: &[Option<TFace>], i: usize| -> Option<usize> {
        let e = faces[i].as_ref()?.edge;
        let same: Vec<usize> = (0..faces.len())
            .filter(|&j| faces[j].as_ref().is_some_and(|f| f.edge.0 == e.0))
            .collect();
        let k = same.iter().position(|&j| j == i)?;
        Some(same[(k + 1) % same.len()])
    };
    for i in 0..faces.len() {
        if faces[i].is_none() {
            continue;
        }
        let mut chain = vec![i];
        for _ in 0..GABLE_MAX_CHAIN {
            if gable_chain(faces, &chain, ends, tol, &mut skipped_first).is_some() {
                break;
            }
            let Some(n) = next_of(faces, *chain.last().unwrap_or(&i)) else {
                break;
            };
            if chain.contains(&n) || !kinked(faces, *chain.last().unwrap_or(&i), n) {
                break;
            }
            chain.push(n);
        }
    }
    if !matches!(ends, Ends::Gabled | Ends::HalfHipped(_)) {
        return;
    }
    for i in 0..faces.len() {
        square_gables(faces, i, ends, tol);
    }
}

/// Whether face `j`'s side follows face `i`'s with a turn under [`GABLE_MAX_KINK_DEG`].
fn kinked(faces: &[Option<TFace>], i: usize, j: usize) -> bool {
    let (Some(f), Some(g)) = (&faces[i], &faces[j]) else {
        return false;
    };
    if f.pts.len() < 2 || g.pts.len() < 2 {
        return false;
    }
    let (rf, rg) = (base_run(f, 0.0), base_run(g, 0.0));
    let (f0, f1) = (rf[rf.len() - 2], rf[rf.len() - 1]);
    if f1.distance(g.pts[0]) > 1e-9 {
        return false;
    }
    let d1 = (f1 - f0).truncate().normalize_or_zero();
    let d2 = (rg[1] - rg[0]).truncate().normalize_or_zero();
    d1.dot(d2) >= GABLE_MAX_KINK_DEG.to_radians().cos()
}

/// The face's side: its first vertices, as long as they are on the footprint (`t` within
/// `tol` of 0), at least its first two. A side with collinear vertices (the corners of parts
/// drawn along it) is one face whose side has them all.
fn base_run(f: &TFace, tol: f64) -> &[DVec3] {
    let n = f
        .pts
        .iter()
        .take_while(|p| p.z.abs() <= tol)
        .count()
        .clamp(2.min(f.pts.len()), f.pts.len());
    &f.pts[..n]
}

/// The two faces holding `a → top` (before `a` in its ring) and `top → b`, with every face
/// touching the top outside `chain`; `None` unless they are exactly two and distinct.
fn end_neighbours(
    faces: &[Option<TFace>],
    chain: &[usize],
    a: DVec3,
    b: DVec3,
    in_top: &impl Fn(DVec3) -> bool,
    tol: f64,
) -> Option<(usize, usize)> {
    let touching: Vec<usize> = (0..faces.len())
        .filter(|j| !chain.contains(j))
        .filter(|&j| {
            faces[j]
                .as_ref()
                .is_some_and(|g| g.pts.iter().any(|q| in_top(*q)))
        })
        .collect();
    if touching.len() != 2 {
        return None;
    }
    let (mut prev, mut next) = (None, None);
    for &j in &touching {
        let g = faces[j].as_ref()?;
        let n = g.pts.len();
        for k in 0..n {
            let (u, v) = (g.pts[k], g.pts[(k + 1) % n]);
            if u.distance(a) <= tol && in_top(v) {
                prev = Some(j);
            }
            if in_top(u) && v.distance(b) <= tol {
                next = Some(j);
            }
        }
    }
    let (jp, jn) = (prev?, next?);
    (jp != jn).then_some((jp, jn))
}

/// The line of face `j`'s edge: origin and unit inward normal (the distance `t = n·(x - o)`),
/// when it runs roughly opposite to the other one's ([`GABLE_MIN_OPPOSITE_DEG`]).
fn opposite_lines(fp: &TFace, fnx: &TFace) -> Option<((DVec2, DVec2), (DVec2, DVec2))> {
    let dp = (fp.pts[1] - fp.pts[0]).truncate().normalize_or_zero();
    let dn = (fnx.pts[1] - fnx.pts[0]).truncate().normalize_or_zero();
    let min_cos = GABLE_MIN_OPPOSITE_DEG.to_radians().cos();
    if dp.dot(dn) > min_cos || dp == DVec2::ZERO || dn == DVec2::ZERO {
        return None;
    }
    Some((
        (fp.pts[0].truncate(), dp.perp()),
        (fnx.pts[0].truncate(), dn.perp()),
    ))
}

/// Makes the end made of the faces `chain` (consecutive sides) a gable or half-hip if it is a
/// hip end (see [`make_gables`]): `Some(true)` when it did, `Some(false)` when the end is one
/// but was left hipped on purpose (the first end of a side-hipped roof), `None` when the chain
/// is no hip end.
fn gable_chain(
    faces: &mut [Option<TFace>],
    chain: &[usize],
    ends: Ends,
    tol: f64,
    skipped_first: &mut bool,
) -> Option<bool> {
    // The base polyline a = q0, …, qm = b, and the top: every other vertex of the chain.
    let mut base: Vec<DVec3> = Vec::new();
    for &k in chain {
        let f = faces[k].as_ref()?;
        if f.pts.len() < 3 {
            return None;
        }
        let run = base_run(f, tol);
        if base.is_empty() {
            base.push(run[0]);
        }
        base.extend_from_slice(&run[1..]);
    }
    let (a, b) = (base[0], base[base.len() - 1]);
    let on_base = |q: DVec3| base.iter().any(|m| m.distance(q) <= tol);
    let mut top: Vec<DVec3> = Vec::new();
    for &k in chain {
        for q in &faces[k].as_ref()?.pts {
            if !on_base(*q) && !top.iter().any(|m| m.distance(*q) <= tol) {
                top.push(*q);
            }
        }
    }
    if top.is_empty() {
        return None;
    }
    // One apex: the top's highest vertex and those near it. A vertex clearly lower may be
    // there too, where a short face of a kinked side closed before the apex (a side drawn
    // in two pieces a few millimetres off straight); the end's neighbours hold it, and it
    // goes with the end. Two vertices far apart at the same height are a ridge: a long
    // side, no end.
    let width = (b - a).truncate().length();
    let cluster = GABLE_APEX_CLUSTER * width;
    let apex = top
        .iter()
        .copied()
        .max_by(|p, q| p.z.total_cmp(&q.z))
        .unwrap_or(a);
    if !top
        .iter()
        .all(|q| q.distance(apex) <= cluster || q.z < apex.z - cluster)
    {
        return None;
    }
    let in_top = |q: DVec3| top.iter().any(|m| m.distance(q) <= tol);
    let (jp, jn) = end_neighbours(faces, chain, a, b, &in_top, tol)?;
    let ((op, np), (on, nn)) = opposite_lines(faces[jp].as_ref()?, faces[jn].as_ref()?)?;
    let tp = |x: DVec2| np.dot(x - op);
    let tn = |x: DVec2| nn.dot(x - on);
    // The gable point: where the base is as far from both neighbours' lines.
    let f = |x: DVec2| tp(x) - tn(x);
    let mut at = None;
    for k in 0..base.len() - 1 {
        let (u, v) = (base[k].truncate(), base[k + 1].truncate());
        let (fu, fv) = (f(u), f(v));
        if fu <= 0.0 && fv > 0.0 {
            let s = -fu / (fv - fu);
            at = Some((k, u + (v - u) * s));
            break;
        }
    }
    let (k, p2) = at?;
    let t_p = tp(p2);
    if !(t_p.is_finite() && t_p > tol && p2.distance(a.truncate()) > 1e-3 * width)
        || p2.distance(b.truncate()) <= 1e-3 * width
    {
        return None;
    }
    if ends == Ends::AllButOne && !*skipped_first {
        *skipped_first = true;
        return Some(false);
    }
    let p = p2.extend(t_p);
    // The kinks of the base lifted onto the neighbour's plane on their side of p.
    let before: Vec<DVec3> = base[1..=k]
        .iter()
        .map(|q| q.truncate().extend(tp(q.truncate())))
        .collect();
    let after: Vec<DVec3> = base[k + 1..base.len() - 1]
        .iter()
        .map(|q| q.truncate().extend(tn(q.truncate())))
        .collect();
    let (with_prev, with_next, hip) = match ends {
        Ends::HalfHipped(c) => {
            let c = c.clamp(0.05, 0.95);
            // The half-hip's base cuts the gable at c of its height, above every kink (a kink
            // higher up would put the hip's base off the wall).
            let cut = c * t_p;
            if before.iter().chain(&after).any(|q| q.z >= cut) {
                return None;
            }
            let last_a = before.last().copied().unwrap_or(a);
            let first_b = after.first().copied().unwrap_or(b);
            let xa = last_a + (p - last_a) * ((cut - last_a.z) / (t_p - last_a.z));
            let xb = first_b + (p - first_b) * ((cut - first_b.z) / (t_p - first_b.z));
            // The hip's top on the ridge (the line both neighbours' planes share), a
            // horizontal (1 - c)·tp from p, so the small hip keeps about the roof's pitch,
            // and no farther than the old apex.
            let apex = top.iter().copied().sum::<DVec3>() / top.len() as f64;
            let mut d = (np - nn).perp().normalize_or_zero();
            if d.dot(apex.truncate() - p2) < 0.0 {
                d = -d;
            }
            let run = ((1.0 - c) * t_p).min((apex.truncate() - p2).dot(d));
            if !(run.is_finite() && run > tol) {
                return None;
            }
            let r = (p2 + d * run).extend(t_p + np.dot(d) * run);
            let mut wp = before.clone();
            wp.extend([xa, r]);
            let mut wn = vec![r, xb];
            wn.extend(after.iter().copied());
            (wp, wn, Some(vec![xa, xb, r]))
        }
        _ => {
            let mut wp = before.clone();
            wp.push(p);
            let mut wn = vec![p];
            wn.extend(after.iter().copied());
            (wp, wn, None)
        }
    };
    let edge = faces[chain[0]].as_ref()?.edge;
    for &c in chain {
        faces[c] = None;
    }
    if let Some(pts) = hip {
        faces[chain[0]] = Some(TFace { edge, pts });
    }
    for (j, with) in [(jp, with_prev), (jn, with_next)] {
        if let Some(g) = faces[j].as_mut() {
            g.pts = replace_runs(&g.pts, &in_top, &with);
            g.pts.dedup_by(|x, y| x.distance(*y) <= tol);
        }
    }
    Some(true)
}

/// A square's roof (four hips meeting in one apex) made gabled: face `i` and the face opposite
/// it become the gables, the two others meet along a ridge between their gable points. Does
/// nothing unless face `i`'s top is one point shared by exactly three other faces: the one
/// before it, the one after it (whose sides run opposite) and one whose side runs opposite to
/// `i`'s.
fn square_gables(faces: &mut [Option<TFace>], i: usize, ends: Ends, tol: f64) {
    let Some(f) = &faces[i] else { return };
    if f.pts.len() != 3 {
        return;
    }
    let (a, b, apex) = (f.pts[0], f.pts[1], f.pts[2]);
    let at_apex = |q: DVec3| q.distance(apex) <= tol;
    let touching: Vec<usize> = (0..faces.len())
        .filter(|&j| j != i)
        .filter(|&j| {
            faces[j]
                .as_ref()
                .is_some_and(|g| g.pts.iter().any(|q| at_apex(*q)))
        })
        .collect();
    if touching.len() != 3 {
        return;
    }
    let side = |j: usize| -> Option<(DVec3, DVec3)> {
        let g = faces[j].as_ref()?;
        (g.pts.len() == 3).then(|| (g.pts[0], g.pts[1]))
    };
    let mut prev = None;
    let mut next = None;
    let mut opposite = None;
    for &j in &touching {
        let Some((u, v)) = side(j) else { return };
        if v.distance(a) <= tol {
            prev = Some(j);
        } else if u.distance(b) <= tol {
            next = Some(j);
        } else {
            opposite = Some(j);
        }
    }
    let (Some(jp), Some(jn), Some(jo)) = (prev, next, opposite) else {
        return;
    };
    let (Some(fp), Some(fnx)) = (&faces[jp], &faces[jn]) else {
        return;
    };
    let Some(((op, np), (on, nn))) = opposite_lines(fp, fnx) else {
        return;
    };
    let Some((c, d)) = side(jo) else { return };
    // The gable points: on each end's side, as far from both neighbours' lines.
    let gable_point = |u: DVec3, v: DVec3| -> Option<DVec3> {
        let (u, v) = (u.truncate(), v.truncate());
        let f = |x: DVec2| np.dot(x - op) - nn.dot(x - on);
        let (fu, fv) = (f(u), f(v));
        if (fu - fv).abs() < 1e-12 {
            return None;
        }
        let s = fu / (fu - fv);
        if !(s > 1e-3 && s < 1.0 - 1e-3) {
            return None;
        }
        let x = u + (v - u) * s;
        let t = np.dot(x - op);
        (t > tol).then(|| x.extend(t))
    };
    let (ab, cd) = ((b - a).truncate(), (d - c).truncate());
    if ab.normalize_or_zero().dot(cd.normalize_or_zero()) > -std::f64::consts::FRAC_1_SQRT_2 {
        return;
    }
    let (Some(p), Some(q)) = (gable_point(a, b), gable_point(c, d)) else {
        return;
    };
    let edge_i = f.edge;
    let edge_o = faces[jo].as_ref().map(|g| g.edge);
    let (with_prev, with_next, hips) = match ends {
        Ends::HalfHipped(frac) => {
            // Each gable stops at `frac` of its height, and a small hip rises from there to
            // the ridge (the segment p q, on both neighbours' planes), a horizontal
            // (1 - frac)·t from the gable point, at most half-way.
            let frac = frac.clamp(0.05, 0.95);
            let cut = |u: DVec3, g: DVec3| u + (g - u) * frac;
            let len = (q - p).truncate().length();
            let run = ((1.0 - frac) * p.z.min(q.z)).min(0.5 * len);
            if !(run > tol && len > tol) {
                return;
            }
            let (rp, rq) = (p + (q - p) * (run / len), q + (p - q) * (run / len));
            let (xa, xb, xc, xd) = (cut(a, p), cut(b, p), cut(c, q), cut(d, q));
            (
                vec![xa, rp, rq, xd],
                vec![xc, rq, rp, xb],
                Some((vec![xa, xb, rp], vec![xc, xd, rq])),
            )
        }
        _ => (vec![p, q], vec![q, p], None),
    };
    faces[i] = None;
    faces[jo] = None;
    if let (Some((hi, ho)), Some(eo)) = (hips, edge_o) {
        faces[i] = Some(TFace {
            edge: edge_i,
            pts: hi,
        });
        faces[jo] = Some(TFace { edge: eo, pts: ho });
    }
    // Before `i` the ridge runs from i's gable to the opposite one; after it, back.
    for (j, with) in [(jp, with_prev), (jn, with_next)] {
        if let Some(g) = faces[j].as_mut() {
            g.pts = replace_runs(&g.pts, &at_apex, &with);
            g.pts.dedup_by(|x, y| x.distance(*y) <= tol);
        }
    }
}

/// The ring with every maximal (cyclic) run of the points `hit` marks replaced by `with`.
fn replace_runs(ring: &[DVec3], hit: &impl Fn(DVec3) -> bool, with: &[DVec3]) -> Vec<DVec3> {
    let n = ring.len();
    let Some(start) = (0..n).find(|&k| !hit(ring[k])) else {
        return with.to_vec();
    };
    let mut out = Vec::with_capacity(n + with.len());
    let mut in_run = false;
    for k in 0..n {
        let q = ring[(start + k) % n];
        if hit(q) {
            if !in_run {
                out.extend_from_slice(with);
                in_run = true;
            }
        } else {
            out.push(q);
            in_run = false;
        }
    }
    out
}

/// Splits a simple ring of points `(x, y, t)` by the level `t = l` (no vertex on it) into the
/// pieces below and above. Pieces keep the ring's orientation.
fn split_ring(ring: &[DVec3], l: f64) -> (Vec<Vec<DVec3>>, Vec<Vec<DVec3>>) {
    let n = ring.len();
    let below = |p: &DVec3| p.z < l;
    if ring.iter().all(below) {
        return (vec![ring.to_vec()], Vec::new());
    }
    if !ring.iter().any(below) {
        return (Vec::new(), vec![ring.to_vec()]);
    }
    // Ring with crossings inserted; `cross[k]` is Some(order along the line) for crossings.
    let mut pts: Vec<DVec3> = Vec::with_capacity(n + 4);
    let mut is_cross: Vec<bool> = Vec::with_capacity(n + 4);
    for i in 0..n {
        let (p, q) = (ring[i], ring[(i + 1) % n]);
        pts.push(p);
        is_cross.push(false);
        if below(&p) != below(&q) {
            pts.push(cross(p, q, l));
            is_cross.push(true);
        }
    }
    let m = pts.len();
    // Direction along the line: any, as long as both sides use the same; take the direction of
    // the first crossing pair's chord by sorting on the dominant axis of the crossings' spread.
    let xs: Vec<usize> = (0..m).filter(|&k| is_cross[k]).collect();
    let (mut lo, mut hi) = (DVec2::splat(f64::INFINITY), DVec2::splat(f64::NEG_INFINITY));
    for &k in &xs {
        lo = lo.min(pts[k].truncate());
        hi = hi.max(pts[k].truncate());
    }
    let axis = if hi.x - lo.x >= hi.y - lo.y {
        DVec2::X
    } else {
        DVec2::Y
    };
    let mut order = xs.clone();
    order.sort_by(|&u, &v| {
        pts[u]
            .truncate()
            .dot(axis)
            .total_cmp(&pts[v].truncate().dot(axis))
    });
    let mut partner = vec![usize::MAX; m];
    for c in order.chunks(2) {
        if let [u, v] = c {
            partner[*u] = *v;
            partner[*v] = *u;
        }
    }
    let mut used = vec![false; m];
    let mut pieces_below = Vec::new();
    let mut pieces_above = Vec::new();
    for start in 0..m {
        if is_cross[start] || used[start] {
            continue;
        }
        let side = below(&pts[start]);
        let mut piece = Vec::new();
        let mut k = start;
        let mut guard = 0;
        loop {
            guard += 1;
            if guard > 4 * m + 8 {
                break;
            }
            used[k] = true;
            piece.push(pts[k]);
            let nk = (k + 1) % m;
            if is_cross[nk] {
                // Leaving the side: take the chord to the partner, then carry on from there.
                piece.push(pts[nk]);
                let p = partner[nk];
                if p == usize::MAX {
                    break;
                }
                piece.push(pts[p]);
                k = (p + 1) % m;
            } else {
                k = nk;
            }
            if k == start {
                break;
            }
        }
        if piece.len() >= 3 {
            if side {
                pieces_below.push(piece);
            } else {
                pieces_above.push(piece);
            }
        }
    }
    (pieces_below, pieces_above)
}

/// The point of segment `p q` at `t = l`, computed from the endpoints in a canonical order so
/// that the two faces sharing the segment get the same bits.
fn cross(p: DVec3, q: DVec3, l: f64) -> DVec3 {
    let key = |v: DVec3| (v.x.to_bits(), v.y.to_bits(), v.z.to_bits());
    let (p, q) = if key(p) <= key(q) { (p, q) } else { (q, p) };
    let s = ((l - p.z) / (q.z - p.z)).clamp(0.0, 1.0);
    let g = p.truncate() + (q.truncate() - p.truncate()) * s;
    g.extend(l)
}

/// A skillion (shed) roof: the footprint as one plane rising against `down`, the unit vector
/// (in plan) the slope faces, with rise `slope` per metre, the lowest corner at z = 0.
pub fn skillion(poly: &Polygon, down: DVec2, slope: f64) -> Result<RoofGeometry, RoofError> {
    if !(slope.is_finite() && slope > 0.0) {
        return Err(RoofError::InvalidParameter(
            "skillion slope must be positive",
        ));
    }
    let down = down.normalize_or_zero();
    if down == DVec2::ZERO || !down.is_finite() {
        return Err(RoofError::InvalidParameter("skillion direction is zero"));
    }
    check_simple(poly)?;
    let smax = poly
        .outer
        .iter()
        .map(|p| p.dot(down))
        .fold(f64::NEG_INFINITY, f64::max);
    let lift = |r: &Vec<DVec2>| -> Vec<DVec3> {
        r.iter()
            .map(|p| p.extend((smax - p.dot(down)) * slope))
            .collect()
    };
    let face = Face {
        outer: lift(&poly.outer),
        holes: poly.holes.iter().map(lift).collect(),
    };
    let faces = vec![face];
    let walls = gable_walls(poly, &faces);
    Ok(RoofGeometry::from_parts(faces, walls))
}

/// Where a saltbox's ridge stands across the footprint (fraction of the width from the side of
/// the short, steep slope): the long slope covers the other 65 %.
pub const SALTBOX_RIDGE_AT: f64 = 0.35;

/// A roof of two planes meeting along one straight ridge parallel to `ridge_dir`, standing at
/// fraction `at` (0..1) of the footprint's width measured along `ridge_dir.perp()`, both eaves
/// at z = 0 on the farthest footprint points. The steeper side has the pitch `pitch_deg`.
///
/// This is the roof of `roof:shape=saltbox` (`at` = [`SALTBOX_RIDGE_AT`]: asymmetric slopes) and
/// of a gabled roof with `roof:orientation=across` (`at` = 0.5, ridge parallel to the short
/// side). It works on any simple polygon, with or without holes: each plane covers the part of
/// the footprint on its side of the ridge line (clipped exactly), and the walls rise to the roof
/// line (`gable_walls`). On an L or T the ridge crosses the wings as a carpenter's single
/// ridge would; the skeleton gables ([`profile_roof`]) are the better answer there and stay the
/// default for `gabled`.
pub fn ridge_roof(
    poly: &Polygon,
    ridge_dir: DVec2,
    at: f64,
    pitch_deg: f64,
) -> Result<RoofGeometry, RoofError> {
    if !(pitch_deg.is_finite() && pitch_deg > 0.0 && pitch_deg < 90.0) {
        return Err(RoofError::InvalidParameter("pitch must be in (0°, 90°)"));
    }
    if !(at.is_finite() && at > 0.0 && at < 1.0) {
        return Err(RoofError::InvalidParameter(
            "ridge position must be in (0, 1)",
        ));
    }
    let dir = ridge_dir.normalize_or_zero();
    if dir == DVec2::ZERO || !dir.is_finite() {
        return Err(RoofError::InvalidParameter("ridge direction is zero"));
    }
    check_simple(poly)?;
    let n = dir.perp();
    let (smin, smax) = poly
        .outer
        .iter()
        .map(|p| p.dot(n))
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), s| {
            (a.min(s), b.max(s))
        });
    let width = smax - smin;
    let ridge = smin + at * width;
    let (da, db) = (ridge - smin, smax - ridge);
    if !(da > 1e-6 * width.max(1.0) && db > 1e-6 * width.max(1.0)) {
        return Err(RoofError::InvalidParameter(
            "footprint too thin for a ridge",
        ));
    }
    let h = pitch_deg.to_radians().tan() * da.min(db);
    let margin = width + 1.0;
    let mut faces = Vec::new();
    for (lo, hi, z) in [
        (
            smin - margin,
            ridge,
            Box::new(move |s: f64| h * (s - smin) / da) as Box<dyn Fn(f64) -> f64>,
        ),
        (
            ridge,
            smax + margin,
            Box::new(move |s: f64| h * (smax - s) / db),
        ),
    ] {
        for piece in crate::geometry::clip::clip_slab(poly, DVec2::ZERO, n, lo, hi) {
            let lift = |r: &Vec<DVec2>| -> Vec<DVec3> {
                r.iter()
                    .map(|p| p.extend(z(p.dot(n)).clamp(0.0, h)))
                    .collect()
            };
            faces.push(Face {
                outer: lift(&piece.outer),
                holes: piece.holes.iter().map(lift).collect(),
            });
        }
    }
    let walls = gable_walls(poly, &faces);
    Ok(RoofGeometry::from_parts(faces, walls))
}

/// Validates a footprint the way the skeleton does (so that every shape rejects the same
/// invalid input).
fn check_simple(poly: &Polygon) -> Result<(), RoofError> {
    straight_skeleton(poly)?;
    Ok(())
}

/// The direction (unit, in plan) across the footprint's minimum-area bounding rectangle's
/// shorter side: a shed roof slopes along it.
pub fn short_axis(poly: &Polygon) -> DVec2 {
    let hull = convex_hull(&poly.outer);
    let mut best = (f64::INFINITY, DVec2::Y);
    for i in 0..hull.len() {
        let d = (hull[(i + 1) % hull.len()] - hull[i]).normalize_or_zero();
        if d == DVec2::ZERO {
            continue;
        }
        let n = d.perp();
        let (mut a0, mut a1, mut b0, mut b1) = (
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::INFINITY,
            f64::NEG_INFINITY,
        );
        for p in &hull {
            a0 = a0.min(p.dot(d));
            a1 = a1.max(p.dot(d));
            b0 = b0.min(p.dot(n));
            b1 = b1.max(p.dot(n));
        }
        let area = (a1 - a0) * (b1 - b0);
        if area < best.0 - 1e-9 * area.abs() {
            best = (area, if a1 - a0 < b1 - b0 { d } else { n });
        }
    }
    best.1
}
