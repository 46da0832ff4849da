//! Ellipsoidal Transverse Mercator by the Krüger series to sixth order in the third flattening
//! `n`, as given by C. F. F. Karney, "Transverse Mercator with an accuracy of a few nanometers",
//! J. Geodesy 85 (2011), eqs. (7), (11), (14), (35), (36).
//!
//! Within 3900 km of the central meridian the truncation error is below 5 nm, far inside the
//! millimetre bar for UTM zones and the British National Grid.

use super::ellipsoid::Ellipsoid;
use std::sync::LazyLock;

/// The series on WGS 84, shared by all WGS84 UTM zones.
pub(crate) static WGS84_SERIES: LazyLock<KruegerSeries> =
    LazyLock::new(|| KruegerSeries::new(Ellipsoid::WGS84));
/// The series on GRS 1980, shared by all ETRS89 UTM zones.
pub(crate) static GRS80_SERIES: LazyLock<KruegerSeries> =
    LazyLock::new(|| KruegerSeries::new(Ellipsoid::GRS80));

/// The series coefficients of one ellipsoid (independent of the projection parameters).
#[derive(Clone, Copy, Debug)]
pub(crate) struct KruegerSeries {
    /// Eccentricity, for the conformal latitude.
    e: f64,
    /// Rectifying radius `A = a/(1+n) (1 + n²/4 + n⁴/64 + n⁶/256)`.
    big_a: f64,
    /// Forward coefficients α₁..α₆ (conformal sphere -> rectifying coordinates).
    alpha: [f64; 6],
    /// Inverse coefficients β₁..β₆.
    beta: [f64; 6],
}

impl KruegerSeries {
    /// The series for `ell`.
    pub(crate) fn new(ell: Ellipsoid) -> Self {
        let n = ell.n();
        let n2 = n * n;
        let n3 = n2 * n;
        let n4 = n3 * n;
        let n5 = n4 * n;
        let n6 = n5 * n;
        let big_a = ell.a / (1.0 + n) * (1.0 + n2 / 4.0 + n4 / 64.0 + n6 / 256.0);
        let alpha = [
            n / 2.0 - 2.0 / 3.0 * n2 + 5.0 / 16.0 * n3 + 41.0 / 180.0 * n4 - 127.0 / 288.0 * n5
                + 7891.0 / 37800.0 * n6,
            13.0 / 48.0 * n2 - 3.0 / 5.0 * n3 + 557.0 / 1440.0 * n4 + 281.0 / 630.0 * n5
                - 1_983_433.0 / 1_935_360.0 * n6,
            61.0 / 240.0 * n3 - 103.0 / 140.0 * n4
                + 15061.0 / 26880.0 * n5
                + 167_603.0 / 181_440.0 * n6,
            49561.0 / 161_280.0 * n4 - 179.0 / 168.0 * n5 + 6_601_661.0 / 7_257_600.0 * n6,
            34729.0 / 80640.0 * n5 - 3_418_889.0 / 1_995_840.0 * n6,
            212_378_941.0 / 319_334_400.0 * n6,
        ];
        let beta = [
            n / 2.0 - 2.0 / 3.0 * n2 + 37.0 / 96.0 * n3 - 1.0 / 360.0 * n4 - 81.0 / 512.0 * n5
                + 96199.0 / 604_800.0 * n6,
            1.0 / 48.0 * n2 + 1.0 / 15.0 * n3 - 437.0 / 1440.0 * n4 + 46.0 / 105.0 * n5
                - 1_118_711.0 / 3_870_720.0 * n6,
            17.0 / 480.0 * n3 - 37.0 / 840.0 * n4 - 209.0 / 4480.0 * n5 + 5569.0 / 90720.0 * n6,
            4397.0 / 161_280.0 * n4 - 11.0 / 504.0 * n5 - 830_251.0 / 7_257_600.0 * n6,
            4583.0 / 161_280.0 * n5 - 108_847.0 / 3_991_680.0 * n6,
            20_648_693.0 / 638_668_800.0 * n6,
        ];
        KruegerSeries {
            e: ell.e(),
            big_a,
            alpha,
            beta,
        }
    }

    /// `tan χ` (χ the conformal latitude) from `tan φ`, Karney eq. (7).
    fn taup(&self, tau: f64) -> f64 {
        let e = self.e;
        let tau1 = 1f64.hypot(tau);
        let sig = (e * (e * tau / tau1).atanh()).sinh();
        1f64.hypot(sig) * tau - sig * tau1
    }

    /// `tan φ` from `tan χ` by Newton's method, Karney eqs. (19)-(21).
    fn tau(&self, taup: f64) -> f64 {
        let e2m = 1.0 - self.e * self.e;
        let mut tau = taup / e2m;
        let tol = f64::EPSILON.sqrt() * 0.1 * taup.abs().max(1.0);
        for _ in 0..8 {
            let taupa = self.taup(tau);
            let dtau = (taup - taupa) * (1.0 + e2m * tau * tau)
                / (e2m * 1f64.hypot(tau) * 1f64.hypot(taupa));
            tau += dtau;
            // Newton converges quadratically: once the step is below √ε the next one is at
            // rounding level, so one more pass is not needed.
            if dtau.abs() < tol {
                break;
            }
        }
        tau
    }

    /// Unit-scale projection: latitude `lat` and longitude `dlon` from the central meridian
    /// (radians) to (η, ξ) multiplied by `A`, i.e. metres for k₀ = 1 with the origin on the
    /// equator.
    pub(crate) fn forward(&self, dlon: f64, lat: f64) -> (f64, f64) {
        let taup = self.taup(lat.tan());
        let (slam, clam) = dlon.sin_cos();
        let xip = taup.atan2(clam);
        let etap = (slam / taup.hypot(clam)).asinh();
        let mut xi = xip;
        let mut eta = etap;
        for (j, a) in self.alpha.iter().enumerate() {
            let k = 2.0 * (j as f64 + 1.0);
            xi += a * (k * xip).sin() * (k * etap).cosh();
            eta += a * (k * xip).cos() * (k * etap).sinh();
        }
        (self.big_a * eta, self.big_a * xi)
    }

    /// Inverse of [`KruegerSeries::forward`]: (x, y) metres at k₀ = 1 to (dlon, lat) radians.
    pub(crate) fn inverse(&self, x: f64, y: f64) -> (f64, f64) {
        let eta = x / self.big_a;
        let xi = y / self.big_a;
        let mut xip = xi;
        let mut etap = eta;
        for (j, b) in self.beta.iter().enumerate() {
            let k = 2.0 * (j as f64 + 1.0);
            xip -= b * (k * xi).sin() * (k * eta).cosh();
            etap -= b * (k * xi).cos() * (k * eta).sinh();
        }
        let (sxip, cxip) = xip.sin_cos();
        let setap = etap.sinh();
        let taup = sxip / setap.hypot(cxip);
        let dlon = setap.atan2(cxip);
        let lat = self.tau(taup).atan();
        (dlon, lat)
    }
}

/// A Transverse Mercator projection: ellipsoid series plus the natural origin, scale and false
/// origin (EPSG method 9807).
#[derive(Clone, Copy, Debug)]
pub(crate) struct TransverseMercator {
    series: KruegerSeries,
    /// Longitude of natural origin, radians.
    lon0: f64,
    /// Scale factor on the central meridian.
    k0: f64,
    false_easting: f64,
    /// False northing minus the scaled meridian arc to the latitude of origin.
    northing_offset: f64,
}

impl TransverseMercator {
    /// A projection on `ell` with natural origin (`lon0_deg`, `lat0_deg`), central scale `k0`
    /// and false origin (`fe`, `fn_`) metres.
    pub(crate) fn new(
        ell: Ellipsoid,
        lon0_deg: f64,
        lat0_deg: f64,
        k0: f64,
        fe: f64,
        fn_: f64,
    ) -> Self {
        let series = KruegerSeries::new(ell);
        // On the central meridian ξ is the rectifying latitude, so this is the meridian arc.
        let (_, m0) = series.forward(0.0, lat0_deg.to_radians());
        TransverseMercator {
            series,
            lon0: lon0_deg.to_radians(),
            k0,
            false_easting: fe,
            northing_offset: fn_ - k0 * m0,
        }
    }

    /// The UTM projection of `zone` (1-60) with a precomputed `series`. Cheap: UTM's origin
    /// is on the equator, so no meridian arc is needed.
    pub(crate) fn utm(series: &KruegerSeries, zone: u8, north: bool) -> Self {
        TransverseMercator {
            series: *series,
            lon0: (-183.0 + 6.0 * f64::from(zone)).to_radians(),
            k0: 0.9996,
            false_easting: 500_000.0,
            northing_offset: if north { 0.0 } else { 10_000_000.0 },
        }
    }

    /// Geodetic degrees on this projection's ellipsoid to (easting, northing) metres.
    pub(crate) fn project(&self, lon_deg: f64, lat_deg: f64) -> (f64, f64) {
        let dlon = wrap_pi(lon_deg.to_radians() - self.lon0);
        let (x, y) = self.series.forward(dlon, lat_deg.to_radians());
        (
            self.false_easting + self.k0 * x,
            self.northing_offset + self.k0 * y,
        )
    }

    /// Inverse of [`TransverseMercator::project`]: (easting, northing) metres to degrees.
    pub(crate) fn unproject(&self, e: f64, n: f64) -> (f64, f64) {
        let x = (e - self.false_easting) / self.k0;
        let y = (n - self.northing_offset) / self.k0;
        let (dlon, lat) = self.series.inverse(x, y);
        (wrap_pi(dlon + self.lon0).to_degrees(), lat.to_degrees())
    }
}

/// Reduces an angle in radians to [-π, π] so longitudes across the antimeridian stay close to
/// the central meridian.
pub(crate) fn wrap_pi(a: f64) -> f64 {
    use std::f64::consts::PI;
    if (-PI..=PI).contains(&a) {
        a
    } else {
        (a + PI).rem_euclid(2.0 * PI) - PI
    }
}
