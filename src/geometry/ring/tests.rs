//! Property tests of the ring-cleaning family: each member keeps its contract on generated
//! rings with duplicates, spikes and collinear runs planted in them.

use glam::DVec2;
use proptest::prelude::*;

use super::*;
use crate::geometry::ring_signed_area;

/// Whether `sub` is a subsequence of `all` (every output point is an input point, in order).
fn subsequence(sub: &[DVec2], all: &[DVec2]) -> bool {
    let mut it = all.iter();
    sub.iter().all(|p| it.any(|q| q == p))
}

/// A ring on a 1 m grid with near-duplicates (1e-5 m), exact repeats, spikes and midpoints.
fn noisy_ring() -> impl Strategy<Value = Vec<DVec2>> {
    prop::collection::vec((0i32..20, 0i32..20, 0u8..6), 3..24).prop_map(|pts| {
        let mut r = Vec::new();
        for (x, y, what) in pts {
            let p = DVec2::new(x as f64, y as f64);
            r.push(p);
            match what {
                0 => r.push(p + DVec2::splat(1e-5)),
                1 => r.push(p),
                2 => {
                    r.push(p + DVec2::new(3.0, 0.0));
                    r.push(p);
                }
                _ => {}
            }
        }
        r
    })
}

proptest! {
    #[test]
    fn dedup_within_leaves_no_neighbours_within_the_tolerance(r in noisy_ring()) {
        let mut d = r.clone();
        dedup_within(&mut d, 1e-4);
        prop_assert!(subsequence(&d, &r));
        for w in d.windows(2) {
            prop_assert!(w[0].distance(w[1]) > 1e-4);
        }
        if d.len() > 1 {
            prop_assert!(d[0].distance(d[d.len() - 1]) > 1e-4);
        }
        let mut again = d.clone();
        dedup_within(&mut again, 1e-4);
        prop_assert_eq!(again, d);
    }

    #[test]
    fn exact_dedup_is_vec_dedup_plus_the_closing_vertex(r in noisy_ring()) {
        let mut d = r.clone();
        dedup_by(&mut d, |a, b| a == b);
        let mut e = r.clone();
        e.dedup();
        while e.len() > 1 && e.first() == e.last() {
            e.pop();
        }
        prop_assert_eq!(d, e);
    }

    #[test]
    fn no_spike_is_left_and_each_costs_two_vertices(r in noisy_ring()) {
        let mut d = r.clone();
        dedup_by(&mut d, |a, b| a == b);
        let before = d.len();
        let spikes = remove_spikes_by(&mut d, |a, b| a == b);
        prop_assert_eq!(before - d.len(), 2 * spikes);
        prop_assert!(subsequence(&d, &r));
        let n = d.len();
        if n >= 3 {
            for i in 0..n {
                prop_assert!(d[(i + n - 1) % n] != d[(i + 1) % n]);
            }
            // No removal made a consecutive duplicate.
            for i in 0..n {
                prop_assert!(d[i] != d[(i + 1) % n]);
            }
        }
    }

    #[test]
    fn clean_ring_is_counter_clockwise_idempotent_and_keeps_the_area(r in noisy_ring()) {
        if let Some(c) = clean_ring(&r) {
            prop_assert!(c.len() >= 3);
            prop_assert!(ring_signed_area(&c) > 0.0);
            prop_assert_eq!(clean_ring(&c), Some(c.clone()));
            // Dropping collinear vertices and 10 µm duplicates changes the area by almost nothing.
            let mut d = r.clone();
            dedup_within(&mut d, 1e-4);
            let (a, b) = (ring_signed_area(&c).abs(), ring_signed_area(&d).abs());
            prop_assert!((a - b).abs() <= 1e-3 * a.max(1.0), "{} vs {}", a, b);
            let n = c.len();
            for i in 0..n {
                let (p, q, s) = (c[(i + n - 1) % n], c[i], c[(i + 1) % n]);
                let chord = s - p;
                prop_assert!((q - p).perp_dot(chord).abs() / chord.length() > 1e-6);
            }
        }
    }

    #[test]
    fn remove_straight_leaves_only_turning_vertices(r in noisy_ring()) {
        let mut d = r.clone();
        remove_straight(&mut d, 1e-7, 1e-7);
        prop_assert!(subsequence(&d, &r));
        let n = d.len();
        if n >= 3 {
            for i in 0..n {
                let (p, q, s) = (d[(i + n - 1) % n], d[i], d[(i + 1) % n]);
                let (e1, e2) = (q - p, s - q);
                prop_assert!(q.distance(p) >= 1e-7);
                let len = e1.length() * e2.length();
                prop_assert!(len == 0.0 || e1.perp_dot(e2).abs() / len >= 1e-7);
            }
        }
    }

    #[test]
    fn simplified_indices_are_increasing_and_drop_only_straight_vertices(r in noisy_ring()) {
        let mut d = r.clone();
        dedup_within(&mut d, 1e-4);
        if let Ok(keep) = simplified_indices(&d, 1e-6, 1e-6, 1e-6) {
            prop_assert!(keep.windows(2).all(|w| w[0] < w[1]));
            prop_assert!(keep.iter().all(|&i| i < d.len()));
        }
    }
}

#[test]
fn a_spike_is_an_error_for_the_skeleton_and_removed_for_prepare() {
    let r = [
        DVec2::new(0.0, 0.0),
        DVec2::new(4.0, 0.0),
        DVec2::new(8.0, 0.0),
        DVec2::new(4.0, 0.0),
        DVec2::new(4.0, 4.0),
    ];
    // 4,0 -> 8,0 -> 4,0: the tip 8,0 turns back.
    assert_eq!(simplified_indices(&r, 1e-6, 1e-6, 1e-6), Err(2));
    let mut v = r.to_vec();
    assert_eq!(remove_spikes_by(&mut v, |a, b| a == b), 1);
    assert_eq!(
        v,
        vec![
            DVec2::new(0.0, 0.0),
            DVec2::new(4.0, 0.0),
            DVec2::new(4.0, 4.0)
        ]
    );
}

#[test]
fn collinear_and_duplicate_vertices_leave_the_writers_ring() {
    let r = [
        DVec2::new(0.0, 0.0),
        DVec2::new(5.0, 0.0),
        DVec2::new(10.0, 0.0),
        DVec2::new(10.0, 0.00001),
        DVec2::new(10.0, 10.0),
        DVec2::new(0.0, 10.0),
        DVec2::new(0.0, 0.0),
    ];
    let c = clean_ring(&r).unwrap();
    assert_eq!(c.len(), 4);
    assert!(clean_ring(&[DVec2::ZERO, DVec2::X, DVec2::new(2.0, 0.0)]).is_none());
    assert!(clean_ring(&[DVec2::ZERO, DVec2::X, DVec2::new(f64::NAN, 1.0)]).is_none());
}
