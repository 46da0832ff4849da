//! NSGA-II (Deb, Pratap, Agarwal & Meyarivan 2002) on fixed-length integer genomes, as seed 003
//! §3.7.2 uses it, and the random search it is compared against.
//!
//! Generic: a genome is a `Vec<u32>` whose gene `i` takes the values `0..alphabet[i]`, and the
//! caller's `eval` maps a genome to its objective values, all **minimised**. Nothing here knows
//! facades.
//!
//! One generation of [`run`]: binary tournaments by (rank, crowding) pick parents; one-point
//! crossover (probability [`Config::crossover`], the cut taken along [`Config::cut_order`]) makes
//! two children per pair; each child is
//! mutated with a probability falling linearly from [`Config::mutation`]`.0` to `.1` over the
//! generations (`mutation_probability`); the children are evaluated in parallel; parents ∪
//! children (2N) are cut back to N by fronts, then by crowding distance (`select`).
//!
//! **Mutation, per individual**: the thesis's 0.5 → 0.3 cannot be a per-gene rate (half the
//! genes reset at each generation would be a random search), so it is the probability that a
//! child is mutated at all; when it is, one gene, chosen uniformly, is reset to a different
//! value of its alphabet, chosen uniformly.
//!
//! **Novel children**: a child equal to a genome evaluated before, or to another child of the
//! generation, is mutated again, one gene at a time, up to `NOVEL_TRIES` times: in a
//! converging population most crossovers give back a parent, and an evaluation budget spent on
//! copies is an exploration lost (random search, its baseline, evaluates distinct genomes too).
//!
//! **Determinism**: every random draw is made in sequence from one [`Rng`] seeded by
//! [`Config::seed`], never inside the parallel evaluation, whose results are collected in index
//! order; so the result is the same whatever rayon's thread count. Evaluations are cached by
//! genome (a `BTreeMap`): a genome seen before is not evaluated again, and
//! [`History::evaluations`] counts the calls to `eval`.
//!
//! **Stopping** ([`Stopped`]): after each generation, when over the last [`Config::window`]
//! generations the population's minimum and mean of every objective have each changed by at
//! most [`Config::epsilon`] (relative to `max(1, |value|)`), the run has converged; otherwise it
//! stops at [`Config::generations`].
//!
//! **Hypervolume**: of the population (equivalently its first front) against
//! [`Config::reference`], a point the caller chooses and must keep the same for runs it compares
//! (`objectives::reference_point` for facades). Points that do not strictly dominate it add
//! nothing.

use std::cmp::Ordering;
use std::collections::{BTreeMap, BTreeSet};

use rayon::prelude::*;
use serde::Serialize;

use crate::rng::Rng;

/// How many times a child equal to a genome already evaluated (or to a sibling) is mutated
/// again (one gene each time) before it is kept as it is.
pub(crate) const NOVEL_TRIES: usize = 8;

/// The RNG stream of [`run`] (mixed with [`Config::seed`]).
const NSGA2_STREAM: u64 = 0x4E53_4741_2D49_4901;
/// The RNG stream of [`random_search`] (mixed with [`Config::seed`]).
const RANDOM_STREAM: u64 = 0x5241_4E44_4F4D_0001;

/// The settings of a run. [`Default`] gives the thesis's: population 50, 30 generations,
/// crossover 0.7, mutation 0.5 → 0.3; a window of 5 generations and a relative epsilon of
/// 1e-9 (unchanged, in practice) for the convergence test; seed 0; no reference point.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Config {
    /// Individuals per generation, N (raised to 2 if smaller).
    pub population: usize,
    /// The generation cap: the number of generations bred after the initial one.
    pub generations: usize,
    /// Probability that a pair of parents is crossed (one-point); otherwise the children are
    /// copies.
    pub crossover: f64,
    /// The gene positions in the order one-point crossover reads them: the cut falls between
    /// two consecutive entries, so genes that belong together (a step's action, arrangement and
    /// parameter, `super::genome::cut_order`) stay together. Empty: the genome's own order. A
    /// list that is not a permutation of the genome's positions is ignored (own order).
    pub cut_order: Vec<usize>,
    /// Mutation probability per child: `(first generation, last generation)`, linear between.
    pub mutation: (f64, f64),
    /// The run's seed.
    pub seed: u64,
    /// Convergence window, generations (0 disables the test: the run goes to the cap).
    pub window: usize,
    /// Convergence threshold: the largest change of each objective's population minimum and
    /// mean over the window, relative to `max(1, |value|)`.
    pub epsilon: f64,
    /// The hypervolume reference point, one value per objective. It also fixes the number of
    /// objectives M: `eval` results are cut or padded (with +∞) to its length. Empty: M is the
    /// length of the first evaluation and every hypervolume is 0.
    pub reference: Vec<f64>,
}

impl Default for Config {
    fn default() -> Self {
        Config {
            population: 50,
            generations: 30,
            crossover: 0.7,
            cut_order: Vec::new(),
            mutation: (0.5, 0.3),
            seed: 0,
            window: 5,
            epsilon: 1e-9,
            reference: Vec::new(),
        }
    }
}

/// One evaluated genome.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Individual {
    /// The genes; gene `i` is in `0..alphabet[i]`.
    pub genome: Vec<u32>,
    /// Its objective values, minimised (+∞ where `eval` gave NaN or too few values; written
    /// `null` in JSON).
    pub objectives: Vec<f64>,
}

/// One generation of a run.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Generation {
    /// 0 for the initial population, then 1, 2, …
    pub index: usize,
    /// The population after selection (NSGA-II), or the batch drawn (random search).
    pub individuals: Vec<Individual>,
    /// Hypervolume against [`Config::reference`]: of this population (NSGA-II), of everything
    /// evaluated so far (random search).
    pub hypervolume: f64,
    /// Per objective, the smallest value among `individuals`.
    pub min: Vec<f64>,
    /// Per objective, the mean value among `individuals`.
    pub mean: Vec<f64>,
    /// The mutation probability used to breed this generation (0 for the initial one and for
    /// random search).
    pub mutation: f64,
    /// Distinct genomes evaluated so far, this generation's included.
    pub evaluations: usize,
}

/// Why a run stopped.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(tag = "reason", rename_all = "snake_case")]
pub enum Stopped {
    /// The minimum and mean of every objective changed by at most epsilon over the window,
    /// checked after this generation.
    Converged {
        /// The last generation made.
        generation: usize,
    },
    /// The generation cap was reached.
    Cap,
    /// Random search: the evaluation budget was spent (or the genome space was exhausted).
    Budget,
}

/// A run's record.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct History {
    /// The settings used.
    pub config: Config,
    /// The number of objectives, M.
    pub objectives: usize,
    /// Every generation, the initial one first.
    pub generations: Vec<Generation>,
    /// The final first front: the non-dominated individuals of the last population (NSGA-II)
    /// or of everything evaluated (random search), one per distinct genome, sorted by objective
    /// values then genome.
    pub front: Vec<Individual>,
    /// The hypervolume of [`History::front`] against [`Config::reference`].
    pub hypervolume: f64,
    /// Why the run stopped.
    pub stopped: Stopped,
    /// Calls made to `eval` (distinct genomes).
    pub evaluations: usize,
}

impl History {
    /// The distinct evaluations made by the end of the first generation whose hypervolume
    /// reached `target` (within a relative 1e-12); `None` when none did. With `target` the
    /// final hypervolume it says how soon a run found what it ends with: the figure that still
    /// tells two runs apart when both end on the optimum.
    pub(crate) fn evaluations_to_reach(&self, target: f64) -> Option<usize> {
        let tolerance = 1e-12 * target.abs().max(1.0);
        self.generations
            .iter()
            .find(|g| g.hypervolume >= target - tolerance)
            .map(|g| g.evaluations)
    }
}

/// Whether `a` dominates `b` (minimisation): no worse on every objective, better on one.
/// Compares the common length; NaN compares as neither better nor worse.
pub(crate) fn dominates(a: &[f64], b: &[f64]) -> bool {
    let mut better = false;
    for (x, y) in a.iter().zip(b) {
        if x > y {
            return false;
        }
        if x < y {
            better = true;
        } else if x.partial_cmp(y).is_none() {
            return false;
        }
    }
    better
}

/// Fast non-dominated sort (Deb 2002), O(M N²): the indices of `objs` by front, the first
/// front (non-dominated) first; each front in ascending index order.
pub(crate) fn fast_non_dominated_sort(objs: &[Vec<f64>]) -> Vec<Vec<usize>> {
    let n = objs.len();
    let mut dominated_by_me: Vec<Vec<usize>> = vec![Vec::new(); n];
    let mut domination_count = vec![0usize; n];
    let mut fronts: Vec<Vec<usize>> = Vec::new();
    let mut current = Vec::new();
    for p in 0..n {
        for q in 0..n {
            if p == q {
                continue;
            }
            if dominates(&objs[p], &objs[q]) {
                dominated_by_me[p].push(q);
            } else if dominates(&objs[q], &objs[p]) {
                domination_count[p] += 1;
            }
        }
        if domination_count[p] == 0 {
            current.push(p);
        }
    }
    while !current.is_empty() {
        let mut next = Vec::new();
        for &p in &current {
            for &q in &dominated_by_me[p] {
                domination_count[q] -= 1;
                if domination_count[q] == 0 {
                    next.push(q);
                }
            }
        }
        next.sort_unstable();
        fronts.push(std::mem::replace(&mut current, next));
    }
    fronts
}

/// Crowding distances (Deb 2002) of the members of one front, aligned with `front` (whose
/// entries index `objs`). Per objective, the members are sorted by value (ties by position in
/// `front`); the two ends get +∞ and each inner member adds `(next − previous) / (max − min)`.
/// An objective on which the whole front is equal (max = min) adds nothing and marks no end.
/// Fronts of one or two members are all +∞.
pub(crate) fn crowding_distance(front: &[usize], objs: &[Vec<f64>]) -> Vec<f64> {
    let k = front.len();
    let mut distance = vec![0.0; k];
    if k <= 2 {
        return vec![f64::INFINITY; k];
    }
    let m = front
        .iter()
        .map(|&i| objs.get(i).map_or(0, Vec::len))
        .min()
        .unwrap_or(0);
    let value = |pos: usize, obj: usize| objs[front[pos]][obj];
    for obj in 0..m {
        let mut order: Vec<usize> = (0..k).collect();
        order.sort_by(|&a, &b| value(a, obj).total_cmp(&value(b, obj)).then(a.cmp(&b)));
        let lo = value(order[0], obj);
        let hi = value(order[k - 1], obj);
        let range = hi - lo;
        if range.is_nan() || range <= 0.0 {
            continue;
        }
        distance[order[0]] = f64::INFINITY;
        distance[order[k - 1]] = f64::INFINITY;
        for w in 1..k - 1 {
            let d = (value(order[w + 1], obj) - value(order[w - 1], obj)) / range;
            if d.is_finite() {
                distance[order[w]] += d;
            }
        }
    }
    distance
}

/// The mutation probability of bred generation `step` of `steps` (0-based): `schedule.0` at the
/// first, `schedule.1` at the last, linear between; `schedule.0` when `steps <= 1`. Clamped
/// to [0, 1].
pub(crate) fn mutation_probability(schedule: (f64, f64), step: usize, steps: usize) -> f64 {
    let (start, end) = schedule;
    let p = if steps <= 1 {
        start
    } else {
        let t = step.min(steps - 1) as f64 / (steps - 1) as f64;
        start + (end - start) * t
    };
    if p.is_nan() {
        0.0
    } else {
        p.clamp(0.0, 1.0)
    }
}

/// Uniform integer in `0..n` (0 when `n` is 0), by multiply-high.
fn below(rng: &mut Rng, n: u64) -> u64 {
    ((u128::from(rng.next_u64()) * u128::from(n)) >> 64) as u64
}

/// The number of values of gene `i` (an alphabet entry of 0 is read as 1: the gene is always 0).
fn gene_values(alphabet: &[u32], i: usize) -> u32 {
    alphabet.get(i).copied().unwrap_or(1).max(1)
}

/// A uniformly random genome of `alphabet`.
pub(crate) fn random_genome(rng: &mut Rng, alphabet: &[u32]) -> Vec<u32> {
    (0..alphabet.len())
        .map(|i| below(rng, u64::from(gene_values(alphabet, i))) as u32)
        .collect()
}

/// One-point crossover: with probability `p`, a cut `c` uniform in `1..len` and the children
/// `a[..c] + b[c..]` and `b[..c] + a[c..]`; otherwise (or for genomes shorter than 2, or of
/// different lengths) copies of the parents. Either way, at each position the two children
/// hold the parents' two genes.
#[cfg(test)]
pub(crate) fn crossover(rng: &mut Rng, p: f64, a: &[u32], b: &[u32]) -> (Vec<u32>, Vec<u32>) {
    crossover_along(rng, p, a, b, &[])
}

/// [`crossover`] with the genome read in `order` (gene positions): the children take the genes
/// of `order[..c]` from one parent and those of `order[c..]` from the other. An `order` that is
/// not a permutation of `0..len` is replaced by the genome's own order. Draws from `rng` exactly
/// as [`crossover`] does.
pub(crate) fn crossover_along(
    rng: &mut Rng,
    p: f64,
    a: &[u32],
    b: &[u32],
    order: &[usize],
) -> (Vec<u32>, Vec<u32>) {
    let fires = rng.next_f64() < p;
    let len = a.len();
    if !fires || len < 2 || b.len() != len {
        return (a.to_vec(), b.to_vec());
    }
    let cut = 1 + below(rng, (len - 1) as u64) as usize;
    let own: Vec<usize>;
    let order = if is_permutation(order, len) {
        order
    } else {
        own = (0..len).collect();
        &own
    };
    let (mut x, mut y) = (a.to_vec(), b.to_vec());
    for &i in &order[cut..] {
        x[i] = b[i];
        y[i] = a[i];
    }
    (x, y)
}

/// Whether `order` holds each of `0..len` once.
fn is_permutation(order: &[usize], len: usize) -> bool {
    let mut seen = vec![false; len];
    order.len() == len
        && order
            .iter()
            .all(|&i| i < len && !std::mem::replace(&mut seen[i], true))
}

/// Random-reset mutation, per individual: with probability `p`, one gene chosen uniformly is
/// set to another value of its alphabet, chosen uniformly (a gene with a single value cannot
/// change). Returns whether the genome changed.
pub(crate) fn mutate(rng: &mut Rng, p: f64, genome: &mut [u32], alphabet: &[u32]) -> bool {
    if genome.is_empty() || rng.next_f64() >= p {
        return false;
    }
    let i = below(rng, genome.len() as u64) as usize;
    let values = gene_values(alphabet, i);
    if values < 2 {
        return false;
    }
    let shift = 1 + below(rng, u64::from(values - 1)) as u32;
    genome[i] = (genome[i].min(values - 1) + shift) % values;
    true
}

/// Each individual's front rank (0 = first front) and crowding distance within its front.
pub(crate) fn rank_and_crowding(objs: &[Vec<f64>]) -> (Vec<usize>, Vec<f64>) {
    let mut rank = vec![0usize; objs.len()];
    let mut crowd = vec![0.0; objs.len()];
    for (r, front) in fast_non_dominated_sort(objs).iter().enumerate() {
        for (&i, d) in front.iter().zip(crowding_distance(front, objs)) {
            rank[i] = r;
            crowd[i] = d;
        }
    }
    (rank, crowd)
}

/// Binary tournament: two indices drawn uniformly (with replacement); the lower rank wins, then
/// the larger crowding distance, then the first drawn.
/// Returns 0 for an empty population; a missing crowding distance reads as 0.
pub(crate) fn tournament(rng: &mut Rng, rank: &[usize], crowd: &[f64]) -> usize {
    if rank.is_empty() {
        return 0;
    }
    let n = rank.len() as u64;
    let a = below(rng, n) as usize;
    let b = below(rng, n) as usize;
    let c = |i: usize| crowd.get(i).copied().unwrap_or(0.0);
    let better = match rank[b].cmp(&rank[a]) {
        Ordering::Less => true,
        Ordering::Greater => false,
        Ordering::Equal => c(b) > c(a),
    };
    if better {
        b
    } else {
        a
    }
}

/// Elitist environmental selection: the indices of the `n` survivors among `objs` (parents ∪
/// offspring), whole fronts first, the last front admitted cut by crowding distance (largest
/// first, ties by index). Candidates whose genome repeats an earlier one's (`duplicate[i]`) are
/// taken only when the distinct ones do not fill `n`, so the population keeps its diversity.
pub(crate) fn select(objs: &[Vec<f64>], duplicate: &[bool], n: usize) -> Vec<usize> {
    let unique: Vec<usize> = (0..objs.len())
        .filter(|&i| !duplicate.get(i).copied().unwrap_or(false))
        .collect();
    let mut chosen = select_distinct(objs, &unique, n);
    if chosen.len() < n {
        let repeats: Vec<usize> = (0..objs.len())
            .filter(|&i| duplicate.get(i).copied().unwrap_or(false))
            .collect();
        chosen.extend(select_distinct(objs, &repeats, n - chosen.len()));
    }
    chosen
}

/// [`select`] among the candidates `among` (indices into `objs`).
fn select_distinct(objs: &[Vec<f64>], among: &[usize], n: usize) -> Vec<usize> {
    let sub: Vec<Vec<f64>> = among.iter().map(|&i| objs[i].clone()).collect();
    let mut chosen = Vec::with_capacity(n);
    for front in fast_non_dominated_sort(&sub) {
        if chosen.len() + front.len() <= n {
            chosen.extend(front.iter().map(|&i| among[i]));
            continue;
        }
        let crowd = crowding_distance(&front, &sub);
        let mut order: Vec<usize> = (0..front.len()).collect();
        order.sort_by(|&a, &b| crowd[b].total_cmp(&crowd[a]).then(front[a].cmp(&front[b])));
        let room = n - chosen.len();
        chosen.extend(order.iter().take(room).map(|&k| among[front[k]]));
        break;
    }
    chosen
}

/// The hypervolume dominated by `points` and bounded by `reference`, for minimisation: the
/// measure of the union of the boxes `[p, reference]`. Only points strictly better than the
/// reference on every objective count (others, and points with NaN, are ignored); the
/// dimension is `reference.len()` (points must have at least as many values; extra ones are
/// ignored). Exact: a sweep for M ≤ 2, the WFG algorithm for M ≥ 3 (exclusive volumes,
/// recursively on the non-dominated limited sets). Fast enough for a run's population
/// (N = 50) with all six objectives.
pub(crate) fn hypervolume(points: &[Vec<f64>], reference: &[f64]) -> f64 {
    let m = reference.len();
    if m == 0 {
        return 0.0;
    }
    let mut inside: Vec<Vec<f64>> = points
        .iter()
        .filter(|p| p.len() >= m && (0..m).all(|k| p[k] < reference[k]))
        .map(|p| p[..m].to_vec())
        .collect();
    inside.sort_by(|a, b| cmp_values(a, b));
    inside.dedup();
    hv_rec(inside, reference)
}

/// Lexicographic total order on objective vectors.
fn cmp_values(a: &[f64], b: &[f64]) -> Ordering {
    a.iter()
        .zip(b)
        .map(|(x, y)| x.total_cmp(y))
        .find(|o| o.is_ne())
        .unwrap_or(a.len().cmp(&b.len()))
}

/// [`hypervolume`] of points already inside the reference box, distinct, all of `reference`'s
/// dimension.
fn hv_rec(points: Vec<Vec<f64>>, reference: &[f64]) -> f64 {
    match reference.len() {
        0 => 0.0,
        1 => points
            .iter()
            .map(|p| reference[0] - p[0])
            .fold(0.0, f64::max),
        2 => {
            let mut pts = points;
            pts.sort_by(|a, b| cmp_values(a, b));
            let mut area = 0.0;
            let mut lowest = reference[1];
            for p in &pts {
                if p[1] < lowest {
                    area += (reference[0] - p[0]) * (lowest - p[1]);
                    lowest = p[1];
                }
            }
            area
        }
        _ => wfg(non_dominated(&points), reference),
    }
}

/// WFG (While, Bradstreet & Barone 2012) on distinct non-dominated points: the sum over the
/// points of their exclusive volumes, each its box minus the volume of the later points
/// limited to it (component-wise max, minimisation), recursively. Points are taken in
/// ascending order of the last objective, which keeps the limited sets small.
fn wfg(mut points: Vec<Vec<f64>>, reference: &[f64]) -> f64 {
    let last = reference.len() - 1;
    points.sort_by(|a, b| a[last].total_cmp(&b[last]).then(cmp_values(a, b)));
    let mut volume = 0.0;
    for (k, p) in points.iter().enumerate() {
        let own: f64 = p.iter().zip(reference).map(|(x, r)| r - x).product();
        let limited: Vec<Vec<f64>> = points[k + 1..]
            .iter()
            .map(|q| q.iter().zip(p).map(|(a, b)| a.max(*b)).collect())
            .collect();
        let shared = if limited.is_empty() {
            0.0
        } else {
            hv_rec(limited, reference)
        };
        volume += own - shared;
    }
    volume
}

/// The distinct non-dominated points of a set.
fn non_dominated(points: &[Vec<f64>]) -> Vec<Vec<f64>> {
    let mut out: Vec<Vec<f64>> = points
        .iter()
        .filter(|p| !points.iter().any(|q| dominates(q, p)))
        .cloned()
        .collect();
    out.sort_by(|a, b| cmp_values(a, b));
    out.dedup();
    out
}

/// Objective values made well-formed: exactly `m` values (cut, or padded with +∞), NaN → +∞.
fn normalise(mut values: Vec<f64>, m: usize) -> Vec<f64> {
    values.resize(m, f64::INFINITY);
    for v in &mut values {
        if v.is_nan() {
            *v = f64::INFINITY;
        }
    }
    values
}

/// The evaluation cache and counter shared by [`run`] and [`random_search`].
struct Evaluator<'a, F> {
    eval: &'a F,
    cache: BTreeMap<Vec<u32>, Vec<f64>>,
    objectives: Option<usize>,
    calls: usize,
}

impl<'a, F> Evaluator<'a, F>
where
    F: Fn(&[u32]) -> Vec<f64> + Sync,
{
    fn new(eval: &'a F, reference: &[f64]) -> Self {
        Evaluator {
            eval,
            cache: BTreeMap::new(),
            objectives: (!reference.is_empty()).then_some(reference.len()),
            calls: 0,
        }
    }

    /// Whether `genome` was evaluated before.
    fn seen(&self, genome: &[u32]) -> bool {
        self.cache.contains_key(genome)
    }

    /// Evaluates the genomes not seen before, in parallel, in index order, then returns every
    /// genome's values.
    fn evaluate(&mut self, genomes: &[Vec<u32>]) -> Vec<Vec<f64>> {
        let mut todo: Vec<&Vec<u32>> = Vec::new();
        let mut queued: BTreeSet<&Vec<u32>> = BTreeSet::new();
        for g in genomes {
            if !self.cache.contains_key(g) && queued.insert(g) {
                todo.push(g);
            }
        }
        let eval = self.eval;
        let results: Vec<Vec<f64>> = todo.par_iter().map(|g| eval(g)).collect();
        self.calls += todo.len();
        for (g, values) in todo.into_iter().zip(results) {
            let m = *self.objectives.get_or_insert(values.len());
            self.cache.insert(g.clone(), normalise(values, m));
        }
        genomes
            .iter()
            .map(|g| self.cache.get(g).cloned().unwrap_or_default())
            .collect()
    }

    fn objectives(&self) -> usize {
        self.objectives.unwrap_or(0)
    }
}

/// Per objective, the minimum and the mean over a set of objective vectors (0 when empty).
fn min_mean(objs: &[Vec<f64>], m: usize) -> (Vec<f64>, Vec<f64>) {
    let mut min = vec![0.0; m];
    let mut mean = vec![0.0; m];
    if objs.is_empty() {
        return (min, mean);
    }
    for k in 0..m {
        let column = objs
            .iter()
            .map(|o| o.get(k).copied().unwrap_or(f64::INFINITY));
        min[k] = column.clone().fold(f64::INFINITY, f64::min);
        mean[k] = column.sum::<f64>() / objs.len() as f64;
    }
    (min, mean)
}

/// A generation's record.
fn record(
    index: usize,
    genomes: &[Vec<u32>],
    objs: &[Vec<f64>],
    m: usize,
    hv: f64,
    mutation: f64,
    evaluations: usize,
) -> Generation {
    let (min, mean) = min_mean(objs, m);
    Generation {
        index,
        individuals: genomes
            .iter()
            .zip(objs)
            .map(|(g, o)| Individual {
                genome: g.clone(),
                objectives: o.clone(),
            })
            .collect(),
        hypervolume: hv,
        min,
        mean,
        mutation,
        evaluations,
    }
}

/// Whether `a` and `b` differ by at most `epsilon` relative to `max(1, |a|, |b|)` (equal
/// infinities are equal).
fn unchanged(a: f64, b: f64, epsilon: f64) -> bool {
    a == b || (a - b).abs() <= epsilon * 1f64.max(a.abs()).max(b.abs())
}

/// Whether the last `window` + 1 generations kept every objective's min and mean within
/// epsilon of the latest.
fn converged(generations: &[Generation], window: usize, epsilon: f64) -> bool {
    if window == 0 || generations.len() <= window {
        return false;
    }
    let recent = &generations[generations.len() - 1 - window..];
    let last = &recent[window];
    recent.iter().all(|g| {
        g.min
            .iter()
            .zip(&last.min)
            .chain(g.mean.iter().zip(&last.mean))
            .all(|(a, b)| unchanged(*a, *b, epsilon))
    })
}

/// The distinct non-dominated individuals among `genomes`/`objs`, sorted by values then genome.
fn first_front(genomes: &[Vec<u32>], objs: &[Vec<f64>]) -> Vec<Individual> {
    let fronts = fast_non_dominated_sort(objs);
    let mut front: Vec<Individual> = fronts
        .first()
        .map(|f| {
            f.iter()
                .map(|&i| Individual {
                    genome: genomes[i].clone(),
                    objectives: objs[i].clone(),
                })
                .collect()
        })
        .unwrap_or_default();
    front.sort_by(|a, b| cmp_values(&a.objectives, &b.objectives).then(a.genome.cmp(&b.genome)));
    front.dedup_by(|a, b| a.genome == b.genome);
    front
}

/// The values of a list of individuals.
fn values_of(individuals: &[Individual]) -> Vec<Vec<f64>> {
    individuals.iter().map(|i| i.objectives.clone()).collect()
}

/// Runs NSGA-II: a random initial population of [`Config::population`] genomes of `alphabet`,
/// then generations bred as the module docs say, until convergence or the cap. `eval` gives a
/// genome's objective values (minimised); it runs in parallel (rayon) and must be pure for the
/// run to be deterministic.
pub fn run<F>(config: &Config, alphabet: &[u32], eval: F) -> History
where
    F: Fn(&[u32]) -> Vec<f64> + Sync,
{
    let n = config.population.max(2);
    let mut rng = Rng::new(config.seed, NSGA2_STREAM);
    let mut evaluator = Evaluator::new(&eval, &config.reference);

    let mut genomes: Vec<Vec<u32>> = (0..n).map(|_| random_genome(&mut rng, alphabet)).collect();
    let mut objs = evaluator.evaluate(&genomes);
    let m = evaluator.objectives();
    let mut generations = vec![record(
        0,
        &genomes,
        &objs,
        m,
        hypervolume(&objs, &config.reference),
        0.0,
        evaluator.calls,
    )];
    let mut stopped = Stopped::Cap;

    for step in 0..config.generations {
        let p_mut = mutation_probability(config.mutation, step, config.generations);
        let (rank, crowd) = rank_and_crowding(&objs);
        let mut children: Vec<Vec<u32>> = Vec::with_capacity(n + 1);
        while children.len() < n {
            let a = tournament(&mut rng, &rank, &crowd);
            let b = tournament(&mut rng, &rank, &crowd);
            let (mut x, mut y) = crossover_along(
                &mut rng,
                config.crossover,
                &genomes[a],
                &genomes[b],
                &config.cut_order,
            );
            mutate(&mut rng, p_mut, &mut x, alphabet);
            mutate(&mut rng, p_mut, &mut y, alphabet);
            for mut c in [x, y] {
                // A child seen before would cost nothing and add nothing: mutated again.
                let mut tries = 0;
                while tries < NOVEL_TRIES && (evaluator.seen(&c) || children.contains(&c)) {
                    mutate(&mut rng, 1.0, &mut c, alphabet);
                    tries += 1;
                }
                children.push(c);
            }
        }
        children.truncate(n);
        let child_objs = evaluator.evaluate(&children);

        let pool: Vec<Vec<u32>> = genomes.iter().chain(&children).cloned().collect();
        let pool_objs: Vec<Vec<f64>> = objs.iter().chain(&child_objs).cloned().collect();
        let mut seen = BTreeSet::new();
        let duplicate: Vec<bool> = pool.iter().map(|g| !seen.insert(g)).collect();
        let survivors = select(&pool_objs, &duplicate, n);
        genomes = survivors.iter().map(|&i| pool[i].clone()).collect();
        objs = survivors.iter().map(|&i| pool_objs[i].clone()).collect();

        let hv = hypervolume(&objs, &config.reference);
        generations.push(record(
            step + 1,
            &genomes,
            &objs,
            m,
            hv,
            p_mut,
            evaluator.calls,
        ));
        if converged(&generations, config.window, config.epsilon) {
            stopped = Stopped::Converged {
                generation: step + 1,
            };
            break;
        }
    }

    let front = first_front(&genomes, &objs);
    let hypervolume = hypervolume(&values_of(&front), &config.reference);
    History {
        config: config.clone(),
        objectives: m,
        generations,
        front,
        hypervolume,
        stopped,
        evaluations: evaluator.calls,
    }
}

/// Random search, the baseline: uniformly random genomes of `alphabet` until `evaluations`
/// distinct ones have been evaluated (or 100 × `evaluations` draws found no more new ones), in
/// batches of [`Config::population`], each batch evaluated in parallel. Each batch is recorded
/// as a generation whose hypervolume is that of everything evaluated so far; the front is the
/// non-dominated set of everything evaluated. Uses [`Config::seed`] (on its own RNG stream),
/// [`Config::population`] and [`Config::reference`] only; stops with [`Stopped::Budget`].
pub(crate) fn random_search<F>(
    config: &Config,
    alphabet: &[u32],
    eval: F,
    evaluations: usize,
) -> History
where
    F: Fn(&[u32]) -> Vec<f64> + Sync,
{
    let n = config.population.max(2);
    let mut rng = Rng::new(config.seed, RANDOM_STREAM);
    let mut evaluator = Evaluator::new(&eval, &config.reference);
    let mut seen: BTreeSet<Vec<u32>> = BTreeSet::new();
    // The non-dominated set of everything evaluated so far, kept as batches arrive.
    let mut archive: Vec<Individual> = Vec::new();
    let mut generations = Vec::new();
    let mut draws_left = evaluations.saturating_mul(100);

    while seen.len() < evaluations && draws_left > 0 {
        let want = n.min(evaluations - seen.len());
        let mut batch = Vec::with_capacity(want);
        while batch.len() < want && draws_left > 0 {
            draws_left -= 1;
            let g = random_genome(&mut rng, alphabet);
            if seen.insert(g.clone()) {
                batch.push(g);
            }
        }
        if batch.is_empty() {
            break;
        }
        let objs = evaluator.evaluate(&batch);
        let genomes: Vec<Vec<u32>> = archive
            .iter()
            .map(|i| i.genome.clone())
            .chain(batch.iter().cloned())
            .collect();
        let values: Vec<Vec<f64>> = values_of(&archive)
            .into_iter()
            .chain(objs.clone())
            .collect();
        archive = first_front(&genomes, &values);
        let hv = hypervolume(&values_of(&archive), &config.reference);
        let m = evaluator.objectives();
        generations.push(record(
            generations.len(),
            &batch,
            &objs,
            m,
            hv,
            0.0,
            evaluator.calls,
        ));
    }

    let hypervolume = hypervolume(&values_of(&archive), &config.reference);
    History {
        config: config.clone(),
        objectives: evaluator.objectives(),
        generations,
        front: archive,
        hypervolume,
        stopped: Stopped::Budget,
        evaluations: evaluator.calls,
    }
}
