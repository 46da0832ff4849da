//! NSGA-II's parts on hand-made sets (sort, crowding, hypervolume, operators, schedule), and
//! whole runs on a toy problem: convergence, thread-count independence, and the margin over
//! random search with the same number of evaluations.

use super::nsga2::*;
use crate::rng::Rng;

fn pts(v: &[&[f64]]) -> Vec<Vec<f64>> {
    v.iter().map(|p| p.to_vec()).collect()
}

/// The toy problem: 8 genes in 0..10; f1 = g0 + Σ others, f2 = (9 − g0) + Σ others. The
/// Pareto front is the 10 genomes whose other genes are all 0: (k, 9 − k), k = 0..9.
fn toy(g: &[u32]) -> Vec<f64> {
    let rest: u32 = g[1..].iter().sum();
    vec![f64::from(g[0] + rest), f64::from(9 - g[0] + rest)]
}

const TOY_ALPHABET: [u32; 8] = [10; 8];

fn toy_config(seed: u64) -> Config {
    Config {
        seed,
        reference: vec![80.0, 80.0],
        ..Config::default()
    }
}

/// The hypervolume of the toy problem's true front against (80, 80).
fn toy_optimum() -> f64 {
    let front: Vec<Vec<f64>> = (0..10).map(|k| vec![k as f64, 9.0 - k as f64]).collect();
    hypervolume(&front, &[80.0, 80.0])
}

#[test]
fn dominance_is_strict_on_one_objective() {
    assert!(dominates(&[1.0, 2.0], &[1.0, 3.0]));
    assert!(!dominates(&[1.0, 2.0], &[1.0, 2.0]));
    assert!(!dominates(&[1.0, 4.0], &[2.0, 3.0]));
    assert!(!dominates(&[f64::NAN, 1.0], &[2.0, 3.0]));
}

#[test]
fn sort_splits_a_hand_made_set_into_its_fronts() {
    // (1,5) (2,3) (3,1) are mutually non-dominated; (2,4) is dominated by (2,3) only;
    // (4,4) by (2,3), (3,1) and (2,4); (5,5) by everything else, (4,4) included.
    let objs = pts(&[
        &[1.0, 5.0],
        &[2.0, 3.0],
        &[3.0, 1.0],
        &[2.0, 4.0],
        &[4.0, 4.0],
        &[5.0, 5.0],
    ]);
    assert_eq!(
        fast_non_dominated_sort(&objs),
        vec![vec![0, 1, 2], vec![3], vec![4], vec![5]]
    );
    // Order of the input does not matter beyond the indices.
    let mut rev = objs.clone();
    rev.reverse();
    assert_eq!(
        fast_non_dominated_sort(&rev),
        vec![vec![3, 4, 5], vec![2], vec![1], vec![0]]
    );
    // Equal points share a front.
    let eq = pts(&[&[1.0, 1.0], &[1.0, 1.0], &[2.0, 2.0]]);
    assert_eq!(fast_non_dominated_sort(&eq), vec![vec![0, 1], vec![2]]);
    assert!(fast_non_dominated_sort(&[]).is_empty());
}

#[test]
fn crowding_on_a_four_point_front() {
    // Sorted on f1: 0, 1, 4, 5 (range 5); on f2: 0, 1, 3, 6 (range 6).
    // Point 1: (4 − 0)/5 + (6 − 1)/6 = 0.8 + 0.8333…; point 2: (5 − 1)/5 + (3 − 0)/6 = 0.8 + 0.5.
    let objs = pts(&[&[0.0, 6.0], &[1.0, 3.0], &[4.0, 1.0], &[5.0, 0.0]]);
    let d = crowding_distance(&[0, 1, 2, 3], &objs);
    assert_eq!(d[0], f64::INFINITY);
    assert_eq!(d[3], f64::INFINITY);
    assert!((d[1] - (0.8 + 5.0 / 6.0)).abs() < 1e-12, "{d:?}");
    assert!((d[2] - 1.3).abs() < 1e-12, "{d:?}");
    // A front listed in another order gives the same distances, aligned with it.
    let d2 = crowding_distance(&[2, 0, 3, 1], &objs);
    assert_eq!(d2[1], f64::INFINITY);
    assert!((d2[0] - 1.3).abs() < 1e-12);
    // Equal on one objective: it adds nothing and marks no end.
    let flat = pts(&[&[1.0, 0.0], &[1.0, 1.0], &[1.0, 3.0]]);
    let d3 = crowding_distance(&[0, 1, 2], &flat);
    assert_eq!(d3[0], f64::INFINITY);
    assert_eq!(d3[2], f64::INFINITY);
    assert!((d3[1] - 1.0).abs() < 1e-12, "{d3:?}");
    let all_equal = vec![vec![1.0, 1.0]; 3];
    assert_eq!(crowding_distance(&[0, 1, 2], &all_equal), vec![0.0; 3]);
    assert_eq!(crowding_distance(&[0, 1], &objs), vec![f64::INFINITY; 2]);
}

#[test]
fn selection_keeps_fronts_then_the_least_crowded_then_duplicates() {
    let objs = pts(&[
        &[0.0, 6.0],
        &[1.0, 3.0],
        &[4.0, 1.0],
        &[5.0, 0.0],
        &[6.0, 7.0],
    ]);
    let none = [false; 5];
    // The whole first front fits in 4; with 3, the least crowded inner point (1) stays.
    assert_eq!(select(&objs, &none, 4), vec![0, 1, 2, 3]);
    assert_eq!(select(&objs, &none, 3), vec![0, 3, 1]);
    assert_eq!(select(&objs, &none, 5), vec![0, 1, 2, 3, 4]);
    // A duplicate genome (index 1 flagged) goes after the distinct dominated point.
    let dup = [false, true, false, false, false];
    assert_eq!(select(&objs, &dup, 4), vec![0, 2, 3, 4]);
    assert_eq!(select(&objs, &dup, 5), vec![0, 2, 3, 4, 1]);
}

#[test]
fn hypervolume_of_known_2d_and_3d_sets() {
    assert_eq!(hypervolume(&pts(&[&[1.0, 1.0]]), &[2.0, 2.0]), 1.0);
    // Staircase: 3·1 + 2·1 + 1·1 = 6.
    let stairs = pts(&[&[1.0, 3.0], &[2.0, 2.0], &[3.0, 1.0]]);
    assert_eq!(hypervolume(&stairs, &[4.0, 4.0]), 6.0);
    // Dominated points, duplicates and points outside the reference add nothing.
    let mut noisy = stairs.clone();
    noisy.extend(pts(&[
        &[3.0, 3.0],
        &[2.0, 2.0],
        &[0.0, 4.0],
        &[5.0, 0.0],
        &[f64::NAN, 0.0],
    ]));
    assert_eq!(hypervolume(&noisy, &[4.0, 4.0]), 6.0);
    // Two points against (3, 4): 2·2 + 1·3 − overlap 1·2 = 5.
    assert_eq!(
        hypervolume(&pts(&[&[1.0, 2.0], &[2.0, 1.0]]), &[3.0, 4.0]),
        5.0
    );
    // 3D, by inclusion-exclusion against (3,3,3): a = (1,2,2) → 2, b = (2,1,1) → 4,
    // c = (2,2,0) → 3; a∩b = a∩c = a∩b∩c = (2,2,2) → 1, b∩c = (2,2,1) → 2. Union: 9 − 4 + 1 = 6.
    let r3 = [3.0, 3.0, 3.0];
    assert_eq!(
        hypervolume(&pts(&[&[1.0, 1.0, 1.0]]), &[2.0, 2.0, 2.0]),
        1.0
    );
    assert_eq!(
        hypervolume(&pts(&[&[1.0, 2.0, 2.0], &[2.0, 1.0, 1.0]]), &r3),
        5.0
    );
    let abc = pts(&[&[1.0, 2.0, 2.0], &[2.0, 1.0, 1.0], &[2.0, 2.0, 0.0]]);
    assert_eq!(hypervolume(&abc, &r3), 6.0);
    // 1D and 4D: the best value, and a single box.
    assert_eq!(hypervolume(&pts(&[&[3.0], &[1.0]]), &[4.0]), 3.0);
    assert_eq!(
        hypervolume(&pts(&[&[1.0, 1.0, 1.0, 1.0]]), &[2.0, 3.0, 4.0, 5.0]),
        24.0
    );
    assert_eq!(hypervolume(&stairs, &[]), 0.0);
}

/// The number of unit cells of `[0, side)^m` whose low corner some point weakly dominates:
/// the hypervolume of integer points against `(side, …, side)`, counted.
fn grid_count(points: &[Vec<f64>], m: usize, side: usize) -> usize {
    (0..side.pow(m as u32))
        .filter(|&cell| {
            let corner: Vec<f64> = (0..m)
                .map(|k| ((cell / side.pow(k as u32)) % side) as f64)
                .collect();
            points.iter().any(|p| (0..m).all(|k| p[k] <= corner[k]))
        })
        .count()
}

#[test]
fn hypervolume_matches_a_grid_count_in_3_4_and_5_dimensions() {
    let side = 6;
    for (m, seed) in [(3, 5), (3, 6), (4, 7), (4, 8), (5, 9)] {
        let mut rng = Rng::new(seed, 5);
        let points: Vec<Vec<f64>> = (0..15)
            .map(|_| {
                (0..m)
                    .map(|_| (rng.next_u64() % side as u64) as f64)
                    .collect()
            })
            .collect();
        let reference = vec![side as f64; m];
        assert_eq!(
            hypervolume(&points, &reference),
            grid_count(&points, m, side) as f64,
            "M = {m}, seed {seed}"
        );
    }
}

#[test]
fn mutation_schedule_runs_from_start_to_end() {
    assert_eq!(mutation_probability((0.5, 0.3), 0, 30), 0.5);
    assert!((mutation_probability((0.5, 0.3), 29, 30) - 0.3).abs() < 1e-15);
    assert!((mutation_probability((0.5, 0.3), 1, 30) - (0.5 - 0.2 / 29.0)).abs() < 1e-15);
    assert_eq!(mutation_probability((0.5, 0.3), 0, 1), 0.5);
    assert!((mutation_probability((0.5, 0.3), 99, 30) - 0.3).abs() < 1e-15);
    assert_eq!(mutation_probability((2.0, -1.0), 0, 2), 1.0);
    assert_eq!(mutation_probability((2.0, -1.0), 1, 2), 0.0);
    // A run to the cap records the schedule's ends on its first and last bred generations.
    let config = Config {
        generations: 12,
        window: 0,
        ..toy_config(3)
    };
    let h = run(&config, &TOY_ALPHABET, toy);
    assert_eq!(h.stopped, Stopped::Cap);
    assert_eq!(h.generations.len(), 13);
    assert_eq!(h.generations[1].mutation, 0.5);
    assert!((h.generations[12].mutation - 0.3).abs() < 1e-15);
}

#[test]
fn crossover_keeps_each_positions_genes_and_cuts_inside() {
    let mut rng = Rng::new(1, 2);
    let a: Vec<u32> = (0..8).collect();
    let b: Vec<u32> = (10..18).collect();
    let mut cuts = std::collections::BTreeSet::new();
    for _ in 0..200 {
        let (x, y) = crossover(&mut rng, 1.0, &a, &b);
        for i in 0..8 {
            let mut here = [x[i], y[i]];
            here.sort_unstable();
            assert_eq!(here, [a[i], b[i]]);
        }
        // One cut c in 1..8: x = a[..c] + b[c..].
        let c = x.iter().position(|g| *g >= 10).unwrap();
        assert!((1..8).contains(&c), "{x:?}");
        assert!(x[c..].iter().all(|g| *g >= 10) && y[..c].iter().all(|g| *g >= 10));
        cuts.insert(c);
    }
    assert_eq!(cuts.len(), 7, "every cut point is used");
    assert_eq!(crossover(&mut rng, 0.0, &a, &b), (a.clone(), b.clone()));
    assert_eq!(crossover(&mut rng, 1.0, &[1], &[2]), (vec![1], vec![2]));
}

#[test]
fn crossover_along_an_order_cuts_between_its_groups_and_draws_as_crossover_does() {
    // Genes of three "steps" stored apart, as the evolve genome does: (0, 1, 6), (2, 3, 7),
    // (4, 5, 8). Read in step order, a cut never splits a step's genes between parents at a
    // cut that falls between steps.
    let order = [0, 1, 6, 2, 3, 7, 4, 5, 8];
    let a: Vec<u32> = (0..9).collect();
    let b: Vec<u32> = (10..19).collect();
    let mut rng = Rng::new(4, 4);
    let mut twin = Rng::new(4, 4);
    let mut cuts = std::collections::BTreeSet::new();
    for _ in 0..300 {
        let (x, y) = crossover_along(&mut rng, 1.0, &a, &b, &order);
        // The same draws as the plain crossover: its cut, read along the order.
        let (px, _) = crossover(&mut twin, 1.0, &a, &b);
        let c = px.iter().position(|g| *g >= 10).unwrap();
        for (k, &i) in order.iter().enumerate() {
            let from_a = k < c;
            assert_eq!(x[i], if from_a { a[i] } else { b[i] }, "{x:?} cut {c}");
            assert_eq!(y[i], if from_a { b[i] } else { a[i] }, "{y:?} cut {c}");
        }
        cuts.insert(c);
    }
    assert_eq!(cuts.len(), 8, "every cut point is used");
    // Not a permutation of the positions (short, repeated, out of range): the genome's order.
    for bad in [
        &[0usize, 1][..],
        &[0, 0, 1, 2, 3, 4, 5, 6, 7],
        &[0, 1, 2, 3, 4, 5, 6, 7, 9],
    ] {
        let mut r1 = Rng::new(8, 1);
        let mut r2 = Rng::new(8, 1);
        assert_eq!(
            crossover_along(&mut r1, 1.0, &a, &b, bad),
            crossover(&mut r2, 1.0, &a, &b)
        );
    }
}

#[test]
fn evaluations_to_reach_is_the_first_generation_at_the_target() {
    let config = Config {
        population: 10,
        generations: 6,
        seed: 5,
        window: 0,
        reference: vec![10.0],
        ..Config::default()
    };
    // Minimise the sum of genes: the optimum, 0, is one genome among 8^4.
    let h = run(&config, &[8, 8, 8, 8], |g| {
        vec![g.iter().map(|&v| f64::from(v)).sum()]
    });
    let target = h.hypervolume;
    let e = h.evaluations_to_reach(target).unwrap();
    let first = h
        .generations
        .iter()
        .position(|g| g.hypervolume >= target)
        .unwrap();
    assert_eq!(e, h.generations[first].evaluations);
    assert!(h
        .generations
        .windows(2)
        .all(|w| w[0].evaluations <= w[1].evaluations));
    assert_eq!(h.generations.last().unwrap().evaluations, h.evaluations);
    assert_eq!(h.evaluations_to_reach(target + 1.0), None);
    assert_eq!(
        h.evaluations_to_reach(0.0),
        Some(h.generations[0].evaluations)
    );
}

#[test]
fn mutation_resets_one_gene_within_its_alphabet() {
    let mut rng = Rng::new(9, 9);
    let alphabet = [3, 1, 7, 0, 2];
    let base = vec![2, 0, 6, 0, 1];
    let mut changed = 0;
    for _ in 0..500 {
        let mut g = base.clone();
        let did = mutate(&mut rng, 1.0, &mut g, &alphabet);
        let diffs: Vec<usize> = (0..5).filter(|&i| g[i] != base[i]).collect();
        assert_eq!(did, diffs.len() == 1, "{g:?}");
        assert!(diffs.len() <= 1);
        for &i in &diffs {
            assert!(g[i] < alphabet[i], "{g:?}");
            assert!(i != 1 && i != 3, "single-value genes cannot change");
        }
        changed += usize::from(did);
        let mut h = base.clone();
        assert!(!mutate(&mut rng, 0.0, &mut h, &alphabet));
        assert_eq!(h, base);
    }
    // Genes 0, 2 and 4 of 5 can change: about 3/5 of the draws.
    assert!((250..350).contains(&changed), "{changed}");
}

#[test]
fn tournament_prefers_rank_then_crowding() {
    let mut rng = Rng::new(4, 4);
    let rank = [1, 0, 1, 1];
    let picks_best = (0..4000)
        .filter(|_| tournament(&mut rng, &rank, &[0.0; 4]) == 1)
        .count();
    // Index 1 wins whenever drawn: 1 − (3/4)² = 7/16 of the time.
    assert!((1600..1900).contains(&picks_best), "{picks_best}");
    let crowd = [0.0, 0.0, f64::INFINITY, 0.0];
    let picks_sparse = (0..4000)
        .filter(|_| tournament(&mut rng, &[0; 4], &crowd) == 2)
        .count();
    assert!((1600..1900).contains(&picks_sparse), "{picks_sparse}");
    assert_eq!(tournament(&mut rng, &[], &[]), 0);
}

#[test]
fn run_converges_on_the_toy_problem() {
    let config = Config {
        generations: 300,
        ..toy_config(11)
    };
    let h = run(&config, &TOY_ALPHABET, toy);
    let Stopped::Converged { generation } = h.stopped else {
        panic!("stopped by {:?}", h.stopped);
    };
    eprintln!(
        "toy problem, seed 11: converged at generation {generation}, {} evaluations",
        h.evaluations
    );
    assert_eq!(generation + 1, h.generations.len());
    assert!(generation < 300);
    // The whole true front, and nothing else, is found.
    let front: Vec<Vec<f64>> = h.front.iter().map(|i| i.objectives.clone()).collect();
    let expected: Vec<Vec<f64>> = (0..10).map(|k| vec![k as f64, 9.0 - k as f64]).collect();
    assert_eq!(front, expected);
    assert_eq!(h.hypervolume, toy_optimum());
    // The last window generations kept min and mean.
    let last = &h.generations[generation];
    let before = &h.generations[generation - config.window];
    assert_eq!((&last.min, &last.mean), (&before.min, &before.mean));
    assert!(h.evaluations <= 50 * h.generations.len());
}

#[test]
fn run_is_the_same_on_one_and_two_threads() {
    let config = toy_config(42);
    let pool = |n| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(n)
            .build()
            .unwrap()
    };
    let one = pool(1).install(|| run(&config, &TOY_ALPHABET, toy));
    let two = pool(2).install(|| run(&config, &TOY_ALPHABET, toy));
    assert_eq!(one, two);
    assert_eq!(
        serde_json::to_string(&one).unwrap(),
        serde_json::to_string(&two).unwrap()
    );
    let rs = |p: rayon::ThreadPool| p.install(|| random_search(&config, &TOY_ALPHABET, toy, 700));
    assert_eq!(rs(pool(1)), rs(pool(2)));
    // Another seed, another run.
    let other = run(&toy_config(43), &TOY_ALPHABET, toy);
    assert_ne!(one.generations[0], other.generations[0]);
}

#[test]
fn nsga2_beats_random_search_with_the_same_evaluations_on_ten_seeds() {
    let optimum = toy_optimum();
    for seed in 0..10 {
        let config = toy_config(seed);
        let ga = run(&config, &TOY_ALPHABET, toy);
        let rs = random_search(&config, &TOY_ALPHABET, toy, ga.evaluations);
        assert_eq!(rs.evaluations, ga.evaluations);
        assert_eq!(rs.stopped, Stopped::Budget);
        assert!(
            ga.hypervolume > rs.hypervolume,
            "seed {seed}: NSGA-II {} vs random {} ({} evaluations)",
            ga.hypervolume,
            rs.hypervolume,
            ga.evaluations
        );
        assert!(ga.hypervolume <= optimum && rs.hypervolume <= optimum);
        eprintln!(
            "seed {seed}: NSGA-II hv {} ({} gens, {:?}), random hv {}, {} evaluations, optimum {optimum}",
            ga.hypervolume,
            ga.generations.len() - 1,
            ga.stopped,
            rs.hypervolume,
            ga.evaluations
        );
    }
}

#[test]
fn odd_inputs_do_not_panic() {
    // Population below 2, empty genome, NaN and short evaluations, empty reference.
    let config = Config {
        population: 0,
        generations: 3,
        ..Config::default()
    };
    let h = run(&config, &[], |_| vec![f64::NAN]);
    assert_eq!(h.evaluations, 1);
    assert_eq!(h.front.len(), 1);
    assert_eq!(h.front[0].objectives, vec![f64::INFINITY]);
    let config = Config {
        reference: vec![10.0, 10.0, 10.0],
        generations: 3,
        ..Config::default()
    };
    let h = run(&config, &[2, 0, 3], |g| vec![f64::from(g[0])]);
    assert_eq!(h.objectives, 3);
    assert!(h.front.iter().all(|i| i.objectives.len() == 3));
    assert_eq!(h.hypervolume, 0.0);
    // A genome space smaller than the budget: random search stops when it is exhausted.
    let rs = random_search(&Config::default(), &[2, 2], |g| vec![f64::from(g[0])], 100);
    assert_eq!(rs.evaluations, 4);
}
