//! Straight skeleton tests: shapes with known skeletons, holes, degenerate and invalid input.

#[test]
fn a_footprint_with_too_many_edges_is_refused_at_once() {
    // 4,000 vertices on a wavy circle: no run of them is collinear.
    let n = 4000;
    let ring: Vec<DVec2> = (0..n)
        .map(|i| {
            let a = i as f64 / n as f64 * std::f64::consts::TAU;
            let r = 20.0 + if i % 2 == 0 { 0.0 } else { 0.5 };
            DVec2::new(r * a.cos(), r * a.sin())
        })
        .collect();
    let t = std::time::Instant::now();
    let err = straight_skeleton(&Polygon::new(ring, vec![])).unwrap_err();
    assert!(
        matches!(
            err,
            SkeletonError::TooComplex {
                edges: 4000,
                max: MAX_EDGES
            }
        ),
        "{err}"
    );
    assert!(t.elapsed().as_secs() < 5, "refused quickly");
}
use super::*;

fn poly(pts: &[(f64, f64)]) -> Polygon {
    Polygon::new(pts.iter().map(|&(x, y)| DVec2::new(x, y)).collect(), vec![])
}

fn square(x: f64, y: f64) -> Vec<DVec2> {
    vec![
        DVec2::new(x, y),
        DVec2::new(x, y + 1.),
        DVec2::new(x + 1., y + 1.),
        DVec2::new(x + 1., y),
    ]
}

#[test]
fn rectangle_faces() {
    let sk = straight_skeleton(&poly(&[(0., 0.), (10., 0.), (10., 4.), (0., 4.)])).unwrap();
    let sizes: Vec<usize> = sk.faces.iter().map(|f| f.polygon.len()).collect();
    assert_eq!(sizes, vec![4, 3, 4, 3]);
    assert_eq!(sk.faces[1].polygon[2], DVec3::new(8., 2., 2.));
}

#[test]
fn collinear_vertices_keep_one_face_per_edge() {
    let sk =
        straight_skeleton(&poly(&[(0., 0.), (4., 0.), (10., 0.), (10., 4.), (0., 4.)])).unwrap();
    assert_eq!(sk.faces.len(), 5);
    let e0 = &sk.faces[0].polygon;
    assert_eq!(
        (e0[0].truncate(), e0[1].truncate()),
        (DVec2::ZERO, DVec2::new(4., 0.))
    );
}

/// Regressions found by the property tests.
#[test]
fn regressions() {
    let stars: [&[(f64, f64)]; 2] = [
        &[
            (0.39838971759809566, 0.035855723561373405),
            (0.33404937147622477, 0.5060631665136619),
            (-0.8479026993284455, 0.9485935222440922),
            (-0.37547005695450164, -0.13792112358367487),
            (-0.3433795174407466, -0.2051597109623623),
            (-0.11857819031895019, -0.8753793534834874),
            (0.603122373712497, -0.1318777078045141),
        ],
        &[
            (1.735785639633616, 0.08395971628638865),
            (1.1675437242486026, 1.5053175665116583),
            (0.24598550744084619, 0.7620072262379639),
            (0.11391485177964451, 1.5685225093791306),
            (-0.2791213097346702, 0.6407584669289865),
            (-0.7847381485905126, 0.6302521174771831),
            (-0.3925480504557654, 0.07685068694148345),
            (-1.2180783529680586, -0.3634810926398813),
            (-0.2862395842976485, -0.27940454609957477),
            (-0.12360679774997903, -0.3804226065180614),
            (0.06734281653881553, -0.39429043237266037),
            (0.24286500312748444, -0.31783107188550175),
            (0.3627497443402183, -0.16856044310901153),
        ],
    ];
    for s in stars {
        assert!(straight_skeleton(&poly(s)).is_ok());
    }
    // Two courtyards whose wavefronts meet each other before the outer one.
    let outer = vec![
        DVec2::new(0., 0.),
        DVec2::new(7., 0.),
        DVec2::new(7., 7.),
        DVec2::new(0., 7.),
    ];
    let p = Polygon::new(outer, vec![square(2., 2.), square(2., 4.)]);
    assert_eq!(straight_skeleton(&p).unwrap().faces.len(), 12);
}

#[test]
fn invalid_inputs_are_errors() {
    let bow = poly(&[(0., 0.), (6., 4.), (6., 0.), (0., 2.)]);
    assert!(matches!(
        straight_skeleton(&bow),
        Err(SkeletonError::SelfIntersection { .. })
    ));
    let spike = poly(&[
        (0., 0.),
        (4., 0.),
        (4., 4.),
        (2., 4.),
        (2., 8.),
        (2., 4.),
        (0., 4.),
    ]);
    assert!(matches!(
        straight_skeleton(&spike),
        Err(SkeletonError::Spike { .. })
    ));
    let nan = poly(&[(0., 0.), (f64::NAN, 0.), (4., 4.)]);
    assert!(matches!(
        straight_skeleton(&nan),
        Err(SkeletonError::NonFinite { .. })
    ));
    assert!(straight_skeleton(&poly(&[(0., 0.), (1., 0.)])).is_err());
    assert!(straight_skeleton(&poly(&[(0., 0.), (1., 0.), (2., 0.)])).is_err());
    let outside = Polygon::new(square(0., 0.), vec![square(5., 5.)]);
    assert!(matches!(
        straight_skeleton(&outside),
        Err(SkeletonError::HoleOutside { .. })
    ));
}
