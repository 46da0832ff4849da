//! The frames of a 3D Tiles content: the run's model frame (local metres around
//! [`OutputContext::origin`] in the projected output CRS), ECEF (EPSG:4978) and a tile's
//! east-north-up frame.
//!
//! A model point goes to ECEF exactly through the CRS (inverse projection to WGS84 lon/lat, the
//! model z plus the origin's as the ellipsoidal height, then the ellipsoid). That costs a few
//! hundred nanoseconds a point, so each building is mapped by its second-order Taylor expansion
//! instead ([`BuildingMap`]): exact at an anchor in the building's middle, with the Jacobian and
//! the Hessian there (central differences over [`STEP`]). A first-order (affine) map would
//! leave out the earth's curvature, 0.4 mm at 50 m from the anchor and 2 mm at 150 m; what
//! the second order leaves out is third order, well under a micrometre at 150 m (`tests.rs`
//! measures both).
//!
//! Heights: without a stated vertical datum the model z plus the origin's is taken as the
//! ellipsoidal height (the buildings stand on z = 0). When the run states one
//! ([`OutputContext::vertical_datum`], heights orthometric: above the geoid, as a DEM gives
//! them), each building is lifted by the EGM96 undulation N at its anchor
//! ([`crate::crs::geoid::undulation`]): h = H + N. One N per building keeps its walls plumb and
//! its roofs as drawn; the geoid's steepest slope on the 15' grid is under 0.5 mm a metre
//! (the Himalaya; `crs::geoid`'s tests), so a vertex 150 m from its anchor is within 7.5 cm of
//! its own H + N, and within 1 cm in most places.

use std::f64::consts::{FRAC_PI_2, PI};

use glam::{DMat3, DVec3};

use crate::crs::{ecef_to_wgs84, wgs84_to_ecef, Crs};
use crate::export::OutputContext;

/// The step of the central differences of [`BuildingMap`] (metres): long enough that rounding
/// (1e-9 m at ECEF magnitudes, divided by the squared step in the Hessian) is negligible, short
/// enough that the truncation (~step² / R² relative) is too.
const STEP: f64 = 10.0;

/// The model frame of a run, placed on the earth.
#[derive(Clone, Copy, Debug)]
pub(crate) struct ModelFrame {
    crs: Crs,
    origin: DVec3,
    /// Heights are orthometric: add the geoid undulation to get ellipsoidal ones.
    orthometric: bool,
}

impl ModelFrame {
    pub(crate) fn new(ctx: &OutputContext) -> ModelFrame {
        ModelFrame {
            crs: ctx.crs,
            origin: ctx.origin,
            orthometric: ctx.vertical_datum.is_some(),
        }
    }

    /// The model point `p` as WGS84 (lon, lat) degrees and its height in the model's datum
    /// (the model z plus the origin's): ellipsoidal without a stated datum, else orthometric.
    pub(crate) fn to_wgs84(self, p: DVec3) -> (f64, f64, f64) {
        let q = self.origin + p;
        let (lon, lat) = self.crs.to_lonlat(q.x, q.y);
        (lon, lat, q.z)
    }

    /// What lifts a height at model point `p` to an ellipsoidal one: the geoid undulation
    /// there when heights are orthometric, `None` when they already are ellipsoidal.
    pub(crate) fn lift_at(self, p: DVec3) -> Option<f64> {
        if !self.orthometric {
            return None;
        }
        let (lon, lat, _) = self.to_wgs84(p);
        Some(crate::crs::geoid::undulation(lon, lat))
    }

    /// The model point `p` in ECEF, exactly, its height raised by `lift` (see
    /// [`ModelFrame::lift_at`]).
    pub(crate) fn to_ecef_lifted(self, p: DVec3, lift: Option<f64>) -> DVec3 {
        let (lon, lat, h) = self.to_wgs84(p);
        let h = match lift {
            Some(n) => h + n,
            None => h,
        };
        DVec3::from(wgs84_to_ecef(lon, lat, h))
    }

    /// The model point `p` in ECEF, exactly, with the undulation at `p` itself.
    #[cfg(test)]
    pub(crate) fn to_ecef(self, p: DVec3) -> DVec3 {
        self.to_ecef_lifted(p, self.lift_at(p))
    }
}

/// The second-order map of one building from the model frame to ECEF (see the module
/// documentation).
#[derive(Clone, Copy, Debug)]
pub(crate) struct BuildingMap {
    /// The anchor in the model frame.
    pub(crate) anchor: DVec3,
    /// The anchor in ECEF (exact).
    pub(crate) anchor_ecef: DVec3,
    /// The lift of the building's heights to ellipsoidal ones ([`ModelFrame::lift_at`] its
    /// anchor), the same for all its points.
    pub(crate) lift: Option<f64>,
    /// d(ECEF) / d(model) at the anchor.
    pub(crate) jacobian: DMat3,
    /// The second derivatives at the anchor: xx, yy, zz, xy, xz, yz.
    hessian: [DVec3; 6],
    /// The inverse transpose of `jacobian`, which carries normals.
    normal_map: DMat3,
}

impl BuildingMap {
    /// The map of a building whose model-frame points lie around `anchor`.
    pub(crate) fn at(frame: &ModelFrame, anchor: DVec3) -> BuildingMap {
        let lift = frame.lift_at(anchor);
        // The 19 points lie over 9 plan positions: each is projected once (the inverse
        // projection is most of the cost), keyed by its exact coordinates, so every point gets
        // the bits `ModelFrame::to_ecef_lifted` gives it.
        let mut plan: Vec<([u64; 2], (f64, f64))> = Vec::with_capacity(9);
        let mut f = |d: DVec3| {
            let q = frame.origin + (anchor + d * STEP);
            let key = [q.x.to_bits(), q.y.to_bits()];
            let (lon, lat) = match plan.iter().find(|(k, _)| *k == key) {
                Some((_, ll)) => *ll,
                None => {
                    let ll = frame.crs.to_lonlat(q.x, q.y);
                    plan.push((key, ll));
                    ll
                }
            };
            let h = match lift {
                Some(n) => q.z + n,
                None => q.z,
            };
            DVec3::from(wgs84_to_ecef(lon, lat, h))
        };
        let centre = f(DVec3::ZERO);
        let axes = [DVec3::X, DVec3::Y, DVec3::Z];
        let plus = axes.map(&mut f);
        let minus = axes.map(|a| f(-a));
        let d1 = |i: usize| (plus[i] - minus[i]) / (2.0 * STEP);
        let d2 = |i: usize| (plus[i] - 2.0 * centre + minus[i]) / (STEP * STEP);
        let mut mixed = |i: usize, j: usize| {
            let (a, b) = (axes[i], axes[j]);
            (f(a + b) - f(a - b) - f(b - a) + f(-a - b)) / (4.0 * STEP * STEP)
        };
        let hessian_mixed = [mixed(0, 1), mixed(0, 2), mixed(1, 2)];
        let jacobian = DMat3::from_cols(d1(0), d1(1), d1(2));
        BuildingMap {
            anchor,
            anchor_ecef: centre,
            lift,
            jacobian,
            hessian: [
                d2(0),
                d2(1),
                d2(2),
                hessian_mixed[0],
                hessian_mixed[1],
                hessian_mixed[2],
            ],
            normal_map: jacobian.inverse().transpose(),
        }
    }

    /// The ECEF offset of model point `p` from the anchor's ECEF position.
    pub(crate) fn offset(&self, p: DVec3) -> DVec3 {
        let d = p - self.anchor;
        let [xx, yy, zz, xy, xz, yz] = self.hessian;
        self.jacobian * d
            + 0.5 * (xx * d.x * d.x + yy * d.y * d.y + zz * d.z * d.z)
            + xy * d.x * d.y
            + xz * d.x * d.z
            + yz * d.y * d.z
    }

    /// The unit ECEF direction of the model-frame normal `n` (a zero vector stays zero). The
    /// normal's turn with the earth's curvature over a building (1e-5 rad at 100 m) is left out.
    pub(crate) fn normal(&self, n: DVec3) -> DVec3 {
        (self.normal_map * n).normalize_or_zero()
    }

    /// The first-order part of [`BuildingMap::offset`] (for the tests' comparison).
    #[cfg(test)]
    pub(crate) fn affine_offset(&self, p: DVec3) -> DVec3 {
        self.jacobian * (p - self.anchor)
    }
}

/// An east-north-up frame at a point on the earth: the frame of a tile's content.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct EnuFrame {
    /// The frame's origin in ECEF.
    pub(crate) origin: DVec3,
    /// ECEF unit vectors of the frame's axes.
    pub(crate) east: DVec3,
    pub(crate) north: DVec3,
    pub(crate) up: DVec3,
}

impl EnuFrame {
    /// The frame at WGS84 (`lon`, `lat`) degrees and ellipsoidal height `h`: east along the
    /// parallel, up along the ellipsoid's normal, north completing a right-handed frame.
    pub(crate) fn at(lon: f64, lat: f64, h: f64) -> EnuFrame {
        let (sl, cl) = lon.to_radians().sin_cos();
        let (sp, cp) = lat.to_radians().sin_cos();
        EnuFrame {
            origin: DVec3::from(wgs84_to_ecef(lon, lat, h)),
            east: DVec3::new(-sl, cl, 0.0),
            north: DVec3::new(-sp * cl, -sp * sl, cp),
            up: DVec3::new(cp * cl, cp * sl, sp),
        }
    }

    /// The ECEF vector `v` in this frame's axes (east, north, up).
    pub(crate) fn rotate_in(&self, v: DVec3) -> DVec3 {
        DVec3::new(v.dot(self.east), v.dot(self.north), v.dot(self.up))
    }

    /// The ECEF point `p` in this frame (east, north, up metres from the origin).
    pub(crate) fn to_enu(self, p: DVec3) -> DVec3 {
        self.rotate_in(p - self.origin)
    }

    /// The frame's point `enu` in ECEF.
    pub(crate) fn to_ecef(self, enu: DVec3) -> DVec3 {
        self.origin + self.east * enu.x + self.north * enu.y + self.up * enu.z
    }

    /// The 4×4 matrix from this frame to ECEF, column-major (a 3D Tiles `transform`).
    pub(crate) fn transform(&self) -> [f64; 16] {
        let (e, n, u, o) = (self.east, self.north, self.up, self.origin);
        [
            e.x, e.y, e.z, 0.0, n.x, n.y, n.z, 0.0, u.x, u.y, u.z, 0.0, o.x, o.y, o.z, 1.0,
        ]
    }
}

/// Margin added on every side of a region (metres), for what sampling its box leaves out
/// (under a millimetre) and for the f32 rounding of the content's positions.
pub(crate) const REGION_MARGIN: f64 = 0.05;

/// Mean earth radius for turning [`REGION_MARGIN`] into radians (only a margin: any close
/// radius does).
const EARTH_RADIUS: f64 = 6_371_000.0;

/// The 3D Tiles region (west, south, east, north radians, min and max ellipsoidal height)
/// holding the box `lo..hi` of `frame` (east, north, up metres), with [`REGION_MARGIN`].
///
/// Longitude and latitude are extreme at the box's corners (to well under a millimetre for a
/// box of a few kilometres); heights over a plane of the box grow with the squared distance
/// from the frame's vertical, so the lowest is the bottom face's point nearest that vertical and
/// the highest a top corner. A 5 × 5 grid over both faces, plus that nearest point, is sampled.
pub(crate) fn region_of_box(frame: &EnuFrame, lo: DVec3, hi: DVec3) -> [f64; 6] {
    let mut r = [
        f64::INFINITY,
        f64::INFINITY,
        f64::NEG_INFINITY,
        f64::NEG_INFINITY,
        f64::INFINITY,
        f64::NEG_INFINITY,
    ];
    let mut add = |enu: DVec3| {
        let (lon, lat, h) = ecef_to_wgs84(frame.to_ecef(enu).to_array());
        let (lon, lat) = (lon.to_radians(), lat.to_radians());
        r[0] = r[0].min(lon);
        r[1] = r[1].min(lat);
        r[2] = r[2].max(lon);
        r[3] = r[3].max(lat);
        r[4] = r[4].min(h);
        r[5] = r[5].max(h);
    };
    const STEPS: u32 = 4;
    for i in 0..=STEPS {
        for j in 0..=STEPS {
            let t = DVec3::new(f64::from(i), f64::from(j), 0.0) / f64::from(STEPS);
            let x = lo.x + (hi.x - lo.x) * t.x;
            let y = lo.y + (hi.y - lo.y) * t.y;
            add(DVec3::new(x, y, lo.z));
            add(DVec3::new(x, y, hi.z));
        }
    }
    // (Not `clamp`, which panics on an empty or NaN range.)
    add(DVec3::new(
        0.0_f64.max(lo.x).min(hi.x),
        0.0_f64.max(lo.y).min(hi.y),
        lo.z,
    ));
    let lat = r[1].abs().max(r[3].abs()).min(1.5);
    let d_lat = REGION_MARGIN / EARTH_RADIUS;
    let d_lon = d_lat / lat.cos();
    // A box across the antimeridian has corners near both -π and π: its longitudes then span
    // more than half the earth, and the region takes every longitude.
    let across = r[2] - r[0] > PI;
    in_range([
        if across { -PI } else { r[0] - d_lon },
        r[1] - d_lat,
        if across { PI } else { r[2] + d_lon },
        r[3] + d_lat,
        r[4] - REGION_MARGIN,
        r[5] + REGION_MARGIN,
    ])
}

/// `r` with its west and east held to [-π, π] and its south and north to [-π/2, π/2], as the 3D
/// Tiles schema wants (a margin near the antimeridian or a pole would pass them).
pub(crate) fn in_range(r: [f64; 6]) -> [f64; 6] {
    let lon = |x: f64| x.clamp(-PI, PI);
    let lat = |x: f64| x.clamp(-FRAC_PI_2, FRAC_PI_2);
    [lon(r[0]), lat(r[1]), lon(r[2]), lat(r[3]), r[4], r[5]]
}

/// The union of two regions (neither crossing the antimeridian).
pub(crate) fn region_union(a: &[f64; 6], b: &[f64; 6]) -> [f64; 6] {
    [
        a[0].min(b[0]),
        a[1].min(b[1]),
        a[2].max(b[2]),
        a[3].max(b[3]),
        a[4].min(b[4]),
        a[5].max(b[5]),
    ]
}
