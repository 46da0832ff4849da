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
