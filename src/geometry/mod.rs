//! Planar geometry in f64 metres: polygons with holes, orientation, areas, the straight
//! skeleton, triangulation. The ground floor: it imports nothing else of citygen.
//!
//! Conventions used everywhere in citygen: the local frame is X east, Y north, Z up, metres.
//! A [`Polygon`]'s outer ring is counter-clockwise, its holes clockwise, and no ring repeats its
//! first vertex at the end.

pub(crate) mod clip;
pub(crate) mod hull;
pub(crate) mod ring;
pub mod skeleton;
pub mod tin;
pub mod triangulate;

use glam::{DVec2, DVec3};

pub(crate) use ring::clean_ring;

/// A simple polygon with holes in the local frame (metres).
#[derive(Clone, Debug, PartialEq)]
pub struct Polygon {
    /// Outer ring, counter-clockwise, not closed (first vertex not repeated).
    pub outer: Vec<DVec2>,
    /// Inner rings (courtyards), clockwise, not closed.
    pub holes: Vec<Vec<DVec2>>,
}

/// Signed area of a ring (positive when counter-clockwise). The ring is not closed.
pub fn ring_signed_area(ring: &[DVec2]) -> f64 {
    let n = ring.len();
    if n < 3 {
        return 0.0;
    }
    let mut s = 0.0;
    for i in 0..n {
        let a = ring[i];
        let b = ring[(i + 1) % n];
        s += a.x * b.y - b.x * a.y;
    }
    0.5 * s
}

impl Polygon {
    /// Builds a polygon and normalises its orientation (outer CCW, holes CW), dropping a closing
    /// vertex that repeats the first one.
    pub fn new(outer: Vec<DVec2>, holes: Vec<Vec<DVec2>>) -> Polygon {
        let mut p = Polygon { outer, holes };
        p.normalize();
        p
    }

    /// Drops closing duplicates and enforces outer CCW / holes CW.
    pub fn normalize(&mut self) {
        fn open(r: &mut Vec<DVec2>) {
            while r.len() > 1 && r.first() == r.last() {
                r.pop();
            }
        }
        open(&mut self.outer);
        if ring_signed_area(&self.outer) < 0.0 {
            self.outer.reverse();
        }
        for h in &mut self.holes {
            open(h);
            if ring_signed_area(h) > 0.0 {
                h.reverse();
            }
        }
    }

    /// Area of the outer ring minus the holes.
    pub fn area(&self) -> f64 {
        ring_signed_area(&self.outer) + self.holes.iter().map(|h| ring_signed_area(h)).sum::<f64>()
    }

    /// All rings, the outer first.
    pub fn rings(&self) -> impl Iterator<Item = &Vec<DVec2>> {
        std::iter::once(&self.outer).chain(self.holes.iter())
    }

    /// Whether `p` lies inside the outer ring and outside every hole (even-odd rule).
    pub fn contains(&self, p: DVec2) -> bool {
        self.rings().filter(|r| ring_contains(r, p)).count() % 2 == 1
    }

    /// Axis-aligned bounds (min, max). Panics never; an empty polygon gives (inf, -inf).
    pub fn bounds(&self) -> (DVec2, DVec2) {
        let mut lo = DVec2::splat(f64::INFINITY);
        let mut hi = DVec2::splat(f64::NEG_INFINITY);
        for p in &self.outer {
            lo = lo.min(*p);
            hi = hi.max(*p);
        }
        (lo, hi)
    }

    /// Translates every vertex.
    pub(crate) fn translated(&self, d: DVec2) -> Polygon {
        Polygon {
            outer: self.outer.iter().map(|p| *p + d).collect(),
            holes: self
                .holes
                .iter()
                .map(|h| h.iter().map(|p| *p + d).collect())
                .collect(),
        }
    }
}

/// Crossing-number point-in-ring test.
pub(crate) fn ring_contains(ring: &[DVec2], p: DVec2) -> bool {
    let n = ring.len();
    let mut inside = false;
    let mut j = n.wrapping_sub(1);
    for i in 0..n {
        let (a, b) = (ring[i], ring[j]);
        if (a.y > p.y) != (b.y > p.y) && p.x < (b.x - a.x) * (p.y - a.y) / (b.y - a.y) + a.x {
            inside = !inside;
        }
        j = i;
    }
    inside
}

/// Newell normal of a 3D polygon ring (not normalised; its length is twice the area).
pub(crate) fn newell_normal(ring: &[DVec3]) -> DVec3 {
    let mut n = DVec3::ZERO;
    for i in 0..ring.len() {
        let a = ring[i];
        let b = ring[(i + 1) % ring.len()];
        n.x += (a.y - b.y) * (a.z + b.z);
        n.y += (a.z - b.z) * (a.x + b.x);
        n.z += (a.x - b.x) * (a.y + b.y);
    }
    n
}

/// The largest distance of `points` from their least-squares plane (the plane through their
/// centroid normal to the direction of least spread: the smallest eigenvector of their
/// covariance), the measure of val3dity's planarity test (error 203: CGAL's
/// `linear_least_squares_fitting_3` over a polygon's points, then every point's distance).
/// A sliver face's Newell normal can tilt far from that plane, so a face within a millimetre
/// of a plane can show centimetres against its Newell normal. 0 for fewer than four points
/// (three points always lie on a plane); NaN when a point is not finite.
pub(crate) fn least_squares_plane_deviation<'a>(
    points: impl Iterator<Item = &'a DVec3> + Clone,
) -> f64 {
    let mut n = 0usize;
    let mut sum = DVec3::ZERO;
    for p in points.clone() {
        n += 1;
        sum += *p;
    }
    if n < 4 {
        return if sum.is_finite() { 0.0 } else { f64::NAN };
    }
    let c = sum / n as f64;
    // The covariance, symmetric: a[i][j].
    let mut a = [[0.0f64; 3]; 3];
    for p in points.clone() {
        let d = (*p - c).to_array();
        for i in 0..3 {
            for j in 0..3 {
                a[i][j] += d[i] * d[j];
            }
        }
    }
    if !a.iter().flatten().all(|v| v.is_finite()) {
        return f64::NAN;
    }
    let normal = smallest_eigenvector(a);
    points
        .map(|p| (*p - c).dot(normal).abs())
        .fold(0.0, f64::max)
}

/// The unit eigenvector of the smallest eigenvalue of the symmetric 3 × 3 matrix `a`, by cyclic
/// Jacobi rotations (converges quadratically; a few sweeps reach machine precision).
fn smallest_eigenvector(mut a: [[f64; 3]; 3]) -> DVec3 {
    let mut v = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    let scale = a.iter().flatten().fold(0.0f64, |m, x| m.max(x.abs()));
    if scale == 0.0 {
        return DVec3::Z;
    }
    for _ in 0..32 {
        let off = a[0][1].abs() + a[0][2].abs() + a[1][2].abs();
        if off <= 1e-15 * scale {
            break;
        }
        for (p, q) in [(0usize, 1usize), (0, 2), (1, 2)] {
            if a[p][q].abs() <= 1e-300 {
                continue;
            }
            let theta = (a[q][q] - a[p][p]) / (2.0 * a[p][q]);
            let t = theta.signum() / (theta.abs() + (theta * theta + 1.0).sqrt());
            let t = if theta == 0.0 { 1.0 } else { t };
            let cs = 1.0 / (t * t + 1.0).sqrt();
            let sn = t * cs;
            // a <- J^T a J, with J the rotation in the (p, q) plane.
            for row in a.iter_mut() {
                let (akp, akq) = (row[p], row[q]);
                row[p] = cs * akp - sn * akq;
                row[q] = sn * akp + cs * akq;
            }
            let (rp, rq) = (a[p], a[q]);
            a[p] = std::array::from_fn(|k| cs * rp[k] - sn * rq[k]);
            a[q] = std::array::from_fn(|k| sn * rp[k] + cs * rq[k]);
            for row in v.iter_mut() {
                let (vp, vq) = (row[p], row[q]);
                row[p] = cs * vp - sn * vq;
                row[q] = sn * vp + cs * vq;
            }
        }
    }
    let k = (0..3)
        .min_by(|&i, &j| a[i][i].total_cmp(&a[j][j]))
        .unwrap_or(2);
    DVec3::new(v[0][k], v[1][k], v[2][k]).normalize_or(DVec3::Z)
}

/// Two unit axes spanning the plane whose unit normal is `normal` (`ex`, `ey`, `normal` right-handed):
/// for projecting a face into its own plane.
pub(crate) fn plane_axes(normal: DVec3) -> (DVec3, DVec3) {
    let t = if normal.x.abs() < 0.9 {
        DVec3::X
    } else {
        DVec3::Y
    };
    let ex = normal.cross(t).normalize();
    (ex, normal.cross(ex))
}

/// The length of a closed ring (closing edge included).
pub(crate) fn ring_perimeter(r: &[DVec2]) -> f64 {
    (0..r.len())
        .map(|i| r[i].distance(r[(i + 1) % r.len()]))
        .sum()
}

/// Two non-adjacent edges closer than this touch, for [`is_simple`] (metres): the distance
/// under which [`clean_ring`] merges vertices, and ten times the precision our IFC files
/// declare, so that what IfcOpenShell sees as self-touching is never called simple here.
pub(crate) const TOUCH_TOLERANCE: f64 = 1e-4;

/// Whether no two non-adjacent edges of the ring touch (within [`TOUCH_TOLERANCE`]) or cross.
pub(crate) fn is_simple(r: &[DVec2]) -> bool {
    let n = r.len();
    let orient = |a: DVec2, b: DVec2, c: DVec2| {
        let v = (b - a).perp_dot(c - a);
        let scale = (b - a).length().max(1e-12);
        if v.abs() / scale <= TOUCH_TOLERANCE {
            0.0
        } else {
            v.signum()
        }
    };
    let on = |a: DVec2, b: DVec2, p: DVec2| {
        p.x >= a.x.min(b.x) - TOUCH_TOLERANCE
            && p.x <= a.x.max(b.x) + TOUCH_TOLERANCE
            && p.y >= a.y.min(b.y) - TOUCH_TOLERANCE
            && p.y <= a.y.max(b.y) + TOUCH_TOLERANCE
    };
    for i in 0..n {
        let (a, b) = (r[i], r[(i + 1) % n]);
        for j in i + 1..n {
            if j == i + 1 || (i == 0 && j == n - 1) {
                continue;
            }
            let (c, d) = (r[j], r[(j + 1) % n]);
            let (o1, o2, o3, o4) = (
                orient(a, b, c),
                orient(a, b, d),
                orient(c, d, a),
                orient(c, d, b),
            );
            if o1 * o2 < 0.0 && o3 * o4 < 0.0 {
                return false;
            }
            if (o1 == 0.0 && on(a, b, c))
                || (o2 == 0.0 && on(a, b, d))
                || (o3 == 0.0 && on(c, d, a))
                || (o4 == 0.0 && on(c, d, b))
            {
                return false;
            }
        }
    }
    true
}

/// A fixed, fast hasher for integer keys (grid cells, coordinates' bits; FxHash's
/// multiply-rotate): no per-process random seed, which is fine because the maps using it are
/// never iterated.
#[derive(Default, Clone, Copy)]
pub(crate) struct CellHash;

impl std::hash::BuildHasher for CellHash {
    type Hasher = CellHasher;
    fn build_hasher(&self) -> CellHasher {
        CellHasher(0)
    }
}

/// See [`CellHash`].
pub(crate) struct CellHasher(u64);

impl std::hash::Hasher for CellHasher {
    fn finish(&self) -> u64 {
        self.0
    }
    fn write(&mut self, bytes: &[u8]) {
        for b in bytes {
            self.write_u64(u64::from(*b));
        }
    }
    fn write_u64(&mut self, v: u64) {
        self.0 = (self.0.rotate_left(5) ^ v).wrapping_mul(0x51_7c_c1_b7_27_22_0a_95);
    }
    fn write_i64(&mut self, v: i64) {
        self.write_u64(v as u64);
    }
    fn write_usize(&mut self, v: usize) {
        self.write_u64(v as u64);
    }
}

#[cfg(test)]
mod plane_tests {
    use super::*;

    #[test]
    fn least_squares_plane_of_a_sliver_is_its_own() {
        // A crown sliver of a barrel roof on the millimetre grid: within 0.82 mm of its
        // least-squares plane, 1 cm off the plane of its Newell normal.
        let f = [
            DVec3::new(3.0, 3.0, 6.289),
            DVec3::new(2.993, 1.628, 6.289),
            DVec3::new(2.667, 1.5, 6.333),
            DVec3::new(2.993, 1.372, 6.289),
            DVec3::new(3.0, 0.0, 6.289),
            DVec3::new(3.012, 0.0, 6.288),
            DVec3::new(3.012, 3.0, 6.288),
        ];
        let dev = least_squares_plane_deviation(f.iter());
        assert!((dev - 0.000819).abs() < 2e-6, "{dev}");
        let n = newell_normal(&f).normalize();
        let c = f.iter().copied().sum::<DVec3>() / 7.0;
        let newell_dev = f.iter().map(|p| (*p - c).dot(n).abs()).fold(0.0, f64::max);
        assert!(newell_dev > 0.01, "{newell_dev}");
    }

    #[test]
    fn least_squares_plane_deviation_measures_a_lifted_corner() {
        // A tilted 10 m square (any orientation) with one corner lifted by d off its plane:
        // the least-squares plane splits it, every corner d / 4 off (to first order in d).
        for (axis, angle) in [
            (DVec3::X, 0.3),
            (DVec3::new(1.0, 2.0, 3.0).normalize(), 1.1),
        ] {
            let rot = glam::DQuat::from_axis_angle(axis, angle);
            let n = rot * DVec3::Z;
            let sq = [
                DVec3::new(0.0, 0.0, 0.0),
                DVec3::new(10.0, 0.0, 0.0),
                DVec3::new(10.0, 10.0, 0.0),
                DVec3::new(0.0, 10.0, 0.0),
            ];
            let mut pts: Vec<DVec3> = sq
                .iter()
                .map(|p| rot * *p + DVec3::new(5e2, 4e3, 7.0))
                .collect();
            assert!(least_squares_plane_deviation(pts.iter()) < 1e-9);
            pts[2] += n * 0.02;
            let dev = least_squares_plane_deviation(pts.iter());
            assert!((dev - 0.005).abs() < 1e-7, "{dev}");
        }
        // Three points, and a point not finite.
        let tri = [DVec3::ZERO, DVec3::X, DVec3::Y];
        assert_eq!(least_squares_plane_deviation(tri.iter()), 0.0);
        let bad = [DVec3::ZERO, DVec3::X, DVec3::Y, DVec3::splat(f64::NAN)];
        assert!(least_squares_plane_deviation(bad.iter()).is_nan());
    }
}
