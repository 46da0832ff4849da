//! The seed's printed programs (tests/data/selex, shared with `selex::eval_tests`) as buildings.

use glam::DVec2;

use super::*;
use crate::model::{Opening, OpeningKind, Wall};
use crate::selex::eval::run;
use crate::selex::parser::parse;

const CLOCK_TOWER: &str = include_str!("../../../tests/data/selex/clock_tower.slx");
const ROUNDED_DOOR: &str = include_str!("../../../tests/data/selex/rounded_door.slx");
const FRAMED: &str = include_str!("../../../tests/data/selex/framed.slx");
const BRITO: &str = include_str!("../../../tests/data/selex/brito.slx");
const JIANG: &str = include_str!("../../../tests/data/selex/jiang.slx");
const UPDATE_GRID: &str = include_str!("../../../tests/data/selex/update_grid.slx");

fn build(src: &str, lod: Lod) -> (Building, Vec<Note>) {
    let program = parse(src, "t.slx").unwrap_or_else(|e| panic!("{e}"));
    let d = run(&program, src, "t.slx").unwrap_or_else(|e| panic!("{e}"));
    let (b, notes) = building(&d, SourceId::Lot(1), "t.slx", lod).unwrap();
    for p in &b.parts {
        assert!(
            massing::check_part(p).is_empty(),
            "{}: {:?}",
            p.key,
            massing::check_part(p)
        );
        assert!(
            p.footprint.area() > 0.0,
            "{} is not counter-clockwise",
            p.key
        );
        assert!(crate::geometry::is_simple(&p.footprint.outer));
        for (s, e) in edges(&p.footprint) {
            assert!(s.distance(e) >= MIN_EDGE - 0.002, "{}: a tiny edge", p.key);
        }
    }
    (b, notes)
}

/// Every opening of a part with its wall.
fn openings(p: &Part) -> Vec<(&Wall, &Opening)> {
    p.walls
        .iter()
        .flat_map(|w| w.openings.iter().map(move |o| (w, o)))
        .collect()
}

fn outward(w: &Wall) -> DVec2 {
    let d = (w.end - w.start).normalize();
    DVec2::new(d.y, -d.x)
}

fn unplaced(notes: &[Note]) -> Vec<&String> {
    notes
        .iter()
        .map(|(_, t)| t)
        .filter(|t| t.contains("not placed") || t.contains("left out"))
        .collect()
}

#[test]
fn the_clock_tower_has_a_rounded_framed_clock_and_six_rounded_windows_on_its_front() {
    let (b, notes) = build(CLOCK_TOWER, Lod::Lod3);
    assert_eq!((b.id, b.zone.as_str()), (SourceId::Lot(1), "selex"));
    assert_eq!((b.appearance.as_str(), b.lod), ("t.slx", Lod::Lod3));
    assert_eq!(b.parts.len(), 1);
    assert!((b.measured_height - 12.0).abs() < 1e-9);
    // Floors near every 3 m, moved off the windows (docs/selex.md §9).
    let floors = &b.parts[0].levels;
    assert_eq!(floors.len(), 4, "{floors:?}");
    for (z, want) in floors.iter().zip([0.0, 3.0, 5.38, 8.7]) {
        assert!((z - want).abs() < 1e-6, "{floors:?}");
    }
    let all = openings(&b.parts[0]);
    assert_eq!(all.len(), 7, "{notes:?}");
    assert!(unplaced(&notes).is_empty(), "{notes:?}");
    for (w, o) in &all {
        assert_eq!(o.kind, OpeningKind::Window);
        assert!(
            outward(w).abs_diff_eq(DVec2::NEG_Y, 1e-9),
            "not on the front"
        );
    }
    let framed: Vec<&Opening> = all.iter().filter(|(_, o)| o.framed).map(|p| p.1).collect();
    assert_eq!(framed.len(), 1);
    let clock = framed[0];
    let r = clock.rounding.expect("the clock is rounded");
    assert_eq!(r.corners, [true; 4]);
    assert_eq!((r.segments, r.radius, r.profile), (5, 1.0, 0.5));
    let f = clock.frame_size.expect("the clock's frame size");
    assert_eq!((f.width, f.protrusion), (0.1, 0.2));
    // 2.4 m wide less the insets, its top 0.3 m under the tower's 12 m (less the inset).
    assert!((clock.width() - 2.36).abs() < 0.03, "{}", clock.width());
    assert!((clock.z1 - 11.68).abs() < 0.01, "{}", clock.z1);
    let windows: Vec<&Opening> = all.iter().filter(|(_, o)| !o.framed).map(|p| p.1).collect();
    assert_eq!(windows.len(), 6);
    for o in windows {
        let r = o.rounding.expect("rounded windows");
        assert_eq!(r.corners, [true, true, false, false]);
        // Whole: 1.2 m high less the inset (no floor cuts them).
        assert!((o.height() - 1.18).abs() < 1e-6, "{o:?}");
    }
}

#[test]
fn the_rounded_door_stands_on_the_arc_of_its_bay() {
    let (b, notes) = build(ROUNDED_DOOR, Lod::Lod3);
    assert!(unplaced(&notes).is_empty(), "{notes:?}");
    assert_eq!(b.parts.len(), 2, "the box and its bay");
    assert!(openings(&b.parts[0]).is_empty());
    let bay = &b.parts[1];
    // The bay: 3 of 7 columns of 9 m, 3 m deep in front of the box's front (y = -2.5), from
    // the ground up 3 of 4 rows of 5 m; its front an arc of many edges, the door's facet a
    // chord a little inside the apex.
    let (lo, hi) = bay.footprint.bounds();
    assert!((hi.x - lo.x - 27.0 / 7.0).abs() < 0.002, "{lo} {hi}");
    assert!(lo.y >= -5.5 - 1e-9 && lo.y < -5.4, "{lo}");
    assert!((hi.y + 2.5).abs() < 0.002);
    assert!((bay.eave_z - 3.75).abs() < 1e-9 && bay.base_z == 0.0);
    assert!(bay.footprint.outer.len() > 12, "{:?}", bay.footprint.outer);
    let doors = openings(bay);
    assert_eq!(doors.len(), 1);
    let (w, door) = doors[0];
    assert_eq!(door.kind, OpeningKind::Door);
    assert_eq!(door.rounding.unwrap().corners, [true, true, false, false]);
    assert!((door.width() - (9.0 / 7.0 - 0.04)).abs() < 0.03, "{door:?}");
    assert!(door.z0 < 0.05 && (door.z1 - 2.48).abs() < 0.01, "{door:?}");
    // On the facet in the middle of the arc, facing out of the box's front.
    assert!(
        outward(w).abs_diff_eq(DVec2::NEG_Y, 1e-3),
        "{:?}",
        outward(w)
    );
    assert!((w.length() - 9.0 / 7.0).abs() < 0.2, "{}", w.length());
}

#[test]
fn the_framed_windows_keep_their_frames_on_the_round_tower_bay() {
    let (b, notes) = build(FRAMED, Lod::Lod3);
    assert!(unplaced(&notes).is_empty(), "{notes:?}");
    assert_eq!(b.parts.len(), 2);
    let all = openings(&b.parts[1]);
    assert_eq!(all.len(), 2, "two windows, neither cut by a floor: {all:?}");
    for (_, o) in &all {
        assert!(o.framed && o.rounding.is_none());
        let f = o.frame_size.unwrap();
        assert_eq!((f.width, f.protrusion), (0.2, 0.2));
    }
    // A degree of 1 on a bay 1.6 m deep and 5 m wide: the arc rises the whole depth, the sides
    // are gone, the back edge and the arc's chords are all the footprint has.
    let bay = &b.parts[1].footprint;
    let (lo, hi) = bay.bounds();
    assert!(hi.y - lo.y <= 1.6 + 1e-9 && hi.y - lo.y > 1.4, "{lo} {hi}");
    let back = edges(bay).filter(|(s, e)| (s.y - e.y).abs() < 1e-9 && (s.y - hi.y).abs() < 0.002);
    assert_eq!(back.count(), 1);
}

#[test]
fn brito_has_a_round_bay_of_thirty_segments() {
    let (b, notes) = build(BRITO, Lod::Lod3);
    assert_eq!(b.parts.len(), 2);
    assert!(unplaced(&notes).is_empty(), "{notes:?}");
    // 30 chords, two sides and the back.
    assert_eq!(b.parts[1].footprint.outer.len(), 33);
    assert!(b.parts.iter().all(|p| openings(p).is_empty()));
    // The bay rises 0.42 of the most it can (half its 3.86 m width): 0.81 m.
    let ys: Vec<f64> = b.parts[1].footprint.outer.iter().map(|p| p.y).collect();
    let front = ys.iter().copied().fold(f64::INFINITY, f64::min);
    let sides = ys
        .iter()
        .copied()
        .filter(|y| *y < -5.5 - 0.01)
        .fold(f64::NEG_INFINITY, f64::max);
    assert!((front + 8.5).abs() < 0.002, "{front}");
    assert!(
        (sides - front - 0.42 * 27.0 / 14.0).abs() < 0.01,
        "{sides} {front}"
    );
}

#[test]
fn jiang_gives_storeys_from_its_grid_and_every_element_family() {
    let (b, notes) = build(JIANG, Lod::Lod3);
    assert_eq!(
        b.parts.len(),
        1,
        "the block behind the free-standing facade"
    );
    let p = &b.parts[0];
    assert_eq!(p.storeys, 4);
    assert!(unplaced(&notes).is_empty(), "{notes:?}");
    let all = openings(p);
    let doors = all
        .iter()
        .filter(|(_, o)| o.kind == OpeningKind::Door)
        .count();
    assert_eq!(doors, 1);
    // 4 + 8 + 2 + 1 windows, and the glass three storeys high cut at the floors.
    assert_eq!(all.len() - doors, 15 + 3);
    let balconies: usize = p.walls.iter().map(|w| w.balconies.len()).sum();
    assert_eq!(balconies, 1, "the ledge");
    // All on the facade, which faces -Y.
    assert!(all
        .iter()
        .all(|(w, _)| outward(w).abs_diff_eq(DVec2::NEG_Y, 1e-9)));
}

#[test]
fn update_grid_puts_the_door_on_the_bay_and_the_windows_on_the_wall() {
    let (b, notes) = build(UPDATE_GRID, Lod::Lod3);
    assert!(unplaced(&notes).is_empty(), "{notes:?}");
    assert_eq!(b.parts.len(), 2);
    assert_eq!(openings(&b.parts[0]).len(), 2);
    let bay = openings(&b.parts[1]);
    assert_eq!(bay.len(), 1);
    assert_eq!(bay[0].1.kind, OpeningKind::Door);
}

#[test]
fn below_lod3_the_parts_have_no_openings() {
    let (b, _) = build(ROUNDED_DOOR, Lod::Lod2);
    assert_eq!(b.parts.len(), 2);
    assert!(b.parts.iter().all(|p| openings(p).is_empty()));
}

#[test]
fn an_element_on_the_part_of_a_side_the_rounding_took_away_is_named() {
    let src = r#"{<> -> createShape("b", 10, 6, 6)};
{< descendant() [label == "b_front"] > -> createGrid("g", 2, 5)};
{< descendant() [label == "g"] / [rowIdx == 1] [colIdx in (2, 3, 4)] [::groupRegions] > -> addVolume("bay", "b_front", 2, ["bay_front", "bay_left", "bay_right"])};
{< descendant() [label == "bay"] > -> roundShape("front", "outside", 1, 12, "main_front", "vertical")};
{< descendant() [label == "bay_left"] > -> createGrid("s", 1, 1)};
{< descendant() [label == "s"] / [rowIdx == 1] > -> addFacade("window")};
"#;
    let (b, notes) = build(src, Lod::Lod3);
    assert_eq!(b.parts.len(), 2);
    let lost = unplaced(&notes);
    assert_eq!(lost.len(), 1, "{notes:?}");
    assert!(
        lost[0].contains("1 element(s) not placed: window"),
        "{}",
        lost[0]
    );
}

#[test]
fn a_program_without_volumes_or_faces_builds_nothing() {
    let program = parse("x = 1;", "t.slx").unwrap();
    let d = run(&program, "x = 1;", "t.slx").unwrap();
    let e = building(&d, SourceId::Lot(0), "t.slx", Lod::Lod3).unwrap_err();
    assert!(e.contains("nothing to build"), "{e}");
}

#[test]
fn floors_move_off_the_elements_and_a_storey_grid_wins() {
    // 12 m: floors near 3, 6 and 9; windows over 5.4..6.6 push the second one down.
    let busy = [(5.38, 6.9)];
    let f = floors_between(0.0, 12.0, &busy);
    assert_eq!(f.len(), 3);
    assert!(
        (f[0] - 3.0).abs() < 1e-9 && (f[1] - 5.38).abs() < 1e-9,
        "{f:?}"
    );
    // Nothing free: the ideal floors, the elements cut.
    let f = floors_between(0.0, 9.0, &[(-0.1, 9.5)]);
    assert_eq!(f, vec![3.0, 6.0]);
}

#[test]
fn an_inside_rounding_curves_the_front_in_and_a_top_rounding_is_drawn_square() {
    let src = |how: &str| {
        format!(
            r#"{{<> -> createShape("b", 10, 6, 6)}};
{{< descendant() [label == "b_front"] > -> createGrid("g", 2, 5)}};
{{< descendant() [label == "g"] / [rowIdx == 1] [colIdx in (2, 3, 4)] [::groupRegions] > -> addVolume("bay", "b_front", 2, ["bay_front", "bay_left", "bay_right"])}};
{{< descendant() [label == "bay"] > -> roundShape({how}, 8, "main_front", "vertical")}};
"#
        )
    };
    let (b, notes) = build(&src(r#""front", "inside", 0.5"#), Lod::Lod3);
    let bay = &b.parts[1].footprint;
    // 6 m wide, 2 m deep: the front dips by 0.5 x min(2 - 0.05, 3) in its middle.
    assert!(
        (bay.area() - (12.0 - 0.975 * 6.0 * 2.0 / 3.0)).abs() < 0.3,
        "{}",
        bay.area()
    );
    assert_eq!(bay.outer.len(), 4 + 7, "{:?}", bay.outer);
    assert!(notes.is_empty(), "{notes:?}");
    let (b, notes) = build(&src(r#""top", "outside", 0.5"#), Lod::Lod3);
    assert_eq!(b.parts[1].footprint.outer.len(), 4);
    assert!(
        notes.iter().any(|(_, t)| t.contains("drawn square")),
        "{notes:?}"
    );
}
