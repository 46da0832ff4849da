//! Lambert Conic Conformal with two standard parallels on an ellipsoid (EPSG method 9802), in
//! the closed form of IOGP Guidance Note 7-2 §3.2.1.1.

use super::ellipsoid::Ellipsoid;
use std::f64::consts::FRAC_PI_2;
use std::f64::consts::FRAC_PI_4;

/// A Lambert Conic Conformal (2SP) projection with its constants precomputed.
#[derive(Clone, Copy, Debug)]
pub(crate) struct LambertConic2Sp {
    e: f64,
    /// Cone constant.
    n: f64,
    /// `a F`, the radius scale.
    af: f64,
    /// Radius of the parallel of the false origin.
    r_f: f64,
    /// Longitude of false origin, radians.
    lon_f: f64,
    easting_f: f64,
    northing_f: f64,
}

impl LambertConic2Sp {
    /// A projection on `ell` with false origin (`lon_f_deg`, `lat_f_deg`), standard parallels
    /// `lat1_deg` and `lat2_deg` (distinct, same hemisphere) and false easting/northing metres.
    pub(crate) fn new(
        ell: Ellipsoid,
        lon_f_deg: f64,
        lat_f_deg: f64,
        lat1_deg: f64,
        lat2_deg: f64,
        easting_f: f64,
        northing_f: f64,
    ) -> Self {
        let e = ell.e();
        let m = |phi: f64| phi.cos() / (1.0 - e * e * phi.sin().powi(2)).sqrt();
        let (p1, p2) = (lat1_deg.to_radians(), lat2_deg.to_radians());
        let (m1, m2) = (m(p1), m(p2));
        let (t1, t2) = (t_of(e, p1), t_of(e, p2));
        let n = (m1.ln() - m2.ln()) / (t1.ln() - t2.ln());
        let f = m1 / (n * t1.powf(n));
        let af = ell.a * f;
        let r_f = af * t_of(e, lat_f_deg.to_radians()).powf(n);
        LambertConic2Sp {
            e,
            n,
            af,
            r_f,
            lon_f: lon_f_deg.to_radians(),
            easting_f,
            northing_f,
        }
    }

    /// Geodetic degrees on this projection's ellipsoid to (easting, northing) metres.
    pub(crate) fn project(&self, lon_deg: f64, lat_deg: f64) -> (f64, f64) {
        let t = t_of(self.e, lat_deg.to_radians());
        let r = self.af * t.powf(self.n);
        let theta = self.n * super::tmerc::wrap_pi(lon_deg.to_radians() - self.lon_f);
        let (s, c) = theta.sin_cos();
        (self.easting_f + r * s, self.northing_f + self.r_f - r * c)
    }

    /// Inverse of [`LambertConic2Sp::project`]: (easting, northing) metres to degrees.
    pub(crate) fn unproject(&self, easting: f64, northing: f64) -> (f64, f64) {
        let dx = easting - self.easting_f;
        let dy = self.r_f - (northing - self.northing_f);
        let sign = self.n.signum();
        let r = sign * dx.hypot(dy);
        let theta = (sign * dx).atan2(sign * dy);
        let t = (r / self.af).powf(1.0 / self.n);
        // φ = π/2 - 2 atan(t ((1 - e sin φ)/(1 + e sin φ))^(e/2)), a contraction that gains
        // roughly two digits per step.
        let e = self.e;
        let mut phi = FRAC_PI_2 - 2.0 * t.atan();
        for _ in 0..20 {
            let es = e * phi.sin();
            let next = FRAC_PI_2 - 2.0 * (t * ((1.0 - es) / (1.0 + es)).powf(e / 2.0)).atan();
            let done = (next - phi).abs() < 1e-15;
            phi = next;
            if done {
                break;
            }
        }
        (
            super::tmerc::wrap_pi(theta / self.n + self.lon_f).to_degrees(),
            phi.to_degrees(),
        )
    }
}

/// Isometric-latitude term `t = tan(π/4 - φ/2) / ((1 - e sin φ)/(1 + e sin φ))^(e/2)`.
fn t_of(e: f64, phi: f64) -> f64 {
    let es = e * phi.sin();
    (FRAC_PI_4 - phi / 2.0).tan() / ((1.0 - es) / (1.0 + es)).powf(e / 2.0)
}
