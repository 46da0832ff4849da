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

use super::clearance::{clear_cut, clear_shift, corners, cut_clearance, size_of};
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
    // The valley at the middle, kept clear of the footprint's corners (see `clear_shift`).
    let c = clear_cut(
        &corners(poly),
        n,
        0.5 * (s0 + s1),
        size_of(poly),
        0.05 * (s1 - s0),
    );
    // Each side at `slope` over the wider half: the outer eaves at one height.
    let h = slope * (c - s0).max(s1 - c);
    let z = move |s: f64| {
        if s < c {
            h * (c - s) / (c - s0)
        } else {
            h * (s - c) / (s1 - c)
        }
    };
    cut_roof(poly, &[(n * c, n)], |p| z(p.dot(n)))
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
    // The profile across the teeth: (s, z) at every foot and top. Each glazed face moves (by up
    // to a third of a tooth's run: the slopes change a little) until both its cuts are clear
    // of the footprint's corners; one that cannot stays where it is.
    let (cs, size) = (corners(poly), size_of(poly));
    let mut pts = vec![(s0, 0.0)];
    for i in 0..n.saturating_sub(1) {
        let b = s0 + i as f64 * pitch;
        let (t, f) = (b + run, b + pitch);
        let d = clear_shift(
            &cs,
            u,
            &[t, f],
            (cut_clearance(size, slope), false),
            run / 3.0,
        )
        .unwrap_or(0.0);
        pts.push((t + d, top));
        pts.push((f + d, 0.0));
    }
    pts.push((s1, top));
    if pts.windows(2).any(|w| w[1].0 <= w[0].0) {
        return Err(RoofError::InvalidParameter("sawtooth teeth too small"));
    }
    let cuts: Vec<Cut> = pts[1..pts.len() - 1]
        .iter()
        .map(|&(c, _)| (u * c, u))
        .collect();
    cut_roof(poly, &cuts, |p| {
        let s = p.dot(u);
        let i = pts.partition_point(|q| q.0 <= s).clamp(1, pts.len() - 1);
        let (a, b) = (pts[i - 1], pts[i]);
        a.1 + (s - a.0) * (b.1 - a.1) / (b.0 - a.0)
    })
}

/// A crosspitched roof: two gabled roofs of one height crossing at the middle of the footprint,
/// one with its ridge along `ridge_dir`, the other across it; each gable falls to the
/// footprint's farthest points on its sides, and the roof is the higher of the two (valleys
/// where they meet). The height is `slope` times half the narrower of the two widths. The
/// crossing moves off the middle by millimetres where a ridge or a valley would pass a hair
/// beside a corner; a footprint where no crossing nearby is clear of every corner is drawn
/// gabled.
pub fn crosspitched(
    poly: &Polygon,
    ridge_dir: DVec2,
    slope: f64,
) -> Result<RoofGeometry, RoofError> {
    let a = unit(ridge_dir, "crosspitched ridge direction is zero")?;
    let na = a.perp();
    let (a0, a1) = extent(poly, na);
    let (b0, b1) = extent(poly, a);
    let (wa, wb) = (0.5 * (a1 - a0), 0.5 * (b1 - b0));
    let tiny = 1e-9 * (wa + wb).max(1.0);
    if !(wa > tiny && wb > tiny) {
        return Err(RoofError::InvalidParameter(
            "footprint too thin for a crosspitched roof",
        ));
    }
    let h = slope * wa.min(wb);
    // The ridges cross at the middle, moved off the corners (see `clear_cut`) together with
    // the four lines where the gables meet; each gable falls from its ridge to the farthest
    // point on either side.
    let (cs, size) = (corners(poly), size_of(poly));
    let eps = cut_clearance(size, h / (2.0 * wa.max(wb)));
    let lines = |ca: f64, cb: f64| -> Option<Vec<Cut>> {
        let centre = na * ca + a * cb;
        let (ap, am, bp, bm) = (a1 - ca, ca - a0, b1 - cb, cb - b0);
        let mut cuts = vec![(centre, na), (centre, a)];
        // In each quarter the gables meet where |sa − ca| / da = |sb − cb| / db.
        for m in [
            na / ap - a / bp,
            na / am + a / bp,
            na / am - a / bm,
            na / ap + a / bm,
        ] {
            cuts.push((centre, unit(m, "degenerate").ok()?));
        }
        Some(cuts)
    };
    // A line exactly through a corner (a rectangle's diagonal) cuts cleanly; one a hair
    // beside it does not.
    let exact = 1e-9 * size.max(1.0);
    let rings: Vec<&Vec<DVec2>> = poly.rings().collect();
    let clear = |cuts: &[Cut]| {
        let corners_clear = cuts.iter().all(|&(o, m)| {
            cs.iter().all(|p| {
                let d = (*p - o).dot(m).abs();
                d > eps || d < exact
            })
        });
        // Nor may two lines cross an edge of the outline a hair apart (near a hole's corner).
        let spaced = rings.iter().all(|r| {
            (0..r.len()).all(|i| {
                let (p, q) = (r[i], r[(i + 1) % r.len()]);
                let len = p.distance(q);
                let mut at: Vec<f64> = cuts
                    .iter()
                    .filter_map(|&(o, m)| {
                        let (fp, fq) = ((p - o).dot(m), (q - o).dot(m));
                        (fp * fq < 0.0).then(|| fp / (fp - fq) * len)
                    })
                    .collect();
                at.sort_by(f64::total_cmp);
                at.windows(2)
                    .all(|w| w[1] - w[0] > eps || w[1] - w[0] < exact)
            })
        });
        corners_clear && spaced
    };
    let (ca0, cb0) = (0.5 * (a0 + a1), 0.5 * (b0 + b1));
    let steps = |j: i32| f64::from((j + 1) / 2) * eps * if j % 2 == 0 { 1.0 } else { -1.0 };
    let fall = |s: f64, c: f64, lo: f64, hi: f64| {
        if s < c {
            (c - s) / (c - lo)
        } else {
            (s - c) / (hi - c)
        }
    };
    let roof = |ca: f64, cb: f64, cuts: &[Cut]| {
        cut_roof(poly, cuts, |p| {
            let ga = h * (1.0 - fall(p.dot(na), ca, a0, a1));
            let gb = h * (1.0 - fall(p.dot(a), cb, b0, b1));
            ga.max(gb)
        })
    };
    // The first centre whose lines are clear and whose roof has no two vertices a hair apart
    // (where lines meet near the outline).
    let found = (0..12)
        .flat_map(|j| (0..12).map(move |k| (j, k)))
        .map(|(j, k)| (ca0 + steps(j), cb0 + steps(k)))
        .filter_map(|(ca, cb)| lines(ca, cb).filter(|c| clear(c)).map(|c| (ca, cb, c)))
        .take(8)
        .find_map(|(ca, cb, cuts)| {
            roof(ca, cb, &cuts)
                .ok()
                .filter(|r| !crowded(&r.faces, &cs, eps))
        });
    match found {
        Some(r) => Ok(r),
        // Every centre near the middle has a line through a corner: drawn gabled.
        None => super::profile_roof(poly, super::Ends::Gabled, |_| super::Profile::linear(slope)),
    }
}

/// Whether two distinct vertices of `faces`, not both footprint `corners`, stand closer than
/// `eps` in plan: a sliver where cut lines meet near the outline.
fn crowded(faces: &[Face], corners: &[DVec2], eps: f64) -> bool {
    let mut pts: Vec<DVec2> = faces
        .iter()
        .flat_map(|f| f.outer.iter().chain(f.holes.iter().flatten()))
        .map(|p| p.truncate())
        .collect();
    pts.sort_by(|p, q| p.x.total_cmp(&q.x).then(p.y.total_cmp(&q.y)));
    pts.dedup();
    let corner = |p: DVec2| corners.contains(&p);
    (0..pts.len()).any(|i| {
        pts[i + 1..]
            .iter()
            .take_while(|q| q.x - pts[i].x < eps)
            .any(|q| q.distance(pts[i]) < eps && !(corner(pts[i]) && corner(*q)))
    })
}
