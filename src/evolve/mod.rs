//! `citygen evolve`: facade rules written by a genetic search (seed 003 §3.7, issue 26).
//!
//! A population of fixed-length integer genomes ([`genome`]) is decoded into rules of
//! citygen's own grammar ([`decode`](mod@decode)); each ruleset is derived on a test facade and read back as
//! a [`Facade`]: its terminals (wall, window, door) with their rectangles, the terminal matrix
//! (rows bottom to top, columns left to right, as the facade is seen from outside) and the
//! counts of subdivisions per iteration. The aesthetic objectives and the global constraints
//! ([`objectives`]) score a facade, all minimised; NSGA-II ([`nsga2`]) evolves the population.
//!
//! Layering: `evolve` may import `grammar`, `kb`, `rng`, `geometry` and `color`
//! (ARCHITECTURE.md).

pub mod decode;
pub mod facade;
pub mod genome;
pub mod nsga2;
pub mod objectives;
pub mod plot;
pub mod run;
pub mod svg;

#[cfg(test)]
mod nsga2_tests;
#[cfg(test)]
mod objectives_tests;
#[cfg(test)]
mod plot_tests;

pub use decode::{decode, decode_for, Decoded};
pub use facade::{derive_facade, derive_lot_facade};
pub use genome::Genome;
pub use svg::facade_svg;

/// A terminal's kind, its code in the terminal matrix.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
#[repr(u8)]
pub enum Kind {
    /// Wall (code 0).
    Wall = 0,
    /// Window (code 1).
    Window = 1,
    /// Door (code 2).
    Door = 2,
}

impl Kind {
    /// The code in the terminal matrix (0 wall, 1 window, 2 door: seed 003 Fig. 3.31's codes).
    pub fn code(self) -> u8 {
        self as u8
    }
}

/// One terminal of a derived facade: its kind and its rectangle in facade metres (x from the
/// left edge, y up from the ground).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Terminal {
    /// What it is.
    pub kind: Kind,
    /// Left edge, metres.
    pub x: f64,
    /// Bottom edge, metres.
    pub y: f64,
    /// Width, metres.
    pub w: f64,
    /// Height, metres.
    pub h: f64,
}

/// A terminal matrix: `rows[i][j]` is the code of the terminal at row `i` (0 = bottom) and
/// column `j` (0 = left). Rows may differ in length when the facade is not a grid.
pub type Matrix = Vec<Vec<u8>>;

/// A derived test facade, as the objectives read it.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Facade {
    /// Facade width, metres.
    pub width: f64,
    /// Facade height, metres.
    pub height: f64,
    /// Every terminal, in derivation order.
    pub terminals: Vec<Terminal>,
    /// The terminal matrix.
    pub matrix: Matrix,
    /// Subdivisions made at each iteration of the decoded rules (index = iteration), for the
    /// global constraint "fewer subdivisions than at the previous iteration".
    pub subdivisions: Vec<usize>,
    /// Rule violations found while decoding or deriving (each adds [`objectives::PENALTY`] to
    /// every objective).
    pub violations: usize,
}
