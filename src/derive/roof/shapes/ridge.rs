//! Roofs on one plane or one ridge: skillion, and the ridge roofs (saltbox and the like) along
//! a footprint's short axis.

use glam::{DVec2, DVec3};

use super::gable_walls;
use crate::derive::roof::{RoofError, RoofGeometry};
use crate::geometry::hull::convex_hull;
use crate::geometry::skeleton::straight_skeleton;
use crate::geometry::Polygon;
use crate::model::Face;

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

/// Where a `gabled_height_moved` roof's ridge stands across the footprint, as
/// [`SALTBOX_RIDGE_AT`]: a quarter of the width, so that it reads apart from a saltbox.
pub const HEIGHT_MOVED_RIDGE_AT: f64 = 0.25;

/// A roof of two planes meeting along one straight ridge parallel to `ridge_dir`, standing at
/// fraction `at` (0..1) of the footprint's width measured along `ridge_dir.perp()` (moved by
/// up to 5 % of the width where it would pass a hair beside a corner), both eaves
/// at z = 0 on the farthest footprint points. The steeper side has the pitch `pitch_deg`.
///
/// This is the roof of `roof:shape=saltbox` (`at` = [`SALTBOX_RIDGE_AT`]: asymmetric slopes) and
/// of a gabled roof with `roof:orientation=across` (`at` = 0.5, ridge parallel to the short
/// side). It works on any simple polygon, with or without holes: each plane covers the part of
/// the footprint on its side of the ridge line (clipped exactly), and the walls rise to the roof
/// line (`gable_walls`). On an L or T the ridge crosses the wings as a carpenter's single
/// ridge would; the skeleton gables (`profile_roof`) are the better
/// answer there and stay the default for `gabled`.
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
    // The ridge kept clear of the footprint's corners (moved by up to 5 % of the width): a
    // ridge a hair beside a vertex leaves a sliver the millimetre grid cannot keep planar.
    // The shallower slope sets the clearance.
    let k = pitch_deg.to_radians().tan();
    let shallow = k * at.min(1.0 - at) / at.max(1.0 - at);
    let ridge = super::clearance::clear_cut(
        &super::clearance::corners(poly),
        n,
        smin + at * width,
        super::clearance::cut_clearance(super::clearance::size_of(poly), shallow),
        0.05 * width,
    );
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
    // The boolean clip drops a footprint vertex where the outline runs straight through it:
    // put it back, so that the walls on both sides of it meet the roof there.
    insert_straight_vertices(&mut faces, poly, footprint_tolerance(poly));
    let walls = gable_walls(poly, &faces);
    Ok(RoofGeometry::from_parts(faces, walls))
}

/// The distance within which a roof's boundary vertex stands on the footprint (as the profile
/// roofs take it: twice the skeleton's collinear tolerance at the footprint's size).
pub(super) fn footprint_tolerance(poly: &Polygon) -> f64 {
    let (lo, hi) = poly.bounds();
    2.0 * crate::geometry::skeleton::collinear_tolerance((hi - lo).max_element())
}

/// Puts every footprint vertex that lies on a boundary edge of the roof (an edge no other face
/// runs back along), strictly between its ends and within `tol` of it in plan, into that edge
/// at the edge's height there. A boolean clip drops a vertex the outline runs straight
/// through; without it the walls on either side of it would not meet the roof at their
/// corner.
pub(super) fn insert_straight_vertices(faces: &mut [Face], poly: &Polygon, tol: f64) {
    type K = (u64, u64, u64);
    let key = |p: DVec3| (p.x.to_bits(), p.y.to_bits(), p.z.to_bits());
    let mut edges: std::collections::HashSet<(K, K), crate::geometry::CellHash> =
        Default::default();
    for f in faces.iter() {
        for r in std::iter::once(&f.outer).chain(f.holes.iter()) {
            for i in 0..r.len() {
                edges.insert((key(r[i]), key(r[(i + 1) % r.len()])));
            }
        }
    }
    let corners: Vec<DVec2> = poly.rings().flatten().copied().collect();
    for f in faces.iter_mut() {
        for r in std::iter::once(&mut f.outer).chain(f.holes.iter_mut()) {
            let n = r.len();
            let mut out = Vec::with_capacity(n);
            for i in 0..n {
                let (u, v) = (r[i], r[(i + 1) % n]);
                out.push(u);
                let d = (v - u).truncate();
                let l2 = d.length_squared();
                if l2 <= 1e-12 || edges.contains(&(key(v), key(u))) {
                    continue;
                }
                let mut on: Vec<(f64, DVec2)> = corners
                    .iter()
                    .filter_map(|&c| {
                        let s = (c - u.truncate()).dot(d) / l2;
                        let off = (c - u.truncate() - d * s).length();
                        let len = l2.sqrt();
                        (s * len > tol && (1.0 - s) * len > tol && off <= tol).then_some((s, c))
                    })
                    .collect();
                on.sort_by(|a, b| a.0.total_cmp(&b.0));
                out.extend(on.into_iter().map(|(s, c)| c.extend(u.z + s * (v.z - u.z))));
            }
            *r = out;
        }
    }
}

/// Validates a footprint the way the skeleton does (so that every shape rejects the same
/// invalid input).
pub(super) fn check_simple(poly: &Polygon) -> Result<(), RoofError> {
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
