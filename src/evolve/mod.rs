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

/// Why a step of `citygen evolve` failed: a genome that is not one, a test facade or lot that
/// cannot be derived, an output that cannot be written, or a knowledge base that `--into-kb`
/// cannot add to (nothing is then changed).
#[derive(Debug, thiserror::Error)]
pub enum EvolveError {
    /// Not `genome::LENGTH` genes.
    #[error(
        "a genome has {} genes (20 action and arrangement genes in 0..=2, then 10 parameter \
         genes in 0..=6); this one has {found}",
        genome::LENGTH
    )]
    GenomeLength {
        /// How many genes it has.
        found: usize,
    },
    /// A gene out of its alphabet.
    #[error("gene {index} is {value}, expected 0..={max} ({what})")]
    Gene {
        /// The gene's index.
        index: usize,
        /// Its value.
        value: u32,
        /// The largest value of its alphabet.
        max: u32,
        /// What kind of gene it is ("a parameter", "an action", "an arrangement").
        what: &'static str,
    },
    /// A facade size to decode for that is not positive and finite.
    #[error("the test facade must have a positive width and height (got {width} x {height} m)")]
    DecodeSize {
        /// The width, metres.
        width: f64,
        /// The height, metres.
        height: f64,
    },
    /// A test facade or lot size that is not positive and finite.
    #[error("a test facade needs a positive size (got {width} x {height} m)")]
    FacadeSize {
        /// The width (or depth), metres.
        width: f64,
        /// The height, metres.
        height: f64,
    },
    /// The rules do not parse.
    #[error("{0}")]
    Rules(#[from] crate::grammar::GrammarError),
    /// The derivation failed.
    #[error("{0}")]
    Derive(#[from] crate::grammar::DeriveError),
    /// The rules make no side face named `decode::FACADE`.
    #[error("the rules make no side face named `{}`", decode::FACADE)]
    NoFacade,
    /// `--facade`/`--lot` is not `WxH`.
    #[error("{text:?}: give WIDTHxHEIGHT in metres, e.g. 12x9")]
    SizeFormat {
        /// The text given.
        text: String,
    },
    /// A side of `--facade`/`--lot` is not a number.
    #[error("{text:?}: {side:?} is not a number of metres")]
    SizeNumber {
        /// The text given.
        text: String,
        /// The side as written.
        side: String,
    },
    /// A side of `--facade`/`--lot` outside 1-200 m.
    #[error("{text:?}: {value} m is outside 1-200 m")]
    SizeRange {
        /// The text given.
        text: String,
        /// The side, metres.
        value: f64,
    },
    /// A file could not be written (the error names the folder, temporary or target).
    #[error(transparent)]
    Write(#[from] crate::fsio::WriteError),
    /// `evolve.json` could not be made.
    #[error("{0}")]
    Json(#[from] serde_json::Error),
    /// `--into-kb` with an empty front.
    #[error("no ruleset to add (the front is empty)")]
    NoMembers,
    /// The knowledge base does not load or check.
    #[error("{0}")]
    Kb(#[from] crate::kb::KbError),
    /// `--zone` names no zone of the knowledge base.
    #[error("{file}: no zone {zone:?} (see `citygen kb explain`)")]
    NoZone {
        /// The knowledge base file.
        file: String,
        /// The zone asked for.
        zone: String,
    },
    /// A file could not be read, written or renamed.
    #[error("{file}: {source}")]
    Io {
        /// The file.
        file: String,
        /// The system's error.
        source: std::io::Error,
    },
    /// The knowledge base's text could not be edited.
    #[error("{file}: {source}")]
    Edit {
        /// The knowledge base file.
        file: String,
        /// Why.
        source: crate::kb::edit::EditError,
    },
    /// `--into-kb` without `--kinds` on a zone whose appearances all serve named kinds, none of
    /// them `apartments`: which group the facades are for is the user's to say.
    #[error(
        "{file}: zone '{zone}' has no appearance for building=yes or apartments: say which \
         kinds the evolved facades are for with --kinds (e.g. --kinds apartments,residential)"
    )]
    NoKinds {
        /// The knowledge base, as given.
        file: String,
        /// The zone's path.
        zone: String,
    },
    /// `--share` not strictly between 0 and 1.
    #[error("--share {0}: give a share between 0 and 1 (exclusive) of the zone's buildings")]
    Share(f64),
    /// The edited knowledge base has `kb check` errors.
    #[error("the edited knowledge base has errors:\n{0}")]
    EditedErrors(Box<crate::kb::tools::CheckReport>),
    /// The edited knowledge base, strict-clean before, fails the strict check.
    #[error("the edited knowledge base fails the strict check:\n{0}")]
    EditedNotStrict(Box<crate::kb::tools::CheckReport>),
}

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
pub(crate) type Matrix = Vec<Vec<u8>>;

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
    /// Rule violations found while decoding or deriving (each adds `objectives::PENALTY` to
    /// every objective).
    pub violations: usize,
}
