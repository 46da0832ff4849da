//! Roof tests: every shape on synthetic footprints (property tests) and on real ones.

use super::*;
use crate::geometry::skeleton::Skeleton;
use proptest::prelude::*;

fn poly(pts: &[(f64, f64)]) -> Polygon {
    Polygon::new(pts.iter().map(|&(x, y)| DVec2::new(x, y)).collect(), vec![])
}

fn dist_to_boundary(p: &Polygon, q: DVec2) -> f64 {
    p.rings()
        .flat_map(|r| {
            (0..r.len()).map(move |i| {
                let (a, b) = (r[i], r[(i + 1) % r.len()]);
                let ab = b - a;
                let t = ((q - a).dot(ab) / ab.length_squared()).clamp(0.0, 1.0);
                q.distance(a + ab * t)
            })
        })
        .fold(f64::INFINITY, f64::min)
}

fn area2(r: &[DVec3]) -> f64 {
    crate::geometry::ring_signed_area(&r.iter().map(|p| p.truncate()).collect::<Vec<_>>())
}

/// Checks the skeleton contract on `p`; returns the skeleton for further checks.
///
/// An input edge whose vertices the propagation merged into a straight run (a vertex within
/// the collinear tolerance of its neighbours' chord) has the run's plane: its face starts on
/// the run's chord (within that tolerance of its own vertices), and its heights are distances
/// to the chord.
fn check_skeleton(p: &Polygon, sk: &Skeleton) -> Result<(), String> {
    use crate::geometry::skeleton::{collinear_tolerance, DUPLICATE_REL};
    let tol = 1e-3;
    let (lo, hi) = p.bounds();
    let size = (hi - lo).max_element();
    let col = collinear_tolerance(size);
    let mut total = 0.0;
    let rings: Vec<&Vec<DVec2>> = p.rings().collect();
    // The run (chord) each input edge lies on.
    let mut simplified_area = 0.0;
    let runs: Vec<Vec<(DVec2, DVec2)>> = rings
        .iter()
        .map(|r| {
            let keep = crate::geometry::ring::simplified_indices(
                r,
                DUPLICATE_REL * size,
                col,
                crate::geometry::skeleton::COLLINEAR_REL * size,
            )
            .unwrap_or_else(|_| (0..r.len()).collect());
            simplified_area +=
                crate::geometry::ring_signed_area(&keep.iter().map(|&i| r[i]).collect::<Vec<_>>());
            let n = r.len();
            (0..n)
                .map(|ei| {
                    let k = keep
                        .iter()
                        .rposition(|&i| i <= ei)
                        .unwrap_or(keep.len() - 1);
                    (r[keep[k]], r[keep[(k + 1) % keep.len()]])
                })
                .collect()
        })
        .collect();
    let mut seen = std::collections::BTreeSet::new();
    for f in &sk.faces {
        let (ri, ei) = f.edge;
        if !seen.insert(f.edge) {
            return Err(format!("edge {:?} owns two faces", f.edge));
        }
        let r = rings[ri];
        let (a, b) = (r[ei], r[(ei + 1) % r.len()]);
        if f.polygon.iter().any(|q| !q.is_finite()) {
            return Err("NaN".into());
        }
        let start_tol = tol + col;
        if f.polygon[0].truncate().distance(a) > start_tol
            || f.polygon[1].truncate().distance(b) > start_tol
        {
            return Err(format!("face {:?} does not start with its edge", f.edge));
        }
        let (a, b) = runs[ri][ei];
        let ar = area2(&f.polygon);
        if ar <= 1e-9 {
            return Err(format!("face {:?} has area {ar}", f.edge));
        }
        total += ar;
        let n = (b - a).normalize().perp();
        for q in &f.polygon {
            let g = q.truncate();
            if !p.contains(g) && dist_to_boundary(p, g) > tol + col {
                return Err(format!("vertex {g} of face {:?} outside", f.edge));
            }
            let d = (g - a).dot(n);
            if (d - q.z).abs() > tol {
                return Err(format!("face {:?}: vertex {q} at distance {d}", f.edge));
            }
        }
    }
    // The faces tile the footprint without its merged vertices.
    let expect = simplified_area;
    if (total - expect).abs() > 1e-3 * expect {
        return Err(format!("faces cover {total}, footprint {expect}"));
    }
    // Every edge longer than the tolerance owns a face.
    for (ri, r) in rings.iter().enumerate() {
        for ei in 0..r.len() {
            if r[ei].distance(r[(ei + 1) % r.len()]) > 1e-3 && !seen.contains(&(ri, ei)) {
                return Err(format!("edge {:?} owns no face", (ri, ei)));
            }
        }
    }
    Ok(())
}

/// Checks a hipped roof: planar faces, all with the pitch, inside the footprint.
pub(super) fn check_hipped(p: &Polygon, pitch: f64) -> Result<RoofGeometry, String> {
    let sk = straight_skeleton(p).map_err(|e| e.to_string())?;
    check_skeleton(p, &sk)?;
    let roof = hipped(p, pitch).map_err(|e| e.to_string())?;
    for f in &roof.faces {
        let n = f.normal();
        if !n.is_finite() || n.z <= 0.0 {
            return Err(format!("bad normal {n}"));
        }
        let slope = n.z.clamp(-1.0, 1.0).acos().to_degrees();
        // As in `check_shape`: a vertex the skeleton took for straight tilts a face w wide by
        // up to COLLINEAR_ABS / w (a 2 m star's small faces: a few hundredths of a degree).
        let width = area2(&f.outer).abs().sqrt().max(1e-9);
        let tol = SLOPE_TOLERANCE_DEG
            + (2.0 * crate::geometry::skeleton::COLLINEAR_ABS / width).to_degrees();
        if (slope - pitch).abs() > tol {
            return Err(format!("slope {slope} != {pitch} (within {tol}°)"));
        }
        let o = f.outer[0];
        if f.outer.iter().any(|q| (*q - o).dot(n).abs() > 1e-3) {
            return Err("face not planar".into());
        }
    }
    Ok(roof)
}

#[test]
fn rectangle_hips_and_ridge() {
    let (l, w) = (12.0, 5.0);
    let p = poly(&[(0., 0.), (l, 0.), (l, w), (0., w)]);
    let roof = check_hipped(&p, 30.0).unwrap();
    let k = 30f64.to_radians().tan();
    let counts: Vec<usize> = roof.faces.iter().map(|f| f.outer.len()).collect();
    assert_eq!(counts, vec![4, 3, 4, 3]);
    assert!((roof.height - w / 2.0 * k).abs() < 1e-9);
    let ridge: Vec<DVec3> = roof.faces[0]
        .outer
        .iter()
        .copied()
        .filter(|p| (p.z - w / 2.0 * k).abs() < 1e-9)
        .collect();
    assert_eq!(ridge.len(), 2);
    assert!((ridge[0].distance(ridge[1]) - (l - w)).abs() < 1e-9);
}

#[test]
fn square_has_one_apex() {
    let p = poly(&[(0., 0.), (6., 0.), (6., 6.), (0., 6.)]);
    let roof = check_hipped(&p, 45.0).unwrap();
    assert_eq!(roof.faces.len(), 4);
    for f in &roof.faces {
        assert_eq!(f.outer.len(), 3);
        assert!(f.outer[2].distance(DVec3::new(3., 3., 3.)) < 1e-9);
    }
}

#[test]
fn letter_shapes() {
    let shapes: Vec<Vec<(f64, f64)>> = vec![
        // L
        vec![
            (0., 0.),
            (10., 0.),
            (10., 4.),
            (4., 4.),
            (4., 10.),
            (0., 10.),
        ],
        // T
        vec![
            (3., 0.),
            (7., 0.),
            (7., 6.),
            (10., 6.),
            (10., 10.),
            (0., 10.),
            (0., 6.),
            (3., 6.),
        ],
        // U
        vec![
            (0., 0.),
            (10., 0.),
            (10., 8.),
            (7., 8.),
            (7., 3.),
            (3., 3.),
            (3., 8.),
            (0., 8.),
        ],
        // H
        vec![
            (0., 0.),
            (3., 0.),
            (3., 4.),
            (7., 4.),
            (7., 0.),
            (10., 0.),
            (10., 10.),
            (7., 10.),
            (7., 6.),
            (3., 6.),
            (3., 10.),
            (0., 10.),
        ],
        // collinear vertices on every side
        vec![
            (0., 0.),
            (5., 0.),
            (10., 0.),
            (10., 3.),
            (10., 6.),
            (5., 6.),
            (0., 6.),
            (0., 2.),
        ],
        // near-collinear vertex (1 µm off)
        vec![(0., 0.), (5., 1e-6), (10., 0.), (10., 6.), (0., 6.)],
        // tiny edge
        vec![
            (0., 0.),
            (10., 0.),
            (10., 6.),
            (5.001, 6.),
            (5., 6.001),
            (0., 6.),
        ],
    ];
    for s in shapes {
        if let Err(e) = check_hipped(&poly(&s), 35.0) {
            panic!("{s:?}: {e}");
        }
    }
}

#[test]
fn regular_100_gon() {
    let pts: Vec<(f64, f64)> = (0..100)
        .map(|i| {
            let a = i as f64 / 100.0 * std::f64::consts::TAU;
            (20.0 * a.cos(), 20.0 * a.sin())
        })
        .collect();
    let roof = check_hipped(&poly(&pts), 40.0).unwrap();
    assert_eq!(roof.faces.len(), 100);
    let apothem = 20.0 * (std::f64::consts::PI / 100.0).cos();
    assert!((roof.height - apothem * 40f64.to_radians().tan()).abs() < 1e-6);
}

#[test]
fn a_round_tower_drawn_by_hand_rises_to_one_apex() {
    // A 36-gon of radius 4.4 m whose vertices wander by up to 2 cm, as a tower is drawn on a
    // map: its skeleton's inner nodes scatter over centimetres; every profile roof rises to
    // the deepest node, in one triangle (or band) per side.
    let pts: Vec<(f64, f64)> = (0..36)
        .map(|i| {
            let a = i as f64 / 36.0 * std::f64::consts::TAU;
            let r = 4.4 + 0.02 * ((i * 7 % 11) as f64 / 10.0 - 0.5);
            (r * a.cos(), r * a.sin())
        })
        .collect();
    let p = poly(&pts);
    for shape in [RoofShape::Hipped, RoofShape::Gabled, RoofShape::Mansard] {
        let roof = build(&p, shape, 35.0, None).unwrap();
        let top = roof
            .faces
            .iter()
            .flat_map(|f| f.outer.iter())
            .copied()
            .max_by(|a, b| a.z.total_cmp(&b.z))
            .unwrap();
        let at_top: Vec<&Face> = roof
            .faces
            .iter()
            .filter(|f| f.outer.contains(&top))
            .collect();
        assert_eq!(
            at_top.len(),
            36,
            "{shape:?}: every side's face meets at the apex"
        );
        assert!(at_top.iter().all(|f| f.outer.len() == 3), "{shape:?}");
        assert!(
            top.truncate().length() < 0.05,
            "{shape:?}: apex near the centre"
        );
    }
    // An elongated octagon (a rectangle with cut corners) keeps its ridge.
    let oct = poly(&[
        (1.0, 0.0),
        (19.0, 0.0),
        (20.0, 1.0),
        (20.0, 7.0),
        (19.0, 8.0),
        (1.0, 8.0),
        (0.0, 7.0),
        (0.0, 1.0),
    ]);
    let roof = build(&oct, RoofShape::Hipped, 35.0, None).unwrap();
    let top_z = roof.height;
    let tops: Vec<DVec3> = roof
        .faces
        .iter()
        .flat_map(|f| f.outer.iter())
        .copied()
        .filter(|q| (q.z - top_z).abs() < 1e-9)
        .collect();
    let span = tops.iter().map(|q| q.x).fold(f64::NEG_INFINITY, f64::max)
        - tops.iter().map(|q| q.x).fold(f64::INFINITY, f64::min);
    assert!(span > 10.0, "ridge of {span} m");
}

#[test]
fn comb_with_ten_teeth() {
    let mut pts = vec![(0.0, 0.0), (39.0, 0.0)];
    for i in (0..10).rev() {
        let x = i as f64 * 4.0;
        pts.push((x + 3.0, 3.0));
        pts.push((x + 3.0, 10.0));
        pts.push((x, 10.0));
        if i > 0 {
            pts.push((x, 3.0));
        }
    }
    // close: last tooth's left side goes down to (0, 0)
    let roof = check_hipped(&poly(&pts), 30.0).unwrap();
    assert_eq!(roof.faces.len(), pts.len());
}

#[test]
fn courtyard_hole() {
    let p = Polygon::new(
        vec![
            DVec2::new(0., 0.),
            DVec2::new(20., 0.),
            DVec2::new(20., 14.),
            DVec2::new(0., 14.),
        ],
        vec![vec![
            DVec2::new(6., 5.),
            DVec2::new(14., 5.),
            DVec2::new(14., 9.),
            DVec2::new(6., 9.),
        ]],
    );
    let roof = check_hipped(&p, 30.0).unwrap();
    assert_eq!(roof.faces.len(), 8);
}

#[test]
fn flat_and_pyramid_and_scaling() {
    let p = poly(&[(0., 0.), (8., 0.), (8., 6.), (0., 6.)]);
    let f = flat(&p);
    assert_eq!(f.faces.len(), 1);
    assert_eq!(f.height, 0.0);
    let py = pyramidal(&p, 3.0).unwrap();
    assert_eq!(py.faces.len(), 4);
    assert!(py.faces.iter().all(|f| f.normal().z > 0.0));
    assert!((py.height - 3.0).abs() < 1e-12);
    let s = py.scaled_to_height(6.0).translated_z(10.0);
    assert!(s
        .faces
        .iter()
        .flat_map(|f| &f.outer)
        .all(|p| p.z >= 10.0 && p.z <= 16.0 + 1e-9));
    let l = poly(&[
        (0., 0.),
        (10., 0.),
        (10., 1.),
        (1., 1.),
        (1., 10.),
        (0., 10.),
    ]);
    assert_eq!(pyramidal(&l, 3.0), Err(RoofError::NotStarShaped));
    assert!(hipped(&p, 90.0).is_err());
}

#[test]
fn gabled_rectangle() {
    let p = poly(&[(0., 0.), (12., 0.), (12., 5.), (0., 5.)]);
    let g = gabled(&p, 45.0).unwrap();
    assert_eq!(g.faces.len(), 2);
    assert_eq!(g.gable_walls.len(), 2);
    for f in &g.faces {
        let n = f.normal();
        assert!((n.z.acos().to_degrees() - 45.0).abs() < 1e-6);
        assert!(f
            .outer
            .iter()
            .all(|q| (*q - f.outer[0]).dot(n).abs() < 1e-9));
    }
    for w in &g.gable_walls {
        let n = w.normal();
        assert!(n.z.abs() < 1e-9);
        // Outward: away from the centre.
        let c = w.outer.iter().map(|p| p.truncate()).sum::<DVec2>() / 3.0;
        assert!(n.truncate().dot(c - DVec2::new(6., 2.5)) > 0.0);
    }
    // A square is gabled too (its four hips meet in one apex: two opposite ends become the
    // gables, the first side's and the third's).
    let sq = gabled(&poly(&[(0., 0.), (5., 0.), (5., 5.), (0., 5.)]), 45.0).unwrap();
    assert_eq!(sq.faces.len(), 2);
    assert_eq!(sq.gable_walls.len(), 2);
    assert!((sq.height - 2.5).abs() < 1e-9);
}

// ---- generated footprints ----

/// An x-monotone rectilinear polygon: columns of given widths, each spanning [lo, hi],
/// overlapping its neighbour. Many right angles, collinear vertices and simultaneous events.
fn histogram(cols: &[(u8, u8, u8)]) -> Vec<DVec2> {
    let mut x = vec![0.0];
    let mut spans = Vec::new();
    for &(w, lo, h) in cols {
        x.push(x[x.len() - 1] + 1.0 + w as f64);
        spans.push((lo as f64, lo as f64 + 1.0 + h as f64));
    }
    // Make each column overlap the previous one by at least 1.
    for i in 1..spans.len() {
        let a = spans[i - 1];
        let b = &mut spans[i];
        if b.0 > a.1 - 1.0 {
            b.0 = a.1 - 1.0;
        }
        if b.1 < a.0 + 1.0 {
            b.1 = a.0 + 1.0;
        }
    }
    let mut pts = Vec::new();
    for (i, s) in spans.iter().enumerate() {
        pts.push(DVec2::new(x[i], s.0));
        pts.push(DVec2::new(x[i + 1], s.0));
    }
    for (i, s) in spans.iter().enumerate().rev() {
        pts.push(DVec2::new(x[i + 1], s.1));
        pts.push(DVec2::new(x[i], s.1));
    }
    pts.dedup();
    pts
}

/// A union of unit cells grown from (0, 0) on a 7 × 7 grid: general rectilinear shapes
/// (spirals, G, comb), courtyards included. `None` when two cells touch only at a corner
/// (the boundary would not be simple).
fn cell_union(steps: &[(u8, u8)], carve: bool) -> Option<Polygon> {
    const K: i32 = 7;
    let mut cells = vec![(0i32, 0i32)];
    if carve {
        // A full block with cells taken out: courtyards and notches.
        cells = (0..K * K).map(|i| (i % K, i / K)).collect();
        for &(pick, _) in steps {
            if cells.len() > 1 {
                cells.remove(pick as usize % cells.len());
            }
        }
    }
    for &(pick, dir) in steps.iter().filter(|_| !carve) {
        let (x, y) = cells[pick as usize % cells.len()];
        let (dx, dy) = [(1, 0), (0, 1), (-1, 0), (0, -1)][dir as usize % 4];
        let c = (x + dx, y + dy);
        if c.0 >= 0 && c.1 >= 0 && c.0 < K && c.1 < K && !cells.contains(&c) {
            cells.push(c);
        }
    }
    // Directed boundary edges: each cell's CCW edges, shared ones cancel.
    let mut edges: std::collections::BTreeSet<((i32, i32), (i32, i32))> = Default::default();
    for &(x, y) in &cells {
        let c = [(x, y), (x + 1, y), (x + 1, y + 1), (x, y + 1)];
        for i in 0..4 {
            let (a, b) = (c[i], c[(i + 1) % 4]);
            if !edges.remove(&(b, a)) {
                edges.insert((a, b));
            }
        }
    }
    let mut next = std::collections::BTreeMap::new();
    for &(a, b) in &edges {
        if next.insert(a, b).is_some() {
            return None;
        }
    }
    let mut rings = Vec::new();
    let mut left = next.clone();
    while let Some((&s, _)) = left.iter().next() {
        let mut ring = vec![s];
        let mut cur = left.remove(&s)?;
        while cur != s {
            ring.push(cur);
            cur = left.remove(&cur)?;
        }
        rings.push(
            ring.iter()
                .map(|&(x, y)| DVec2::new(x as f64, y as f64))
                .collect::<Vec<_>>(),
        );
    }
    let outer_ix = (0..rings.len()).max_by(|&i, &j| {
        crate::geometry::ring_signed_area(&rings[i])
            .total_cmp(&crate::geometry::ring_signed_area(&rings[j]))
    })?;
    let outer = rings.remove(outer_ix);
    if rings
        .iter()
        .any(|r| crate::geometry::ring_signed_area(r) > 0.0)
    {
        return None; // several components
    }
    Some(Polygon::new(outer, rings))
}

fn cases() -> u32 {
    std::env::var("PROPTEST_CASES")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(2000)
}

proptest! {
    #![proptest_config(ProptestConfig { cases: cases(), ..ProptestConfig::default() })]

    #[test]
    fn hipped_orthogonal(
        cols in prop::collection::vec((0u8..5, 0u8..6, 0u8..7), 1..8),
        angle in prop_oneof![Just(0.0), 0.0..std::f64::consts::TAU],
        scale in 0.5f64..20.0,
        pitch in 10.0f64..60.0,
    ) {
        let pts = histogram(&cols);
        let (s, c) = angle.sin_cos();
        let pts: Vec<DVec2> = pts.iter()
            .map(|p| DVec2::new(c * p.x - s * p.y, s * p.x + c * p.y) * scale + DVec2::new(5e5, 4e6))
            .collect();
        // Work in a local frame, as the pipeline does.
        let p = Polygon::new(pts, vec![]).translated(DVec2::new(-5e5, -4e6));
        if let Err(e) = check_hipped(&p, pitch) {
            return Err(TestCaseError::fail(format!("{e}: {:?}", p.outer)));
        }
    }

    #[test]
    fn hipped_cell_union(
        steps in prop::collection::vec((0u8..255, 0u8..4), 1..30),
        carve in any::<bool>(),
        angle in prop_oneof![Just(0.0), 0.0..std::f64::consts::TAU],
        scale in 1.0f64..15.0,
        pitch in 10.0f64..60.0,
    ) {
        let Some(p) = cell_union(&steps, carve) else { return Ok(()); };
        let (s, c) = angle.sin_cos();
        let rot = |r: &Vec<DVec2>| -> Vec<DVec2> {
            r.iter().map(|p| DVec2::new(c * p.x - s * p.y, s * p.x + c * p.y) * scale).collect()
        };
        let p = Polygon::new(rot(&p.outer), p.holes.iter().map(rot).collect());
        if let Err(e) = check_hipped(&p, pitch) {
            return Err(TestCaseError::fail(format!("{e}: {:?} {:?}", p.outer, p.holes)));
        }
    }

    #[test]
    fn hipped_star(
        pts in prop::collection::vec((0.0f64..1.0, 0.2f64..1.0), 3..24),
        size in 2.0f64..60.0,
        pitch in 10.0f64..60.0,
    ) {
        let n = pts.len();
        // Angles: evenly spread sectors with jitter, so they stay ordered.
        let ring: Vec<DVec2> = pts.iter().enumerate().map(|(i, &(j, r))| {
            let a = (i as f64 + 0.1 + 0.8 * j) / n as f64 * std::f64::consts::TAU;
            DVec2::new(a.cos(), a.sin()) * r * size
        }).collect();
        let p = Polygon::new(ring, vec![]);
        if let Err(e) = check_hipped(&p, pitch) {
            return Err(TestCaseError::fail(format!("{e}: {:?}", p.outer)));
        }
    }
}

// ---- every shape: the invariants of issue 4 on the built part ----

fn roof_cases() -> u32 {
    std::env::var("PROPTEST_CASES")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(if cfg!(debug_assertions) { 1000 } else { 10000 })
}

/// Builds `shape` on `p` through massing and checks the part ([`crate::derive::massing::check_part`])
/// and the slopes: hipped and gabled faces all at `pitch`, mansard faces at one of its two
/// pitches.
pub(super) fn check_shape(p: &Polygon, shape: RoofShape, pitch: f64) -> Result<(), String> {
    check_oriented(p, shape, pitch, None, false)
}

/// [`check_shape`] with `roof:direction` (a bearing, degrees) and `roof:orientation=across`;
/// the slopes are checked only without them (a turned skeleton roof has steeper ends, see
/// `shapes::turned_profile_roof`).
pub(super) fn check_oriented(
    p: &Polygon,
    shape: RoofShape,
    pitch: f64,
    bearing: Option<f64>,
    across: bool,
) -> Result<(), String> {
    use crate::derive::massing::{build_part, check_part, roof_geometry, Mass};
    let m = Mass {
        footprint: p.clone(),
        base_z: 0.0,
        eave_z: 5.0,
        storeys: 2,
        roof: shape,
        roof_angle_deg: pitch,
        roof_direction: bearing,
        roof_across: across,
        roof_height: None,
        wall_color: crate::color::Color::WHITE,
        roof_color: crate::color::Color::GREY,
    };
    let r = match roof_geometry(&m) {
        Ok(r) => r,
        // A roof under 5 cm (a sliver of a footprint at a low pitch) is drawn flat on
        // purpose; only that fallback is allowed.
        Err(f) if f.reason.starts_with("roof would be") => return Ok(()),
        Err(f) => return Err(format!("{shape:?} fell back: {}", f.reason)),
    };
    let part = build_part("p0".into(), &m, &r, crate::model::Lod::Lod2);
    // Known weakness (reported, not hidden in the data-set test's ratchet): the skeleton can
    // emit nodes just beyond the weld distance, leaving one edge shared by 4 or 6 faces
    // ("used n times, reverse n times"); every use still has its reverse, so the shell is
    // watertight there, but not 2-manifold.
    let balanced = |l: &str| {
        let tail: Vec<&str> = l
            .rsplit("used ")
            .next()
            .unwrap_or("")
            .split_whitespace()
            .collect();
        tail.len() == 5 && tail[1] == "times," && tail[2] == "reverse" && tail[0] == tail[3]
    };
    let d: Vec<String> = check_part(&part)
        .into_iter()
        .filter(|l| !balanced(l))
        .collect();
    if !d.is_empty() {
        return Err(format!("{shape:?}: {}", d[..d.len().min(5)].join("; ")));
    }
    if bearing.is_some() || across {
        return Ok(());
    }
    let slopes: Vec<f64> = match shape {
        RoofShape::Hipped | RoofShape::Gabled => vec![pitch],
        RoofShape::Mansard => vec![shapes::MANSARD_LOWER_DEG, shapes::MANSARD_UPPER_DEG],
        _ => return Ok(()),
    };
    // A footprint vertex that the skeleton took for straight lies up to its collinear
    // tolerance off the plane's eave line (a vertex a millimetre off a straight wall once on
    // the grid): moving a corner of a face w wide by d tilts it by up to d / w. The slope must
    // match to 0.01° plus twice that tilt (a 1 m face: 0.58°; a 10 m one: 0.06°).
    let moved = crate::geometry::skeleton::COLLINEAR_ABS;
    // A round outline rises to one apex (`shapes::to_one_apex`): its faces' pitches are off
    // by up to the angle the apex's move makes.
    let apex_tol = if r.has_one_apex() {
        RoofGeometry::one_apex_pitch_tolerance(slopes[0])
    } else {
        0.0
    };
    for f in &r.faces {
        let s = f.normal().z.clamp(-1.0, 1.0).acos().to_degrees();
        let width = area2(&f.outer).abs().sqrt().max(1e-9);
        let tol = SLOPE_TOLERANCE_DEG + (2.0 * moved / width).to_degrees() + apex_tol;
        if !slopes.iter().any(|x| (s - x).abs() < tol) {
            return Err(format!(
                "{shape:?}: face slope {s}, expected one of {slopes:?} (within {tol}°)"
            ));
        }
    }
    Ok(())
}

/// How far a face's slope may be from the pitch, in degrees, besides the tilt of the
/// skeleton's node merge (see `check_shape`).
const SLOPE_TOLERANCE_DEG: f64 = 0.01;

const CHECKED: [RoofShape; 3] = [RoofShape::Hipped, RoofShape::Gabled, RoofShape::Mansard];

/// Every shape of the catalogue but flat: each property case checks [`CHECKED`] and one of
/// these (picked by the case), so that every shape meets every kind of footprint over a run.
const ALL_PITCHED: [RoofShape; 21] = [
    RoofShape::Skillion,
    RoofShape::Gabled,
    RoofShape::Hipped,
    RoofShape::HalfHipped,
    RoofShape::SideHipped,
    RoofShape::Pyramidal,
    RoofShape::Mansard,
    RoofShape::Gambrel,
    RoofShape::Saltbox,
    RoofShape::Dome,
    RoofShape::Onion,
    RoofShape::Round,
    RoofShape::Cone,
    RoofShape::GabledHeightMoved,
    RoofShape::SideHalfHipped,
    RoofShape::HippedAndGabled,
    RoofShape::BellcastGable,
    RoofShape::Crosspitched,
    RoofShape::Sawtooth,
    RoofShape::Butterfly,
    RoofShape::ApseGabled,
];

/// The shapes a property case checks: [`CHECKED`] and `ALL_PITCHED[pick]`.
fn case_shapes(pick: usize) -> impl Iterator<Item = RoofShape> {
    CHECKED
        .into_iter()
        .chain(std::iter::once(ALL_PITCHED[pick % ALL_PITCHED.len()]))
}

proptest! {
    #![proptest_config(ProptestConfig { cases: roof_cases(), ..ProptestConfig::default() })]

    #[test]
    fn shapes_orthogonal(
        cols in prop::collection::vec((0u8..5, 0u8..6, 0u8..7), 1..8),
        angle in prop_oneof![Just(0.0), 0.0..std::f64::consts::TAU],
        scale in 0.5f64..20.0,
        pitch in 10.0f64..60.0,
        pick in 0usize..21,
        turn in prop::option::of(0.0f64..360.0),
        across in any::<bool>(),
    ) {
        let (s, c) = angle.sin_cos();
        let pts: Vec<DVec2> = histogram(&cols).iter()
            .map(|p| DVec2::new(c * p.x - s * p.y, s * p.x + c * p.y) * scale)
            .collect();
        let p = Polygon::new(pts, vec![]);
        for shape in case_shapes(pick) {
            if let Err(e) = check_shape(&p, shape, pitch) {
                return Err(TestCaseError::fail(format!("{e}: {:?}", p.outer)));
            }
        }
        if let Err(e) = check_oriented(&p, ALL_PITCHED[pick % ALL_PITCHED.len()], pitch, turn, across) {
            return Err(TestCaseError::fail(format!("{e} ({turn:?}, across {across}): {:?}", p.outer)));
        }
    }

    #[test]
    fn shapes_cell_union_with_holes(
        steps in prop::collection::vec((0u8..255, 0u8..4), 1..30),
        carve in any::<bool>(),
        angle in prop_oneof![Just(0.0), 0.0..std::f64::consts::TAU],
        scale in 1.0f64..15.0,
        pitch in 10.0f64..60.0,
        pick in 0usize..21,
        turn in prop::option::of(0.0f64..360.0),
        across in any::<bool>(),
    ) {
        let Some(p) = cell_union(&steps, carve) else { return Ok(()); };
        let (s, c) = angle.sin_cos();
        let rot = |r: &Vec<DVec2>| -> Vec<DVec2> {
            r.iter().map(|p| DVec2::new(c * p.x - s * p.y, s * p.x + c * p.y) * scale).collect()
        };
        let p = Polygon::new(rot(&p.outer), p.holes.iter().map(rot).collect());
        for shape in case_shapes(pick) {
            if let Err(e) = check_shape(&p, shape, pitch) {
                return Err(TestCaseError::fail(format!("{e}: {:?} {:?}", p.outer, p.holes)));
            }
        }
        if let Err(e) = check_oriented(&p, ALL_PITCHED[pick % ALL_PITCHED.len()], pitch, turn, across) {
            return Err(TestCaseError::fail(format!(
                "{e} ({turn:?}, across {across}): {:?} {:?}", p.outer, p.holes
            )));
        }
    }

    #[test]
    fn shapes_general(
        pts in prop::collection::vec((0.0f64..1.0, 0.2f64..1.0), 3..24),
        size in 2.0f64..60.0,
        pitch in 10.0f64..60.0,
        pick in 0usize..21,
        hole in any::<bool>(),
        turn in prop::option::of(0.0f64..360.0),
        across in any::<bool>(),
    ) {
        let n = pts.len();
        let ring: Vec<DVec2> = pts.iter().enumerate().map(|(i, &(j, r))| {
            let a = (i as f64 + 0.1 + 0.8 * j) / n as f64 * std::f64::consts::TAU;
            DVec2::new(a.cos(), a.sin()) * r * size
        }).collect();
        // A small square hole at the centre when the disc around it that holds the square
        // lies inside the star.
        let outer = Polygon::new(ring.clone(), vec![]);
        let h = 0.05 * size;
        let holes = if hole
            && outer.contains(DVec2::ZERO)
            && dist_to_boundary(&outer, DVec2::ZERO) > 2.0 * h
        {
            vec![vec![DVec2::new(-h, -h), DVec2::new(-h, h), DVec2::new(h, h), DVec2::new(h, -h)]]
        } else {
            vec![]
        };
        let p = Polygon::new(ring, holes);
        for shape in case_shapes(pick) {
            if let Err(e) = check_shape(&p, shape, pitch) {
                return Err(TestCaseError::fail(format!("{e}: {:?}", p.outer)));
            }
        }
        if let Err(e) = check_oriented(&p, ALL_PITCHED[pick % ALL_PITCHED.len()], pitch, turn, across) {
            return Err(TestCaseError::fail(format!("{e} ({turn:?}, across {across}): {:?}", p.outer)));
        }
    }
}

mod real_footprints;

/// Distinct planes among faces (unit normals and offsets within 1e-6).
pub(super) fn planes(faces: &[Face]) -> usize {
    let mut seen: Vec<(DVec3, f64)> = Vec::new();
    for f in faces {
        let n = f.normal();
        let d = n.dot(f.outer[0]);
        if !seen
            .iter()
            .any(|(m, e)| m.distance(n) < 1e-6 && (e - d).abs() < 1e-6)
        {
            seen.push((n, d));
        }
    }
    seen.len()
}

/// Gable ends: gable walls, those in one plane that share a corner counted once (a side with
/// a collinear vertex has two walls under one gable).
pub(super) fn gable_ends(walls: &[Face]) -> usize {
    let n = walls.len();
    let mut rep: Vec<usize> = (0..n).collect();
    for i in 0..n {
        for j in 0..i {
            let same_plane = planes(&[walls[i].clone(), walls[j].clone()]) == 1;
            let touch = walls[i]
                .outer
                .iter()
                .any(|p| walls[j].outer.iter().any(|q| p.distance(*q) < 1e-9));
            if same_plane && touch {
                let (a, b) = (rep[i], rep[j]);
                for r in rep.iter_mut() {
                    if *r == a {
                        *r = b;
                    }
                }
            }
        }
    }
    rep.sort_unstable();
    rep.dedup();
    rep.len()
}

mod corpus;

#[test]
fn a_side_drawn_in_two_pieces_off_straight_still_ends_in_a_gable() {
    // A 31 x 33 m block (Monaco's way/572948281, moved to the origin) whose north side is
    // three pieces, the corners of the parts drawn along it: the first piece turns 0.09° (7 mm
    // off the chord, beyond the skeleton's collinear tolerance), so its face closes early, at
    // t = 4.4 m, below the end's apex. Gabled, the side is still one gable end.
    let pts = [
        (26.6317, 24.5552),
        (22.3003, 23.7924),
        (0.7650, 20.0318),
        (-4.2855, 19.1493),
        (1.4578, -13.7236),
        (32.3826, -8.3511),
    ];
    let p = poly(&pts);
    for shape in [RoofShape::Gabled, RoofShape::HalfHipped, RoofShape::Gambrel] {
        let r = build(&p, shape, 35.0, None).unwrap();
        let want = if shape == RoofShape::Gabled { 2 } else { 4 };
        assert_eq!(r.faces.len(), want, "{shape:?}: {:?}", r.faces);
        // Walls under the north side's three pieces and one under the south side.
        assert_eq!(r.gable_walls.len(), 4, "{shape:?}");
        let north = r
            .gable_walls
            .iter()
            .filter(|w| w.outer.iter().all(|q| q.y > 15.0))
            .count();
        assert_eq!(north, 3, "{shape:?}");
    }
}

#[test]
fn a_square_takes_half_hips_at_two_opposite_ends() {
    // A 6.4 m square (Clifton's shp/515, moved to the origin), a few centimetres off true.
    let pts = [
        (-4.1484, -1.7574),
        (2.0167, -3.4719),
        (3.7311, 2.6931),
        (-2.4339, 4.4076),
    ];
    let p = poly(&pts);
    let r = build(&p, RoofShape::HalfHipped, 35.0, None).unwrap();
    // Two slopes and two small hips; two trapezoid walls, cut at HALF_HIP_FRACTION of the
    // gable's height.
    assert_eq!(r.faces.len(), 4);
    assert_eq!(r.faces.iter().filter(|f| f.outer.len() == 3).count(), 2);
    assert_eq!(r.gable_walls.len(), 2);
    let top = r.height;
    for w in &r.gable_walls {
        assert_eq!(w.outer.len(), 4);
        let h = w.outer.iter().map(|q| q.z).fold(0.0, f64::max);
        assert!(
            (h / top - shapes::HALF_HIP_FRACTION).abs() < 0.01,
            "{h} of {top}"
        );
    }
    // Closed: every face edge has its twin among the faces and walls, or lies on the eave.
    let mut all: Vec<Face> = r.faces.clone();
    all.extend(r.gable_walls.iter().cloned());
    let k = |q: DVec3| {
        (
            (q * 1e6).round().x as i64,
            (q * 1e6).round().y as i64,
            (q * 1e6).round().z as i64,
        )
    };
    let mut edges = std::collections::HashMap::new();
    for f in &all {
        let n = f.outer.len();
        for i in 0..n {
            *edges
                .entry((k(f.outer[i]), k(f.outer[(i + 1) % n])))
                .or_insert(0) += 1;
        }
    }
    for (a, b) in edges.keys() {
        let on_eave = a.2 == 0 && b.2 == 0;
        assert!(
            on_eave || edges.contains_key(&(*b, *a)),
            "edge {a:?} {b:?} alone"
        );
    }
}

/// The star ring of `shapes_general`: point i at angle (i + 0.1 + 0.8 j) / n of a turn and
/// radius r, scaled by `size`.
fn star(pts: &[(f64, f64)], size: f64) -> Polygon {
    let n = pts.len();
    let ring: Vec<DVec2> = pts
        .iter()
        .enumerate()
        .map(|(i, &(j, r))| {
            let a = (i as f64 + 0.1 + 0.8 * j) / n as f64 * std::f64::consts::TAU;
            DVec2::new(a.cos(), a.sin()) * r * size
        })
        .collect();
    Polygon::new(ring, vec![])
}

#[test]
fn a_small_arc_with_a_spur_closes_its_gabled_roof() {
    // Found by `shapes_general` in CI (2026-12-04): a 16-sided arc of 0.43 m radius and a
    // spur of five points, 2.1 m across, gabled at 33°, left a 3 mm triangle of the roof open.
    let mut pts = vec![(0.0, 0.2); 16];
    pts.extend([
        (0.25406973368238495, 0.20936447601288027),
        (0.6132069981254028, 0.5343493446644739),
        (0.6306154509226558, 0.46027327809836055),
        (0.9048405364692078, 0.435278086050924),
        (0.9967843047503764, 0.22906785220971468),
        (0.0, 0.2),
    ]);
    let p = star(&pts, 2.1381250817159962);
    for shape in CHECKED {
        if let Err(e) = check_shape(&p, shape, 33.02319772424959) {
            panic!("{e}");
        }
    }
}
mod catalogue;

/// A property case (seed-dependent, found by `shapes_orthogonal`): a barrel roof turned across
/// a small T of two wings leaves a sliver face 12 mm wide at the crown; on the grid it lies
/// within a millimetre of its least-squares plane (val3dity's measure), though 1 cm off the
/// plane of its Newell normal, which the check used to take.
#[test]
fn round_roof_turned_across_a_small_t_is_planar() {
    let cols = [(3u8, 2u8, 1u8), (3, 0, 5)];
    let pts: Vec<DVec2> = histogram(&cols).iter().map(|p| *p * 0.5).collect();
    let p = Polygon::new(pts, vec![]);
    for turn in [None, Some(90.0)] {
        check_oriented(&p, RoofShape::Round, 10.0, turn, true).unwrap();
    }
}

/// A proptest case of `shapes_cell_union_with_holes` (December 2026): a moved-ridge gable
/// turned to a bearing on a small stepped cell union at 10°. Its corners project onto the
/// ridge's normal closer together than twice the clearance (17 cm at that slope) all across
/// the ridge's 5 % reach, so no place was clear and the ridge stayed where it was, 6 mm from a
/// straight-through corner that then fell out of the roof's outline (an open edge). The ridge
/// now takes the place within reach farthest from every corner.
#[test]
fn moved_ridge_gable_turned_on_a_stepped_union() {
    let steps = [
        (0, 0),
        (55, 0),
        (64, 1),
        (30, 0),
        (114, 1),
        (130, 0),
        (47, 0),
        (83, 1),
        (224, 2),
        (13, 0),
        (10, 0),
    ];
    let p = cell_union(&steps, false).unwrap();
    let (angle, scale) = (4.087742393367577f64, 1.038530710917864);
    let (s, c) = angle.sin_cos();
    let rot = |r: &Vec<DVec2>| -> Vec<DVec2> {
        r.iter()
            .map(|p| DVec2::new(c * p.x - s * p.y, s * p.x + c * p.y) * scale)
            .collect()
    };
    let p = Polygon::new(rot(&p.outer), p.holes.iter().map(rot).collect());
    check_oriented(
        &p,
        RoofShape::GabledHeightMoved,
        10.0,
        Some(114.70061894910762),
        false,
    )
    .unwrap();
}

/// A `shapes_general` case on a random seed (December 2026): a pyramid over a nine-point star
/// 8.8 m across at 10°, whose outline turns back on itself at two near-collinear corners.
#[test]
fn pyramid_over_a_nine_point_star() {
    let pts = [
        (0.3611125150386453, 0.4891053891869367),
        (0.9237854848121274, 0.336215633292744),
        (0.9913003795727122, 0.8414685661351231),
        (0.5677965863749853, 0.8962287471263827),
        (0.8034768981410844, 0.9332281012633152),
        (0.206408754367298, 0.22711611369512677),
        (0.1913798013927692, 0.5230513777543668),
        (0.9643083743523202, 0.6545431521399907),
        (0.35605523364038205, 0.3730511273442392),
    ];
    let p = star(&pts, 8.841111875221241);
    for shape in case_shapes(5) {
        check_shape(&p, shape, 10.0).unwrap_or_else(|e| panic!("{shape:?}: {e}"));
    }
    check_oriented(&p, RoofShape::Pyramidal, 10.0, None, false).unwrap();
}
