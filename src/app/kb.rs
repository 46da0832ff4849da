//! `citygen kb check|compile|explain|learn|edit`: their arguments, the reports printed, one
//! building explained (`explain_building`) and a knowledge base learned (`learn_kb`).

use std::io::Write;
use std::path::{Path, PathBuf};

use clap::{ArgGroup, Subcommand};

use super::args::{parse_infer, InferArg};
use super::{AppError, Outcome};
use crate::derive::merged_tags;
use crate::export::{AtomicFile, ExportError};
use crate::kb::{self, tools::Explanation, KnowledgeBase};
use crate::model::SourceId;
use crate::pipeline::{infer_from_neighbours, outputs, read_source, RunError, Source};
use crate::prepare;
use crate::report::Report;

#[derive(Subcommand, Debug)]
pub(crate) enum KbCommand {
    /// Read a knowledge base and list what the lenient reader repaired (with lines), errors and
    /// warnings. Exit code 1 on errors, 0 with repairs or warnings only.
    Check {
        /// The knowledge base.
        kb: PathBuf,
        /// Read our clean format only (schemas/kb.xsd): every repair becomes an error.
        #[arg(long)]
        strict: bool,
        /// Allow `<ruleset file=...>` paths outside the knowledge base's folder.
        #[arg(long)]
        allow_external_rulesets: bool,
    },
    /// Print the grammar rules generated for each appearance of a zone.
    Compile {
        /// The knowledge base.
        kb: PathBuf,
        /// Zone path, e.g. France/Occitanie/Toulouse/Centre-Ville (with or without `earth/`).
        #[arg(long)]
        zone: String,
    },
    /// Explain the zone chain, inherited values, and the appearance chosen for one building.
    #[command(group(ArgGroup::new("explain_input").required(true).args(["osm", "shp"])))]
    Explain {
        /// The knowledge base.
        kb: PathBuf,
        /// The OpenStreetMap extract holding the building.
        #[arg(long, value_name = "FILE.pbf")]
        osm: Option<PathBuf>,
        /// The shapefile holding the building.
        #[arg(long, value_name = "FILE.shp")]
        shp: Option<PathBuf>,
        /// The building: way/123, relation/45 (OSM), a GIS feature's own id as the outputs
        /// write it (feature/7, a GUID, a TOID), or a 0-based shapefile record number.
        #[arg(long)]
        id: String,
        /// The run's --seed: the appearance picked is the one a run with this seed picks.
        #[arg(long, default_value_t = 0)]
        seed: u64,
        /// The run's --infer: what the building takes from its tagged neighbours.
        #[arg(long, value_name = "WHAT", default_value = "kb", value_parser = parse_infer)]
        infer: InferArg,
    },
    /// Edit a knowledge base in a browser: serves a page on 127.0.0.1 (the address, with the
    /// session's token, is printed on start) with the input's footprints on a map, the zone
    /// tree, values, appearances and drawn window splits, and a 3D preview of a building.
    /// Edits are checked as `kb check --strict` checks; saving writes the KB atomically.
    /// Runs until stopped (Ctrl-C). See docs/kb-editor.md.
    Edit {
        /// The knowledge base to edit (the one file saved).
        kb: PathBuf,
        /// An OpenStreetMap extract whose footprints the map shows.
        #[arg(long, value_name = "FILE.pbf", conflicts_with = "shp")]
        osm: Option<PathBuf>,
        /// A shapefile whose footprints the map shows.
        #[arg(long, value_name = "FILE.shp")]
        shp: Option<PathBuf>,
        /// The port to listen on (127.0.0.1 only); 0 picks a free one.
        #[arg(long, default_value_t = 0)]
        port: u16,
        /// The seed of the appearance picks and previews (a run's --seed).
        #[arg(long, default_value_t = 0)]
        seed: u64,
    },
    /// Learn a knowledge base from an extract's tags: storeys (building:levels), roof shape,
    /// floor height, colours and material per grid cell or per zone, written as zones and
    /// appearances to edit. A zone with fewer than --min-samples tagged values of an attribute
    /// takes its parent's (the grid's parent is the whole extract). Errors (exit 1): an input
    /// that cannot be read or holds no building. An extract without any of these tags gives a
    /// KB of the built-in defaults with a comment saying so.
    #[command(group(ArgGroup::new("learn_input").required(true).args(["osm", "shp"])))]
    Learn {
        /// The OpenStreetMap extract to learn from.
        #[arg(long, value_name = "FILE.pbf")]
        osm: Option<PathBuf>,
        /// The shapefile to learn from (its height and level fields detected).
        #[arg(long, value_name = "FILE.shp")]
        shp: Option<PathBuf>,
        /// Group by square cells of this many metres.
        #[arg(long, value_name = "METRES", conflicts_with = "zones",
              default_value_t = crate::kb::learn::DEFAULT_GRID_M as u32,
              value_parser = clap::value_parser!(u32).range(10..))]
        grid: u32,
        /// Group by the deepest zone of this knowledge base instead of a grid (its zones'
        /// circles and polygons are kept, its values and appearances replaced).
        #[arg(long, value_name = "KB.xml")]
        zones: Option<PathBuf>,
        /// Least tagged values of an attribute for a cell or zone to have its own distribution.
        #[arg(long, value_name = "N", default_value_t = crate::kb::learn::DEFAULT_MIN_SAMPLES,
              value_parser = clap::builder::RangedU64ValueParser::<usize>::new().range(1..))]
        min_samples: usize,
        /// Most appearances per zone and group (the rare tail is merged, as the file's comments say).
        #[arg(long, value_name = "N", default_value_t = crate::kb::learn::DEFAULT_MAX_APPEARANCES,
              value_parser = clap::builder::RangedU64ValueParser::<usize>::new().range(1..=100))]
        max_appearances: usize,
        /// Where to write the learned knowledge base.
        #[arg(long, value_name = "LEARNED.xml")]
        out: PathBuf,
    },
}

/// `citygen kb ...`.
pub(crate) fn run(cmd: KbCommand) -> Result<Outcome, AppError> {
    use crate::kb::{tools, ReadMode};
    let load = |p: &PathBuf| KnowledgeBase::load(p).map(|(kb, _)| kb);
    match cmd {
        KbCommand::Check {
            kb,
            strict,
            allow_external_rulesets,
        } => {
            let mode = if strict {
                ReadMode::Strict
            } else {
                ReadMode::Lenient
            };
            let r = tools::check_report_with(&kb, mode, allow_external_rulesets)?;
            emit(&r.to_string())?;
            Ok(if r.has_errors() {
                Outcome::Problems
            } else {
                Outcome::Done
            })
        }
        KbCommand::Edit {
            kb,
            osm,
            shp,
            port,
            seed,
        } => {
            let source = match (osm, shp) {
                (Some(p), _) => Some(crate::pipeline::Source::Osm(p)),
                (None, Some(p)) => Some(crate::pipeline::Source::Shp {
                    path: p,
                    height_field: None,
                    levels_field: None,
                    fields: Vec::new(),
                    layer: None,
                }),
                (None, None) => None,
            };
            let opts = crate::editor::EditOptions {
                kb,
                source,
                port,
                seed,
            };
            crate::editor::run(&opts).map_err(|e| AppError::Editor(e.to_string()))?;
            Ok(Outcome::Done)
        }
        KbCommand::Compile { kb, zone } => {
            let kb = load(&kb)?;
            let list = tools::compile_zone(&kb, &zone)?;
            let all: String = list
                .iter()
                .map(|(label, text)| format!("# {label}\n{text}\n"))
                .collect();
            emit(&all)?;
            Ok(Outcome::Done)
        }
        KbCommand::Explain {
            kb,
            osm,
            shp,
            id,
            seed,
            infer,
        } => {
            let kb = load(&kb)?;
            let source = match (osm, shp) {
                (Some(p), _) => Source::Osm(p),
                (None, Some(path)) => Source::Shp {
                    path,
                    height_field: None,
                    levels_field: None,
                    fields: Vec::new(),
                    layer: None,
                },
                (None, None) => return Err(AppError::Missing),
            };
            let e =
                explain_building(&kb, &source, &id, seed, infer.0).map_err(AppError::Explain)?;
            emit(&e.to_string())?;
            Ok(Outcome::Done)
        }
        KbCommand::Learn {
            osm,
            shp,
            grid,
            zones,
            min_samples,
            max_appearances,
            out,
        } => {
            let (source, file) = match (osm, shp) {
                (Some(p), _) => (Source::Osm(p.clone()), p),
                (None, Some(path)) => (
                    Source::Shp {
                        path: path.clone(),
                        height_field: None,
                        levels_field: None,
                        fields: Vec::new(),
                        layer: None,
                    },
                    path,
                ),
                (None, None) => return Err(AppError::Missing),
            };
            let name = file
                .file_name()
                .map(|n| n.to_string_lossy().into_owned())
                .unwrap_or_default();
            let stem = [".osm.pbf", ".pbf", ".shp", ".SHP"]
                .iter()
                .find_map(|ext| name.strip_suffix(ext))
                .unwrap_or(&name)
                .to_string();
            let options = crate::kb::learn::LearnOptions {
                grouping: crate::kb::learn::Grouping::Grid {
                    metres: f64::from(grid),
                },
                min_samples,
                max_appearances,
                name: stem,
                source: name,
            };
            let l = learn_kb(&source, zones.as_deref(), &options, &out)?;
            eprintln!(
                "citygen: learned {} buildings into {} zones ({} with data of their own) \
                 and {} appearances ({} per-kind groups); wrote {} ({} bytes)",
                l.samples,
                l.zones,
                l.zones_with_own_data,
                l.appearances,
                l.kind_groups,
                out.display(),
                l.text.len()
            );
            Ok(Outcome::Done)
        }
    }
}

/// Writes `text` to standard output, ending it with a newline (nothing for no text). A reader
/// that stops early (`citygen kb explain ... | head`) closes the pipe: that is no error, and
/// nothing more is written. [`AppError::Stdout`] when standard output could not be written
/// otherwise.
fn emit(text: &str) -> Result<(), AppError> {
    let mut out = std::io::stdout().lock();
    let nl: &[u8] = if text.is_empty() || text.ends_with('\n') {
        b""
    } else {
        b"\n"
    };
    match out
        .write_all(text.as_bytes())
        .and_then(|()| out.write_all(nl))
        .and_then(|()| out.flush())
    {
        Ok(()) => Ok(()),
        Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => Ok(()),
        Err(e) => Err(AppError::Stdout(e)),
    }
}

/// `citygen kb explain`: reads the source and prepares it as a run does, finds building `id`
/// (`way/123`, `relation/45`, a GIS feature's own text id as the outputs write it, or for a
/// shapefile also a bare 0-based record number; a
/// `building:part` gets its outline's tags under its own) and explains, for the knowledge base,
/// its zone chain, inherited values and the appearance the run's `seed` picks for it.
pub(crate) fn explain_building(
    kb: &KnowledgeBase,
    source: &Source,
    id: &str,
    seed: u64,
    infer: Option<crate::model::Inference>,
) -> Result<Explanation, RunError> {
    let text = id.trim();
    // Anything else is a GIS feature's own text id (a GUID, a BAG identificatie, a TOID), as
    // the outputs and the report write it.
    let wanted = match (source, SourceId::parse(text)) {
        (Source::Shp { .. }, None) => text.parse().ok().map(SourceId::Shape),
        (_, parsed) => parsed,
    }
    .or_else(|| (!text.is_empty()).then(|| SourceId::Text(crate::model::TextId::new(text))));
    let Some(wanted) = wanted else {
        return Err(RunError::Input(
            "an empty id is not a building id (way/123, relation/45, a record number or the \
             feature's own id)"
                .to_string(),
        ));
    };
    let mut report = Report::default();
    let read = read_source(source, None, None, &mut report)?;
    let mut site = prepare::prepare(read.footprints, read.source_crs, None, &mut report);
    let boundaries = kb::BoundaryZones::new(kb, &read.boundaries);
    let inferred = infer_from_neighbours(kb, &boundaries, &mut site.lots, infer);
    let mut notes = inferred.notes;
    let found = site.lots.iter().find_map(|lot| {
        if lot.id == wanted {
            return Some((lot.lonlat, (*lot.tags).clone()));
        }
        let part = lot.parts.iter().find(|p| p.id == wanted)?;
        Some((lot.lonlat, merged_tags(&part.tags, &lot.tags, true)))
    });
    let Some((lonlat, tags)) = found else {
        let why = report
            .entries
            .iter()
            .find(|e| e.id == wanted.to_string())
            .map(|e| e.reason.clone());
        return Err(RunError::Input(match why {
            Some(r) => format!("{wanted} was not generated: {r}"),
            None => format!("no building {wanted} in the input"),
        }));
    };
    let mut e = kb::tools::explain_at(
        kb,
        &boundaries,
        lonlat.0,
        lonlat.1,
        &tags,
        wanted.seed_value(),
        seed,
    );
    // A part's own tags win over what its outline inferred; the outline's note tells what.
    let outline = site
        .lots
        .iter()
        .find(|l| l.id == wanted || l.parts.iter().any(|p| p.id == wanted))
        .map(|l| l.id);
    if let Some(note) = outline.and_then(|id| notes.remove(&id)) {
        e.inferred = note.split("; ").map(str::to_string).collect();
    }
    let index = outline.and_then(|id| site.lots.iter().position(|l| l.id == id));
    if let Some(i) = index {
        e.inferred
            .extend(prepare::estimate::explain(&inferred.outcome, i));
    }
    Ok(e)
}

/// `citygen kb learn`: reads and prepares the source as a run does, takes one
/// [`kb::learn::Sample`] per lot (its outline's tags at its representative point, the point
/// the generator locates; `building=roof` canopies left out), learns a knowledge base
/// ([`kb::learn::learn`]) grouped by a grid or by the zones of the `--zones` knowledge base
/// (`options.grouping` is then replaced), and writes it atomically to `out`. The output may
/// not be an input. Errors name the file: an input that cannot be read or holds no building
/// is an input error, as is a `--zones` KB that does not load.
pub(crate) fn learn_kb(
    source: &Source,
    zones: Option<&Path>,
    options: &kb::learn::LearnOptions<'_>,
    out: &Path,
) -> Result<kb::learn::Learned, RunError> {
    let mut inputs: Vec<(&'static str, PathBuf)> = match source {
        Source::Osm(p) => vec![("--osm", p.clone())],
        Source::Shp { path, .. } => outputs::shapefile_parts(path)
            .into_iter()
            .map(|p| ("--shp", p))
            .collect(),
    };
    inputs.extend(zones.map(|z| ("--zones", z.to_path_buf())));
    outputs::check(&[("--out", out.to_path_buf())], &inputs, true)?;
    let zones_kb = match zones {
        Some(z) => Some(
            KnowledgeBase::load(z)
                .map(|(kb, _)| kb)
                .map_err(|e| RunError::Input(e.to_string()))?,
        ),
        None => None,
    };
    let file = match source {
        Source::Osm(p) | Source::Shp { path: p, .. } => p.clone(),
    };
    let mut report = Report::default();
    let read = read_source(source, None, None, &mut report)?;
    if read.footprints.is_empty() {
        return Err(RunError::Input(format!(
            "{}: no building footprint to learn from",
            file.display()
        )));
    }
    let site = prepare::prepare(read.footprints, read.source_crs, None, &mut report);
    let samples: Vec<kb::learn::Sample> = site
        .lots
        .iter()
        .filter_map(|lot| kb::learn::Sample::from_tags(lot.lonlat, &lot.tags))
        .collect();
    let mut o = options.clone();
    if let Some(kb) = &zones_kb {
        o.grouping = kb::learn::Grouping::Zones(kb);
    }
    let learned = kb::learn::learn(&samples, &o)
        .map_err(|e| RunError::Input(format!("{}: {e}", file.display())))?;
    let write = || -> std::io::Result<()> {
        let f = AtomicFile::create(out)?;
        let mut w = f.writer()?;
        w.write_all(learned.text.as_bytes())?;
        w.flush()?;
        drop(w);
        f.commit()
    };
    write().map_err(|e| RunError::Output {
        path: out.to_path_buf(),
        source: ExportError::Io(e),
    })?;
    Ok(learned)
}
