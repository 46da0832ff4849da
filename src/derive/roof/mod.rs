//! Roof surfaces over a footprint: flat, pyramidal, hipped (from the straight skeleton) and
//! gabled (the hipped roof with its end triangles raised to vertical gables).
//!
//! All constructions put the eave at z = 0; `RoofGeometry::translated_z` lifts them onto the
//! walls and `RoofGeometry::scaled_to_height` fits them to a known roof height (OSM
//! `roof:height`). Faces are planar, their outer ring counter-clockwise seen from above (their
//! normal points up and out of the building), in the `Face` convention of [`crate::model`].

use glam::{DVec2, DVec3};
use thiserror::Error;

pub mod shapes;

use self::shapes::{Ends, Profile};
use crate::geometry::skeleton::{straight_skeleton, SkeletonError};
use crate::geometry::Polygon;
use crate::model::{Face, RoofShape};

/// Why a roof shape cannot be built on a footprint (the caller falls back to a flat roof).
#[derive(Clone, Debug, Error, PartialEq)]
pub enum RoofError {
    /// The straight skeleton failed: the footprint is degenerate, crosses itself or is too
    /// complex (`geometry::skeleton::SkeletonError`).
    #[error("straight skeleton failed: {0}")]
    Skeleton(#[from] SkeletonError),
    /// The pitch is not in (0°, 90°) or the height is not positive and finite.
    #[error("invalid roof parameter: {0}")]
    InvalidParameter(&'static str),
    /// A pyramid needs a footprint without holes that is star-shaped from its apex.
    #[error(
        "a pyramidal roof needs a footprint without holes that is star-shaped around its centroid"
    )]
    NotStarShaped,
}

/// Roof surfaces with the eave at z = 0 (until translated).
#[derive(Clone, Debug, PartialEq)]
pub struct RoofGeometry {
    /// Roof planes, normals pointing up/out.
    pub faces: Vec<Face>,
    /// Vertical walls closing gable ends (empty for other shapes). Their outer ring is
    /// counter-clockwise seen from outside the building; the bottom edge lies on the eave.
    pub gable_walls: Vec<Face>,
    /// Height of the highest point above the eave.
    pub height: f64,
}

impl RoofGeometry {
    /// Builds the geometry from its faces and gable walls; `height` is the highest z.
    pub(crate) fn from_parts(faces: Vec<Face>, gable_walls: Vec<Face>) -> RoofGeometry {
        RoofGeometry::new(faces, gable_walls)
    }

    fn new(faces: Vec<Face>, gable_walls: Vec<Face>) -> RoofGeometry {
        let top = faces
            .iter()
            .chain(&gable_walls)
            .flat_map(|f| f.outer.iter())
            .map(|p| p.z)
            .fold(0.0, f64::max);
        RoofGeometry {
            faces,
            gable_walls,
            height: top,
        }
    }

    /// Whether every face meets at the highest point: a pyramid, a cone, or a round outline's
    /// roof risen to one apex (see `shapes::ONE_APEX_SPREAD`).
    pub fn has_one_apex(&self) -> bool {
        let top = self
            .faces
            .iter()
            .flat_map(|f| f.outer.iter())
            .copied()
            .max_by(|a, b| a.z.total_cmp(&b.z));
        top.is_some_and(|t| self.faces.iter().all(|f| f.outer.contains(&t)))
    }

    /// How far (degrees) a face of a roof risen to one apex may be off `pitch_deg`, the slope
    /// its side was given: the apex stands up to `shapes::ONE_APEX_SPREAD` of the largest
    /// skeleton distance farther from a side than that side's own top would (2.5° at 35°).
    pub fn one_apex_pitch_tolerance(pitch_deg: f64) -> f64 {
        let k = pitch_deg.to_radians().tan();
        pitch_deg - (k / (1.0 + shapes::ONE_APEX_SPREAD)).atan().to_degrees()
    }

    /// Scales heights (about z = 0, the eave) so that the highest point is at `height`. A flat
    /// roof (height 0) is left unchanged. Planarity is preserved (a vertical scale is affine).
    pub(crate) fn scaled_to_height(mut self, height: f64) -> RoofGeometry {
        if self.height > 0.0 && height.is_finite() && height >= 0.0 {
            let k = height / self.height;
            for f in self.faces.iter_mut().chain(self.gable_walls.iter_mut()) {
                for p in f.outer.iter_mut().chain(f.holes.iter_mut().flatten()) {
                    p.z *= k;
                }
            }
            self.height = height;
        }
        self
    }

    /// Moves every vertex up by `dz` (the eave height). `height` stays relative to the eave.
    #[cfg(test)]
    pub(crate) fn translated_z(mut self, dz: f64) -> RoofGeometry {
        for f in self.faces.iter_mut().chain(self.gable_walls.iter_mut()) {
            for p in f.outer.iter_mut().chain(f.holes.iter_mut().flatten()) {
                p.z += dz;
            }
        }
        self
    }
}

/// A flat roof: one face at z = 0 with the footprint's holes.
pub fn flat(poly: &Polygon) -> RoofGeometry {
    let lift = |r: &Vec<DVec2>| r.iter().map(|p| p.extend(0.0)).collect::<Vec<_>>();
    let face = Face {
        outer: lift(&poly.outer),
        holes: poly.holes.iter().map(lift).collect(),
    };
    RoofGeometry::new(vec![face], Vec::new())
}

fn check_pitch(pitch_deg: f64) -> Result<f64, RoofError> {
    if !(pitch_deg.is_finite() && pitch_deg > 0.0 && pitch_deg < 90.0) {
        return Err(RoofError::InvalidParameter(
            "pitch must be between 0 and 90 degrees",
        ));
    }
    Ok(pitch_deg.to_radians().tan())
}

/// A hipped roof: one plane per footprint edge, all with slope `pitch_deg`, meeting along the
/// straight skeleton; z = distance to the edge × tan(pitch). Works for any simple footprint,
/// holes included (the courtyards get inward-facing hips). One face per input edge (see
/// straight skeleton for degenerate edges), in ring then edge order.
///
/// Errors: pitch not in (0°, 90°), or any straight-skeleton error (`SkeletonError`).
pub fn hipped(poly: &Polygon, pitch_deg: f64) -> Result<RoofGeometry, RoofError> {
    let k = check_pitch(pitch_deg)?;
    let sk = straight_skeleton(poly)?;
    let faces = sk
        .faces
        .into_iter()
        .map(|f| {
            Face::new(
                f.polygon
                    .into_iter()
                    .map(|p| DVec3::new(p.x, p.y, p.z * k))
                    .collect(),
            )
        })
        .collect();
    Ok(RoofGeometry::new(faces, Vec::new()))
}

/// The least distance, in plan, from a pyramid's apex to the line of any footprint edge (m).
const PYRAMID_MIN_RUN: f64 = 0.01;

/// A pyramidal roof: one triangle per edge rising to an apex `height` above the centroid of the
/// footprint.
///
/// Errors: non-positive height, holes, or a footprint that is not star-shaped from the
/// centroid with room to spare (some triangle would fold over or stand almost upright).
pub fn pyramidal(poly: &Polygon, height: f64) -> Result<RoofGeometry, RoofError> {
    if !(height.is_finite() && height > 0.0) {
        return Err(RoofError::InvalidParameter("height must be positive"));
    }
    if !poly.holes.is_empty() || poly.outer.len() < 3 {
        return Err(RoofError::NotStarShaped);
    }
    let c = centroid(&poly.outer).ok_or(RoofError::NotStarShaped)?;
    let n = poly.outer.len();
    // The apex must be left of every edge by a centimetre (clear of the millimetre grid the
    // part is snapped to, which could turn a sliver face over) and every face no steeper
    // than about 84° (a tenth of the height away): a centroid next to an edge's line would
    // give a wall-like face, and the roof is hipped instead.
    let clear = PYRAMID_MIN_RUN.max(0.1 * height);
    let mut faces = Vec::with_capacity(n);
    for i in 0..n {
        let (a, b) = (poly.outer[i], poly.outer[(i + 1) % n]);
        let run = (b - a).perp_dot(c - a) / (b - a).length();
        if run.is_nan() || run < clear {
            return Err(RoofError::NotStarShaped);
        }
        faces.push(Face::new(vec![
            a.extend(0.0),
            b.extend(0.0),
            c.extend(height),
        ]));
    }
    Ok(RoofGeometry::new(faces, Vec::new()))
}

/// Area centroid of a ring; `None` for a zero-area ring.
fn centroid(r: &[DVec2]) -> Option<DVec2> {
    let n = r.len();
    let o = r[0];
    let (mut a, mut c) = (0.0, DVec2::ZERO);
    for i in 0..n {
        let (p, q) = (r[i] - o, r[(i + 1) % n] - o);
        let w = p.perp_dot(q);
        a += w;
        c += (p + q) * w;
    }
    if a.abs() < 1e-300 || !a.is_finite() {
        return None;
    }
    Some(o + c / (3.0 * a))
}

/// A gabled roof: the hipped roof with every hip end raised to a vertical gable (after Laycock
/// and Day; see [`shapes`] for the rule that picks the ends). The roof line over
/// each gable is returned in `gable_walls`. Footprints without hip ends (a square) keep their
/// hips.
///
/// Errors: as [`hipped`].
pub fn gabled(poly: &Polygon, pitch_deg: f64) -> Result<RoofGeometry, RoofError> {
    let k = check_pitch(pitch_deg)?;
    shapes::profile_roof(poly, Ends::Gabled, |_| Profile::linear(k))
}

/// Builds any roof of the catalogue on `poly` with the eave at z = 0, with no
/// `roof:orientation` (see [`build_oriented`]).
///
/// Errors: as [`build_oriented`].
pub fn build(
    poly: &Polygon,
    shape: RoofShape,
    pitch_deg: f64,
    down: Option<DVec2>,
) -> Result<RoofGeometry, RoofError> {
    build_oriented(poly, shape, pitch_deg, down, false)
}

/// Builds any roof of the catalogue on `poly` with the eave at z = 0.
///
/// `pitch_deg` is the pitch of hipped, gabled, half-hipped, side-hipped, saltbox, skillion,
/// pyramidal, cone, butterfly, sawtooth and crosspitched roofs (the steeper slope of the
/// asymmetric ones); the mansard and gambrel use their own two pitches (see [`shapes`]),
/// bellcast its pitch and half of it at the eaves, and dome, onion and round roofs a height
/// from the inscribed radius. The caller scales the result with
/// `RoofGeometry::scaled_to_height` when the height is known.
///
/// `down` is OSM `roof:direction` (in plan, the way the main slope falls): a skillion or
/// sawtooth falls towards it (else across the short side; a sawtooth along it with `across`); a
/// saltbox's or `gabled_height_moved`'s long slope faces it; a butterfly's valley and a
/// crosspitched roof's first ridge run across it; a gabled roof takes the ridge across it
/// when it is nearer the footprint's long axis than its short one. `across` is
/// `roof:orientation=across`: the ridge (or valley, or sawtooth ridges) of gabled, saltbox,
/// `gabled_height_moved`, butterfly and sawtooth roofs parallel to the short side. The
/// skeleton roofs with a ridge (hipped and its variants, mansard, gambrel, bellcast, round)
/// follow the footprint's wings unless `across` or a `down` nearer the long axis than the
/// short one turns them (`shapes::turned_profile_roof`: the ridge parallel to the short
/// side; a roof that cannot be turned is built unturned); dome, onion, pyramidal, cone and
/// `apse_gabled` take neither.
///
/// Pyramidal and cone roofs rise to one apex over the centroid when the footprint has no
/// holes and is star-shaped from it, and are hipped otherwise. Saltbox and
/// `gabled_height_moved` are two-plane ridge roofs ([`shapes::ridge_roof`]) with the ridge at
/// 35 % and 25 % of the width. Fallbacks to a simpler shape: a hipped-and-gabled end whose
/// small gable does not fit stays hipped (a square's: no ridge); an `apse_gabled` footprint
/// without a rounded end keeps its first end hipped (as side-hipped); a crosspitched roof whose
/// crossing cannot keep clear of the corners is gabled. The cut roofs' runtime safety net (a
/// part that fails its checks is drawn simpler) is `massing::part_with_roof`.
///
/// Errors: a pitch outside (0°, 90°), or an invalid footprint (a `SkeletonError`); never a
/// fallback for a valid simple polygon.
pub fn build_oriented(
    poly: &Polygon,
    shape: RoofShape,
    pitch_deg: f64,
    down: Option<DVec2>,
    across: bool,
) -> Result<RoofGeometry, RoofError> {
    let k = check_pitch(pitch_deg)?;
    let lin = |_: f64| Profile::linear(k);
    let tan = |d: f64| d.to_radians().tan();
    let down = down
        .map(|d| d.normalize_or_zero())
        .filter(|d| *d != DVec2::ZERO && d.is_finite());
    let short = || shapes::short_axis(poly);
    // The direction of a ridge (or valley) when roof:direction does not give it.
    let ridge = || if across { short() } else { short().perp() };
    // A skeleton roof's ridge turned across the wings (parallel to the short axis) when
    // `roof:orientation=across` says so or `roof:direction` points along the long axis.
    let turned = across
        || down.is_some_and(|d| {
            let s = short();
            d.dot(s).abs() < d.dot(s.perp()).abs()
        });
    // A profile roof, turned when the tags say so; a turned roof that cannot be built on the
    // squeezed footprint is built unturned.
    let skeleton = |ends: Ends, profile: &dyn Fn(f64) -> Profile| {
        if turned {
            if let Ok(g) = shapes::turned_profile_roof(poly, short(), ends, profile) {
                return Ok(g);
            }
        }
        shapes::profile_roof(poly, ends, profile)
    };
    match shape {
        RoofShape::Flat => {
            straight_skeleton(poly)?;
            Ok(flat(poly))
        }
        RoofShape::Hipped => skeleton(Ends::Hipped, &lin),
        RoofShape::Gabled => {
            // roof:direction along the long axis puts the ridge across.
            if turned {
                shapes::ridge_roof(poly, short(), 0.5, pitch_deg)
            } else {
                shapes::profile_roof(poly, Ends::Gabled, lin)
            }
        }
        RoofShape::Saltbox | RoofShape::GabledHeightMoved => {
            let at = if shape == RoofShape::Saltbox {
                shapes::SALTBOX_RIDGE_AT
            } else {
                shapes::HEIGHT_MOVED_RIDGE_AT
            };
            // The long slope faces `down` (roof:direction) when given: the ridge stands on the
            // other side.
            let ridge_dir = down.map_or_else(ridge, |d| d.perp());
            shapes::ridge_roof(poly, -ridge_dir, at, pitch_deg)
        }
        RoofShape::SideHipped => skeleton(Ends::AllButOne, &lin),
        RoofShape::HalfHipped => skeleton(Ends::HalfHipped(shapes::HALF_HIP_FRACTION), &lin),
        RoofShape::SideHalfHipped => {
            skeleton(Ends::SideHalfHipped(shapes::HALF_HIP_FRACTION), &lin)
        }
        RoofShape::HippedAndGabled => {
            let steep = tan(shapes::HIP_AND_GABLE_DEG) / k;
            let ends = Ends::HipAndGable(shapes::HIP_AND_GABLE_FRACTION, steep);
            skeleton(ends, &lin)
        }
        RoofShape::BellcastGable => skeleton(Ends::Gabled, &|t: f64| {
            let lower = tan(pitch_deg * shapes::BELLCAST_LOWER_REL);
            Profile::broken(lower, k, shapes::BELLCAST_BREAK_REL * t)
        }),
        RoofShape::ApseGabled => {
            let ends = if shapes::has_rounded_end(poly) {
                Ends::Gabled
            } else {
                Ends::AllButOne
            };
            shapes::profile_roof(poly, ends, lin)
        }
        RoofShape::Mansard => skeleton(Ends::Hipped, &|t: f64| {
            let t0 = shapes::MANSARD_BREAK_M.min(shapes::MANSARD_BREAK_REL * t);
            Profile::broken(
                tan(shapes::MANSARD_LOWER_DEG),
                tan(shapes::MANSARD_UPPER_DEG),
                t0,
            )
        }),
        RoofShape::Gambrel => skeleton(Ends::Gabled, &|t: f64| {
            Profile::broken(
                tan(shapes::GAMBREL_LOWER_DEG),
                tan(shapes::GAMBREL_UPPER_DEG),
                shapes::GAMBREL_BREAK_REL * t,
            )
        }),
        RoofShape::Dome => shapes::profile_roof(poly, Ends::Hipped, Profile::circle),
        RoofShape::Round => skeleton(Ends::Gabled, &Profile::circle),
        RoofShape::Onion => shapes::profile_roof(poly, Ends::Hipped, Profile::onion),
        RoofShape::Pyramidal | RoofShape::Cone => {
            let sk = straight_skeleton(poly)?;
            let t = sk
                .faces
                .iter()
                .flat_map(|f| f.polygon.iter())
                .map(|p| p.z)
                .fold(0.0, f64::max);
            match pyramidal(poly, t * k) {
                Ok(g) => Ok(g),
                Err(_) => shapes::profile_roof(poly, Ends::Hipped, lin),
            }
        }
        RoofShape::Skillion => shapes::skillion(poly, down.unwrap_or_else(short), k),
        RoofShape::Sawtooth => {
            let d = down.unwrap_or_else(|| if across { short().perp() } else { short() });
            shapes::sawtooth(poly, d, k)
        }
        RoofShape::Butterfly => {
            let valley = down.map_or_else(ridge, |d| d.perp());
            shapes::butterfly(poly, valley, k)
        }
        RoofShape::Crosspitched => {
            let first = down.map_or_else(|| short().perp(), |d| d.perp());
            shapes::crosspitched(poly, first, k)
        }
    }
}

#[cfg(test)]
mod tests;
