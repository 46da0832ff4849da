//! Unit tests: every roof shape on a rectangle, an L and a courtyard block builds a closed,
//! planar part whose walls meet the roof.

use super::*;

fn poly(pts: &[(f64, f64)]) -> Polygon {
    Polygon::new(pts.iter().map(|&(x, y)| DVec2::new(x, y)).collect(), vec![])
}

pub(crate) fn mass(footprint: Polygon, roof: RoofShape) -> Mass {
    Mass {
        footprint,
        base_z: 0.0,
        eave_z: 6.0,
        storeys: 2,
        roof,
        roof_angle_deg: 35.0,
        roof_direction: None,
        roof_across: false,
        roof_height: None,
        wall_color: Color::WHITE,
        roof_color: Color::GREY,
    }
}

pub(crate) const ALL: [RoofShape; 22] = [
    RoofShape::Flat,
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

fn rect() -> Polygon {
    poly(&[(0., 0.), (12., 0.), (12., 6.), (0., 6.)])
}

fn ell() -> Polygon {
    poly(&[
        (0., 0.),
        (16., 0.),
        (16., 6.),
        (6., 6.),
        (6., 14.),
        (0., 14.),
    ])
}

fn courtyard() -> Polygon {
    Polygon::new(
        vec![
            DVec2::new(0., 0.),
            DVec2::new(20., 0.),
            DVec2::new(20., 16.),
            DVec2::new(0., 16.),
        ],
        vec![vec![
            DVec2::new(6., 6.),
            DVec2::new(14., 6.),
            DVec2::new(14., 10.),
            DVec2::new(6., 10.),
        ]],
    )
}

fn build(p: &Polygon, shape: RoofShape) -> (RoofGeometry, Part) {
    let m = mass(p.clone(), shape);
    let r = match roof_geometry(&m) {
        Ok(r) => r,
        Err(f) => panic!("{shape:?}: fallback {}", f.reason),
    };
    let part = build_part("p0".into(), &m, &r, Lod::Lod2);
    (r, part)
}

/// Walls whose outline rises above the eave (gables, sheds).
fn raised_walls(part: &Part) -> usize {
    part.walls
        .iter()
        .filter(|w| w.outline.outer.iter().any(|p| p.z > w.top_z + 1e-6))
        .count()
}

#[test]
fn every_shape_on_rectangle_l_and_courtyard_is_closed() {
    for (name, p) in [("rect", rect()), ("L", ell()), ("court", courtyard())] {
        for shape in ALL {
            let (_, part) = build(&p, shape);
            let d = check_part(&part);
            assert!(d.is_empty(), "{name} {shape:?}: {}", d.join("\n"));
            assert_eq!(part.roof_shape, shape, "{name}");
        }
    }
}

#[test]
fn gabled_rectangle_has_two_pentagon_walls() {
    let (r, part) = build(&rect(), RoofShape::Gabled);
    assert_eq!(r.faces.len(), 2);
    assert_eq!(r.gable_walls.len(), 2);
    assert!((r.height - 3.0 * 35f64.to_radians().tan()).abs() < 1e-9);
    let pent: Vec<&Wall> = part
        .walls
        .iter()
        .filter(|w| w.outline.outer.len() == 5)
        .collect();
    assert_eq!(pent.len(), 2);
    for w in pent {
        // start-base, end-base, end-eave, apex, start-eave; apex over the middle.
        let o = &w.outline.outer;
        assert_eq!(o[2].z, 6.0);
        assert_eq!(o[4].z, 6.0);
        let mid = (w.start + w.end) / 2.0;
        assert!(o[3].truncate().distance(mid) < 1e-9);
        assert!((o[3].z - part.top_z).abs() < 1e-9);
    }
}

#[test]
fn gabled_l_has_one_gable_per_wing_and_a_hip_at_the_corner() {
    let (r, part) = build(&ell(), RoofShape::Gabled);
    // Two wing ends: x = 16 and y = 14.
    assert_eq!(raised_walls(&part), 2);
    let ends: Vec<DVec2> = r
        .gable_walls
        .iter()
        .map(|w| (w.outer[0].truncate() + w.outer[1].truncate()) / 2.0)
        .collect();
    assert!(ends.contains(&DVec2::new(16., 3.)), "{ends:?}");
    assert!(ends.contains(&DVec2::new(3., 14.)), "{ends:?}");
    // Both ridges at the same height (equal wing widths): width / 2 · tan 35°.
    let h = 3.0 * 35f64.to_radians().tan();
    assert!((r.height - h).abs() < 1e-9);
    // Four roof planes: two per wing, meeting in a valley and a hip.
    assert_eq!(r.faces.len(), 4);
}

#[test]
fn hip_variants_on_rectangle() {
    let (r, part) = build(&rect(), RoofShape::SideHipped);
    assert_eq!(r.gable_walls.len(), 1);
    assert_eq!(raised_walls(&part), 1);
    let (r, _) = build(&rect(), RoofShape::HalfHipped);
    // Two long planes, two small hips, two walls ending in a horizontal cut.
    assert_eq!(r.faces.len(), 4);
    assert_eq!(r.gable_walls.len(), 2);
    for w in &r.gable_walls {
        assert_eq!(w.outer.len(), 4, "{:?}", w.outer);
        let top = w.outer[2].z;
        assert!((w.outer[3].z - top).abs() < 1e-9);
        assert!((top - HALF_HIP_TEST * r.height).abs() < 1e-9);
    }
    let (r, _) = build(&rect(), RoofShape::Hipped);
    assert_eq!(r.faces.len(), 4);
    assert!(r.gable_walls.is_empty());
}

const HALF_HIP_TEST: f64 = crate::derive::roof::shapes::HALF_HIP_FRACTION;

#[test]
fn mansard_and_gambrel_have_two_slopes() {
    use crate::derive::roof::shapes as rs;
    for (shape, lower, upper) in [
        (
            RoofShape::Mansard,
            rs::MANSARD_LOWER_DEG,
            rs::MANSARD_UPPER_DEG,
        ),
        (
            RoofShape::Gambrel,
            rs::GAMBREL_LOWER_DEG,
            rs::GAMBREL_UPPER_DEG,
        ),
    ] {
        for p in [rect(), ell()] {
            let (r, _) = build(&p, shape);
            let mut seen = [false, false];
            for f in &r.faces {
                let s = f.normal().z.acos().to_degrees();
                if (s - lower).abs() < 1e-6 {
                    seen[0] = true;
                } else if (s - upper).abs() < 1e-6 {
                    seen[1] = true;
                } else {
                    panic!("{shape:?}: slope {s}");
                }
            }
            assert_eq!(seen, [true, true], "{shape:?}");
        }
    }
    let (r, _) = build(&rect(), RoofShape::Gambrel);
    assert_eq!(r.gable_walls.len(), 2);
    // The gambrel gable wall has the break points: a heptagon.
    assert!(r.gable_walls.iter().all(|w| w.outer.len() == 5));
}

#[test]
fn skillion_walls_are_trapezoids() {
    let (r, part) = build(&rect(), RoofShape::Skillion);
    assert_eq!(r.faces.len(), 1);
    // Slopes across the short side (y): the wall at y = 0 or y = 6 is the high one.
    let k = 35f64.to_radians().tan();
    assert!((r.height - 6.0 * k).abs() < 1e-9);
    let n = r.faces[0].normal();
    assert!(n.x.abs() < 1e-12 && n.y.abs() > 0.1);
    // Two side walls are trapezoids, one wall is raised to the full height.
    let trapezoids = part
        .walls
        .iter()
        .filter(|w| {
            let o = &w.outline.outer;
            o.len() == 4 && (o[2].z - o[3].z).abs() > 1.0
        })
        .count();
    assert_eq!(trapezoids, 2);
}

#[test]
fn curved_roofs_are_banded() {
    let sq = poly(&[(0., 0.), (10., 0.), (10., 10.), (0., 10.)]);
    let (d, _) = build(&sq, RoofShape::Dome);
    // Hemisphere-like: height = inscribed radius.
    assert!((d.height - 5.0).abs() < 1e-9);
    assert_eq!(d.faces.len(), 4 * crate::derive::roof::shapes::CURVE_BANDS);
    let (o, _) = build(&sq, RoofShape::Onion);
    assert!((o.height - crate::derive::roof::shapes::ONION_HEIGHT_REL * 5.0).abs() < 1e-9);
    let (r, part) = build(&rect(), RoofShape::Round);
    assert_eq!(r.gable_walls.len(), 2);
    assert!((r.height - 3.0).abs() < 1e-9);
    assert_eq!(raised_walls(&part), 2);
    let (c, _) = build(&sq, RoofShape::Cone);
    assert_eq!(c.faces.len(), 4);
    assert!(c.faces.iter().all(|f| f.outer.len() == 3));
    // A pyramid on an L (not star-shaped from its centroid) is hipped, not flat.
    let (py, _) = build(&ell(), RoofShape::Pyramidal);
    assert!(py.height > 1.0);
}

#[test]
fn roof_height_scales_every_shape() {
    for shape in ALL.into_iter().filter(|s| *s != RoofShape::Flat) {
        let mut m = mass(ell(), shape);
        m.roof_height = Some(4.0);
        let r = roof_geometry(&m).unwrap_or_else(|f| panic!("{shape:?}: {}", f.reason));
        assert!((r.height - 4.0).abs() < 1e-9, "{shape:?}");
        let part = build_part("p0".into(), &m, &r, Lod::Lod2);
        assert!((part.top_z - 10.0).abs() < 1e-9);
        assert!(check_part(&part).is_empty(), "{shape:?}");
    }
}

#[test]
fn invalid_footprint_is_an_error_not_a_panic() {
    let bow = poly(&[(0., 0.), (10., 10.), (10., 0.), (0., 10.)]);
    for shape in ALL.into_iter().filter(|s| *s != RoofShape::Flat) {
        assert!(
            roof_geometry(&mass(bow.clone(), shape)).is_err(),
            "{shape:?}"
        );
    }
}

#[test]
fn skillion_slopes_down_towards_roof_direction() {
    let rect = poly(&[(0.0, 0.0), (10.0, 0.0), (10.0, 6.0), (0.0, 6.0)]);
    // (bearing, the horizontal direction the roof must fall towards)
    for (bearing, down) in [
        (90.0, DVec2::X),
        (270.0, -DVec2::X),
        (0.0, DVec2::Y),
        (180.0, -DVec2::Y),
    ] {
        let mut m = mass(rect.clone(), RoofShape::Skillion);
        m.roof_direction = Some(bearing);
        let r = roof_geometry(&m).unwrap();
        let pts: Vec<DVec3> = r
            .faces
            .iter()
            .flat_map(|f| f.outer.iter().copied())
            .collect();
        let high = pts.iter().max_by(|a, b| a.z.total_cmp(&b.z)).unwrap();
        let low = pts.iter().min_by(|a, b| a.z.total_cmp(&b.z)).unwrap();
        let fall = DVec2::new(low.x - high.x, low.y - high.y);
        assert!(
            fall.dot(down) > 0.0,
            "bearing {bearing}: falls towards {fall:?}"
        );
        let part = build_part("p0".into(), &m, &r, Lod::Lod2);
        assert!(check_part(&part).is_empty(), "{:?}", check_part(&part));
    }
}

/// The two planes of a ridge roof: (area-weighted) slopes in degrees, steepest first.
fn plane_slopes(r: &RoofGeometry) -> Vec<f64> {
    let mut s: Vec<f64> = r
        .faces
        .iter()
        .map(|f| f.normal().z.clamp(-1.0, 1.0).acos().to_degrees())
        .collect();
    s.sort_by(|a, b| b.total_cmp(a));
    s.dedup_by(|a, b| (*a - *b).abs() < 1e-6);
    s
}

#[test]
fn saltbox_has_two_unequal_slopes_and_the_long_one_faces_roof_direction() {
    let rect = poly(&[(0.0, 0.0), (12.0, 0.0), (12.0, 8.0), (0.0, 8.0)]);
    let mut m = mass(rect.clone(), RoofShape::Saltbox);
    let r = roof_geometry(&m).unwrap();
    let slopes = plane_slopes(&r);
    assert_eq!(slopes.len(), 2, "{slopes:?}");
    assert!(
        (slopes[0] - 35.0).abs() < 1e-6,
        "the steep side has the pitch: {slopes:?}"
    );
    assert!(slopes[1] < slopes[0] - 5.0, "{slopes:?}");
    // The ridge runs along the long (x) axis: every top vertex has the same y.
    let top = r.height;
    let ridge: Vec<f64> = r
        .faces
        .iter()
        .flat_map(|f| f.outer.iter())
        .filter(|p| (p.z - top).abs() < 1e-9)
        .map(|p| p.y)
        .collect();
    assert!(
        ridge.len() >= 2 && ridge.iter().all(|y| (y - ridge[0]).abs() < 1e-6),
        "{ridge:?}"
    );
    let part = build_part("p0".into(), &m, &r, Lod::Lod2);
    assert!(check_part(&part).is_empty(), "{:?}", check_part(&part));
    // roof:direction = south: the long, shallow slope faces south, so the ridge is north of the
    // middle.
    m.roof_direction = Some(180.0);
    let r = roof_geometry(&m).unwrap();
    let ridge_y = r
        .faces
        .iter()
        .flat_map(|f| f.outer.iter())
        .find(|p| (p.z - r.height).abs() < 1e-9)
        .unwrap()
        .y;
    assert!(ridge_y > 4.5, "ridge at y = {ridge_y}");
}

#[test]
fn saltbox_and_across_work_on_an_l_and_a_courtyard() {
    let l = poly(&[
        (0.0, 0.0),
        (20.0, 0.0),
        (20.0, 8.0),
        (8.0, 8.0),
        (8.0, 18.0),
        (0.0, 18.0),
    ]);
    let mut court = poly(&[(0.0, 0.0), (24.0, 0.0), (24.0, 16.0), (0.0, 16.0)]);
    court.holes = vec![vec![
        DVec2::new(8.0, 5.0),
        DVec2::new(8.0, 11.0),
        DVec2::new(16.0, 11.0),
        DVec2::new(16.0, 5.0),
    ]];
    for footprint in [l, court] {
        for (shape, across) in [(RoofShape::Saltbox, false), (RoofShape::Gabled, true)] {
            let mut m = mass(footprint.clone(), shape);
            m.roof_across = across;
            let r = roof_geometry(&m).unwrap();
            let projected: f64 = r
                .faces
                .iter()
                .map(|f| {
                    let ring: Vec<DVec2> = f.outer.iter().map(|p| p.truncate()).collect();
                    crate::geometry::ring_signed_area(&ring)
                        + f.holes
                            .iter()
                            .map(|h| {
                                crate::geometry::ring_signed_area(
                                    &h.iter().map(|p| p.truncate()).collect::<Vec<_>>(),
                                )
                            })
                            .sum::<f64>()
                })
                .sum();
            assert!(
                (projected - footprint.area()).abs() < 1e-3 * footprint.area(),
                "{shape:?}: {projected} vs {}",
                footprint.area()
            );
            let part = build_part("p0".into(), &m, &r, Lod::Lod2);
            assert!(
                check_part(&part).is_empty(),
                "{shape:?} across={across}: {:?}",
                check_part(&part)
            );
        }
    }
}

#[test]
fn across_turns_the_ridge_of_a_gabled_rectangle() {
    let rect = poly(&[(0.0, 0.0), (12.0, 0.0), (12.0, 8.0), (0.0, 8.0)]);
    let mut m = mass(rect, RoofShape::Gabled);
    m.roof_across = true;
    let r = roof_geometry(&m).unwrap();
    // Ridge across the short side: parallel to y, at x = 6; gables on the long walls.
    let top: Vec<DVec3> = r
        .faces
        .iter()
        .flat_map(|f| f.outer.iter().copied())
        .filter(|p| (p.z - r.height).abs() < 1e-9)
        .collect();
    assert!(top.iter().all(|p| (p.x - 6.0).abs() < 1e-6), "{top:?}");
    assert!((r.height - 6.0 * 35f64.to_radians().tan()).abs() < 1e-6);
}

#[test]
fn jambs_move_to_grid_points_by_the_walls_line() {
    use crate::rng::Rng;
    use grid::{along_on_grid, point2_on_grid};
    let off = |s: DVec2, e: DVec2, u: f64| {
        let d = (e - s).normalize();
        let q = point2_on_grid(s + d * u);
        (q - s).perp_dot(d).abs()
    };
    let mut rng = Rng::new(19, 0);
    let (mut before, mut after) = (Vec::new(), Vec::new());
    for _ in 0..2000 {
        let g = |r: &mut Rng| (r.range(-50_000.0, 50_000.0)).round() / 1000.0;
        let s = DVec2::new(g(&mut rng), g(&mut rng));
        let e = DVec2::new(g(&mut rng), g(&mut rng));
        let len = s.distance(e);
        if len < 1.0 {
            continue;
        }
        let u = rng.range(0.1, len - 0.1);
        let shift = if rng.next_f64() < 0.5 { 0.02 } else { -0.02 };
        let v = along_on_grid(s, e, u, shift);
        // Within the range it may move in, on the side it may move to.
        let (lo, hi) = (u.min(u + shift), u.max(u + shift));
        assert!(v >= lo - 1e-9 && v <= hi + 1e-9, "{u} -> {v} ({shift})");
        before.push(off(s, e, u));
        after.push(off(s, e, v));
        assert!(
            off(s, e, v) <= off(s, e, u) + 1e-12,
            "never further off the line"
        );
    }
    let median = |v: &mut Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    let (b, a) = (median(&mut before), median(&mut after));
    // Rounding alone leaves a point a quarter of a millimetre off its line, typically.
    assert!(
        b > 1.5e-4 && a < 2e-5,
        "median off the line: {b} m -> {a} m"
    );
    // On an axis, exactly on it; off the grid, not moved.
    let (s, e) = (DVec2::new(1.0, 2.0), DVec2::new(11.0, 2.0));
    assert_eq!(off(s, e, along_on_grid(s, e, 3.2137, 0.02)), 0.0);
    let s = DVec2::new(1.00042, 2.0);
    assert_eq!(along_on_grid(s, e, 3.2137, 0.02), 3.2137);
}

/// A 10 m square box (walls 0 to 3 m) under `roof`, put on the grid by `grid::finish`.
fn finished_box(roof: Vec<Face>) -> (Face, Vec<Wall>, Vec<Face>) {
    let c = [(0.0, 0.0), (10.0, 0.0), (10.0, 10.0), (0.0, 10.0)].map(|(x, y)| DVec2::new(x, y));
    let mut ground = Face::new(c.iter().rev().map(|p| p.extend(0.0)).collect());
    let mut walls: Vec<Wall> = (0..4)
        .map(|i| {
            let (a, b) = (c[i], c[(i + 1) % 4]);
            Wall {
                start: a,
                end: b,
                base_z: 0.0,
                top_z: 3.0,
                thickness: 0.3,
                outline: Face::new(vec![
                    a.extend(0.0),
                    b.extend(0.0),
                    b.extend(3.0),
                    a.extend(3.0),
                ]),
                storey: 0,
                openings: Vec::new(),
                balconies: Vec::new(),
                party: 0.0,
            }
        })
        .collect();
    let mut roof = roof;
    grid::finish(&mut ground, &mut walls, &mut roof);
    (ground, walls, roof)
}

/// Four faces over the box's eave (z = 3) meeting in `a` (west) and `b` (east), joined by an
/// edge.
fn split_top(a: DVec3, b: DVec3) -> Vec<Face> {
    let e = |x: f64, y: f64| DVec3::new(x, y, 3.0);
    vec![
        Face::new(vec![e(0.0, 0.0), e(10.0, 0.0), b, a]),
        Face::new(vec![e(10.0, 0.0), e(10.0, 10.0), b]),
        Face::new(vec![e(10.0, 10.0), e(0.0, 10.0), a, b]),
        Face::new(vec![e(0.0, 10.0), e(0.0, 0.0), a]),
    ]
}

#[test]
fn a_split_apex_whose_planes_meet_in_one_point_becomes_that_point() {
    // A low pyramid (3°) over the box whose apex the skeleton left as two nodes 1.3 cm
    // apart, joined by an edge: each is within a millimetre of the planes of the faces
    // through it, and all four planes meet within a millimetre of one point.
    let (a, b) = (DVec3::new(5.0, 5.0, 3.25), DVec3::new(5.012, 5.004, 3.25));
    let (_, _, roof) = finished_box(split_top(a, b));
    assert_eq!(roof.len(), 4);
    assert!(roof.iter().all(|f| f.outer.len() == 3), "{roof:?}");
    let apex = roof[0].outer[2];
    assert!(roof.iter().all(|f| f.outer.contains(&apex)));
    assert!(apex.distance(a) < 0.013 && apex.distance(b) < 0.013);
}

#[test]
fn a_short_ridge_whose_planes_do_not_meet_in_one_point_is_kept() {
    // A hipped roof on the box with a ridge of 2.5 cm, less than ROOF_CLUSTER: made one
    // point, the hips' planes would be 6 mm off it, so the ridge stays.
    let (a, b) = (DVec3::new(4.9875, 5.0, 6.0), DVec3::new(5.0125, 5.0, 6.0));
    assert!(a.distance(b) < grid::ROOF_CLUSTER);
    let (_, _, roof) = finished_box(split_top(a, b));
    assert_eq!(roof[0].outer.len(), 4, "{roof:?}");
    let on_grid = |p: DVec3| DVec3::new(on_grid(p.x), on_grid(p.y), on_grid(p.z));
    assert!(roof[0].outer.contains(&on_grid(a)) && roof[0].outer.contains(&on_grid(b)));
}

#[test]
fn a_cut_roof_that_fails_the_part_checks_is_drawn_as_the_next_simpler_shape() {
    // A sound sawtooth is drawn as asked, without a note.
    let m = mass(rect(), RoofShape::Sawtooth);
    let (part, notes) = part_with_roof("p0".into(), &m, Lod::Lod2, "way/7", roof_geometry);
    assert!(notes.is_empty(), "{notes:?}");
    assert_eq!(part.roof_shape, RoofShape::Sawtooth);
    // A sawtooth with a corner of a face lifted by a metre (not planar) is drawn as a
    // skillion, and the report names the building.
    let broken = |m: &Mass| {
        let r = roof_geometry(m)?;
        if m.roof != RoofShape::Sawtooth {
            return Ok(r);
        }
        let mut faces = r.faces.clone();
        faces[0].outer[0].z += 1.0;
        Ok(RoofGeometry::from_parts(faces, r.gable_walls))
    };
    let (part, notes) = part_with_roof("p0".into(), &m, Lod::Lod2, "way/7", broken);
    assert_eq!(part.roof_shape, RoofShape::Skillion);
    assert!(check_part(&part).is_empty(), "{:?}", check_part(&part));
    assert_eq!(notes.len(), 1, "{notes:?}");
    assert!(
        notes[0].starts_with("sawtooth roof of way/7 drawn as skillion: "),
        "{notes:?}"
    );
    // Saltbox and a turned gabled roof fall back to the skeleton's gabled roof; a skillion to
    // flat; the skeleton roofs have no fallback.
    let saltbox = simpler_roof(&Mass {
        roof_direction: Some(90.0),
        ..mass(rect(), RoofShape::Saltbox)
    });
    assert_eq!(
        saltbox.map(|m| (m.roof, m.roof_direction, m.roof_across)),
        Some((RoofShape::Gabled, None, false))
    );
    let turned = simpler_roof(&Mass {
        roof_across: true,
        ..mass(rect(), RoofShape::Gabled)
    });
    assert_eq!(
        turned.map(|m| (m.roof, m.roof_across)),
        Some((RoofShape::Gabled, false))
    );
    let skillion = simpler_roof(&mass(rect(), RoofShape::Skillion));
    assert_eq!(skillion.map(|m| m.roof), Some(RoofShape::Flat));
    for shape in [RoofShape::Gabled, RoofShape::Hipped, RoofShape::Flat] {
        assert!(simpler_roof(&mass(rect(), shape)).is_none(), "{shape:?}");
    }
    // A skeleton roof turned by roof:direction falls back to the same shape unturned.
    let mansard = simpler_roof(&Mass {
        roof_direction: Some(0.0),
        ..mass(rect(), RoofShape::Mansard)
    });
    assert_eq!(
        mansard.map(|m| (m.roof, m.roof_direction, m.roof_across)),
        Some((RoofShape::Mansard, None, false))
    );
    assert!(simpler_roof(&mass(rect(), RoofShape::Dome)).is_none());
    // At LOD1 the part is a block: nothing to fall back from.
    let (part, notes) = part_with_roof("p0".into(), &m, Lod::Lod1, "way/7", broken);
    assert!(notes.is_empty());
    assert_eq!(part.roof_shape, RoofShape::Sawtooth);
}
