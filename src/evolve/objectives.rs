//! The aesthetic objectives and the global constraints of seed 003 §3.7.2.8, all minimised.
//!
//! Every objective is a pure function of a derived [`Facade`] (the symmetries and the
//! uniformity read only its terminal `Matrix`). `score` adds to each chosen objective the
//! global penalty: `PENALTY` (100, the thesis's figure) for each broken global constraint and
//! for each rule violation recorded in [`Facade::violations`]. The thesis adds its global
//! measures to every aesthetic objective; so does `score`.
//!
//! What the thesis leaves open, chosen here:
//! - **rectilinear**: the thresholds on width / height (`RECTILINEAR_WINDOW`,
//!   `RECTILINEAR_DOOR`) and the measure (the summed excess of the ratio, not a count);
//! - **fragmented**: the minimised form of "maximise the terminal count":
//!   `PENALTY / (1 + count)`;
//! - the global bounds: opening sizes (`WINDOW_WIDTH`, `WINDOW_HEIGHT`, `DOOR_WIDTH`,
//!   `DOOR_HEIGHT`) and the minimum number of openings (`MIN_OPENINGS`).

use std::fmt;
use std::str::FromStr;

use super::{Facade, Kind, Matrix, Terminal};

/// What one rule violation or one broken global constraint adds to every objective (seed 003
/// L1347: "each rule violation adds a penalty of 100").
pub(crate) const PENALTY: f64 = 100.0;

/// Allowed window width, metres, inclusive: `(min, max)`. A window narrower than 0.6 m is a
/// slit; one wider than 3 m is a shop front or a curtain wall, neither of which the grammar's
/// `window` means.
pub(crate) const WINDOW_WIDTH: (f64, f64) = (0.6, 3.0);
/// Allowed window height, metres, inclusive: `(min, max)`. At most 3 m, a storey's height.
pub(crate) const WINDOW_HEIGHT: (f64, f64) = (0.8, 3.0);
/// Allowed door width, metres, inclusive: `(min, max)`: a single leaf (0.8 m, the usual
/// accessible minimum) up to a wide double door.
pub(crate) const DOOR_WIDTH: (f64, f64) = (0.8, 2.5);
/// Allowed door height, metres, inclusive: `(min, max)`: a person passes (2 m) and the door
/// stays within a tall ground storey (3.5 m).
pub(crate) const DOOR_HEIGHT: (f64, f64) = (2.0, 3.5);
/// The fewest openings (windows and doors) a facade may have; each missing one is one
/// violation. Three, so that a facade has a pattern at all (the symmetries and the uniformity
/// are empty on a blank wall) — the thesis's "minimum number of facade elements".
pub(crate) const MIN_OPENINGS: usize = 3;

/// The rectilinear style's largest width / height ratio of a window: 0.75, so a window is
/// at least a third taller than it is wide (the tall, narrow openings of the style).
pub(crate) const RECTILINEAR_WINDOW: f64 = 0.75;
/// The rectilinear style's largest width / height ratio of a door: 0.6 (a 0.9 × 2.1 m door is
/// 0.43; a 1.4 m double door of 2.3 m is 0.61, just over).
pub(crate) const RECTILINEAR_DOOR: f64 = 0.6;

/// One aesthetic objective of seed 003 §3.7.2.8; every one is minimised (0 is ideal, except
/// for [`Objective::Fragmented`], which tends to 0).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Objective {
    /// `vsym`: mirror inequalities within each row (about the facade's vertical axis).
    VerticalSymmetry,
    /// `hsym`: mirror inequalities within each column (about the horizontal mid-line).
    HorizontalSymmetry,
    /// `uniform`: the smallest distance to a matrix made of one row of the facade repeated.
    Uniformity,
    /// `rectilinear`: the summed excess of openings' width / height over the style's thresholds.
    Rectilinear,
    /// `monolithic`: the terminal count.
    Monolithic,
    /// `fragmented`: `PENALTY / (1 + terminal count)`, the minimised form of "maximise the
    /// terminal count".
    Fragmented,
}

/// A bad objective list (`--objectives`).
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum ObjectiveError {
    /// A name that is none of the six.
    #[error("unknown objective `{0}`; the objectives are vsym, hsym, uniform, rectilinear, monolithic, fragmented")]
    Unknown(String),
    /// The same objective twice.
    #[error("objective `{0}` is listed twice")]
    Duplicate(String),
    /// No objective at all.
    #[error("no objective given; list one or more of vsym, hsym, uniform, rectilinear, monolithic, fragmented, separated by commas")]
    Empty,
}

impl Objective {
    /// The six, in the order of the thesis.
    pub const ALL: [Objective; 6] = [
        Objective::VerticalSymmetry,
        Objective::HorizontalSymmetry,
        Objective::Uniformity,
        Objective::Rectilinear,
        Objective::Monolithic,
        Objective::Fragmented,
    ];

    /// The command-line name: `vsym`, `hsym`, `uniform`, `rectilinear`, `monolithic`,
    /// `fragmented`.
    pub(crate) fn name(self) -> &'static str {
        match self {
            Objective::VerticalSymmetry => "vsym",
            Objective::HorizontalSymmetry => "hsym",
            Objective::Uniformity => "uniform",
            Objective::Rectilinear => "rectilinear",
            Objective::Monolithic => "monolithic",
            Objective::Fragmented => "fragmented",
        }
    }

    /// Parses a comma-separated list (`"vsym,hsym"`; spaces around names are allowed), in the
    /// order given. Errors name the first unknown or repeated name, or say the list is empty.
    pub(crate) fn parse_list(list: &str) -> Result<Vec<Objective>, ObjectiveError> {
        let mut out: Vec<Objective> = Vec::new();
        for part in list.split(',') {
            let name = part.trim();
            if name.is_empty() {
                continue;
            }
            let objective = name.parse::<Objective>()?;
            if out.contains(&objective) {
                return Err(ObjectiveError::Duplicate(name.to_string()));
            }
            out.push(objective);
        }
        if out.is_empty() {
            return Err(ObjectiveError::Empty);
        }
        Ok(out)
    }

    /// The objective's own value on a facade, without the global penalty (see [`score`]).
    pub(crate) fn value(self, facade: &Facade) -> f64 {
        match self {
            Objective::VerticalSymmetry => vertical_symmetry(&facade.matrix) as f64,
            Objective::HorizontalSymmetry => horizontal_symmetry(&facade.matrix) as f64,
            Objective::Uniformity => uniformity(&facade.matrix) as f64,
            Objective::Rectilinear => rectilinear(facade),
            Objective::Monolithic => monolithic(facade) as f64,
            Objective::Fragmented => fragmented(facade),
        }
    }
}

impl fmt::Display for Objective {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for Objective {
    type Err = ObjectiveError;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Objective::ALL
            .into_iter()
            .find(|o| o.name() == s)
            .ok_or_else(|| ObjectiveError::Unknown(s.to_string()))
    }
}

impl serde::Serialize for Objective {
    fn serialize<S: serde::Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        serializer.serialize_str(self.name())
    }
}

/// Vertical symmetry (seed 003 L1355-1357): within each row, the cells are compared from both
/// ends towards the centre, `a[i][j]` with `a[i][m-1-j]` for `j < m-1-j`, and each inequality
/// counts one. Each row is mirrored about its own centre (`m` is that row's length), so rows of
/// different lengths need no special case; a middle cell is its own mirror.
pub(crate) fn vertical_symmetry(matrix: &Matrix) -> usize {
    matrix
        .iter()
        .map(|row| {
            let m = row.len();
            (0..m / 2).filter(|&j| row[j] != row[m - 1 - j]).count()
        })
        .sum()
}

/// Horizontal symmetry: the same on the columns, `a[i][j]` with `a[n-1-i][j]` for `i < n-1-i`,
/// each inequality counting one. When the two mirrored rows differ in length, the cells of the
/// longer one beyond the shorter's end have no mirror and each counts as one inequality.
pub(crate) fn horizontal_symmetry(matrix: &Matrix) -> usize {
    let n = matrix.len();
    (0..n / 2)
        .map(|i| {
            let (a, b) = (&matrix[i], &matrix[n - 1 - i]);
            let common = a.len().min(b.len());
            let unequal = (0..common).filter(|&j| a[j] != b[j]).count();
            unequal + a.len().max(b.len()) - common
        })
        .sum()
}

/// What a cell without a counterpart costs in [`uniformity`]: the largest distance between two
/// codes (door 2 − wall 0), so a missing cell is as different as two cells can be.
pub(crate) const UNMATCHED_CELL: usize = (Kind::Door as usize) - (Kind::Wall as usize);

/// Uniformity (seed 003 L1365-1370): the smallest, over the rows `r`, of the distance
/// `d(A, B_r) = Σ_i Σ_j |a_ij − b_ij|` between the matrix `A` and the matrix `B_r` whose every
/// row is row `r` of `A`. Codes are the [`Kind`] codes (0 wall, 1 window, 2 door), so the
/// distance depends on them, as in the thesis. Rows of different lengths are compared on their
/// common columns; each cell beyond that has no counterpart and costs [`UNMATCHED_CELL`]. An
/// empty matrix has uniformity 0.
pub(crate) fn uniformity(matrix: &Matrix) -> usize {
    matrix
        .iter()
        .map(|reference| {
            matrix
                .iter()
                .map(|row| {
                    let common = row.len().min(reference.len());
                    let diff: usize = (0..common)
                        .map(|j| usize::from(row[j].abs_diff(reference[j])))
                        .sum();
                    diff + (row.len().max(reference.len()) - common) * UNMATCHED_CELL
                })
                .sum::<usize>()
        })
        .min()
        .unwrap_or(0)
}

/// The rectilinear style's largest width / height of a terminal kind; `None` for walls, which
/// are what is left between openings and whose proportions follow from theirs.
pub(crate) fn rectilinear_threshold(kind: Kind) -> Option<f64> {
    match kind {
        Kind::Wall => None,
        Kind::Window => Some(RECTILINEAR_WINDOW),
        Kind::Door => Some(RECTILINEAR_DOOR),
    }
}

/// Rectilinearity (seed 003 L1374: "the width/height ratio must be below a threshold defined
/// per terminal"): the sum over windows and doors of `max(0, w/h − threshold)`
/// ([`rectilinear_threshold`]). A sum of excesses rather than a count of offenders, so that the
/// search sees a window become narrower before it passes. A degenerate opening (height not
/// positive, or a size not finite) counts an excess of 1 (the global size bounds penalise it
/// too).
pub(crate) fn rectilinear(facade: &Facade) -> f64 {
    facade
        .terminals
        .iter()
        .filter_map(|t| rectilinear_threshold(t.kind).map(|limit| (t, limit)))
        .map(|(t, limit)| {
            if !(t.w.is_finite() && t.h.is_finite() && t.h > 0.0) {
                return 1.0;
            }
            (t.w / t.h - limit).max(0.0)
        })
        .sum()
}

/// Monolithism (seed 003 L1380): the number of terminals (walls, windows and doors); fewer
/// terminals, more monolithic.
pub(crate) fn monolithic(facade: &Facade) -> usize {
    facade.terminals.len()
}

/// Fragmentation (seed 003 L1385: "maximise the number of terminals, within the thresholds of
/// the global objectives"), minimised as `PENALTY / (1 + count)`: 100 for a blank facade (as
/// bad as one violation), 50 for one terminal, 1 for 99, tending to 0. The global constraints
/// (opening sizes) are what bound the count. Scaled by [`PENALTY`] so that it spans the same
/// range as the other objectives below one penalty, which [`reference_point`] relies on.
pub(crate) fn fragmented(facade: &Facade) -> f64 {
    PENALTY / (1.0 + facade.terminals.len() as f64)
}

/// True when `v` is finite and within `bounds` (inclusive).
fn within(v: f64, (lo, hi): (f64, f64)) -> bool {
    v.is_finite() && v >= lo && v <= hi
}

/// How many size bounds one terminal breaks: 0, 1 or 2 (width and height each count once);
/// walls have no bounds.
fn size_violations(t: &Terminal) -> usize {
    let (w, h) = match t.kind {
        Kind::Wall => return 0,
        Kind::Window => (WINDOW_WIDTH, WINDOW_HEIGHT),
        Kind::Door => (DOOR_WIDTH, DOOR_HEIGHT),
    };
    usize::from(!within(t.w, w)) + usize::from(!within(t.h, h))
}

/// The number of broken global constraints (seed 003 L1351), each worth one [`PENALTY`]:
/// - each window or door dimension outside its bounds ([`WINDOW_WIDTH`], [`WINDOW_HEIGHT`],
///   [`DOOR_WIDTH`], [`DOOR_HEIGHT`]; a non-finite size is outside): one per dimension;
/// - each opening missing below [`MIN_OPENINGS`]: one per missing opening;
/// - each iteration with more subdivisions than the previous one ([`Facade::subdivisions`]):
///   one per increase.
///
/// The rule violations of [`Facade::violations`] are not included (see [`penalty`]).
pub(crate) fn global_violations(facade: &Facade) -> usize {
    let sizes: usize = facade.terminals.iter().map(size_violations).sum();
    let openings = facade
        .terminals
        .iter()
        .filter(|t| t.kind != Kind::Wall)
        .count();
    let missing = MIN_OPENINGS.saturating_sub(openings);
    let increases = facade
        .subdivisions
        .windows(2)
        .filter(|w| w[1] > w[0])
        .count();
    sizes + missing + increases
}

/// The penalty added to every objective: [`PENALTY`] × (global violations + rule violations).
pub(crate) fn penalty(facade: &Facade) -> f64 {
    PENALTY * (global_violations(facade) + facade.violations) as f64
}

/// The fitness of a facade: for each objective, in the order given, its value
/// ([`Objective::value`]) plus the [`penalty`]. All minimised.
pub(crate) fn score(facade: &Facade, objectives: &[Objective]) -> Vec<f64> {
    let penalty = penalty(facade);
    objectives
        .iter()
        .map(|o| o.value(facade) + penalty)
        .collect()
}

/// The hypervolume reference point for a list of objectives: [`PENALTY`] on each. A facade
/// adds to the hypervolume only when all its values are below 100, so only when it breaks no
/// global constraint and no rule (any penalty puts it at 100 or more); the fragmentation is at
/// most 100 by construction, and the counts of the other objectives stay below 100 on test
/// facades of a few dozen terminals. The same point must be used for every run that is
/// compared (NSGA-II against random search).
pub(crate) fn reference_point(objectives: &[Objective]) -> Vec<f64> {
    vec![PENALTY; objectives.len()]
}
