//! The genome: a fixed-length integer chromosome (seed 003 §3.7.2.6-7), and what each gene means.
//!
//! The thesis prints its chromosomes (30 genes: 20 in {0, 1, 2}, then 10 in {0..6}) and names
//! two *actions* (`ajoute`, `contient`), three *arrangements* (vertical repetition, horizontal
//! repetition, grid) and numeric *parameters* (the number of repetitions and divisions), but
//! not how the genes map to them. citygen's decoding:
//!
//! * **Layout.** 10 steps. Step `k` (1-based, `k` = 1..=10) reads the action gene `2(k−1)`,
//!   the arrangement gene `2(k−1) + 1` and the parameter gene `20 + (k−1)`. Genes 0..20 are
//!   in {0, 1, 2}, genes 20..30 in {0..6} (`alphabet`).
//! * **Action** (gene value → [`Action`]): 0 = `ajoute`, 1 = `contient`, 2 = skip (the step
//!   does nothing: the thesis names two actions but its genes take three values, and a neutral
//!   value lets a chromosome use fewer than 10 steps). Their effect on the rules is specified
//!   in [`super::decode`](mod@super::decode).
//! * **Arrangement** (→ [`Arrangement`]): 0 = vertical repetition (rows, along Z), 1 =
//!   horizontal repetition (columns, along X), 2 = grid (rows × columns).
//! * **Parameter** `p` (0..=6) → the count `n = p + 1` (1..=7): the number of repetitions of a
//!   vertical or horizontal repetition, the number of rows and of columns of a grid (1 to 49
//!   cells), and the number of pieces of an `ajoute` alternation — lowered by the decoder where
//!   pieces would be under 0.3 m ([`super::decode::MIN_PIECE`]).
//!
//! * **Crossover** cuts between steps (`cut_order`), so a child inherits whole steps.
//!
//! A genome of any other length, or with a gene outside its alphabet, is rejected with an error
//! naming the gene: the thesis's rectilinear + monolithic chromosome (Fig. 3.44) has 29 genes,
//! one parameter lost in print; it decodes once a parameter is appended (see the tests).

use super::EvolveError;
#[cfg(test)]
use crate::rng::Rng;

/// Genes in a genome.
pub(crate) const LENGTH: usize = 30;

/// Steps a genome describes (one action, one arrangement and one parameter each).
pub(crate) const STEPS: usize = 10;

/// Values an action gene takes (0 `ajoute`, 1 `contient`, 2 skip).
pub(crate) const ACTIONS: u32 = 3;

/// Values an arrangement gene takes (0 vertical, 1 horizontal, 2 grid).
pub(crate) const ARRANGEMENTS: u32 = 3;

/// Values a parameter gene takes (0..=6, a count of 1..=7).
pub(crate) const PARAMETERS: u32 = 7;

/// The number of values each gene may take: 20 × 3 (action and arrangement genes, interleaved),
/// then 10 × 7 (parameter genes). Gene `i` is valid when `gene < alphabet()[i]`.
pub(crate) fn alphabet() -> [u32; LENGTH] {
    let mut a = [PARAMETERS; LENGTH];
    for (i, v) in a.iter_mut().enumerate().take(2 * STEPS) {
        *v = if i % 2 == 0 { ACTIONS } else { ARRANGEMENTS };
    }
    a
}

/// The gene positions step by step (`0, 1, 20, 2, 3, 21, …`: step `k`'s action, arrangement and
/// parameter), the order one-point crossover reads a genome in (`nsga2::Config::cut_order`):
/// the thesis prints the actions and arrangements first and the parameters after, and a cut in
/// that order would give a child the first steps of one parent with every parameter of the
/// other, breaking each step it crosses. Cut between steps, a child inherits whole steps.
pub(crate) fn cut_order() -> Vec<usize> {
    (0..STEPS)
        .flat_map(|k| [2 * k, 2 * k + 1, 2 * STEPS + k])
        .collect()
}

/// What a step does to the rules (see [`super::decode`](mod@super::decode) for the rules each one writes).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Action {
    /// Gene 0, `ajoute` ("adds"): rewrites the rule that made the last concerned shape so that
    /// it makes the step's arrangement of the new marker alternating with that shape.
    Ajoute,
    /// Gene 1, `contient` ("contains"): keeps every rule and adds one that subdivides the last
    /// concerned shape into the step's arrangement of a new marker.
    Contient,
    /// Gene 2: the step does nothing.
    Skip,
}

/// How the pieces of a subdivision are laid out.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Arrangement {
    /// Gene 0: rows, stacked bottom to top (a `repeat` along Z).
    Vertical,
    /// Gene 1: columns, left to right (a `repeat` along X).
    Horizontal,
    /// Gene 2: rows of columns (a `repeat` along Z, each row a `repeat` along X).
    Grid,
}

/// One decoded step of a genome.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Step {
    /// The iteration, 1..=10: the number its marker carries (`shape3` is made by step 3).
    pub iteration: usize,
    /// The action.
    pub action: Action,
    /// The arrangement.
    pub arrangement: Arrangement,
    /// The parameter gene, 0..=6.
    pub parameter: u32,
}

impl Step {
    /// The count the parameter gives: `parameter + 1` (1..=7) repetitions, rows and columns of
    /// a grid, or pieces of an alternation.
    pub fn count(&self) -> usize {
        self.parameter as usize + 1
    }
}

/// A valid genome: `LENGTH` genes, each within its `alphabet`.
#[derive(Clone, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct Genome(Vec<u32>);

impl Genome {
    /// Checks `genes` and wraps them. The error names the length or the first gene out of its
    /// alphabet (`gene 21 is 9, expected 0..=6 (a parameter)`).
    pub(crate) fn new(genes: &[u32]) -> Result<Genome, EvolveError> {
        if genes.len() != LENGTH {
            return Err(EvolveError::GenomeLength { found: genes.len() });
        }
        let alpha = alphabet();
        for (i, (&g, &a)) in genes.iter().zip(alpha.iter()).enumerate() {
            if g >= a {
                let what = if i >= 2 * STEPS {
                    "a parameter"
                } else if i % 2 == 0 {
                    "an action"
                } else {
                    "an arrangement"
                };
                return Err(EvolveError::Gene {
                    index: i,
                    value: g,
                    max: a - 1,
                    what,
                });
            }
        }
        Ok(Genome(genes.to_vec()))
    }

    /// A uniformly random genome (each gene uniform in its alphabet), drawn from `rng`.
    #[cfg(test)]
    pub(crate) fn random(rng: &mut Rng) -> Genome {
        let genes = alphabet()
            .iter()
            .map(|&a| ((rng.next_f64() * f64::from(a)) as u32).min(a - 1))
            .collect();
        Genome(genes)
    }

    /// The genes.
    pub(crate) fn genes(&self) -> &[u32] {
        &self.0
    }

    /// The 10 steps, in order (see the module docs for which genes each reads).
    pub(crate) fn steps(&self) -> Vec<Step> {
        (0..STEPS)
            .map(|s| {
                let g = |i: usize| self.0.get(i).copied().unwrap_or(0);
                Step {
                    iteration: s + 1,
                    action: match g(2 * s) {
                        0 => Action::Ajoute,
                        1 => Action::Contient,
                        _ => Action::Skip,
                    },
                    arrangement: match g(2 * s + 1) {
                        0 => Arrangement::Vertical,
                        1 => Arrangement::Horizontal,
                        _ => Arrangement::Grid,
                    },
                    parameter: g(2 * STEPS + s),
                }
            })
            .collect()
    }
}

impl std::fmt::Display for Genome {
    /// The genes as the thesis prints them: `[1, 2, 2, …]`.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("[")?;
        for (i, g) in self.0.iter().enumerate() {
            if i > 0 {
                f.write_str(", ")?;
            }
            write!(f, "{g}")?;
        }
        f.write_str("]")
    }
}

/// The chromosomes printed in the thesis (seed 003 Figs 3.38, 3.40, 3.42, 3.44), verbatim:
/// horizontal symmetry, vertical symmetry (identical to the first, as printed), both
/// symmetries, rectilinear + monolithic (29 genes as printed).
#[cfg(test)]
pub(crate) const THESIS_CHROMOSOMES: [&[u32]; 4] = [
    &[
        1, 2, 2, 2, 0, 0, 1, 2, 0, 1, 1, 0, 2, 0, 0, 0, 2, 0, 2, 2, 2, 5, 3, 3, 3, 6, 5, 4, 4, 3,
    ],
    &[
        1, 2, 2, 2, 0, 0, 1, 2, 0, 1, 1, 0, 2, 0, 0, 0, 2, 0, 2, 2, 2, 5, 3, 3, 3, 6, 5, 4, 4, 3,
    ],
    &[
        2, 2, 1, 2, 2, 0, 2, 2, 1, 2, 1, 0, 0, 2, 2, 0, 2, 2, 2, 2, 5, 5, 1, 1, 5, 6, 5, 2, 6, 1,
    ],
    &[
        1, 0, 1, 1, 2, 1, 2, 1, 2, 2, 0, 2, 0, 2, 0, 0, 0, 2, 1, 0, 6, 3, 2, 5, 5, 5, 5, 6, 0,
    ],
];

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn alphabet_is_twenty_threes_then_ten_sevens() {
        let a = alphabet();
        assert!(a[..20].iter().all(|&v| v == 3));
        assert!(a[20..].iter().all(|&v| v == 7));
    }

    #[test]
    fn the_cut_order_lists_each_step_s_three_genes_together_once() {
        let order = cut_order();
        assert_eq!(order.len(), LENGTH);
        let mut sorted = order.clone();
        sorted.sort_unstable();
        assert_eq!(sorted, (0..LENGTH).collect::<Vec<_>>());
        let g: Vec<u32> = (0..LENGTH as u32).map(|i| i % 3).collect();
        let genome = Genome::new(&[g[..20].to_vec(), vec![0; 10]].concat()).unwrap();
        for (k, step) in genome.steps().iter().enumerate() {
            let [a, r, p] = [order[3 * k], order[3 * k + 1], order[3 * k + 2]];
            assert_eq!((a, r, p), (2 * k, 2 * k + 1, 20 + k));
            assert_eq!(step.iteration, k + 1);
        }
    }

    #[test]
    fn thesis_chromosomes_are_valid_except_the_29_gene_one() {
        for c in &THESIS_CHROMOSOMES[..3] {
            assert!(Genome::new(c).is_ok(), "{c:?}");
        }
        let e = Genome::new(THESIS_CHROMOSOMES[3]).unwrap_err().to_string();
        assert!(e.contains("30 genes") && e.contains("has 29"), "{e}");
    }

    #[test]
    fn out_of_alphabet_genes_are_named() {
        let mut g = THESIS_CHROMOSOMES[0].to_vec();
        g[21] = 7;
        assert_eq!(
            Genome::new(&g).unwrap_err().to_string(),
            "gene 21 is 7, expected 0..=6 (a parameter)"
        );
        g[21] = 0;
        g[3] = 3;
        assert_eq!(
            Genome::new(&g).unwrap_err().to_string(),
            "gene 3 is 3, expected 0..=2 (an arrangement)"
        );
    }

    #[test]
    fn steps_read_interleaved_pairs_then_parameters() {
        let g = Genome::new(THESIS_CHROMOSOMES[0]).unwrap();
        let s = g.steps();
        assert_eq!(s.len(), STEPS);
        // Genes 0, 1 and 20: contient, grid, parameter 2 (3 rows × 3 columns).
        assert_eq!(
            s[0],
            Step {
                iteration: 1,
                action: Action::Contient,
                arrangement: Arrangement::Grid,
                parameter: 2
            }
        );
        assert_eq!(s[0].count(), 3);
        // Genes 18, 19 and 29: skip, grid, 3.
        assert_eq!(s[9].action, Action::Skip);
        assert_eq!(s[9].iteration, 10);
        assert_eq!(s[9].parameter, 3);
        assert_eq!(g.to_string(), format!("{:?}", THESIS_CHROMOSOMES[0]));
    }

    #[test]
    fn random_genomes_are_valid_and_cover_the_alphabet() {
        let mut rng = Rng::new(7, 0);
        let mut seen = [[false; 7]; LENGTH];
        for _ in 0..400 {
            let g = Genome::random(&mut rng);
            assert!(Genome::new(g.genes()).is_ok());
            for (i, &v) in g.genes().iter().enumerate() {
                seen[i][v as usize] = true;
            }
        }
        let alpha = alphabet();
        for i in 0..LENGTH {
            assert!((0..alpha[i] as usize).all(|v| seen[i][v]), "gene {i}");
        }
    }
}
