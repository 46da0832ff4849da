//! Where a straight segment of the local frame crosses the files' pixel-centre lines: between
//! two such crossings a bilinear height along the segment is one quadratic, so its lowest
//! point there is at an end or at the quadratic's vertex (`prepare::ground` uses this to find
//! a footprint's lowest terrain exactly along its rings).

use glam::DVec2;

use super::Framed;

impl Framed<'_> {
    /// The parameters t in (0, 1) where the local segment `a`→`b` crosses a pixel-centre row
    /// or column of any file, sorted, at most `max` (the segment taken as straight in each
    /// file's pixel space, which it is to far below a millimetre over a building's edge).
    pub fn crossings(&self, a: DVec2, b: DVec2, max: usize) -> Vec<f64> {
        let mut out = Vec::new();
        for (d, dem) in self.set.dems.iter().enumerate() {
            let pa = dem.georef.to_pixel(self.to_model(d, a));
            let pb = dem.georef.to_pixel(self.to_model(d, b));
            if !(pa.is_finite() && pb.is_finite()) {
                continue;
            }
            for (u, v, size) in [(pa.x, pb.x, dem.width), (pa.y, pb.y, dem.height)] {
                let (lo, hi) = (u.min(v), u.max(v));
                // Only the lines of the raster matter (clamped: off it there is no height).
                let first = lo.floor().max(-1.0) + 1.0;
                let last = hi.ceil().min(f64::from(size)) - 1.0;
                let mut k = first;
                while k <= last && out.len() < max {
                    let t = (k - u) / (v - u);
                    if t > 0.0 && t < 1.0 {
                        out.push(t);
                    }
                    k += 1.0;
                }
            }
        }
        out.sort_by(f64::total_cmp);
        out.dedup_by(|x, y| (*x - *y).abs() < 1e-9);
        out
    }
}

#[cfg(test)]
mod tests {
    use glam::DVec2;

    use crate::crs::Crs;
    use crate::input::dem::DemSet;
    use crate::testkit::geotiff::GeoTiff;

    #[test]
    fn crossings_of_pixel_centre_lines() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("d.tif");
        // 2 m pixels from (499 900, 5 000 100): centres at odd metres.
        GeoTiff::projected(32609, (499_900.0, 5_000_100.0), 2.0, (100, 100), |_, _| 1.0)
            .write(&p)
            .unwrap();
        let set = DemSet::open(&[p]).unwrap();
        let utm = Crs::Utm {
            zone: 9,
            north: true,
        };
        let f = set.framed(utm, DVec2::new(500_000.0, 5_000_000.0));
        let t = f.crossings(DVec2::new(0.3, 0.3), DVec2::new(10.3, 0.3), 100);
        let want = [0.07, 0.27, 0.47, 0.67, 0.87];
        assert_eq!(t.len(), want.len(), "{t:?}");
        assert!(
            t.iter().zip(want).all(|(a, b)| (a - b).abs() < 1e-9),
            "{t:?}"
        );
        // Diagonal, backwards: columns and rows both, sorted; capped.
        let t = f.crossings(DVec2::new(4.0, 4.0), DVec2::new(0.0, 0.0), 100);
        assert_eq!(t, vec![0.25, 0.75]);
        assert_eq!(
            f.crossings(DVec2::new(0.3, 0.3), DVec2::new(10.3, 0.3), 2)
                .len(),
            2
        );
        // Off the raster: no line.
        assert!(f
            .crossings(DVec2::new(500.0, 0.0), DVec2::new(520.0, 0.0), 100)
            .is_empty());
    }
}
