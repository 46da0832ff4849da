//! The convex hull: counter-clockwise, convex, holding every input point, its vertices taken
//! from the input.

use glam::DVec2;
use proptest::prelude::*;

use super::convex_hull;
use crate::geometry::ring_signed_area;

proptest! {
    #[test]
    fn the_hull_is_convex_counter_clockwise_and_holds_every_point(
        pts in prop::collection::vec((-50i32..50, -50i32..50), 0..40),
    ) {
        let pts: Vec<DVec2> = pts.iter().map(|&(x, y)| DVec2::new(x as f64, y as f64)).collect();
        let h = convex_hull(&pts);
        prop_assert!(h.iter().all(|p| pts.contains(p)));
        if h.len() >= 3 {
            prop_assert!(ring_signed_area(&h) > 0.0);
            let n = h.len();
            for i in 0..n {
                let (a, b) = (h[i], h[(i + 1) % n]);
                // Strictly convex: no collinear vertex is kept.
                prop_assert!((b - a).perp_dot(h[(i + 2) % n] - b) > 0.0);
                for p in &pts {
                    prop_assert!((b - a).perp_dot(*p - a) >= 0.0, "{} outside edge {}-{}", p, a, b);
                }
            }
        }
    }
}
