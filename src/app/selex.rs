//! `citygen selex check|derive`: their arguments, the program parsed, checked and run, its
//! shape tree printed or (`derive` with outputs) its building written (`derive_selex_lot`).

use std::path::{Path, PathBuf};

use clap::Subcommand;

use super::args::{parse_box, parse_lod, parse_lonlat};
use super::{lot_outcome, AppError, Outcome};
use crate::model::{Lod, SourceId};
use crate::pipeline::{
    file_name, outputs, write_batches, Batch, FileSet, Ledger, Maker, RunError, Summary, Targets,
};
use crate::prepare;
use crate::report::Report;

#[derive(Subcommand, Debug)]
pub(crate) enum SelexCommand {
    /// Parse a SELEX program, warn about what parses but looks wrong (the seed's `>` arrow, a
    /// bare word taken as a string, a pattern shorter than its grid), then run it and warn
    /// about every rule whose selection picks nothing (it is skipped) and every constraint
    /// dropped. Exit code 1 on errors, 0 with warnings only.
    Check {
        /// The program (.slx).
        file: PathBuf,
        /// Run it on a box `building` of width x depth x height metres made first, for a
        /// program that only lays out facades (its paths name building_front, ...).
        #[arg(long, value_name = "WxDxH", value_parser = parse_box)]
        lot: Option<(f64, f64, f64)>,
    },
    /// Run a SELEX program and print its shape tree: volumes, faces, grids, the elements with
    /// their rectangles on their face (metres from the bottom-left seen from outside), the
    /// cover, the constraints kept, then the warnings. With an output (--ifc, --citygml,
    /// --gltf, --cityjson, --cityjsonseq), write
    /// the building it makes instead: each volume (box or bay) a part with a flat roof, a bay's
    /// rounded front an arc, the elements doors (door*, entrance*), balconies (balcony*,
    /// ledge*) or windows, rounded and framed as the program asks (docs/selex.md §9).
    Derive {
        /// The program (.slx).
        file: PathBuf,
        /// Run it on a box `building` of width x depth x height metres made first.
        #[arg(long, value_name = "WxDxH", value_parser = parse_box)]
        lot: Option<(f64, f64, f64)>,
        /// Level of detail of the outputs, 1 to 3 (3: storeys, openings, balconies).
        #[arg(long, value_parser = parse_lod, default_value = "3")]
        lod: Lod,
        /// Where the building stands (lon,lat in degrees): it picks the UTM zone of the outputs.
        #[arg(long, value_name = "LON,LAT", value_parser = parse_lonlat, default_value = "1.4442,43.6045")]
        at: (f64, f64),
        /// Write IFC4 (STEP) here.
        #[arg(long, value_name = "OUT.ifc")]
        ifc: Option<PathBuf>,
        /// Write CityGML 2.0 here.
        #[arg(long, value_name = "OUT.gml")]
        citygml: Option<PathBuf>,
        /// Write glTF 2.0 binary (.glb) here.
        #[arg(long, value_name = "OUT.glb")]
        gltf: Option<PathBuf>,
        /// Write CityJSON 2.0 here.
        #[arg(long, value_name = "OUT.city.json")]
        cityjson: Option<PathBuf>,
        /// Write CityJSONSeq here.
        #[arg(long, value_name = "OUT.city.jsonl")]
        cityjsonseq: Option<PathBuf>,
        /// Write the JSON report here (with an output).
        #[arg(long, value_name = "OUT.json")]
        report: Option<PathBuf>,
    },
}

/// `citygen selex ...`.
pub(crate) fn run(cmd: SelexCommand) -> Result<Outcome, AppError> {
    let (file, lot, print_tree, write) = match cmd {
        SelexCommand::Check { file, lot } => (file, lot, false, None),
        SelexCommand::Derive {
            file,
            lot,
            lod,
            at,
            ifc,
            citygml,
            gltf,
            cityjson,
            cityjsonseq,
            report,
        } => {
            let targets = Targets {
                ifc,
                ifc_schema: Default::default(),
                ifc_max_bytes: None,
                citygml,
                gltf,
                cityjson,
                cityjsonseq,
                report,
                preview: None,
                tiles3d: None,
                dry_run: false,
                textures: false,
                allow_empty: false,
                manifest: None,
                terrain: None,
            };
            let outputs = targets.ifc.is_some()
                || targets.citygml.is_some()
                || targets.gltf.is_some()
                || targets.cityjson.is_some()
                || targets.cityjsonseq.is_some();
            if targets.report.is_some() && !outputs {
                return Err(AppError::Usage("--report goes with an output (--ifc, --citygml, --gltf, --cityjson, --cityjsonseq)".into()));
            }
            (file, lot, !outputs, outputs.then_some((targets, lod, at)))
        }
    };
    let text = match crate::grammar::read_source(&file) {
        Ok(t) => t,
        Err(source) => return Err(AppError::Read { path: file, source }),
    };
    let name = file.display().to_string();
    let program = crate::selex::parser::parse(&text, &name)?;
    let mut warnings: Vec<String> = crate::selex::parser::check(&program, &text, &name)
        .into_iter()
        .map(|w| w.to_string())
        .collect();
    let run = match lot {
        Some(b) => crate::selex::eval::run_on_box(&program, &text, &name, b),
        None => crate::selex::eval::run(&program, &text, &name),
    };
    let derivation = match run {
        Ok(d) => d,
        Err(e) => {
            for w in &warnings {
                eprintln!("{w}");
            }
            return Err(e.into());
        }
    };
    // Written, the run's warnings are the report's notes (printed with its entries).
    if write.is_none() {
        warnings.extend(
            derivation
                .warnings
                .iter()
                .map(|n| format!("{name}:{}:{}: warning: {}", n.line, n.col, n.message)),
        );
    }
    if print_tree {
        print!("{}", derivation.to_text());
    }
    for w in &warnings {
        eprintln!("{w}");
    }
    if let Some((targets, lod, at)) = write {
        return lot_outcome(derive_selex_lot(&file, &derivation, at, lod, &targets));
    }
    eprintln!(
        "{name}: {} commands, {} shapes, {} elements, {} warnings",
        program.commands.len(),
        derivation.shapes.len(),
        derivation.elements().count(),
        warnings.len()
    );
    Ok(Outcome::Done)
}

/// `citygen selex derive FILE --ifc ...`: the building that `derivation` (the shape tree of the
/// SELEX program `program`, run on its own box lot) describes
/// ([`crate::derive::selex_lot::building`]), placed at `lonlat` and written to `targets` as
/// `rules derive` writes its lot: outputs checked first, written atomically, with the report.
/// LOD 1 to 3 (LOD4's interiors are not planned for it: a usage error).
pub(crate) fn derive_selex_lot(
    program: &Path,
    derivation: &crate::selex::eval::Derivation,
    lonlat: (f64, f64),
    lod: Lod,
    targets: &Targets,
) -> Result<Summary, RunError> {
    if lod > Lod::Lod3 {
        return Err(RunError::Usage(
            "selex derive writes LOD 1 to 3 (no interiors are planned for it)".into(),
        ));
    }
    outputs::check(
        &targets.flagged(),
        &[("the program", program.to_path_buf())],
        false,
    )?;
    // A box too large to build (a 1e300 m side) is refused before any storey is planned.
    if let Some(why) = crate::derive::selex_lot::too_large(derivation) {
        return Err(RunError::Input(format!("{}: {why}", program.display())));
    }
    let name = file_name(program);
    let mut report = Report::default();
    let (building, notes) =
        crate::derive::selex_lot::building(derivation, SourceId::Lot(0), &name, lod)
            .map_err(RunError::Input)?;
    // The lot is the building's plan bounds (it only places the site).
    let (mut lo, mut hi) = (
        glam::DVec2::splat(f64::INFINITY),
        glam::DVec2::splat(f64::NEG_INFINITY),
    );
    for p in &building.parts {
        let (a, b) = p.footprint.bounds();
        lo = lo.min(a);
        hi = hi.max(b);
    }
    let lot = crate::geometry::Polygon::new(
        vec![
            lo,
            glam::DVec2::new(hi.x, lo.y),
            hi,
            glam::DVec2::new(lo.x, hi.y),
        ],
        vec![],
    );
    let site = prepare::single_lot(lot, lonlat, None, &mut report)
        .ok_or_else(|| RunError::Input(format!("{name}: the building's plan is degenerate")))?;
    let made = move |lot: &prepare::Lot| {
        let mut b = building.clone();
        b.id = lot.id;
        for p in &mut b.parts {
            p.source = Some(lot.id);
        }
        Ok((b, notes.clone()))
    };
    let all = [Batch {
        suffix: None,
        range: 0..site.lots.len(),
        cell: (0, 0),
    }];
    write_batches(
        &site,
        &all,
        &Maker::Made {
            lod,
            seed: 0,
            make: &made,
        },
        &FileSet {
            name: &name,
            input: None,
            targets,
        },
        report,
        Ledger::default(),
        &|_, _| {},
    )
}
