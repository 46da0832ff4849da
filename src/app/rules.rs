//! `citygen rules check|derive`: their arguments, the lint, and one ruleset derived on one test
//! lot (`derive_lot`).

use std::path::{Path, PathBuf};
use std::sync::Arc;

use clap::{ArgGroup, Subcommand};

use super::args::{parse_lod, parse_lonlat, parse_lot, parse_wkt};
use super::{lot_outcome, AppError, Outcome};
use crate::derive::{Generator, Rules};
use crate::geometry::Polygon;
use crate::grammar::Caps;
use crate::model::Lod;
use crate::pipeline::{
    file_name, generate_and_write, load_kb, outputs, read_rules, RunError, Summary, Targets,
};
use crate::prepare;
use crate::report::Report;

// Parsed once per process: the size difference between variants does not matter.
#[allow(clippy::large_enum_variant)]
#[derive(Subcommand, Debug)]
pub(crate) enum RulesCommand {
    /// Parse a ruleset and lint it: undefined successors, unreachable rules, probabilities
    /// that do not sum to 1, duplicate deterministic rules, rules that never terminate or
    /// grow exponentially (rule bombs: the derivation would stop at a cap). Exit code 1 on
    /// errors, 0 with warnings only.
    Check {
        /// The ruleset file.
        file: PathBuf,
    },
    /// Derive a ruleset on one test lot and write the outputs, to see a ruleset without a city.
    #[command(group(ArgGroup::new("lot_shape").required(true).args(["lot", "wkt"])))]
    #[command(group(ArgGroup::new("derive_outputs").required(true).multiple(true).args(["ifc", "citygml", "gltf"])))]
    Derive {
        /// The ruleset file.
        file: PathBuf,
        /// A rectangular lot, width x depth in metres, e.g. 20x12.
        #[arg(long, value_name = "WxD", value_parser = parse_lot)]
        lot: Option<Polygon>,
        /// A lot given as WKT in local metres, e.g. "POLYGON ((0 0, 20 0, 20 12, 0 12, 0 0))".
        #[arg(long, value_name = "WKT", value_parser = parse_wkt)]
        wkt: Option<Polygon>,
        /// Where the lot stands (lon,lat in degrees): it picks the UTM zone and the KB zone.
        #[arg(long, value_name = "LON,LAT", value_parser = parse_lonlat, default_value = "1.4442,43.6045")]
        at: (f64, f64),
        /// Knowledge base for default colours and heights (default: built-in defaults).
        #[arg(long, value_name = "KB.xml")]
        kb: Option<PathBuf>,
        /// Level of detail, 1 to 4 (as for the main job).
        #[arg(long, value_parser = parse_lod, default_value = "2")]
        lod: Lod,
        /// Seed of every random choice.
        #[arg(long, default_value_t = 0)]
        seed: u64,
        #[arg(long, value_name = "OUT.ifc")]
        ifc: Option<PathBuf>,
        #[arg(long, value_name = "OUT.gml")]
        citygml: Option<PathBuf>,
        #[arg(long, value_name = "OUT.glb")]
        gltf: Option<PathBuf>,
        #[arg(long, value_name = "OUT.json")]
        report: Option<PathBuf>,
    },
}

/// `citygen rules ...`.
pub(crate) fn run(cmd: RulesCommand) -> Result<Outcome, AppError> {
    match cmd {
        RulesCommand::Check { file } => {
            let text = match crate::grammar::read_source(&file) {
                Ok(t) => t,
                Err(source) => return Err(AppError::Read { path: file, source }),
            };
            let name = file.display().to_string();
            let rules = crate::grammar::parse(&text, &name)?;
            let diagnostics = crate::grammar::lint::lint(&rules, &text);
            for d in &diagnostics {
                eprintln!("{d}");
            }
            let errors = crate::grammar::lint::has_errors(&diagnostics);
            let n_err = diagnostics
                .iter()
                .filter(|d| d.severity == crate::grammar::lint::Severity::Error)
                .count();
            eprintln!(
                "{name}: {} rules, {n_err} errors, {} warnings",
                rules.rules().len(),
                diagnostics.len() - n_err
            );
            Ok(if errors {
                Outcome::Problems
            } else {
                Outcome::Done
            })
        }
        RulesCommand::Derive {
            file,
            lot,
            wkt,
            at,
            kb,
            lod,
            seed,
            ifc,
            citygml,
            gltf,
            report,
        } => {
            let Some(polygon) = lot.or(wkt) else {
                return Err(AppError::Missing);
            };
            lot_outcome(derive_lot(
                &file,
                polygon,
                at,
                kb.as_deref(),
                lod,
                seed,
                &Targets {
                    ifc,
                    ifc_schema: Default::default(),
                    ifc_max_bytes: None,
                    citygml,
                    gltf,
                    cityjson: None,
                    cityjsonseq: None,
                    report,
                    preview: None,
                    tiles3d: None,
                    dry_run: false,
                    textures: false,
                    allow_empty: false,
                    manifest: None,
                    terrain: None,
                },
            ))
        }
    }
}

/// `citygen rules derive`: one ruleset on one test lot (local metres) placed at `lonlat`.
pub(crate) fn derive_lot(
    rules_path: &Path,
    lot: crate::geometry::Polygon,
    lonlat: (f64, f64),
    kb: Option<&Path>,
    lod: Lod,
    seed: u64,
    targets: &Targets,
) -> Result<Summary, RunError> {
    let mut inputs = vec![("the ruleset", rules_path.to_path_buf())];
    inputs.extend(kb.map(|p| ("--kb", p.to_path_buf())));
    outputs::check(&targets.flagged(), &inputs, false)?;
    let mut report = Report::default();
    let rules = read_rules(rules_path)?;
    let kb = load_kb(kb, &mut report)?;
    let site = prepare::single_lot(lot, lonlat, None, &mut report)
        .ok_or_else(|| RunError::Input("the lot is degenerate (see the report)".into()))?;
    let caps = Caps {
        facades: lod >= Lod::Lod3,
        ..Caps::default()
    };
    let generator = Generator::new(kb, Rules::File(Arc::new(rules)), lod, seed, caps);
    generate_and_write(
        &site,
        &generator,
        &file_name(rules_path),
        targets,
        report,
        &|_, _| {},
    )
}
