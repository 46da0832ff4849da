//! Acceptance of the floor plans (issue 8): on every footprint of data/monaco and
//! data/clifton, at one and three storeys, rooms are simple, inside the storey polygon, do not
//! overlap and fill the usable area, every room is reachable from the entrance through doors,
//! every upper storey is reached by the same stair core, and doors and walls lie on the walls
//! they claim. Plus the RGEU minimum-area count, determinism and property tests on synthetic
//! shapes.

use std::path::Path;

use geo::{Area, BooleanOps};
use glam::DVec2;
use proptest::prelude::*;

use super::geom::{self, to_geo, GMulti};
use super::*;
use crate::input::{osm::read_osm, shp::read_shp, shp::ShpOptions};
use crate::report::Report;

fn point_segment_distance(p: DVec2, a: DVec2, b: DVec2) -> f64 {
    let d = b - a;
    let l2 = d.length_squared();
    if l2 <= 0.0 {
        return p.distance(a);
    }
    let t = ((p - a).dot(d) / l2).clamp(0.0, 1.0);
    p.distance(a + d * t)
}

fn ring_distance(p: DVec2, r: &[DVec2]) -> f64 {
    (0..r.len())
        .map(|i| point_segment_distance(p, r[i], r[(i + 1) % r.len()]))
        .fold(f64::INFINITY, f64::min)
}

fn on_ring(s: (DVec2, DVec2), r: &[DVec2]) -> bool {
    let tol = 2e-3;
    ring_distance(s.0, r) < tol
        && ring_distance(s.1, r) < tol
        && ring_distance(0.5 * (s.0 + s.1), r) < tol
}

/// Checks every invariant of a plan; `Err` names the first broken one.
fn check(footprint: &Polygon, plan: &BuildingPlan, storeys: u32) -> Result<(), String> {
    let usable_area = plan.usable.area();
    let fp = to_geo(footprint);
    let expected = match plan.fallback {
        Some(Fallback::TooSmall) | Some(Fallback::NoStair) => 1,
        _ => storeys as usize,
    };
    if plan.storeys.len() != expected {
        return Err(format!(
            "{} storeys, expected {expected}",
            plan.storeys.len()
        ));
    }
    if expected > 1 && plan.stair.is_none() {
        return Err("several storeys without a stair".into());
    }
    for (level, s) in plan.storeys.iter().enumerate() {
        if level >= 2 && *s == plan.storeys[level - 1] {
            continue; // a repeated storey: checked once
        }
        let mut sum = 0.0;
        for (i, r) in s.rooms.iter().enumerate() {
            if !r.polygon.holes.is_empty() || r.polygon.outer.len() < 3 {
                return Err(format!("storey {level} room {i} ({}) not simple", r.name));
            }
            if !geom::is_valid(&to_geo(&r.polygon)) {
                return Err(format!("storey {level} room {i} ({}) invalid", r.name));
            }
            // What the writers build a solid from: the cleaned ring must stay simple.
            if !crate::geometry::clean_ring(&r.polygon.outer)
                .is_some_and(|c| crate::geometry::is_simple(&c))
            {
                return Err(format!(
                    "storey {level} room {i} ({}) not simple once cleaned",
                    r.name
                ));
            }
            let a = r.area();
            if a <= 0.0 {
                return Err(format!("storey {level} room {i} has area {a}"));
            }
            sum += a;
        }
        if (sum - usable_area).abs() > 0.01 * usable_area {
            return Err(format!(
                "storey {level}: rooms {sum:.2} m² vs usable {usable_area:.2} m²"
            ));
        }
        let polys: Vec<geo::Polygon<f64>> = s.rooms.iter().map(|r| to_geo(&r.polygon)).collect();
        let union: GMulti = geo::unary_union(&polys);
        // The union inside the footprint means every room is.
        let outside = union.difference(&fp).unsigned_area();
        if outside > 1e-3 * usable_area.max(1.0) {
            return Err(format!(
                "storey {level}: {outside} m² of rooms outside the storey polygon"
            ));
        }
        let overlap = sum - union.unsigned_area();
        if overlap > 0.005 * usable_area.max(1.0) {
            return Err(format!("storey {level}: rooms overlap by {overlap:.3} m²"));
        }
        // Stair: the same rectangle on every storey.
        if let Some(st) = &plan.stair {
            let Some(k) = s.stair_room else {
                return Err(format!("storey {level} has no stair room"));
            };
            if s.rooms[k].polygon != st.polygon || s.rooms[k].kind != RoomKind::Stair {
                return Err(format!("storey {level}: stair room differs from the core"));
            }
        }
        // Doors on shared walls.
        for d in &s.doors {
            let Some(b) = d.b else {
                return Err("interior door to the outside".into());
            };
            if d.a >= s.rooms.len() || b >= s.rooms.len() {
                return Err("door room index out of range".into());
            }
            if !on_ring(d.segment, &s.rooms[d.a].polygon.outer)
                || !on_ring(d.segment, &s.rooms[b].polygon.outer)
            {
                return Err(format!(
                    "storey {level}: door {}-{b} not on their shared wall",
                    d.a
                ));
            }
            if d.width < 0.59 || (d.segment.0.distance(d.segment.1) - d.width).abs() > 1e-6 {
                return Err(format!("storey {level}: door width {}", d.width));
            }
        }
        for w in &s.walls {
            if !on_ring(w.segment, &s.rooms[w.a].polygon.outer)
                || !on_ring(w.segment, &s.rooms[w.b].polygon.outer)
            {
                return Err(format!("storey {level}: wall {}-{} not shared", w.a, w.b));
            }
        }
        // Reachability.
        let start = if level == 0 {
            let Some(e) = &s.entrance else {
                return Err("ground floor without entrance".into());
            };
            if e.b.is_some() || e.a >= s.rooms.len() {
                return Err("bad entrance".into());
            }
            if !on_ring(e.segment, &s.rooms[e.a].polygon.outer)
                || !on_ring(e.segment, &plan.usable.outer)
            {
                return Err("entrance not on the outer wall of its room".into());
            }
            e.a
        } else {
            if s.entrance.is_some() {
                return Err(format!("storey {level} has an entrance"));
            }
            s.stair_room.ok_or(format!("storey {level}: no stair"))?
        };
        let mut seen = vec![false; s.rooms.len()];
        seen[start] = true;
        let mut changed = true;
        while changed {
            changed = false;
            for d in &s.doors {
                if let Some(b) = d.b {
                    if seen[d.a] != seen[b] {
                        seen[d.a] = true;
                        seen[b] = true;
                        changed = true;
                    }
                }
            }
        }
        if let Some(i) = seen.iter().position(|x| !x) {
            return Err(format!(
                "storey {level}: room {i} ({}, {:.2} m²) unreachable",
                s.rooms[i].name,
                s.rooms[i].area()
            ));
        }
    }
    Ok(())
}

fn input<'a>(fp: &'a Polygon, storeys: u32, building: Option<&'a str>) -> PlanInput<'a> {
    PlanInput {
        footprint: fp,
        storeys,
        storey_height: 3.0,
        building,
        programme: None,
        front: None,
        wall_thickness: 0.3,
    }
}

/// (id, building value, polygon) of every outline and part polygon of a data set.
fn footprints(rel: &str) -> Vec<(String, Option<String>, Polygon)> {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("data").join(rel);
    let mut report = Report::default();
    let read = if rel.ends_with(".shp") {
        read_shp(&path, &ShpOptions::default(), &mut report)
    } else {
        read_osm(&path, &mut report)
    };
    let read = match read {
        Ok(r) => r,
        Err(e) => panic!("{}: {e}", path.display()),
    };
    let site = crate::prepare::prepare(read.footprints, read.source_crs, None, &mut report);
    let mut out = Vec::new();
    for lot in &site.lots {
        for p in &lot.polygons {
            out.push((lot.id.to_string(), lot.tags.building.clone(), p.clone()));
        }
        for part in &lot.parts {
            for p in &part.polygons {
                out.push((part.id.to_string(), part.tags.building.clone(), p.clone()));
            }
        }
    }
    out
}

#[derive(Default)]
struct Tally {
    plans: usize,
    fallbacks: usize,
    failures: Vec<String>,
    with_min: usize,
    violations: usize,
    rooms: usize,
}

fn survey(rel: &str, tally: &mut Tally) {
    let (mut t_plan, mut t_check) = (std::time::Duration::ZERO, std::time::Duration::ZERO);
    for (n, (id, building, fp)) in footprints(rel).iter().enumerate() {
        // Every footprint at one storey; three storeys on every footprint too (the upper
        // storeys repeat the first upper one, so the cost is about two storeys).
        for storeys in [1u32, 3] {
            let mut rng = crate::rng::Rng::new(7, n as u64);
            let t0 = std::time::Instant::now();
            let plan = plan_building(&input(fp, storeys, building.as_deref()), &mut rng);
            t_plan += t0.elapsed();
            let t0 = std::time::Instant::now();
            let checked = check(fp, &plan, storeys);
            t_check += t0.elapsed();
            tally.plans += 1;
            if plan.fallback.is_some() {
                tally.fallbacks += 1;
            }
            if let Err(e) = checked {
                tally.failures.push(format!(
                    "{rel} {id} ({storeys} storeys, {:?}): {e}",
                    plan.fallback
                ));
            }
            for s in &plan.storeys {
                tally.rooms += s.rooms.len();
                if matches!(plan.programme, Programme::House | Programme::Apartments) {
                    for r in &s.rooms {
                        if let Some(m) = r.min_area {
                            tally.with_min += 1;
                            if r.area() < m - 0.01 {
                                tally.violations += 1;
                            }
                        }
                    }
                }
            }
        }
    }
    println!("{rel}: planning {t_plan:?}, checking {t_check:?}");
}

#[test]
fn plans_on_every_footprint_of_both_data_sets() {
    let mut tally = Tally::default();
    survey("monaco/monaco.osm.pbf", &mut tally);
    survey("clifton/clifton_test.shp", &mut tally);
    println!(
        "{} plans, {} rooms, {} fallbacks, {} failures; RGEU minimums: {} of {} rooms below",
        tally.plans,
        tally.rooms,
        tally.fallbacks,
        tally.failures.len(),
        tally.violations,
        tally.with_min
    );
    for f in tally.failures.iter().take(30) {
        println!("  {f}");
    }
    assert!(tally.plans > 8000, "{} plans", tally.plans);
    assert_eq!(
        tally.failures.len(),
        0,
        "failures (first: {:?})",
        tally.failures.first()
    );
    // Residential minimum areas hold where the programme fits the storey (the layout's merges
    // and concave pieces may shave a room): bound the share of rooms below their minimum.
    assert!(
        tally.with_min > 5000,
        "{} rooms with minimums",
        tally.with_min
    );
    assert!(
        (tally.violations as f64) < 0.05 * tally.with_min as f64,
        "{} of {} rooms below the RGEU minimum",
        tally.violations,
        tally.with_min
    );
}

fn rect_poly(w: f64, h: f64) -> Polygon {
    Polygon::new(
        vec![
            DVec2::new(0.0, 0.0),
            DVec2::new(w, 0.0),
            DVec2::new(w, h),
            DVec2::new(0.0, h),
        ],
        vec![],
    )
}

#[test]
fn a_rectangular_house_gets_a_t2_programme_with_rgeu_minimums() {
    let fp = rect_poly(10.0, 8.6); // usable 9.4 x 8.0 = 75.2 m² -> T2
    let mut rng = crate::rng::Rng::new(1, 1);
    let plan = plan_building(&input(&fp, 1, Some("house")), &mut rng);
    check(&fp, &plan, 1).unwrap();
    assert_eq!(plan.programme, Programme::House);
    let kinds: Vec<RoomKind> = plan.storeys[0].rooms.iter().map(|r| r.kind).collect();
    for k in [
        RoomKind::Hall,
        RoomKind::Living,
        RoomKind::Kitchen,
        RoomKind::Bathroom,
    ] {
        assert!(kinds.contains(&k), "{k:?} missing from {kinds:?}");
    }
    assert_eq!(kinds.iter().filter(|k| **k == RoomKind::Bedroom).count(), 2);
    for r in &plan.storeys[0].rooms {
        if let Some(m) = r.min_area {
            assert!(r.area() >= m - 0.01, "{} {} < {m}", r.name, r.area());
        }
    }
}

#[test]
fn a_three_storey_house_has_one_stair_core_and_bedrooms_upstairs() {
    let fp = rect_poly(9.0, 8.0);
    let mut rng = crate::rng::Rng::new(1, 2);
    let plan = plan_building(&input(&fp, 3, Some("house")), &mut rng);
    check(&fp, &plan, 3).unwrap();
    assert!(plan.stair.is_some());
    assert!(plan.storeys[0]
        .rooms
        .iter()
        .all(|r| r.kind != RoomKind::Bedroom));
    assert!(plan.storeys[1]
        .rooms
        .iter()
        .any(|r| r.kind == RoomKind::Bedroom));
}

#[test]
fn a_courtyard_office_block_gets_a_corridor_and_simple_rooms() {
    // 40 x 24 m block with an 8 x 6 m courtyard.
    let fp = Polygon::new(
        rect_poly(40.0, 24.0).outer,
        vec![vec![
            DVec2::new(16.0, 9.0),
            DVec2::new(16.0, 15.0),
            DVec2::new(24.0, 15.0),
            DVec2::new(24.0, 9.0),
        ]],
    );
    let mut rng = crate::rng::Rng::new(1, 3);
    let plan = plan_building(&input(&fp, 4, Some("office")), &mut rng);
    check(&fp, &plan, 4).unwrap();
    assert_eq!(plan.fallback, None);
    let s = &plan.storeys[1];
    assert!(s.rooms.iter().any(|r| r.kind == RoomKind::Corridor));
    assert!(
        s.rooms
            .iter()
            .filter(|r| r.kind == RoomKind::Office)
            .count()
            >= 10
    );
}

#[test]
fn large_apartment_storeys_hold_several_flats() {
    let fp = rect_poly(36.0, 16.0);
    let mut rng = crate::rng::Rng::new(1, 4);
    let plan = plan_building(&input(&fp, 5, Some("apartments")), &mut rng);
    check(&fp, &plan, 5).unwrap();
    let units: std::collections::BTreeSet<usize> = plan.storeys[2]
        .rooms
        .iter()
        .filter_map(|r| r.unit)
        .collect();
    assert!(units.len() >= 4, "{units:?}");
}

#[test]
fn a_tiny_footprint_falls_back_to_one_room() {
    let fp = rect_poly(2.0, 2.0);
    let mut rng = crate::rng::Rng::new(1, 5);
    let plan = plan_building(&input(&fp, 3, None), &mut rng);
    assert_eq!(plan.fallback, Some(Fallback::TooSmall));
    assert_eq!(plan.storeys.len(), 1);
    assert_eq!(plan.storeys[0].rooms.len(), 1);
    check(&fp, &plan, 3).unwrap();
}

#[test]
fn degenerate_input_gives_an_empty_plan_not_a_panic() {
    let fp = Polygon::new(
        vec![DVec2::ZERO, DVec2::new(f64::NAN, 1.0), DVec2::ONE],
        vec![],
    );
    let mut rng = crate::rng::Rng::new(1, 6);
    let plan = plan_building(&input(&fp, 2, None), &mut rng);
    assert!(plan.storeys.is_empty());
    assert_eq!(plan.fallback, Some(Fallback::TooSmall));
}

#[test]
fn plans_are_deterministic() {
    let fp = rect_poly(14.0, 11.0);
    let a = plan_building(&input(&fp, 2, None), &mut crate::rng::Rng::new(3, 9));
    let b = plan_building(&input(&fp, 2, None), &mut crate::rng::Rng::new(3, 9));
    assert_eq!(a, b);
}

#[test]
fn the_entrance_faces_the_given_front() {
    let fp = rect_poly(12.0, 9.0);
    let mut inp = input(&fp, 1, Some("house"));
    inp.front = Some(DVec2::new(1.0, 0.0)); // east
    let plan = plan_building(&inp, &mut crate::rng::Rng::new(1, 7));
    let e = plan.storeys[0].entrance.as_ref().unwrap();
    assert!((e.segment.0.x - 11.7).abs() < 1e-6 && (e.segment.1.x - 11.7).abs() < 1e-6);
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(24))]
    #[test]
    fn l_shapes_with_any_size_and_rotation_plan_cleanly(
        w in 4.0f64..40.0, h in 4.0f64..30.0, cw in 0.2f64..0.8, ch in 0.2f64..0.8,
        angle in 0.0f64..std::f64::consts::TAU, storeys in 1u32..4, kind in 0usize..4,
    ) {
        let (c, s) = (angle.cos(), angle.sin());
        let rot = |x: f64, y: f64| DVec2::new(c * x - s * y, s * x + c * y);
        let fp = Polygon::new(vec![
            rot(0.0, 0.0), rot(w, 0.0), rot(w, h * ch), rot(w * cw, h * ch), rot(w * cw, h), rot(0.0, h),
        ], vec![]);
        let building = ["house", "apartments", "office", "retail"][kind];
        let plan = plan_building(&input(&fp, storeys, Some(building)), &mut crate::rng::Rng::new(5, 5));
        prop_assert!(check(&fp, &plan, storeys).is_ok(), "{:?}", check(&fp, &plan, storeys));
    }
}

#[test]
fn a_ring_touching_itself_is_cut_into_simple_pieces() {
    let v = |x: f64, y: f64| DVec2::new(x, y);
    // Two rectangles joined by a zero-width seam along y = 0 (seen on Monaco way/49209503).
    let seam = [
        v(0.0, 0.0),
        v(0.0, -4.0),
        v(2.4, -4.0),
        v(2.4, 0.0),
        v(4.4, 0.0),
        v(4.4, -4.0),
        v(6.6, -4.0),
        v(6.6, 0.0),
    ];
    assert!(!crate::geometry::is_simple(&seam));
    let (outers, holes) = geom::simple_parts(&seam);
    assert!(holes.is_empty());
    assert_eq!(outers.len(), 2, "{outers:?}");
    let area: f64 = outers
        .iter()
        .map(|r| crate::geometry::ring_signed_area(r))
        .sum();
    assert!((area - (2.4 * 4.0 + 2.2 * 4.0)).abs() < 1e-9, "{area}");
    assert!(outers
        .iter()
        .all(|r| r.len() == 4 && crate::geometry::is_simple(r)));
    // Two squares meeting at one corner.
    let bow = [
        v(0.0, 0.0),
        v(1.0, 0.0),
        v(1.0, 1.0),
        v(2.0, 1.0),
        v(2.0, 2.0),
        v(1.0, 2.0),
        v(1.0, 1.0),
        v(0.0, 1.0),
    ];
    let (outers, holes) = geom::simple_parts(&bow);
    assert_eq!((outers.len(), holes.len()), (2, 0), "{outers:?}");
    // A hole pinched onto the outer ring at one vertex comes back as a hole.
    let pinched = [
        v(0.0, 0.0),
        v(4.0, 0.0),
        v(4.0, 4.0),
        v(2.0, 4.0),
        v(3.0, 2.0),
        v(1.0, 2.0),
        v(2.0, 4.0),
        v(0.0, 4.0),
    ];
    let (outers, holes) = geom::simple_parts(&pinched);
    assert_eq!((outers.len(), holes.len()), (1, 1), "{outers:?} {holes:?}");
}
