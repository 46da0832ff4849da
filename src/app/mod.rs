//! The `citygen` command line, the top floor: the clap types of the main job and of every
//! subcommand (each beside its command), the commands themselves (what they print, what they
//! call), and [`AppError`], whose [`AppError::exit_code`] is the one place an error becomes an
//! exit code. `main.rs` is `run(parse())`.

use std::path::PathBuf;

use clap::{Parser, Subcommand};
use thiserror::Error;

use crate::kb::KbError;
use crate::pipeline::{RunError, Summary};

mod args;
pub mod eval;
pub mod evolve;
pub mod kb;
pub mod merge;
pub mod rules;
pub mod run;
pub mod selex;
mod split;

/// Turns a city's building footprints (OSM PBF or shapefile) into BIM and city models:
/// IFC4, CityGML 2.0 and glTF 2.0 binary, at LOD1 to LOD4.
///
/// Each footprint is matched to the deepest zone of the knowledge base (or ruled by --rules),
/// derived with the shape grammar, and written to every requested output. Outputs are written
/// atomically. Same inputs and --seed give byte-identical files, whatever --threads is.
///
/// Subcommands: `citygen rules check|derive` for rule authors, `citygen kb
/// check|compile|explain|learn|edit` for knowledge-base authors (`citygen rules --help`, `citygen kb
/// --help`).
///
/// Exit codes: 0 success; 1 bad input (file, knowledge base, rules; a run that generates no
/// building); 2 bad usage (flags, output paths); 3 an output could not be written.
#[derive(Parser, Debug)]
#[command(name = "citygen", version, about, long_about)]
#[command(args_conflicts_with_subcommands = true, subcommand_negates_reqs = true)]
pub struct Cli {
    #[command(subcommand)]
    command: Option<Command>,
    #[command(flatten)]
    run: run::RunArgs,
}

/// Tools for rule authors.
#[derive(Subcommand, Debug)]
enum Command {
    /// Check and try grammar rulesets.
    #[command(subcommand)]
    Rules(rules::RulesCommand),
    /// Check, compile, explain and learn knowledge bases.
    #[command(subcommand)]
    Kb(kb::KbCommand),
    /// Check and try SELEX programs (selection expressions and facade grids, docs/selex.md).
    #[command(subcommand)]
    Selex(selex::SelexCommand),
    /// Put the shards of a tiled run together (`--shard I/N`), after checking that their
    /// manifests add up: one run, every shard, tile and building once, every file as listed.
    /// Writes the merged report, the region's CityJSONSeq, its 3D Tiles tileset and a picture.
    Merge(merge::MergeArgs),
    /// Cut an OSM PBF into the parts the shards of a tiled run read (`part-I-of-N.osm.pbf`
    /// with its head `part-I-of-N.split.json`): each shard's tiles and a halo around them, so
    /// that each machine downloads and reads only its share; a shard run on its part
    /// (`--split-part`) writes the same bytes as on the whole input.
    Split(split::SplitArgs),
    /// Write facade rules by a genetic search (seed 003 §3.7): NSGA-II evolves integer genomes
    /// decoded into grammar rules, each derived on a test facade and scored on the seed's
    /// aesthetic objectives (all minimised). Writes the Pareto front as ruleset files with
    /// pictures, the front and convergence as SVG, and evolve.json.
    Evolve(evolve::EvolveArgs),
    /// Measure the height and roof estimator: hide an extract's own tags fold by fold, or
    /// compare with measured city models (footprints in, heights and roofs out); print MAE,
    /// the constant-median baseline, their ratio, storey and roof accuracy. `--save-model`
    /// fits the shipped models.
    Eval(eval::EvalArgs),
}

/// The command line as given (clap exits with its usage message, code 2, on bad arguments).
pub fn parse() -> Cli {
    Cli::parse()
}

/// Runs the command `cli` names (the main job without one).
pub fn run(cli: Cli) -> Result<Outcome, AppError> {
    match cli.command {
        Some(Command::Rules(cmd)) => rules::run(cmd),
        Some(Command::Kb(cmd)) => kb::run(cmd),
        Some(Command::Selex(cmd)) => selex::run(cmd),
        Some(Command::Merge(args)) => merge::run(args),
        Some(Command::Split(args)) => split::run(args),
        Some(Command::Evolve(args)) => evolve::run(args),
        Some(Command::Eval(args)) => eval::run(args),
        None => run::run(cli.run),
    }
}

/// How a command that ran to its end finishes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Outcome {
    /// All went well (exit code 0).
    Done,
    /// The command ran and printed the problems it found (exit code 1): a checked file with
    /// errors (`rules check`, `kb check`), a test lot that made no building.
    Problems,
}

impl Outcome {
    /// The process's exit code.
    pub fn exit_code(self) -> u8 {
        match self {
            Outcome::Done => 0,
            Outcome::Problems => 1,
        }
    }
}

/// Why a command stopped. Its `Display` is the whole message for standard error (empty for
/// [`AppError::Missing`]); [`AppError::exit_code`] is the process's exit code.
#[derive(Debug, Error)]
pub enum AppError {
    /// A run's error (the main job, `merge`, `rules derive`, `selex derive`, `kb learn`): exit
    /// code 1, 2 or 3 as [`RunError`] says.
    #[error("citygen: error: {0}")]
    Run(#[from] RunError),
    /// `kb explain`'s error: exit code 1, whatever its kind.
    #[error("citygen: error: {0}")]
    Explain(RunError),
    /// A knowledge base that could not be read, or a zone not in it (exit code 1).
    #[error("citygen: error: {0}")]
    Kb(#[from] KbError),
    /// The knowledge-base editor could not start or stopped (exit code 1).
    #[error("citygen: error: {0}")]
    Editor(String),
    /// A ruleset or SELEX program that could not be read (exit code 1).
    #[error("citygen: error: {}: {source}", path.display())]
    Read {
        /// The file.
        path: PathBuf,
        /// Why.
        source: std::io::Error,
    },
    /// A ruleset that does not parse: the diagnostic alone (exit code 1).
    #[error("{0}")]
    Grammar(#[from] crate::grammar::GrammarError),
    /// A SELEX program that does not parse: the diagnostic alone (exit code 1).
    #[error("{0}")]
    Selex(#[from] crate::selex::parser::SelexError),
    /// A SELEX program that fails when run: the diagnostic alone (exit code 1).
    #[error("{0}")]
    SelexRun(#[from] crate::selex::eval::RunError),
    /// Flags that cannot go together, found by the command (exit code 2); and every error of
    /// `evolve` but its outputs'.
    #[error("citygen: error: {0}")]
    Usage(String),
    /// The worker threads asked for could not be started (exit code 2).
    #[error("citygen: cannot start {threads} threads: {source}")]
    Threads {
        /// How many.
        threads: usize,
        /// Why not.
        source: rayon::ThreadPoolBuildError,
    },
    /// An input that clap's argument groups require was missing (exit code 2, nothing printed;
    /// clap refuses such a command line first).
    #[error("")]
    Missing,
    /// An output that could not be written (`evolve`; exit code 3).
    #[error("citygen: error: {0}")]
    Output(String),
    /// Standard output could not be written, other than by a reader that stopped (exit code 3).
    #[error("citygen: error: standard output: {0}")]
    Stdout(std::io::Error),
}

impl AppError {
    /// The process's exit code: 1 bad input, 2 bad usage, 3 an output not written.
    pub fn exit_code(&self) -> u8 {
        match self {
            AppError::Run(e) => match e {
                RunError::Input(_) => 1,
                RunError::Usage(_) => 2,
                RunError::Output { .. } => 3,
            },
            AppError::Explain(_)
            | AppError::Kb(_)
            | AppError::Editor(_)
            | AppError::Read { .. }
            | AppError::Grammar(_)
            | AppError::Selex(_)
            | AppError::SelexRun(_) => 1,
            AppError::Usage(_) | AppError::Threads { .. } | AppError::Missing => 2,
            AppError::Output(_) | AppError::Stdout(_) => 3,
        }
    }
}

/// The end of a one-lot derivation (`rules derive`, `selex derive` with outputs): its report's
/// entries, the count, the files written; [`Outcome::Problems`] when no building was made.
fn lot_outcome(result: Result<Summary, RunError>) -> Result<Outcome, AppError> {
    let summary = result?;
    let r = &summary.report;
    for e in &r.entries {
        eprintln!("  {} {:?}: {}", e.id, e.outcome, e.reason);
    }
    eprintln!(
        "citygen: {} building(s), {} polygons",
        r.generated, summary.polygons
    );
    for p in &summary.outputs {
        eprintln!("  wrote {}", p.display());
    }
    Ok(if r.generated == 1 {
        Outcome::Done
    } else {
        Outcome::Problems
    })
}
