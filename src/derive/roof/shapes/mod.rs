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
//! * mansard: steep (`MANSARD_LOWER_DEG`) up to the break distance `t0`, then shallow
//!   (`MANSARD_UPPER_DEG`); gambrel the same with gable ends (`GAMBREL_LOWER_DEG`,
//!   `GAMBREL_UPPER_DEG`);
//! * dome: a quarter circle of radius `T` (the largest `t`, the inscribed radius) in
//!   `CURVE_BANDS` chords; round (a barrel vault): the same circle with gable ends; onion: a
//!   bulb profile (`ONION_PROFILE`) that rises almost vertically from the eave, bulges and
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
//! neighbouring edges run roughly opposite (more than `GABLE_MIN_OPPOSITE_DEG` apart: the end
//! of a wing, not a chamfered corner). The apex is moved along the ridge (the line where the
//! two neighbouring planes meet) onto the vertical plane of the edge: the point `p` of `a b`
//! equidistant from the two neighbouring edges' lines. The neighbours take over the two halves of
//! the end triangle; `p` lies on both their planes, so they stay planar and the roof stays
//! closed. The wall under the edge is then closed by the roof line `b → p → a` (see
//! `RoofLine::over`). On an L, T, U, H or a courtyard block each wing ends in its own gable
//! and the wings' ridges meet in valleys and hips, as a carpenter frames them. An end whose
//! side has a vertex a little off straight (more than the skeleton's collinear tolerance, less
//! than `GABLE_MAX_KINK_DEG`) is made of two or three faces and is still one end; a square's
//! four hips meet in one apex, and two opposite ones become gables. An end that is no hip end
//! (an irregular junction) stays hipped, which is still a closed roof.
//!
//! A half-hip cuts the gable at the fraction `HALF_HIP_FRACTION` of its height: the wall stops
//! at a horizontal line there, and a small hip rises from it to the ridge.

use std::collections::HashSet;

use glam::{DVec2, DVec3};

use super::{RoofError, RoofGeometry};
use crate::geometry::skeleton::{collinear_tolerance, straight_skeleton_merged};
use crate::geometry::{CellHash, Polygon};
use crate::model::Face;

mod clearance;
mod cut;
mod gables;
mod ridge;
mod rings;
mod roofline;

pub use cut::{butterfly, crosspitched, sawtooth};
pub use cut::{SAWTOOTH_DEPTH_M, SAWTOOTH_GLAZING_DEG};
use gables::make_gables;
pub use ridge::{ridge_roof, short_axis, skillion, HEIGHT_MOVED_RIDGE_AT, SALTBOX_RIDGE_AT};
use rings::split_ring;
pub(crate) use roofline::RoofLine;

/// Pitch of the mansard's lower (steep) slope, degrees.
pub(crate) const MANSARD_LOWER_DEG: f64 = 70.0;
/// Pitch of the mansard's upper (shallow) slope, degrees.
pub(crate) const MANSARD_UPPER_DEG: f64 = 25.0;
/// Horizontal depth of the mansard's lower slope, metres (about one storey at 70°), at most
/// [`MANSARD_BREAK_REL`] of the inscribed radius.
pub(crate) const MANSARD_BREAK_M: f64 = 1.0;
/// Upper bound of the mansard break as a fraction of the inscribed radius `T`.
pub(crate) const MANSARD_BREAK_REL: f64 = 0.35;
/// Gambrel (barn) lower slope, degrees.
pub(crate) const GAMBREL_LOWER_DEG: f64 = 60.0;
/// Gambrel upper slope, degrees.
pub(crate) const GAMBREL_UPPER_DEG: f64 = 30.0;
/// Gambrel break as a fraction of the inscribed radius `T` (a barn's lower slope covers
/// about 40 % of its half-width).
pub(crate) const GAMBREL_BREAK_REL: f64 = 0.4;
/// Number of chords of the dome and barrel-vault quarter circles.
pub(crate) const CURVE_BANDS: usize = 6;
/// Onion profile as (t / T, z / H) points, H = [`ONION_HEIGHT_REL`] · T.
pub(crate) const ONION_PROFILE: [(f64, f64); 8] = [
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
pub(crate) const ONION_HEIGHT_REL: f64 = 1.6;
/// Two edges next to a triangular end face must differ in direction by more than this for the
/// end to become a gable.
pub(crate) const GABLE_MIN_OPPOSITE_DEG: f64 = 135.0;
/// The top of a hip end (its vertices off the base) may spread over this fraction of the
/// base's length and still be one apex (see `make_gables`).
pub(crate) const GABLE_APEX_CLUSTER: f64 = 0.05;
/// A footprint's skeleton whose inner nodes all lie within this fraction of its largest `t`
/// (in plan) of the deepest node rises to that one apex (see `to_one_apex`).
pub(crate) const ONE_APEX_SPREAD: f64 = 0.1;
/// Fewest sides of an outline that `to_one_apex` takes for round (an octagonal tower).
pub(crate) const ONE_APEX_MIN_SIDES: usize = 8;
/// Height fraction of the gable wall under a half-hip.
pub(crate) const HALF_HIP_FRACTION: f64 = 0.6;
/// Height fraction of the hip under a hipped-and-gabled roof's small gable.
pub(crate) const HIP_AND_GABLE_FRACTION: f64 = 0.6;
/// Slope of a hipped-and-gabled roof's small gable, degrees: steep but not vertical (it stands
/// inside the footprint, where a face must face up).
pub(crate) const HIP_AND_GABLE_DEG: f64 = 80.0;
/// Flared eaves of `bellcast_gable`: the lowest fraction of the inscribed radius at this
/// fraction of the pitch.
pub(crate) const BELLCAST_BREAK_REL: f64 = 0.25;
/// See [`BELLCAST_BREAK_REL`].
pub(crate) const BELLCAST_LOWER_REL: f64 = 0.5;

/// What happens to the hip ends of a profile roof.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum Ends {
    /// Keep every hip.
    Hipped,
    /// Every hip end becomes a gable.
    Gabled,
    /// Every hip end but the first (in ring and edge order) becomes a gable.
    AllButOne,
    /// Every hip end becomes a gable up to the given fraction of its height, then a small hip.
    HalfHipped(f64),
    /// The first hip end (in ring and edge order) is half-hipped as [`Ends::HalfHipped`], every
    /// other one a gable.
    SideHalfHipped(f64),
    /// Every hip end stays a hip up to the fraction `.0` of its height, under a small steep
    /// gable face set back on top of it (a Dutch gable), rising `.1` in `t` per metre (the
    /// profile must be linear: [`HIP_AND_GABLE_DEG`] over the roof's slope).
    HipAndGable(f64, f64),
}

/// A piecewise-linear height profile `z = h(t)`: points `(t, z)` with increasing `t`, starting
/// at (0, 0); beyond the last point the last slope continues.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct Profile(pub Vec<(f64, f64)>);

impl Profile {
    /// `z = t·tan(pitch)`.
    pub(crate) fn linear(slope: f64) -> Profile {
        Profile(vec![(0.0, 0.0), (1.0, slope)])
    }

    /// Steep `lower` slope up to `t0`, then `upper`.
    pub(crate) fn broken(lower: f64, upper: f64, t0: f64) -> Profile {
        Profile(vec![
            (0.0, 0.0),
            (t0, lower * t0),
            (t0 + 1.0, lower * t0 + upper),
        ])
    }

    /// A quarter circle of radius `r` (a dome or a barrel vault), in [`CURVE_BANDS`] chords.
    pub(crate) fn circle(r: f64) -> Profile {
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
    pub(crate) fn onion(r: f64) -> Profile {
        let h = ONION_HEIGHT_REL * r;
        Profile(ONION_PROFILE.iter().map(|&(t, z)| (t * r, z * h)).collect())
    }

    /// Evaluates `h(t)`.
    pub(crate) fn eval(&self, t: f64) -> f64 {
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

/// How long a turned profile roof's footprint is drawn across its ridge, as a fraction of its
/// extent along the ridge (see [`turned_profile_roof`]).
pub(crate) const TURN_SQUEEZE: f64 = 0.5;

/// A profile roof whose ridge runs parallel to `ridge` (in plan), across the footprint's
/// wings: `roof:direction` or `roof:orientation=across` on a skeleton roof (half-hipped,
/// gambrel, mansard, ...).
///
/// The skeleton lays a roof's ridges along the longest wings. To turn them, the footprint is
/// squeezed across `ridge` until its extent across is [`TURN_SQUEEZE`] of its extent along;
/// the profile roof of the squeezed footprint has its ridge along `ridge`, and is stretched
/// back. The map is affine in plan (planes stay planes, vertical gable walls stay vertical,
/// the squeezed footprint's vertices map back exactly onto the footprint's own, so the roof's
/// projection is the footprint). Heights are divided by the squeeze so that the slopes facing
/// `ridge`'s normal (the main slopes) keep the profile's pitch; the ends facing along the
/// ridge come out steeper, as a carpenter frames a turned roof. This is the weighted straight
/// skeleton for the two axes of the footprint.
///
/// Errors: as [`profile_roof`] on the squeezed footprint.
pub(crate) fn turned_profile_roof(
    poly: &Polygon,
    ridge: DVec2,
    ends: Ends,
    profile: impl Fn(f64) -> Profile,
) -> Result<RoofGeometry, RoofError> {
    let r = ridge.normalize_or_zero();
    let n = r.perp();
    let (mut r0, mut r1, mut n0, mut n1) = (
        f64::INFINITY,
        f64::NEG_INFINITY,
        f64::INFINITY,
        f64::NEG_INFINITY,
    );
    for p in &poly.outer {
        r0 = r0.min(p.dot(r));
        r1 = r1.max(p.dot(r));
        n0 = n0.min(p.dot(n));
        n1 = n1.max(p.dot(n));
    }
    let (along, across) = (r1 - r0, n1 - n0);
    let squeeze = TURN_SQUEEZE * along / across;
    if r == DVec2::ZERO || !(squeeze.is_finite() && squeeze > 0.0) {
        return Err(RoofError::InvalidParameter(
            "no direction to turn the roof to",
        ));
    }
    let o = poly.outer[0];
    let to = |p: DVec2| p + n * ((squeeze - 1.0) * (p - o).dot(n));
    let back = |p: DVec2| p + n * ((1.0 / squeeze - 1.0) * (p - o).dot(n));
    let mut exact = std::collections::HashMap::new();
    let mut ring = |v: &Vec<DVec2>| -> Vec<DVec2> {
        v.iter()
            .map(|&p| {
                let q = to(p);
                exact.insert((q.x.to_bits(), q.y.to_bits()), p);
                q
            })
            .collect()
    };
    let squeezed = Polygon::new(
        ring(&poly.outer),
        poly.holes.iter().map(&mut ring).collect(),
    );
    let g = profile_roof(&squeezed, ends, profile)?;
    let unsqueeze = |f: Face| -> Face {
        let map = |v: Vec<DVec3>| -> Vec<DVec3> {
            v.into_iter()
                .map(|p| {
                    let q = exact
                        .get(&(p.x.to_bits(), p.y.to_bits()))
                        .copied()
                        .unwrap_or_else(|| back(p.truncate()));
                    q.extend(p.z / squeeze)
                })
                .collect()
        };
        Face {
            outer: map(f.outer),
            holes: f.holes.into_iter().map(map).collect(),
        }
    };
    Ok(RoofGeometry::from_parts(
        g.faces.into_iter().map(unsqueeze).collect(),
        g.gable_walls.into_iter().map(unsqueeze).collect(),
    ))
}

/// Builds a profile roof (see the module documentation) with the eave at z = 0.
///
/// `profile` receives `T`, the largest skeleton distance (the inscribed radius), and returns
/// the height profile. Errors: any straight-skeleton error (an invalid footprint).
pub(crate) fn profile_roof(
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

/// Whether the footprint's outline has a rounded end (an apse): a run of at least
/// [`APSE_MIN_CORNERS`] consecutive corners each turning outwards by 2° to 60°, turning by 90° or
/// more in all. A polygonal apse of three sides or more counts; the corners of a rectangle do
/// not.
pub(crate) fn has_rounded_end(poly: &Polygon) -> bool {
    let r = &poly.outer;
    let n = r.len();
    if n < APSE_MIN_CORNERS + 2 {
        return false;
    }
    let turn = |i: usize| {
        let (a, b, c) = (r[(i + n - 1) % n], r[i], r[(i + 1) % n]);
        let (u, v) = (b - a, c - b);
        u.perp_dot(v).atan2(u.dot(v)).to_degrees()
    };
    let turns: Vec<f64> = (0..n).map(turn).collect();
    let soft = |t: f64| (2.0..=60.0).contains(&t);
    // Start after a corner that is not soft, so that no run wraps around the start.
    let Some(start) = (0..n).find(|&i| !soft(turns[i])) else {
        return false;
    };
    let (mut count, mut total) = (0usize, 0.0);
    for k in 1..=n {
        let t = turns[(start + k) % n];
        if soft(t) {
            count += 1;
            total += t;
            if count >= APSE_MIN_CORNERS && total >= 90.0 {
                return true;
            }
        } else {
            count = 0;
            total = 0.0;
        }
    }
    false
}

/// Fewest corners of a rounded end (see [`has_rounded_end`]).
pub(crate) const APSE_MIN_CORNERS: usize = 3;

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
/// [`RoofLine::over`]), counter-clockwise seen from outside. A roof line that comes down to the
/// eave between its ends (a valley's foot) closes one face on each stretch above the eave.
fn gable_walls(poly: &Polygon, faces: &[Face]) -> Vec<Face> {
    let line = RoofLine::new(faces, poly);
    let mut out = Vec::new();
    for (ri, r) in poly.rings().enumerate() {
        for i in 0..r.len() {
            let (a, b) = (r[i], r[(i + 1) % r.len()]);
            let top = line.over(ri, i);
            if !top.iter().any(|p| p.z > 0.0) {
                continue;
            }
            // From b back to a: a stretch starts at an eave point (or b) and ends at the next.
            let mut start = b.extend(0.0);
            let mut run: Vec<DVec3> = Vec::new();
            for (k, p) in top.iter().enumerate() {
                let last = k + 1 == top.len();
                if p.z > 0.0 {
                    run.push(*p);
                }
                if p.z <= 0.0 && k > 0 || last {
                    let end = if last { a.extend(0.0) } else { *p };
                    if !run.is_empty() {
                        let mut ring = vec![end, start];
                        ring.append(&mut run);
                        out.push(Face::new(ring));
                    }
                    start = end;
                    run.clear();
                }
            }
        }
    }
    out
}
