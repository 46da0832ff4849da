//! WGS 84 / Pseudo-Mercator (EPSG:3857, "web mercator"): the spherical Mercator formulas applied
//! to WGS 84 longitude and latitude, on a sphere of the WGS 84 semi-major axis (IOGP Guidance
//! Note 7-2, method EPSG:1024). Read only, for DEMs made for web maps: its metres are not
//! metres on the ground (1 / cos φ too long), so citygen never writes in it.

/// The sphere's radius: the WGS 84 semi-major axis, metres.
const R: f64 = 6_378_137.0;

/// WGS 84 (longitude, latitude) degrees to Pseudo-Mercator (easting, northing) metres.
pub(crate) fn from_lonlat(lon: f64, lat: f64) -> (f64, f64) {
    let phi = lat.to_radians();
    (
        R * lon.to_radians(),
        R * (std::f64::consts::FRAC_PI_4 + phi / 2.0).tan().ln(),
    )
}

/// Pseudo-Mercator (easting, northing) metres to WGS 84 (longitude, latitude) degrees.
pub(crate) fn to_lonlat(x: f64, y: f64) -> (f64, f64) {
    ((x / R).to_degrees(), (y / R).sinh().atan().to_degrees())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// IOGP Guidance Note 7-2's example for EPSG:1024: 24°22'54.433"N, 100°20'00.000"W is
    /// E = -11 169 055.58 m, N = 2 800 000.00 m.
    #[test]
    fn iogp_example_and_round_trip() {
        let lat = 24.0 + 22.0 / 60.0 + 54.433 / 3600.0;
        let lon = -(100.0 + 20.0 / 60.0);
        let (x, y) = from_lonlat(lon, lat);
        assert!((x - -11_169_055.58).abs() < 0.01, "{x}");
        assert!((y - 2_800_000.00).abs() < 0.01, "{y}");
        let (lo, la) = to_lonlat(x, y);
        assert!((lo - lon).abs() < 1e-12 && (la - lat).abs() < 1e-12);
        // The square's corner: 180°E at the latitude where the map is square.
        let (x, y) = from_lonlat(180.0, 85.051_128_779_806_6);
        assert!((x - 20_037_508.342_789_244).abs() < 1e-6, "{x}");
        assert!((y - 20_037_508.342_789_244).abs() < 1e-3, "{y}");
    }
}
