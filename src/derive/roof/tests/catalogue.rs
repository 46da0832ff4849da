//! The shapes added to complete the OSM catalogue (issue 45): each one's form on a rectangle
//! (and a church with an apse), and `roof:direction` / `roof:orientation` where they apply.

use glam::{DVec2, DVec3};

use super::{check_shape, poly};
use crate::derive::massing::{build_part, check_part, roof_geometry, Mass};
use crate::derive::roof::{build, build_oriented, shapes, RoofGeometry};
use crate::geometry::Polygon;
use crate::model::{Face, Lod, RoofShape};

const PITCH: f64 = 35.0;

fn rect(l: f64, w: f64) -> Polygon {
    poly(&[(0., 0.), (l, 0.), (l, w), (0., w)])
}

fn slope(f: &Face) -> f64 {
    f.normal().z.clamp(-1.0, 1.0).acos().to_degrees()
}

fn top_points(r: &RoofGeometry) -> Vec<DVec3> {
    r.faces
        .iter()
        .flat_map(|f| f.outer.iter().copied())
        .filter(|p| (p.z - r.height).abs() < 1e-6)
        .collect()
}

/// The mass of `shape` on `p` with a bearing and `roof:orientation=across`.
fn mass(p: &Polygon, shape: RoofShape, bearing: Option<f64>, across: bool) -> Mass {
    Mass {
        footprint: p.clone(),
        base_z: 0.0,
        eave_z: 6.0,
        storeys: 2,
        roof: shape,
        roof_angle_deg: PITCH,
        roof_direction: bearing,
        roof_across: across,
        roof_height: None,
        wall_color: crate::color::Color::WHITE,
        roof_color: crate::color::Color::GREY,
    }
}

/// Builds the part and asserts it passes the part checks.
fn checked(m: &Mass) -> RoofGeometry {
    let r = roof_geometry(m).unwrap_or_else(|f| panic!("{:?}: {}", m.roof, f.reason));
    let part = build_part("p".into(), m, &r, Lod::Lod2);
    let d = check_part(&part);
    assert!(d.is_empty(), "{:?}: {d:?}", m.roof);
    assert_eq!(part.roof_shape, m.roof);
    r
}

#[test]
fn every_new_shape_closes_on_a_rectangle_an_l_and_a_courtyard() {
    let ell = poly(&[
        (0., 0.),
        (16., 0.),
        (16., 6.),
        (6., 6.),
        (6., 14.),
        (0., 14.),
    ]);
    let court = Polygon::new(
        rect(24.0, 16.0).outer,
        vec![vec![
            DVec2::new(8., 5.),
            DVec2::new(8., 11.),
            DVec2::new(16., 11.),
            DVec2::new(16., 5.),
        ]],
    );
    for p in [rect(12.0, 6.0), ell, court, church()] {
        for shape in [
            RoofShape::GabledHeightMoved,
            RoofShape::SideHalfHipped,
            RoofShape::HippedAndGabled,
            RoofShape::BellcastGable,
            RoofShape::Crosspitched,
            RoofShape::Sawtooth,
            RoofShape::Butterfly,
            RoofShape::ApseGabled,
        ] {
            if let Err(e) = check_shape(&p, shape, PITCH) {
                panic!("{e}");
            }
            for bearing in [0.0, 35.0, 90.0, 200.0] {
                for across in [false, true] {
                    checked(&mass(&p, shape, Some(bearing), across));
                }
            }
            checked(&mass(&p, shape, None, true));
        }
    }
}

#[test]
fn butterfly_falls_to_a_valley_on_the_eave_along_the_middle() {
    let r = checked(&mass(&rect(12.0, 6.0), RoofShape::Butterfly, None, false));
    assert_eq!(r.faces.len(), 2);
    let k = PITCH.to_radians().tan();
    assert!((r.height - 3.0 * k).abs() < 1e-9, "{}", r.height);
    // The valley: every vertex at the eave lies on y = 3; the outer eaves (y = 0, 6) are high.
    for p in r.faces.iter().flat_map(|f| f.outer.iter()) {
        if p.z.abs() < 1e-9 {
            assert!((p.y - 3.0).abs() < 1e-9, "{p}");
        } else {
            assert!((p.z - k * (p.y - 3.0).abs()).abs() < 1e-9, "{p}");
        }
    }
    // The long walls rise to the high eaves; each end wall is a V: two triangles.
    assert_eq!(r.gable_walls.len(), 6, "{:?}", r.gable_walls);
    assert!(r.gable_walls.iter().filter(|w| w.outer.len() == 3).count() == 4);
    // Across: the valley parallel to the short side (x = 6).
    let r = checked(&mass(&rect(12.0, 6.0), RoofShape::Butterfly, None, true));
    for p in r.faces.iter().flat_map(|f| f.outer.iter()) {
        if p.z.abs() < 1e-9 {
            assert!((p.x - 6.0).abs() < 1e-9, "{p}");
        }
    }
}

#[test]
fn sawtooth_has_teeth_of_steep_glazing_looking_away_from_roof_direction() {
    // 24 m deep along y, roof:direction = south: three teeth whose slopes fall south and whose
    // glazed faces look north.
    let p = rect(10.0, 24.0);
    let r = checked(&mass(&p, RoofShape::Sawtooth, Some(180.0), false));
    let slopes: Vec<&Face> = r
        .faces
        .iter()
        .filter(|f| (slope(f) - PITCH).abs() < 1e-6)
        .collect();
    let glazed: Vec<&Face> = r
        .faces
        .iter()
        .filter(|f| (slope(f) - shapes::SAWTOOTH_GLAZING_DEG).abs() < 1e-6)
        .collect();
    assert_eq!(slopes.len(), 3, "{:?}", r.faces);
    assert_eq!(glazed.len(), 2, "{:?}", r.faces);
    assert_eq!(r.faces.len(), 5);
    assert!(
        slopes.iter().all(|f| f.normal().y < -0.1),
        "slopes face south"
    );
    assert!(
        glazed.iter().all(|f| f.normal().y > 0.9),
        "glazing looks north"
    );
    // Each tooth at the same height; the last one ends at the north wall.
    let north_top = r
        .gable_walls
        .iter()
        .filter(|w| w.outer.iter().all(|q| (q.y - 24.0).abs() < 1e-9))
        .flat_map(|w| w.outer.iter().map(|q| q.z))
        .fold(0.0, f64::max);
    assert!((north_top - r.height).abs() < 1e-9);
    // The side walls follow the teeth down to the eave between them.
    let east: Vec<&Face> = r
        .gable_walls
        .iter()
        .filter(|w| w.outer.iter().all(|q| (q.x - 10.0).abs() < 1e-9))
        .collect();
    assert_eq!(east.len(), 3, "one wall piece under each tooth");
    // Unset direction: the teeth's ridges along the long side (slopes across the short one).
    let r = build(&rect(30.0, 16.0), RoofShape::Sawtooth, PITCH, None).unwrap();
    let teeth = r
        .faces
        .iter()
        .filter(|f| (slope(f) - PITCH).abs() < 1e-6)
        .count();
    assert_eq!(teeth, 2);
    assert!(r.faces.iter().all(|f| f.normal().x.abs() < 1e-9));
}

#[test]
fn crosspitched_has_four_gables_on_a_rectangle() {
    let r = checked(&mass(
        &rect(12.0, 8.0),
        RoofShape::Crosspitched,
        None,
        false,
    ));
    assert_eq!(r.gable_walls.len(), 4, "{:?}", r.gable_walls);
    assert!(r.gable_walls.iter().all(|w| w.outer.len() == 3));
    let k = PITCH.to_radians().tan();
    assert!((r.height - 4.0 * k).abs() < 1e-9);
    // The two ridges cross at the centre: the top is a cross.
    let top = top_points(&r);
    assert!(top
        .iter()
        .any(|p| p.truncate().distance(DVec2::new(6.0, 4.0)) < 1e-9));
    assert!(top
        .iter()
        .any(|p| (p.x - 0.0).abs() < 1e-9 && (p.y - 4.0).abs() < 1e-9));
    assert!(top
        .iter()
        .any(|p| (p.y - 8.0).abs() < 1e-9 && (p.x - 6.0).abs() < 1e-9));
    assert_eq!(r.faces.len(), 8);
}

/// A church: a 20 × 8 m nave with a semicircular apse of radius 4 m at its east end, drawn as
/// eight sides.
fn church() -> Polygon {
    let mut pts = vec![(0.0, 0.0), (20.0, 0.0)];
    for i in 1..8 {
        let a = -std::f64::consts::FRAC_PI_2 + i as f64 / 8.0 * std::f64::consts::PI;
        pts.push((20.0 + 4.0 * a.cos(), 4.0 + 4.0 * a.sin()));
    }
    pts.extend([(20.0, 8.0), (0.0, 8.0)]);
    poly(&pts)
}

#[test]
fn apse_gabled_has_a_gable_west_and_a_round_apse_east() {
    let p = church();
    assert!(shapes::has_rounded_end(&p));
    assert!(!shapes::has_rounded_end(&rect(20.0, 8.0)));
    let r = checked(&mass(&p, RoofShape::ApseGabled, None, false));
    // One gable wall, at the west front.
    assert_eq!(r.gable_walls.len(), 1, "{:?}", r.gable_walls);
    assert!(r.gable_walls[0].outer.iter().all(|q| q.x.abs() < 1e-9));
    // The apse: a face on each of its eight sides, all at the pitch, meeting at the ridge's
    // east end: a half cone.
    let apse: Vec<&Face> = r
        .faces
        .iter()
        .filter(|f| {
            let (a, b) = (f.outer[0], f.outer[1]);
            a.z.abs() < 1e-9 && b.z.abs() < 1e-9 && a.x > 20.0 - 1e-9 && b.x > 20.0 - 1e-9
        })
        .collect();
    assert_eq!(apse.len(), 8, "{:?}", r.faces);
    assert!(apse.iter().all(|f| (slope(f) - PITCH).abs() < 0.5));
    // On a plain rectangle, one end hipped (as side_hipped).
    let r = build(&rect(20.0, 8.0), RoofShape::ApseGabled, PITCH, None).unwrap();
    assert_eq!(r.gable_walls.len(), 1);
}

#[test]
fn hipped_and_gabled_puts_a_steep_small_gable_on_each_hip() {
    let r = checked(&mass(
        &rect(12.0, 6.0),
        RoofShape::HippedAndGabled,
        None,
        false,
    ));
    // Two long slopes, two hips, two small gables; no wall rises above the eave.
    assert_eq!(r.faces.len(), 6, "{:?}", r.faces);
    assert!(r.gable_walls.is_empty());
    let gables: Vec<&Face> = r
        .faces
        .iter()
        .filter(|f| (slope(f) - shapes::HIP_AND_GABLE_DEG).abs() < 1e-6)
        .collect();
    assert_eq!(gables.len(), 2);
    for g in gables {
        let low = g.outer.iter().map(|q| q.z).fold(f64::INFINITY, f64::min);
        assert!(
            (low / r.height - shapes::HIP_AND_GABLE_FRACTION).abs() < 1e-9,
            "{low} of {}",
            r.height
        );
    }
    let at_pitch = r
        .faces
        .iter()
        .filter(|f| (slope(f) - PITCH).abs() < 1e-6)
        .count();
    assert_eq!(at_pitch, 4);
}

#[test]
fn side_half_hipped_has_one_half_hip_and_one_gable() {
    let r = checked(&mass(
        &rect(12.0, 6.0),
        RoofShape::SideHalfHipped,
        None,
        false,
    ));
    assert_eq!(r.faces.len(), 3, "{:?}", r.faces);
    let mut sizes: Vec<usize> = r.gable_walls.iter().map(|w| w.outer.len()).collect();
    sizes.sort_unstable();
    assert_eq!(
        sizes,
        vec![3, 4],
        "a gable triangle and a half-hip trapezoid"
    );
}

#[test]
fn bellcast_flares_at_the_eaves() {
    let r = checked(&mass(
        &rect(12.0, 6.0),
        RoofShape::BellcastGable,
        None,
        false,
    ));
    assert_eq!(r.gable_walls.len(), 2);
    let mut s: Vec<f64> = r.faces.iter().map(slope).collect();
    s.sort_by(f64::total_cmp);
    s.dedup_by(|a, b| (*a - *b).abs() < 1e-6);
    let lower = PITCH * shapes::BELLCAST_LOWER_REL;
    assert_eq!(s.len(), 2, "{s:?}");
    assert!(
        (s[0] - lower).abs() < 1e-6 && (s[1] - PITCH).abs() < 1e-6,
        "{s:?}"
    );
    // The flared band is the lower one.
    for f in &r.faces {
        let low = f.outer.iter().map(|q| q.z).fold(f64::INFINITY, f64::min);
        assert_eq!(low.abs() < 1e-9, (slope(f) - lower).abs() < 1e-6);
    }
}

#[test]
fn gabled_height_moved_puts_the_ridge_at_a_quarter_and_follows_roof_direction() {
    let p = rect(12.0, 8.0);
    let r = checked(&mass(&p, RoofShape::GabledHeightMoved, None, false));
    let top = top_points(&r);
    let y = top[0].y;
    assert!(
        top.iter().all(|q| (q.y - y).abs() < 1e-9),
        "a ridge along x"
    );
    assert!(
        (y - 2.0).abs() < 1e-9 || (y - 6.0).abs() < 1e-9,
        "at a quarter of the width: {y}"
    );
    // roof:direction = south: the long slope faces south, the ridge is at y = 6.
    let r = checked(&mass(&p, RoofShape::GabledHeightMoved, Some(180.0), false));
    assert!(top_points(&r).iter().all(|q| (q.y - 6.0).abs() < 1e-9));
    // Across: the ridge parallel to the short side.
    let r = checked(&mass(&p, RoofShape::GabledHeightMoved, None, true));
    let top = top_points(&r);
    assert!(top.iter().all(|q| (q.x - top[0].x).abs() < 1e-9));
}

#[test]
fn roof_direction_turns_the_ridge_of_a_gabled_roof() {
    // roof:direction east on a rectangle long in x: the slopes face east and west, so the
    // ridge runs north-south, across. North: the ridge along x, as without the tag.
    let p = rect(12.0, 8.0);
    let r = checked(&mass(&p, RoofShape::Gabled, Some(90.0), false));
    assert!(top_points(&r).iter().all(|q| (q.x - 6.0).abs() < 1e-9));
    let r = checked(&mass(&p, RoofShape::Gabled, Some(0.0), false));
    assert!(top_points(&r).iter().all(|q| (q.y - 4.0).abs() < 1e-9));
    let plain = build_oriented(&p, RoofShape::Gabled, PITCH, None, false).unwrap();
    assert_eq!(plain.faces, r.faces, "north is the skeleton's own ridge");
}

/// The skeleton roofs that `roof:direction` and `roof:orientation=across` turn
/// (`shapes::turned_profile_roof`).
const TURNABLE: [RoofShape; 9] = [
    RoofShape::Hipped,
    RoofShape::HalfHipped,
    RoofShape::SideHipped,
    RoofShape::SideHalfHipped,
    RoofShape::HippedAndGabled,
    RoofShape::BellcastGable,
    RoofShape::Mansard,
    RoofShape::Gambrel,
    RoofShape::Round,
];

#[test]
fn roof_direction_and_orientation_turn_the_ridge_of_every_skeleton_roof() {
    // A 20 x 8 m rectangle long in x. Slopes facing east (or 80°, nearer east than north) or
    // `across` put the ridge north-south through the middle; north keeps the skeleton's own
    // roof, its ridge along x.
    let p = rect(20.0, 8.0);
    for shape in TURNABLE {
        let plain = build_oriented(&p, shape, PITCH, None, false).unwrap();
        let north = checked(&mass(&p, shape, Some(0.0), false));
        assert_eq!(
            plain.faces, north.faces,
            "{shape:?}: north is the skeleton's own"
        );
        let top = top_points(&north);
        assert!(
            top.iter().all(|q| (q.y - 4.0).abs() < 1e-6),
            "{shape:?} {top:?}"
        );
        for (bearing, across) in [
            (Some(90.0), false),
            (Some(270.0), false),
            (Some(80.0), false),
            (None, true),
        ] {
            let r = checked(&mass(&p, shape, bearing, across));
            let top = top_points(&r);
            assert!(
                top.iter().all(|q| (q.x - 10.0).abs() < 1e-6),
                "{shape:?} {bearing:?} {across}: ridge not north-south {top:?}"
            );
            let span = |f: fn(&DVec3) -> f64| {
                let v: Vec<f64> = top.iter().map(f).collect();
                v.iter().copied().fold(f64::MIN, f64::max)
                    - v.iter().copied().fold(f64::MAX, f64::min)
            };
            assert!(
                span(|q| q.y) > 1.0,
                "{shape:?}: a ridge, not an apex {top:?}"
            );
            // The main slopes (facing east and west) keep the pitch: the ridge is 10 m from
            // the eaves they rise from.
            if matches!(shape, RoofShape::Hipped | RoofShape::HalfHipped) {
                assert!((r.height - 10.0 * PITCH.to_radians().tan()).abs() < 1e-6);
                for f in r.faces.iter().filter(|f| f.normal().x.abs() > 0.5) {
                    assert!((slope(f) - PITCH).abs() < 1e-6, "{shape:?}: {}", slope(f));
                }
            }
        }
    }
    // An L and a courtyard turn and close too.
    let ell = poly(&[
        (0., 0.),
        (16., 0.),
        (16., 6.),
        (6., 6.),
        (6., 14.),
        (0., 14.),
    ]);
    let court = Polygon::new(
        rect(24.0, 16.0).outer,
        vec![vec![
            DVec2::new(8., 5.),
            DVec2::new(8., 11.),
            DVec2::new(16., 11.),
            DVec2::new(16., 5.),
        ]],
    );
    for p in [ell, court, church()] {
        for shape in TURNABLE {
            for bearing in [0.0, 35.0, 90.0, 200.0] {
                checked(&mass(&p, shape, Some(bearing), false));
            }
            checked(&mass(&p, shape, None, true));
        }
    }
}

#[test]
fn new_names_parse_and_map_to_their_codes() {
    for (name, shape, code) in [
        ("gabled_height_moved", RoofShape::GabledHeightMoved, "1030"),
        ("side_half-hipped", RoofShape::SideHalfHipped, "1050"),
        ("hipped-and-gabled", RoofShape::HippedAndGabled, "1050"),
        ("bellcast_gable", RoofShape::BellcastGable, "1030"),
        ("crosspitched", RoofShape::Crosspitched, "1130"),
        ("sawtooth", RoofShape::Sawtooth, "1100"),
        ("butterfly", RoofShape::Butterfly, "1020"),
        ("apse_gabled", RoofShape::ApseGabled, "1030"),
    ] {
        assert_eq!(RoofShape::parse(name), Some(shape), "{name}");
        assert_eq!(RoofShape::parse(&name.to_uppercase()), Some(shape));
        assert_eq!(shape.osm_name(), name);
        assert_eq!(shape.citygml_code(), code);
    }
}

#[test]
fn a_ridge_roof_on_an_l_keeps_a_vertex_the_outline_runs_straight_through() {
    // Found by `shapes_orthogonal` once saltbox joined it: the boolean clip of the L dropped
    // the vertex at (0.5, 0), so the wall under the ridge's end did not meet the roof.
    let p = poly(&[
        (0.0, 0.0),
        (0.5, 0.0),
        (1.0, 0.0),
        (1.0, 1.5),
        (0.5, 1.5),
        (0.5, 0.5),
        (0.0, 0.5),
    ]);
    for shape in [
        RoofShape::Saltbox,
        RoofShape::GabledHeightMoved,
        RoofShape::Butterfly,
    ] {
        if let Err(e) = check_shape(&p, shape, 10.0) {
            panic!("{e}");
        }
    }
}
