//! The whole run: read -> prepare -> derive (parallel, in chunks) -> write (in input order).

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::{Duration, Instant};

use glam::DVec3;
use rayon::prelude::*;
use thiserror::Error;

use crate::crs::Crs;
use crate::derive::{Generator, Rules};
use crate::export::citygml::CityGmlWriter;
use crate::export::gltf::GltfWriter;
use crate::export::ifc::IfcWriter;
use crate::export::{AtomicFile, BuildingWriter, ExportError, OutputContext};
use crate::grammar::Caps;
use crate::input::{self, shp::ShpOptions};
use crate::kb::KnowledgeBase;
use crate::model::Lod;
use crate::prepare;
use crate::report::{Outcome, Report};

/// Buildings derived in parallel before being written; bounds memory.
const CHUNK: usize = 2048;

/// The footprint source.
#[derive(Clone, Debug)]
pub enum Source {
    Osm(PathBuf),
    Shp {
        path: PathBuf,
        height_field: Option<String>,
        levels_field: Option<String>,
    },
}

/// Everything a run needs, as the CLI gives it.
#[derive(Clone, Debug)]
pub struct Options {
    pub source: Source,
    pub kb: Option<PathBuf>,
    pub rules: Option<PathBuf>,
    pub lod: Lod,
    pub ifc: Option<PathBuf>,
    pub citygml: Option<PathBuf>,
    pub gltf: Option<PathBuf>,
    pub report: Option<PathBuf>,
    pub seed: u64,
    pub crs: Option<Crs>,
    pub src_crs: Option<Crs>,
    pub caps: Caps,
}

/// What went wrong, for the exit code and the message.
#[derive(Debug, Error)]
pub enum RunError {
    /// Bad input file (exit code 1).
    #[error("{0}")]
    Input(String),
    /// An output could not be written (exit code 3).
    #[error("{path}: {source}")]
    Output { path: PathBuf, source: ExportError },
}

/// Totals of a run, for the summary line.
#[derive(Clone, Debug, Default)]
pub struct Summary {
    pub report: Report,
    pub polygons: usize,
    pub elapsed: Duration,
    pub outputs: Vec<PathBuf>,
}

/// Called after each chunk with (buildings done, buildings in all).
pub type Progress<'a> = &'a (dyn Fn(usize, usize) + Sync);

/// Runs the pipeline and writes every requested output atomically.
pub fn run(opts: &Options, progress: Progress<'_>) -> Result<Summary, RunError> {
    let start = Instant::now();
    let mut report = Report::default();
    let read = match &opts.source {
        Source::Osm(p) => input::osm::read_osm(p, &mut report),
        Source::Shp {
            path,
            height_field,
            levels_field,
        } => {
            let o = ShpOptions {
                height_field: height_field.clone(),
                levels_field: levels_field.clone(),
                src_crs: opts.src_crs,
            };
            input::shp::read_shp(path, &o, &mut report)
        }
    }
    .map_err(|e| RunError::Input(e.to_string()))?;
    let source_crs = opts.src_crs.or(read.source_crs);
    let source_name = match &opts.source {
        Source::Osm(p) | Source::Shp { path: p, .. } => file_name(p),
    };

    let kb = match &opts.kb {
        Some(p) => {
            let (kb, repairs) =
                KnowledgeBase::load(p).map_err(|e| RunError::Input(e.to_string()))?;
            for r in repairs {
                report.add(None, Outcome::Note, format!("{}: {r}", p.display()));
            }
            kb
        }
        None => KnowledgeBase::earth_only(),
    };
    let rules = match &opts.rules {
        Some(p) => {
            let text = std::fs::read_to_string(p)
                .map_err(|e| RunError::Input(format!("{}: {e}", p.display())))?;
            let rs = crate::grammar::parse(&text, &p.display().to_string())
                .map_err(|e| RunError::Input(e.to_string()))?;
            Rules::File(Arc::new(rs))
        }
        None => Rules::Kb,
    };

    let site = prepare::prepare(read.footprints, source_crs, opts.crs, &mut report);
    let ctx = OutputContext {
        crs: site.crs,
        origin: DVec3::new(site.origin.x, site.origin.y, 0.0),
        origin_lonlat: site.origin_lonlat,
        lod: opts.lod,
        source_name,
        seed: opts.seed,
    };

    // Open every output before the work, so a bad path fails fast.
    let mut outputs: Vec<(PathBuf, Box<dyn BuildingWriter>, AtomicFile)> = Vec::new();
    if let Some(p) = &opts.ifc {
        let f = AtomicFile::create(p).map_err(io_err(p))?;
        outputs.push((
            p.clone(),
            Box::new(IfcWriter::new(f.writer().map_err(io_err(p))?)),
            f,
        ));
    }
    if let Some(p) = &opts.citygml {
        let f = AtomicFile::create(p).map_err(io_err(p))?;
        outputs.push((
            p.clone(),
            Box::new(CityGmlWriter::new(f.writer().map_err(io_err(p))?)),
            f,
        ));
    }
    if let Some(p) = &opts.gltf {
        let f = AtomicFile::create(p).map_err(io_err(p))?;
        let w = GltfWriter::beside(f.writer().map_err(io_err(p))?, p).map_err(io_err(p))?;
        outputs.push((p.clone(), Box::new(w), f));
    }
    for (path, w, _) in &mut outputs {
        w.begin(&ctx).map_err(|e| RunError::Output {
            path: path.clone(),
            source: e,
        })?;
    }

    let caps = Caps {
        facades: opts.lod >= Lod::Lod3,
        ..opts.caps
    };
    let generator = Generator::new(kb, rules, opts.lod, opts.seed, caps);
    let total = site.lots.len();
    let mut polygons = 0usize;
    for (ci, chunk) in site.lots.chunks(CHUNK).enumerate() {
        let results: Vec<_> = chunk
            .par_iter()
            .map(|lot| generator.generate(lot))
            .collect();
        for (lot, result) in chunk.iter().zip(results) {
            match result {
                Ok((building, notes)) => {
                    for (outcome, text) in notes {
                        report.add(Some(lot.id), outcome, text);
                    }
                    polygons += building.polygon_count();
                    for (path, w, _) in &mut outputs {
                        w.write(&building).map_err(|e| RunError::Output {
                            path: path.clone(),
                            source: e,
                        })?;
                    }
                    report.generated += 1;
                }
                Err(reason) => report.add(Some(lot.id), Outcome::Skipped, reason),
            }
        }
        progress(((ci + 1) * CHUNK).min(total), total);
    }
    for (path, w, _) in &mut outputs {
        w.finish().map_err(|e| RunError::Output {
            path: path.clone(),
            source: e,
        })?;
    }
    report.skipped = report
        .entries
        .iter()
        .filter(|e| e.outcome == Outcome::Skipped)
        .count();
    report.repaired = report
        .entries
        .iter()
        .filter(|e| e.outcome == Outcome::Repaired)
        .count();
    let mut paths = Vec::with_capacity(outputs.len());
    for (path, writer, file) in outputs {
        drop(writer);
        file.commit().map_err(io_err(&path))?;
        paths.push(path);
    }
    if let Some(p) = &opts.report {
        write_report(p, &report).map_err(|e| RunError::Output {
            path: p.clone(),
            source: e.into(),
        })?;
    }
    Ok(Summary {
        report,
        polygons,
        elapsed: start.elapsed(),
        outputs: paths,
    })
}

fn write_report(path: &Path, report: &Report) -> std::io::Result<()> {
    let f = AtomicFile::create(path)?;
    let mut w = f.writer()?;
    serde_json::to_writer_pretty(&mut w, report).map_err(std::io::Error::other)?;
    std::io::Write::write_all(&mut w, b"\n")?;
    std::io::Write::flush(&mut w)?;
    drop(w);
    f.commit()
}

/// Maps an I/O error on an output path to a [`RunError`].
fn io_err(p: &Path) -> impl Fn(std::io::Error) -> RunError + '_ {
    move |e| RunError::Output {
        path: p.to_path_buf(),
        source: e.into(),
    }
}

fn file_name(p: &Path) -> String {
    p.file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default()
}
