//! Reference ellipsoids and the geodetic <-> geocentric conversions every datum shift needs.

/// A reference ellipsoid, given by its semi-major axis `a` (metres) and flattening `f`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Ellipsoid {
    /// Semi-major axis in metres.
    pub a: f64,
    /// Flattening `(a - b) / a`.
    pub f: f64,
}

impl Ellipsoid {
    /// WGS 84 (EPSG:7030).
    pub(crate) const WGS84: Ellipsoid = Ellipsoid {
        a: 6_378_137.0,
        f: 1.0 / 298.257_223_563,
    };
    /// GRS 1980 (EPSG:7019), the ellipsoid of ETRS89 and RGF93.
    pub(crate) const GRS80: Ellipsoid = Ellipsoid {
        a: 6_378_137.0,
        f: 1.0 / 298.257_222_101,
    };
    /// Airy 1830 (EPSG:7001), the ellipsoid of OSGB36. The Ordnance Survey defines it by
    /// a = 6377563.396 m and b = 6356256.909 m, so the flattening is derived from both.
    pub(crate) const AIRY1830: Ellipsoid = Ellipsoid {
        a: 6_377_563.396,
        f: (6_377_563.396 - 6_356_256.909) / 6_377_563.396,
    };

    /// First eccentricity squared, `f (2 - f)`.
    pub(crate) fn e2(&self) -> f64 {
        self.f * (2.0 - self.f)
    }

    /// First eccentricity.
    pub(crate) fn e(&self) -> f64 {
        self.e2().sqrt()
    }

    /// Third flattening `n = f / (2 - f)`, the small parameter of the Krüger series.
    pub(crate) fn n(&self) -> f64 {
        self.f / (2.0 - self.f)
    }

    /// Geodetic (longitude, latitude in radians, ellipsoidal height in metres) to geocentric
    /// cartesian (X, Y, Z) metres.
    pub(crate) fn geodetic_to_geocentric(&self, lon: f64, lat: f64, h: f64) -> [f64; 3] {
        let e2 = self.e2();
        let (sphi, cphi) = lat.sin_cos();
        let (slam, clam) = lon.sin_cos();
        // Prime-vertical radius of curvature.
        let nu = self.a / (1.0 - e2 * sphi * sphi).sqrt();
        [
            (nu + h) * cphi * clam,
            (nu + h) * cphi * slam,
            (nu * (1.0 - e2) + h) * sphi,
        ]
    }

    /// Geocentric cartesian (X, Y, Z) metres to geodetic (longitude, latitude in radians,
    /// ellipsoidal height in metres).
    ///
    /// Iterates `tan φ = (Z + e² ν sin φ) / p`, which is exact for any height and converges to
    /// machine precision in a handful of steps for points near the surface.
    pub(crate) fn geocentric_to_geodetic(&self, xyz: [f64; 3]) -> (f64, f64, f64) {
        let [x, y, z] = xyz;
        let e2 = self.e2();
        let p = x.hypot(y);
        let lon = y.atan2(x);
        let mut lat = z.atan2(p * (1.0 - e2));
        for _ in 0..10 {
            let s = lat.sin();
            let nu = self.a / (1.0 - e2 * s * s).sqrt();
            let next = (z + e2 * nu * s).atan2(p);
            let done = (next - lat).abs() < 1e-15;
            lat = next;
            if done {
                break;
            }
        }
        let (s, c) = lat.sin_cos();
        let nu = self.a / (1.0 - e2 * s * s).sqrt();
        // Height from whichever of p and Z is better conditioned at this latitude.
        let h = if c.abs() > 0.5 {
            p / c - nu
        } else {
            z / s - nu * (1.0 - e2)
        };
        (lon, lat, h)
    }
}
