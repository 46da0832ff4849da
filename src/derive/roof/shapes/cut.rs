//! Roofs whose height is a continuous piecewise-linear function of the position in plan, linear
//! between straight cut lines: butterfly, sawtooth and crosspitched.
//!
//! The footprint is cut by every line in turn (each piece by each line, so a point where two
//! lines cross is a vertex of every piece around it), and each piece is lifted by the height
//! function: it is linear on the piece, so the piece is a plane, and two pieces meeting along a
//! cut get the same heights there (the function is continuous). The pieces tile the footprint
//! (holes included: `geometry::clip::clip_slab`), and the walls rise to the roof line
//! (`gable_walls`), so these roofs work on any valid footprint, as `ridge_roof` does.

use glam::{DVec2, DVec3};

use super::gable_walls;
use super::ridge::{check_simple, footprint_tolerance, insert_straight_vertices};
use crate::derive::roof::{RoofError, RoofGeometry};
use crate::geometry::clip::clip_slab;
use crate::geometry::Polygon;
use crate::model::Face;

/// Slope of a sawtooth roof's glazed face, degrees: steep but not vertical, since a roof face
/// must face up (a vertical face inside the footprint is no wall and no roof surface).
pub const SAWTOOTH_GLAZING_DEG: f64 = 80.0;
/// Depth (metres, across the teeth) a sawtooth tooth aims at: the footprint's depth is split
/// into the nearest whole number of teeth, at least one.
pub const SAWTOOTH_DEPTH_M: f64 = 8.0;

/// A cut line: a point on it and its unit normal.
type Cut = (DVec2, DVec2);

/// Lowest and highest `p·n` over the outer ring.
fn extent(poly: &Polygon, n: DVec2) -> (f64, f64) {
    poly.outer
        .iter()
        .map(|p| p.dot(n))
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), s| {
            (a.min(s), b.max(s))
        })
}

/// The roof of `height` over `poly`, cut by `cuts` (see the module documentation); heights
/// below 0 are raised to 0.
fn cut_roof(
    poly: &Polygon,
    cuts: &[Cut],
    height: impl Fn(DVec2) -> f64,
) -> Result<RoofGeometry, RoofError> {
    check_simple(poly)?;
    let (lo, hi) = poly.bounds();
    let big = 4.0 * (hi - lo).length() + 1.0;
    let mut pieces = vec![poly.clone()];
    for &(o, n) in cuts {
        let c = o.dot(n);
        let mut next = Vec::with_capacity(pieces.len() + 2);
        for p in &pieces {
            next.extend(clip_slab(p, DVec2::ZERO, n, c - big, c));
            next.extend(clip_slab(p, DVec2::ZERO, n, c, c + big));
        }
        pieces = next;
    }
    let lift = |r: &Vec<DVec2>| -> Vec<DVec3> {
        r.iter().map(|p| p.extend(height(*p).max(0.0))).collect()
    };
    let mut faces: Vec<Face> = pieces
        .iter()
        .map(|piece| Face {
            outer: lift(&piece.outer),
            holes: piece.holes.iter().map(lift).collect(),
        })
        .collect();
    if faces.is_empty() {
        return Err(RoofError::InvalidParameter("footprint has no area"));
    }
    // The boolean clip drops a footprint vertex where the outline runs straight through it.
    insert_straight_vertices(&mut faces, poly, footprint_tolerance(poly));
    let walls = gable_walls(poly, &faces);
    Ok(RoofGeometry::from_parts(faces, walls))
}

fn unit(d: DVec2, what: &'static str) -> Result<DVec2, RoofError> {
    let d = d.normalize_or_zero();
    if d == DVec2::ZERO || !d.is_finite() {
        return Err(RoofError::InvalidParameter(what));
    }
    Ok(d)
}

/// A butterfly roof: two planes at `slope` (rise per metre) falling inwards to a valley
/// parallel to `valley_dir` through the middle of the footprint's width, the valley on the
/// eave (z = 0) and the outer eaves highest.
pub fn butterfly(poly: &Polygon, valley_dir: DVec2, slope: f64) -> Result<RoofGeometry, RoofError> {
    let n = unit(valley_dir, "butterfly valley direction is zero")?.perp();
    let (s0, s1) = extent(poly, n);
    let c = 0.5 * (s0 + s1);
    cut_roof(poly, &[(n * c, n)], |p| slope * (p.dot(n) - c).abs())
}

/// A sawtooth roof: skillions falling towards `down` (unit, in plan) at `slope`, each rising
/// to a glazed face at [`SAWTOOTH_GLAZING_DEG`] that drops to the foot of the next; the last
/// tooth ends at the wall. The footprint's depth along `down` holds the whole number of teeth
/// nearest to [`SAWTOOTH_DEPTH_M`] each (at least one: a single tooth is a skillion).
pub fn sawtooth(poly: &Polygon, down: DVec2, slope: f64) -> Result<RoofGeometry, RoofError> {
    // Uphill: the slopes rise along `u`, the glazed faces look along `u` too (away from down).
    let u = -unit(down, "sawtooth direction is zero")?;
    if !(slope.is_finite() && slope > 0.0) {
        return Err(RoofError::InvalidParameter(
            "sawtooth slope must be positive",
        ));
    }
    let (s0, s1) = extent(poly, u);
    let depth = s1 - s0;
    let teeth = (depth / SAWTOOTH_DEPTH_M).round().clamp(1.0, 1e4);
    let steep = SAWTOOTH_GLAZING_DEG.to_radians().tan();
    // Each tooth rises over `run`, each glazed face but the last drops over `glass`:
    // depth = teeth · run + (teeth − 1) · glass, glass = slope · run / steep.
    let run = depth / (teeth + (teeth - 1.0) * slope / steep);
    let glass = slope * run / steep;
    let pitch = run + glass;
    let top = slope * run;
    let n = teeth as usize;
    let mut cuts = Vec::with_capacity(2 * n);
    for i in 0..n.saturating_sub(1) {
        let b = s0 + i as f64 * pitch;
        cuts.push((u * (b + run), u));
        cuts.push((u * (b + pitch), u));
    }
    let last = n.saturating_sub(1);
    cut_roof(poly, &cuts, |p| {
        let s = p.dot(u) - s0;
        let i = ((s / pitch).floor().max(0.0) as usize).min(last);
        let x = s - i as f64 * pitch;
        if x <= run || i == last {
            slope * x
        } else {
            top - steep * (x - run)
        }
    })
}

/// A crosspitched roof: two gabled roofs of one height crossing at the middle of the footprint,
/// one with its ridge along `ridge_dir`, the other across it; each gable falls to the
/// footprint's farthest points on its sides, and the roof is the higher of the two (valleys
/// where they meet). The height is `slope` times half the narrower of the two widths.
pub fn crosspitched(
    poly: &Polygon,
    ridge_dir: DVec2,
    slope: f64,
) -> Result<RoofGeometry, RoofError> {
    let a = unit(ridge_dir, "crosspitched ridge direction is zero")?;
    let na = a.perp();
    let (a0, a1) = extent(poly, na);
    let (b0, b1) = extent(poly, a);
    let (ca, cb) = (0.5 * (a0 + a1), 0.5 * (b0 + b1));
    let (wa, wb) = (0.5 * (a1 - a0), 0.5 * (b1 - b0));
    let tiny = 1e-9 * (wa + wb).max(1.0);
    if !(wa > tiny && wb > tiny) {
        return Err(RoofError::InvalidParameter(
            "footprint too thin for a crosspitched roof",
        ));
    }
    let h = slope * wa.min(wb);
    let centre = na * ca + a * cb;
    let diag = |m: DVec2| -> Result<Cut, RoofError> { Ok((centre, unit(m, "degenerate")?)) };
    let cuts = [
        (centre, na),
        (centre, a),
        diag(na / wa - a / wb)?,
        diag(na / wa + a / wb)?,
    ];
    cut_roof(poly, &cuts, |p| {
        let ga = h * (1.0 - (p.dot(na) - ca).abs() / wa);
        let gb = h * (1.0 - (p.dot(a) - cb).abs() / wb);
        ga.max(gb)
    })
}
