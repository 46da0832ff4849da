//! The objectives on seed 003's Fig. 3.31 matrix (the notes' worked values), the ragged-row
//! conventions, the global constraints and the penalty.

use super::objectives::*;
use super::{Facade, Kind, Matrix, Terminal};

/// Fig. 3.31 as printed, top row first.
fn fig_3_31_printed() -> Matrix {
    vec![
        vec![0, 1, 1, 0, 2, 0, 1, 0],
        vec![0, 1, 1, 0, 2, 0, 0, 1],
        vec![0, 1, 1, 0, 2, 1, 1, 1],
    ]
}

fn terminal(kind: Kind, w: f64, h: f64) -> Terminal {
    Terminal {
        kind,
        x: 0.0,
        y: 0.0,
        w,
        h,
    }
}

/// A clean facade: three good windows (1.0 × 1.6, ratio 0.625), a door (1.0 × 2.2, ratio
/// 0.45) and two walls; subdivisions decreasing.
fn clean_facade() -> Facade {
    Facade {
        width: 10.0,
        height: 6.0,
        terminals: vec![
            terminal(Kind::Wall, 10.0, 1.0),
            terminal(Kind::Window, 1.0, 1.6),
            terminal(Kind::Window, 1.0, 1.6),
            terminal(Kind::Window, 1.0, 1.6),
            terminal(Kind::Door, 1.0, 2.2),
            terminal(Kind::Wall, 2.0, 3.0),
        ],
        matrix: vec![vec![0, 2, 0], vec![1, 1, 1]],
        subdivisions: vec![3, 2, 2, 0],
        violations: 0,
    }
}

#[test]
fn fig_3_31_gives_the_worked_values_in_either_row_order() {
    let printed = fig_3_31_printed();
    let mut bottom_up = printed.clone();
    bottom_up.reverse();
    for m in [&printed, &bottom_up] {
        assert_eq!(horizontal_symmetry(m), 2, "{m:?}");
        assert_eq!(vertical_symmetry(m), 8, "{m:?}");
        assert_eq!(uniformity(m), 4, "{m:?}");
    }
    let facade = Facade {
        matrix: printed,
        ..Facade::default()
    };
    assert_eq!(Objective::HorizontalSymmetry.value(&facade), 2.0);
    assert_eq!(Objective::VerticalSymmetry.value(&facade), 8.0);
    assert_eq!(Objective::Uniformity.value(&facade), 4.0);
}

#[test]
fn symmetric_and_uniform_matrices_score_zero_and_single_changes_count_once() {
    let m: Matrix = vec![vec![0, 1, 2, 1, 0]; 4];
    assert_eq!(vertical_symmetry(&m), 0);
    assert_eq!(horizontal_symmetry(&m), 0);
    assert_eq!(uniformity(&m), 0);
    let mut one = m.clone();
    one[0][0] = 2; // breaks row 0's mirror (0 vs 4) and column 0's (row 0 vs 3)
    assert_eq!(vertical_symmetry(&one), 1);
    assert_eq!(horizontal_symmetry(&one), 1);
    // Best reference: an unchanged row; the changed cell costs |2 − 0|.
    assert_eq!(uniformity(&one), 2);
    // The middle cell of an odd row and the middle row of an odd matrix are their own mirror.
    let odd: Matrix = vec![vec![0, 2, 0], vec![1, 0, 1], vec![0, 1, 0]];
    assert_eq!(vertical_symmetry(&odd), 0);
    assert_eq!(horizontal_symmetry(&odd), 1);
}

#[test]
fn ragged_rows_count_unmatched_cells() {
    // Rows mirror about their own centres: both rows are symmetric.
    let m: Matrix = vec![vec![1, 0, 1], vec![1, 1, 2, 2, 1, 1]];
    assert_eq!(vertical_symmetry(&m), 0);
    // Columns: row 0 vs row 1 on 3 common cells: (1,1) (0,1) (1,2) → 2 unequal, plus 3
    // unmatched cells.
    assert_eq!(horizontal_symmetry(&m), 5);
    // Reference row 0: row 1 differs by 0+1+1 on the common cells, plus 3 unmatched × 2 = 8;
    // reference row 1: the same, symmetric. Min 8.
    assert_eq!(uniformity(&m), 2 + 3 * UNMATCHED_CELL);
    assert_eq!(uniformity(&Matrix::new()), 0);
    assert_eq!(horizontal_symmetry(&vec![vec![], vec![0, 1]]), 2);
}

#[test]
fn names_round_trip_and_lists_report_the_bad_name() {
    for o in Objective::ALL {
        assert_eq!(o.name().parse::<Objective>(), Ok(o));
        assert_eq!(o.to_string(), o.name());
    }
    assert_eq!(
        Objective::parse_list("vsym, hsym"),
        Ok(vec![
            Objective::VerticalSymmetry,
            Objective::HorizontalSymmetry
        ])
    );
    let err = Objective::parse_list("vsym,hsymm").unwrap_err();
    assert_eq!(err, ObjectiveError::Unknown("hsymm".into()));
    assert!(err.to_string().contains("`hsymm`"), "{err}");
    assert!(err.to_string().contains("rectilinear"), "{err}");
    assert_eq!(
        Objective::parse_list("uniform,uniform"),
        Err(ObjectiveError::Duplicate("uniform".into()))
    );
    assert_eq!(Objective::parse_list(" , "), Err(ObjectiveError::Empty));
    assert_eq!(
        serde_json::to_string(&Objective::Rectilinear).unwrap(),
        "\"rectilinear\""
    );
}

#[test]
fn rectilinear_sums_the_excess_ratio_of_openings_only() {
    let mut f = clean_facade();
    assert_eq!(rectilinear(&f), 0.0);
    // A square window (ratio 1.0) exceeds 0.75 by 0.25; a 2 × 2.5 door (0.8) exceeds 0.6 by 0.2;
    // a wide wall does not count.
    f.terminals.push(terminal(Kind::Window, 1.5, 1.5));
    f.terminals.push(terminal(Kind::Door, 2.0, 2.5));
    f.terminals.push(terminal(Kind::Wall, 20.0, 0.5));
    assert!(
        (rectilinear(&f) - 0.45).abs() < 1e-12,
        "{}",
        rectilinear(&f)
    );
    f.terminals.push(terminal(Kind::Window, 1.0, 0.0));
    assert!((rectilinear(&f) - 1.45).abs() < 1e-12);
    assert!(rectilinear(&f).is_finite());
}

#[test]
fn monolithic_counts_terminals_and_fragmented_falls_with_them() {
    let f = clean_facade();
    assert_eq!(monolithic(&f), 6);
    assert_eq!(Objective::Monolithic.value(&f), 6.0);
    assert!((fragmented(&f) - 100.0 / 7.0).abs() < 1e-12);
    assert_eq!(fragmented(&Facade::default()), PENALTY);
    let mut more = f.clone();
    more.terminals.push(terminal(Kind::Wall, 1.0, 1.0));
    assert!(fragmented(&more) < fragmented(&f));
    assert!(monolithic(&more) > monolithic(&f));
}

#[test]
fn global_constraints_each_add_one_penalty_to_every_objective() {
    let f = clean_facade();
    assert_eq!(global_violations(&f), 0);
    let all = Objective::ALL;
    let clean = score(&f, &all);
    assert_eq!(clean.len(), 6);
    for (o, v) in all.iter().zip(&clean) {
        assert_eq!(*v, o.value(&f), "{o}");
    }

    // A window too narrow (0.4 < 0.6) and too tall (3.2 > 3.0): two violations.
    let mut bad = f.clone();
    bad.terminals[1] = terminal(Kind::Window, 0.4, 3.2);
    assert_eq!(global_violations(&bad), 2);
    // A door too low (1.8 < 2.0): one more; a NaN door width: one more.
    bad.terminals[4] = terminal(Kind::Door, f64::NAN, 1.8);
    assert_eq!(global_violations(&bad), 4);

    // Subdivisions rising twice: two violations.
    let mut rising = f.clone();
    rising.subdivisions = vec![1, 2, 2, 4, 0];
    assert_eq!(global_violations(&rising), 2);

    // Only one opening left: two missing below MIN_OPENINGS = 3.
    let mut sparse = f.clone();
    sparse.terminals.retain(|t| t.kind == Kind::Wall);
    sparse.terminals.push(terminal(Kind::Window, 1.0, 1.5));
    assert_eq!(global_violations(&sparse), MIN_OPENINGS - 1);
    assert_eq!(global_violations(&Facade::default()), MIN_OPENINGS);

    // Rule violations from the derivation count too, through `penalty`, on every objective.
    rising.violations = 3;
    let scored = score(&rising, &all);
    for (o, v) in all.iter().zip(&scored) {
        assert_eq!(*v, o.value(&rising) + 5.0 * PENALTY, "{o}");
    }
    assert_eq!(score(&f, &[]), Vec::<f64>::new());
}

#[test]
fn the_reference_point_is_one_penalty_per_objective() {
    assert_eq!(
        reference_point(&[Objective::Rectilinear, Objective::Monolithic]),
        vec![PENALTY, PENALTY]
    );
    // A penalised facade never dominates it; a clean one does.
    let f = clean_facade();
    let objs = [Objective::VerticalSymmetry, Objective::Fragmented];
    assert!(score(&f, &objs).iter().all(|v| *v < PENALTY));
    let mut bad = f;
    bad.violations = 1;
    assert!(score(&bad, &objs).iter().all(|v| *v >= PENALTY));
}
