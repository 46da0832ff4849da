//! Clipping to a slab: the pieces of both sides of a cut partition the polygon, on the convex
//! fast path and through `geo` for concave outlines.

use glam::DVec2;
use proptest::prelude::*;

use super::clip_slab;
use crate::geometry::hull::convex_hull;
use crate::geometry::Polygon;

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]
    /// Slab pieces of any polygon (convex fast path or geo) partition it.
    #[test]
    fn slab_clips_partition_the_polygon(
        pts in prop::collection::vec((0.0f64..50.0, 0.0f64..50.0), 3..9),
        cut in 0.05f64..0.95,
        angle in 0.0f64..6.3,
    ) {
        let hull = convex_hull(&pts.iter().map(|&(x, y)| DVec2::new(x, y)).collect::<Vec<_>>());
        prop_assume!(hull.len() >= 3);
        let poly = Polygon::new(hull, vec![]);
        prop_assume!(poly.area() > 1.0);
        let axis = DVec2::from_angle(angle);
        let (lo, hi) = poly.outer.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), p| (a.min(p.dot(axis)), b.max(p.dot(axis))));
        let c = lo + (hi - lo) * cut;
        let a: f64 = clip_slab(&poly, DVec2::ZERO, axis, f64::NEG_INFINITY, c).iter().map(Polygon::area).sum();
        let b: f64 = clip_slab(&poly, DVec2::ZERO, axis, c, f64::INFINITY).iter().map(Polygon::area).sum();
        prop_assert!((a + b - poly.area()).abs() < 1e-6 * poly.area().max(1.0));
        // A concave version (a notch) goes through geo and must still partition.
        let mut notched = poly.outer.clone();
        let centroid = notched.iter().copied().sum::<DVec2>() / notched.len() as f64;
        notched.insert(1, centroid);
        let np = Polygon::new(notched, vec![]);
        let a: f64 = clip_slab(&np, DVec2::ZERO, axis, f64::NEG_INFINITY, c).iter().map(Polygon::area).sum();
        let b: f64 = clip_slab(&np, DVec2::ZERO, axis, c, f64::INFINITY).iter().map(Polygon::area).sum();
        prop_assert!((a + b - np.area()).abs() < 1e-6 * np.area().max(1.0), "{} + {} vs {}", a, b, np.area());
    }
}
