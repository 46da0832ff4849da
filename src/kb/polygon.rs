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
///
/// Built by `ZonePolygon::new` or `ZonePolygon::parse`, which also index its edges by
/// latitude bands; the public fields are read-only in effect (changing `ring` afterwards leaves
/// the index describing the old ring).
#[derive(Clone, Debug, PartialEq)]
pub struct ZonePolygon {
    /// Vertices (lon, lat) in degrees, the closing vertex not repeated.
    pub ring: Vec<[f64; 2]>,
    /// Lower-left and upper-right corners (lon, lat) of the ring.
    pub bbox: ([f64; 2], [f64; 2]),
    /// Area on the mean sphere, km² (local equirectangular projection: exact enough to order
    /// zones by size, which is all it is used for).
    pub area_km2: f64,
    /// The edges by latitude band, so that containment and the self-intersection check look
    /// at the edges near one latitude only.
    bands: Bands,
}

/// Edge `k` runs from `ring[k]` to `ring[(k + 1) % n]`. The ring's latitude range is cut into
/// `count` equal bands; an edge is listed in every band its closed latitude range touches.
/// Band numbers come from one monotone formula ([`Bands::band`]), so a latitude `y` within an
/// edge's range always falls in one of that edge's bands: nothing the brute-force rules would
/// see is missed.
#[derive(Clone, Debug, PartialEq)]
struct Bands {
    /// Latitude of the bottom of band 0 (the ring's lowest latitude).
    lo: f64,
    /// Height of one band, degrees (positive).
    height: f64,
    /// Edges of band `b`: `edges[start[b]..start[b + 1]]`.
    start: Vec<u32>,
    edges: Vec<u32>,
}

impl Bands {
    fn new(ring: &[[f64; 2]], lo: f64, hi: f64) -> Bands {
        let n = ring.len();
        // About two edges a band for a ring whose edges each touch a few bands.
        let count = (n / 2).clamp(1, 1 << 16);
        let span = hi - lo;
        let height = if span > 0.0 && span.is_finite() {
            span / count as f64
        } else {
            1.0
        };
        let mut bands = Bands {
            lo,
            height,
            start: vec![0; count + 1],
            edges: Vec::new(),
        };
        // Counting sort of (band, edge) pairs: count, prefix sums, fill.
        for k in 0..n {
            let (b0, b1) = bands.range(ring, k);
            for b in b0..=b1 {
                bands.start[b + 1] += 1;
            }
        }
        for b in 0..count {
            bands.start[b + 1] += bands.start[b];
        }
        let mut fill = bands.start.clone();
        bands.edges = vec![0; bands.start[count] as usize];
        for k in 0..n {
            let (b0, b1) = bands.range(ring, k);
            for slot in &mut fill[b0..=b1] {
                bands.edges[*slot as usize] = k as u32;
                *slot += 1;
            }
        }
        bands
    }

    fn count(&self) -> usize {
        self.start.len() - 1
    }

    /// The band of latitude `y` (clamped into the bands).
    fn band(&self, y: f64) -> usize {
        let b = ((y - self.lo) / self.height).floor();
        if b >= 0.0 {
            (b as usize).min(self.count() - 1)
        } else {
            0
        }
    }

    /// First and last band of edge `k`.
    fn range(&self, ring: &[[f64; 2]], k: usize) -> (usize, usize) {
        let (a, b) = (ring[k][1], ring[(k + 1) % ring.len()][1]);
        (self.band(a.min(b)), self.band(a.max(b)))
    }

    fn edges_of(&self, band: usize) -> &[u32] {
        let (s, e) = (self.start[band] as usize, self.start[band + 1] as usize);
        &self.edges[s..e]
    }
}

/// Why a zone polygon is refused ([`ZonePolygon::parse`], [`ZonePolygon::new`]). Points are
/// numbered from 1.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub(crate) enum PolygonError {
    /// A point that is not two numbers separated by spaces.
    #[error(
        "point {point} \"{text}\" is not a 'lon lat' pair (pairs are separated by commas, \
         decimals written with a point)"
    )]
    NotAPair {
        /// The point's number.
        point: usize,
        /// Its text, trimmed.
        text: String,
    },
    /// A point whose two words are not finite numbers.
    #[error("point {point} \"{text}\" is not two numbers")]
    NotNumbers {
        /// The point's number.
        point: usize,
        /// Its text, trimmed.
        text: String,
    },
    /// A point outside lon -180..180, lat -90..90.
    #[error("point {point} ({lon} {lat}) is outside lon -180..180, lat -90..90")]
    OutsideRange {
        /// The point's number.
        point: usize,
        /// Its longitude.
        lon: f64,
        /// Its latitude.
        lat: f64,
    },
    /// More points than one polygon may have (`MAX_POLYGON_POINTS`).
    #[error("more than {} points in one polygon", MAX_POLYGON_POINTS)]
    TooManyPoints,
    /// Fewer than 3 distinct points.
    #[error("a polygon needs at least 3 distinct points")]
    FewPoints,
    /// Wider than 180 degrees of longitude.
    #[error(
        "the polygon spans more than 180 degrees of longitude; split a ring that crosses the \
         antimeridian into two polygons"
    )]
    TooWide,
    /// Two edges cross (numbered from 1).
    #[error("the ring crosses itself (edges {first} and {second})")]
    Crossing {
        /// The first edge's number.
        first: usize,
        /// The second edge's number.
        second: usize,
    },
    /// No area.
    #[error("the polygon has no area")]
    NoArea,
}

impl ZonePolygon {
    /// Parses a `points` attribute: `lon lat` pairs separated by commas, numbers with a decimal
    /// point. Returns a description of the first problem.
    pub(crate) fn parse(points: &str) -> Result<ZonePolygon, PolygonError> {
        let mut ring: Vec<[f64; 2]> = Vec::new();
        for (k, pair) in points.split(',').enumerate() {
            let mut nums = pair.split_whitespace();
            let (Some(lon), Some(lat), None) = (nums.next(), nums.next(), nums.next()) else {
                return Err(PolygonError::NotAPair {
                    point: k + 1,
                    text: pair.trim().to_string(),
                });
            };
            let num = |s: &str| s.parse::<f64>().ok().filter(|x| x.is_finite());
            let (Some(lon), Some(lat)) = (num(lon), num(lat)) else {
                return Err(PolygonError::NotNumbers {
                    point: k + 1,
                    text: pair.trim().to_string(),
                });
            };
            if !(-180.0..=180.0).contains(&lon) || !(-90.0..=90.0).contains(&lat) {
                return Err(PolygonError::OutsideRange {
                    point: k + 1,
                    lon,
                    lat,
                });
            }
            if k >= MAX_POLYGON_POINTS {
                return Err(PolygonError::TooManyPoints);
            }
            ring.push([lon, lat]);
        }
        ZonePolygon::new(ring)
    }

    /// Builds a polygon from a ring (closed or not); see the module docs for the rules.
    pub(crate) fn new(mut ring: Vec<[f64; 2]>) -> Result<ZonePolygon, PolygonError> {
        ring.dedup();
        if ring.len() > 1 && ring.first() == ring.last() {
            ring.pop();
        }
        if ring.len() < 3 {
            return Err(PolygonError::FewPoints);
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
            return Err(PolygonError::TooWide);
        }
        let bands = Bands::new(&ring, lo[1], hi[1]);
        if let Some((i, j)) = first_crossing(&ring, &bands) {
            return Err(PolygonError::Crossing {
                first: i + 1,
                second: j + 1,
            });
        }
        let area_km2 = area_km2(&ring);
        if area_km2.is_nan() || area_km2 <= 0.0 {
            return Err(PolygonError::NoArea);
        }
        Ok(ZonePolygon {
            ring,
            bbox: (lo, hi),
            area_km2,
            bands,
        })
    }

    /// Whether (lon, lat) lies inside (even-odd rule; points on an edge may fall either way).
    /// Only the edges of the point's latitude band are tested, with the same arithmetic as the
    /// plain even-odd loop over every edge, so the answer is the same bit for bit.
    pub(crate) fn contains(&self, lon: f64, lat: f64) -> bool {
        let (lo, hi) = self.bbox;
        if lon < lo[0] || lon > hi[0] || lat < lo[1] || lat > hi[1] {
            return false;
        }
        odd_crossings(&self.ring, &self.bands, lon, lat)
    }
}

/// Whether a ray from (lon, lat) towards +lon crosses the ring an odd number of times, looking
/// at the edges of the point's latitude band only (the even-odd loop's arithmetic).
fn odd_crossings(ring: &[[f64; 2]], bands: &Bands, lon: f64, lat: f64) -> bool {
    let n = ring.len();
    let mut inside = false;
    for &k in bands.edges_of(bands.band(lat)) {
        let k = k as usize;
        // The even-odd loop's pair (ring[i], ring[i - 1]) with i = k + 1.
        let (a, b) = (ring[(k + 1) % n], ring[k]);
        if (a[1] > lat) != (b[1] > lat) {
            let x = a[0] + (lat - a[1]) * (b[0] - a[0]) / (b[1] - a[1]);
            if lon < x {
                inside = !inside;
            }
        }
    }
    inside
}

/// A polygon with holes from the input (an admin boundary's): containment by the even-odd
/// rule over all its rings, each ring's edges indexed by latitude band as a zone polygon's.
/// Unlike a zone polygon it is not checked for crossings or size: a boundary of a hundred
/// thousand vertices is looked up in time proportional to the edges of one band.
#[derive(Clone, Debug)]
pub(crate) struct RingSet {
    rings: Vec<(Vec<[f64; 2]>, Bands)>,
    /// Lower-left and upper-right corners (lon, lat).
    pub(crate) bbox: ([f64; 2], [f64; 2]),
}

impl RingSet {
    /// The rings (lon, lat, not closed; each of at least 3 points, else left out); `None` when
    /// no ring is left or a coordinate is not finite.
    pub(crate) fn new(rings: Vec<Vec<[f64; 2]>>) -> Option<RingSet> {
        let mut lo = [f64::INFINITY; 2];
        let mut hi = [f64::NEG_INFINITY; 2];
        let mut out = Vec::with_capacity(rings.len());
        for ring in rings.into_iter().filter(|r| r.len() >= 3) {
            let (mut rlo, mut rhi) = (f64::INFINITY, f64::NEG_INFINITY);
            for p in &ring {
                if !p[0].is_finite() || !p[1].is_finite() {
                    return None;
                }
                for d in 0..2 {
                    lo[d] = lo[d].min(p[d]);
                    hi[d] = hi[d].max(p[d]);
                }
                rlo = rlo.min(p[1]);
                rhi = rhi.max(p[1]);
            }
            let bands = Bands::new(&ring, rlo, rhi);
            out.push((ring, bands));
        }
        (!out.is_empty()).then_some(RingSet {
            rings: out,
            bbox: (lo, hi),
        })
    }

    /// Whether (lon, lat) lies inside: in an odd number of the rings (points on an edge may
    /// fall either way).
    pub(crate) fn contains(&self, lon: f64, lat: f64) -> bool {
        let (lo, hi) = self.bbox;
        if !(lon >= lo[0] && lon <= hi[0] && lat >= lo[1] && lat <= hi[1]) {
            return false;
        }
        self.rings
            .iter()
            .filter(|(ring, bands)| odd_crossings(ring, bands, lon, lat))
            .count()
            % 2
            == 1
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
///
/// Two edges that touch share a latitude, hence a band: only pairs of one band are compared
/// (with a bounding-box test first). When any pair is found, the brute-force scan names the
/// first pair in index order, as it always did.
fn first_crossing(ring: &[[f64; 2]], bands: &Bands) -> Option<(usize, usize)> {
    let n = ring.len();
    let edge = |i: usize| (ring[i], ring[(i + 1) % n]);
    let found = (0..n).any(|i| folds_back(ring, i, (i + 1) % n))
        || (0..bands.count()).any(|band| {
            let list = bands.edges_of(band);
            list.iter().enumerate().any(|(x, &i)| {
                let i = i as usize;
                let (a, b) = edge(i);
                let (alo, ahi) = (
                    [a[0].min(b[0]), a[1].min(b[1])],
                    [a[0].max(b[0]), a[1].max(b[1])],
                );
                list[x + 1..].iter().any(|&j| {
                    let j = j as usize;
                    if adjacent(i, j, n) {
                        return false;
                    }
                    let (c, d) = edge(j);
                    if c[0].max(d[0]) < alo[0]
                        || c[0].min(d[0]) > ahi[0]
                        || c[1].max(d[1]) < alo[1]
                        || c[1].min(d[1]) > ahi[1]
                    {
                        return false;
                    }
                    segments_touch(a, b, c, d)
                })
            })
        });
    if found {
        brute_first_crossing(ring)
    } else {
        None
    }
}

fn adjacent(i: usize, j: usize, n: usize) -> bool {
    let (i, j) = (i.min(j), i.max(j));
    j == i + 1 || (i == 0 && j == n - 1)
}

/// Whether adjacent edges `i` and `j` (`i < j`) fold back onto each other (they share one
/// vertex, and are wrong only when they overlap from it).
fn folds_back(ring: &[[f64; 2]], i: usize, j: usize) -> bool {
    let (i, j) = (i.min(j), i.max(j));
    let n = ring.len();
    let edge = |i: usize| (ring[i], ring[(i + 1) % n]);
    let (a, b) = edge(i);
    let (c, d) = edge(j);
    let shared = if j == i + 1 { b } else { a };
    let (p, q) = if j == i + 1 { (a, d) } else { (b, c) };
    let u = [p[0] - shared[0], p[1] - shared[1]];
    let v = [q[0] - shared[0], q[1] - shared[1]];
    u[0] * v[1] - u[1] * v[0] == 0.0 && u[0] * v[0] + u[1] * v[1] > 0.0
}

/// The plain O(n²) scan over every pair of edges, in index order.
fn brute_first_crossing(ring: &[[f64; 2]]) -> Option<(usize, usize)> {
    let n = ring.len();
    let edge = |i: usize| (ring[i], ring[(i + 1) % n]);
    for i in 0..n {
        for j in i + 1..n {
            if adjacent(i, j, n) {
                if folds_back(ring, i, j) {
                    return Some((i, j));
                }
                continue;
            }
            let (a, b) = edge(i);
            let (c, d) = edge(j);
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
                Err(e) => assert!(e.to_string().contains(want), "{s}: {e}"),
            }
        }
    }

    /// The plain even-odd loop over every edge, as `contains` was before the bands.
    fn brute_contains(p: &ZonePolygon, lon: f64, lat: f64) -> bool {
        let (lo, hi) = p.bbox;
        if lon < lo[0] || lon > hi[0] || lat < lo[1] || lat > hi[1] {
            return false;
        }
        let n = p.ring.len();
        let mut inside = false;
        let mut j = n - 1;
        for i in 0..n {
            let (a, b) = (p.ring[i], p.ring[j]);
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

    /// A star-shaped ring of `n` points with random radii (simple), on a coarse grid so that
    /// test points often share a vertex's latitude.
    fn star(rng: &mut crate::rng::Rng, n: usize) -> Vec<[f64; 2]> {
        (0..n)
            .map(|k| {
                let a = k as f64 / n as f64 * std::f64::consts::TAU;
                let r = 0.2 + rng.next_f64();
                [
                    (10.0 + r * a.cos() * 1000.0).round() / 1000.0,
                    (45.0 + r * a.sin() * 1000.0).round() / 1000.0,
                ]
            })
            .collect()
    }

    #[test]
    fn banded_containment_matches_the_even_odd_loop() {
        let mut rng = crate::rng::Rng::new(7, 21);
        let mut checked = 0;
        for round in 0..200 {
            let n = 3 + round * 7 % 900;
            let Ok(p) = ZonePolygon::new(star(&mut rng, n)) else {
                continue;
            };
            for _ in 0..500 {
                // Half the points on a vertex's latitude or longitude, where ties live.
                let v = p.ring[(rng.next_f64() * n as f64) as usize % p.ring.len()];
                let mut lon = 8.7 + rng.next_f64() * 2.6;
                let mut lat = 43.7 + rng.next_f64() * 2.6;
                if rng.next_f64() < 0.25 {
                    lat = v[1];
                } else if rng.next_f64() < 0.33 {
                    lon = v[0];
                } else if rng.next_f64() < 0.5 {
                    (lon, lat) = (v[0], v[1]);
                }
                assert_eq!(
                    p.contains(lon, lat),
                    brute_contains(&p, lon, lat),
                    "{lon} {lat} in ring of {n}"
                );
                checked += 1;
            }
        }
        assert!(checked > 50_000, "{checked}");
    }

    #[test]
    fn banded_crossing_check_matches_the_brute_force_scan() {
        let mut rng = crate::rng::Rng::new(11, 21);
        let (mut simple, mut crossed) = (0, 0);
        for round in 0..400 {
            let n = 3 + round % 60;
            let mut ring = star(&mut rng, n);
            // Swap two vertices in most rounds: often a crossing, sometimes not.
            if round % 4 != 0 {
                let i = (rng.next_f64() * n as f64) as usize % n;
                let j = (rng.next_f64() * n as f64) as usize % n;
                ring.swap(i, j);
            }
            // Or fold an edge back.
            if round % 9 == 1 {
                let m = [
                    (ring[0][0] + ring[1][0]) / 2.0,
                    (ring[0][1] + ring[1][1]) / 2.0,
                ];
                ring.insert(2, m);
            }
            ring.dedup();
            if ring.len() > 1 && ring.first() == ring.last() {
                ring.pop();
            }
            if ring.len() < 3 {
                continue;
            }
            let (lo, hi) = ring.iter().fold(
                ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]),
                |(lo, hi), p| {
                    (
                        [lo[0].min(p[0]), lo[1].min(p[1])],
                        [hi[0].max(p[0]), hi[1].max(p[1])],
                    )
                },
            );
            let bands = Bands::new(&ring, lo[1], hi[1]);
            let want = brute_first_crossing(&ring);
            assert_eq!(first_crossing(&ring, &bands), want, "{ring:?}");
            if want.is_some() {
                crossed += 1;
            } else {
                simple += 1;
            }
        }
        assert!(
            simple > 50 && crossed > 50,
            "{simple} simple, {crossed} crossed"
        );
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
