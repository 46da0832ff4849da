//! Polygon zones (our extension, suggested by the thesis at seed 003 L1019): a zone may carry
//! `<polygon points="lon lat, lon lat, ..."/>` rings in WGS84 degrees instead of, or beside, its
//! circle.
//!
//! A ring is one outer boundary without holes (a hole is expressed by a deeper zone instead).
//! It may be written closed or open, in either orientation. It must have at least three distinct
//! vertices, no self-intersection, a non-zero area, longitudes in -180..=180, latitudes in
//! -90..=90, and span at most 180° of longitude (a ring that crosses the antimeridian is written
//! as two polygons of the same zone). Containment is the even-odd rule in lon/lat, which for
//! rings of city size matches the ground to well under a metre.

use super::dom::MAX_POLYGON_POINTS;
use super::KM_PER_DEG;

/// One polygon of a zone: a simple ring in (lon, lat) degrees, not closed.
#[derive(Clone, Debug, PartialEq)]
pub struct ZonePolygon {
    /// Vertices (lon, lat) in degrees, the closing vertex not repeated.
    pub ring: Vec<[f64; 2]>,
    /// Lower-left and upper-right corners (lon, lat) of the ring.
    pub bbox: ([f64; 2], [f64; 2]),
    /// Area on the mean sphere, km² (local equirectangular projection: exact enough to order
    /// zones by size, which is all it is used for).
    pub area_km2: f64,
}

impl ZonePolygon {
    /// Parses a `points` attribute: `lon lat` pairs separated by commas, numbers with a decimal
    /// point. Returns a description of the first problem.
    pub fn parse(points: &str) -> Result<ZonePolygon, String> {
        let mut ring: Vec<[f64; 2]> = Vec::new();
        for (k, pair) in points.split(',').enumerate() {
            let nums: Vec<&str> = pair.split_whitespace().collect();
            let [lon, lat] = nums.as_slice() else {
                return Err(format!(
                    "point {} \"{}\" is not a 'lon lat' pair (pairs are separated by commas, \
                     decimals written with a point)",
                    k + 1,
                    pair.trim()
                ));
            };
            let num = |s: &str| s.parse::<f64>().ok().filter(|x| x.is_finite());
            let (Some(lon), Some(lat)) = (num(lon), num(lat)) else {
                return Err(format!(
                    "point {} \"{}\" is not two numbers",
                    k + 1,
                    pair.trim()
                ));
            };
            if !(-180.0..=180.0).contains(&lon) || !(-90.0..=90.0).contains(&lat) {
                return Err(format!(
                    "point {} ({lon} {lat}) is outside lon -180..180, lat -90..90",
                    k + 1
                ));
            }
            if k >= MAX_POLYGON_POINTS {
                return Err(format!(
                    "more than {MAX_POLYGON_POINTS} points in one polygon"
                ));
            }
            ring.push([lon, lat]);
        }
        ZonePolygon::new(ring)
    }

    /// Builds a polygon from a ring (closed or not); see the module docs for the rules.
    pub fn new(mut ring: Vec<[f64; 2]>) -> Result<ZonePolygon, String> {
        ring.dedup();
        if ring.len() > 1 && ring.first() == ring.last() {
            ring.pop();
        }
        if ring.len() < 3 {
            return Err("a polygon needs at least 3 distinct points".into());
        }
        let mut lo = [f64::INFINITY; 2];
        let mut hi = [f64::NEG_INFINITY; 2];
        for p in &ring {
            for d in 0..2 {
                lo[d] = lo[d].min(p[d]);
                hi[d] = hi[d].max(p[d]);
            }
        }
        if hi[0] - lo[0] > 180.0 {
            return Err(
                "the polygon spans more than 180 degrees of longitude; split a ring that \
                 crosses the antimeridian into two polygons"
                    .into(),
            );
        }
        if let Some((i, j)) = first_crossing(&ring) {
            return Err(format!(
                "the ring crosses itself (edges {} and {})",
                i + 1,
                j + 1
            ));
        }
        let area_km2 = area_km2(&ring);
        if area_km2.is_nan() || area_km2 <= 0.0 {
            return Err("the polygon has no area".into());
        }
        Ok(ZonePolygon {
            ring,
            bbox: (lo, hi),
            area_km2,
        })
    }

    /// Whether (lon, lat) lies inside (even-odd rule; points on an edge may fall either way).
    pub fn contains(&self, lon: f64, lat: f64) -> bool {
        let (lo, hi) = self.bbox;
        if lon < lo[0] || lon > hi[0] || lat < lo[1] || lat > hi[1] {
            return false;
        }
        let n = self.ring.len();
        let mut inside = false;
        let mut j = n - 1;
        for i in 0..n {
            let (a, b) = (self.ring[i], self.ring[j]);
            if (a[1] > lat) != (b[1] > lat) {
                let x = a[0] + (lat - a[1]) * (b[0] - a[0]) / (b[1] - a[1]);
                if lon < x {
                    inside = !inside;
                }
            }
            j = i;
        }
        inside
    }
}

/// Area in km² by the shoelace formula after a local equirectangular projection.
fn area_km2(ring: &[[f64; 2]]) -> f64 {
    let lat0 = ring.iter().map(|p| p[1]).sum::<f64>() / ring.len() as f64;
    let kx = KM_PER_DEG * lat0.to_radians().cos();
    let n = ring.len();
    let mut twice = 0.0;
    for i in 0..n {
        let (a, b) = (ring[i], ring[(i + 1) % n]);
        twice += (a[0] * kx) * (b[1] * KM_PER_DEG) - (b[0] * kx) * (a[1] * KM_PER_DEG);
    }
    (twice / 2.0).abs()
}

/// The first pair of non-adjacent edges that intersect (or adjacent ones that overlap).
fn first_crossing(ring: &[[f64; 2]]) -> Option<(usize, usize)> {
    let n = ring.len();
    let edge = |i: usize| (ring[i], ring[(i + 1) % n]);
    for i in 0..n {
        for j in i + 1..n {
            let adjacent = j == i + 1 || (i == 0 && j == n - 1);
            let (a, b) = edge(i);
            let (c, d) = edge(j);
            if adjacent {
                // Adjacent edges share one vertex; they are wrong only when they fold back.
                let shared = if j == i + 1 { b } else { a };
                let (p, q) = if j == i + 1 { (a, d) } else { (b, c) };
                let u = [p[0] - shared[0], p[1] - shared[1]];
                let v = [q[0] - shared[0], q[1] - shared[1]];
                if u[0] * v[1] - u[1] * v[0] == 0.0 && u[0] * v[0] + u[1] * v[1] > 0.0 {
                    return Some((i, j));
                }
                continue;
            }
            if segments_touch(a, b, c, d) {
                return Some((i, j));
            }
        }
    }
    None
}

fn orient(a: [f64; 2], b: [f64; 2], c: [f64; 2]) -> f64 {
    (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])
}

fn on_segment(a: [f64; 2], b: [f64; 2], p: [f64; 2]) -> bool {
    p[0] >= a[0].min(b[0])
        && p[0] <= a[0].max(b[0])
        && p[1] >= a[1].min(b[1])
        && p[1] <= a[1].max(b[1])
}

fn segments_touch(a: [f64; 2], b: [f64; 2], c: [f64; 2], d: [f64; 2]) -> bool {
    let (o1, o2) = (orient(a, b, c), orient(a, b, d));
    let (o3, o4) = (orient(c, d, a), orient(c, d, b));
    if ((o1 > 0.0 && o2 < 0.0) || (o1 < 0.0 && o2 > 0.0))
        && ((o3 > 0.0 && o4 < 0.0) || (o3 < 0.0 && o4 > 0.0))
    {
        return true;
    }
    (o1 == 0.0 && on_segment(a, b, c))
        || (o2 == 0.0 && on_segment(a, b, d))
        || (o3 == 0.0 && on_segment(c, d, a))
        || (o4 == 0.0 && on_segment(c, d, b))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_open_and_closed_rings() {
        let p = ZonePolygon::parse("1.44 43.60, 1.45 43.60, 1.45 43.61, 1.44 43.61, 1.44 43.60");
        let p = p.unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(p.ring.len(), 4);
        // 0.01° x 0.01° at 43.6°N: about 1.11 km x 0.80 km.
        assert!((p.area_km2 - 0.896).abs() < 0.01, "{}", p.area_km2);
        assert!(p.contains(1.445, 43.605));
        assert!(!p.contains(1.455, 43.605));
        assert!(!p.contains(1.445, 43.615));
    }

    #[test]
    fn bad_rings_are_refused_with_reasons() {
        let bad = [
            ("1.44 43.60, 1.45 43.60", "at least 3"),
            ("1,44 43,60, 1.45 43.60, 1.45 43.61", "pair"),
            (
                "1.44 43.60, 1.45 43.61, 1.45 43.60, 1.44 43.61",
                "crosses itself",
            ),
            ("1 1, 2 2, 3 3", "crosses itself"),
            ("-179 0, 179 0, 179 1", "antimeridian"),
            ("1 95, 2 0, 3 0", "outside"),
            ("a b, 1 2, 3 4", "two numbers"),
        ];
        for (s, want) in bad {
            match ZonePolygon::parse(s) {
                Ok(p) => panic!("{s} accepted: {p:?}"),
                Err(e) => assert!(e.contains(want), "{s}: {e}"),
            }
        }
    }

    proptest::proptest! {
        /// A convex ring (points on a circle) contains its centroid and not far points.
        #[test]
        fn convex_rings_contain_their_centre(n in 3usize..40, r in 0.001f64..1.0, cx in -170.0f64..170.0, cy in -80.0f64..80.0) {
            let ring: Vec<[f64; 2]> = (0..n)
                .map(|k| {
                    let a = k as f64 / n as f64 * std::f64::consts::TAU;
                    [cx + r * a.cos(), cy + r * a.sin()]
                })
                .collect();
            let p = ZonePolygon::new(ring);
            proptest::prop_assert!(p.is_ok());
            if let Ok(p) = p {
                proptest::prop_assert!(p.contains(cx, cy));
                proptest::prop_assert!(!p.contains(cx + 2.0 * r, cy));
                proptest::prop_assert!(p.area_km2 > 0.0);
            }
        }
    }
}
