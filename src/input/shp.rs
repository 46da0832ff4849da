//! ESRI shapefile reader: Polygon, PolygonZ and PolygonM records with their `.dbf` attributes.
//!
//! Each record is one footprint (`shp/<record index>`), however many outer rings it has. ESRI
//! declares ring roles by orientation (outer clockwise, holes counter-clockwise), but files
//! written by other tools often get it wrong, so rings are grouped by how they nest (see
//! `input::rings`) and disagreements are counted in one file-level note.
//!
//! Attributes: a height field and a levels field are mapped to the OSM keys `height` and
//! `building:levels` and parsed by [`BuildingTags`]. Without `--shp-height-field`, the first field
//! whose name matches `HEIGHT_FIELDS` (case-insensitively, in that order) is used.
//!
//! About the Clifton sample (`data/clifton/clifton_test.dbf`): `MEAN_mean`, `MIN_min` and
//! `MAX_max` are zonal statistics (mean, min, max) of a LiDAR normalised surface model (heights
//! above ground, integer metres) over each footprint. They are not absolute heights: `MIN_min`
//! is 0 for every record (ground pixels fall inside each footprint), `MAX_max` is an integer
//! (median 8 m, 61 m at most) and absolute heights in Clifton, Nottingham (the data lie at
//! BNG 454000-456300 E, 333000-335900 N) would be some 25 to 90 m above datum. `MEAN_mean` is dragged down by those ground pixels at the edges (median 4.4 m), so
//! `MAX_max`, the top of the roof, is what matches OSM `height`; it comes before `MEAN_mean`
//! in `HEIGHT_FIELDS`. `MAX_max = 0` (no LiDAR return) is reported as an ignored height.

use std::fs::File;
use std::io::{BufReader, Read};
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::{Path, PathBuf};

use shapefile::dbase::{self, FieldValue};
use shapefile::{Shape, ShapeReader, ShapeType};

use super::{
    BuildingTags, Footprint, FootprintKind, InputError, ReadResult, Ring, SourceId, TagInterner,
};
use crate::report::{Outcome, Report};

pub use super::features::ShpOptions;
pub(crate) use super::features::{HEIGHT_FIELDS, LEVELS_FIELDS};
use super::features::{MORE_HEIGHT_FIELDS, MORE_LEVELS_FIELDS};

/// Reads the polygon records of a shapefile and their attributes.
///
/// Needs the `.shp`, `.shx` and `.dbf` side by side (same stem; the extension's case follows
/// the `.shp`'s). Footprints come in record order with id `shp/<index>`; null shapes and
/// records without a usable ring are `Skipped` report entries. `source_crs` is
/// `opts.src_crs`, else the CRS of the `.prj`; without either, coordinates that look like
/// longitude/latitude are taken as WGS84 (with a note), anything else is an error.
/// Errors name the file and, for a bad record, its index. Never panics.
pub fn read_shp(
    path: &Path,
    opts: &ShpOptions,
    report: &mut Report,
) -> Result<ReadResult, InputError> {
    let shx_path = companion(path, "shx");
    let dbf_path = companion(path, "dbf");
    let shp = open(path, "the .shp")?;
    let shx = open(&shx_path, "the index file (.shx)")?;
    let dbf = open(&dbf_path, "the attribute table (.dbf)")?;

    let mut shapes = ShapeReader::with_shx(shp, shx).map_err(|e| InputError::Shapefile {
        path: path.to_path_buf(),
        reason: match e {
            shapefile::Error::InvalidFileCode(_) => {
                "not a shapefile (bad file code in the header)".to_string()
            }
            e => format!("cannot read the header or the .shx index: {e}"),
        },
    })?;
    let header = *shapes.header();
    match header.shape_type {
        ShapeType::Polygon | ShapeType::PolygonZ | ShapeType::PolygonM | ShapeType::NullShape => {}
        t => {
            return Err(InputError::Shapefile {
                path: path.to_path_buf(),
                reason: format!(
                    "shape type {t} is not a polygon type (Polygon, PolygonZ, PolygonM)"
                ),
            })
        }
    }
    let count = shapes.shape_count().map_err(|e| InputError::Shapefile {
        path: shx_path.clone(),
        reason: e.to_string(),
    })?;

    let mut table = dbase::Reader::new(dbf).map_err(|e| InputError::Shapefile {
        path: dbf_path.clone(),
        reason: format!("not a readable dBASE table: {e}"),
    })?;
    let rows = table.header().num_records as usize;
    if rows != count {
        return Err(InputError::Shapefile {
            path: dbf_path.clone(),
            reason: format!("has {rows} rows but the .shx indexes {count} shapes"),
        });
    }
    let field_names: Vec<String> = table
        .fields()
        .iter()
        .map(|f| f.name().to_string())
        .collect();
    // The shapefile reads a height and a level count (`--field height=`/`levels=` too) with
    // the municipal names; not 3DBAG's absolute heights, which need its ground column.
    let heights: Vec<&str> = HEIGHT_FIELDS
        .iter()
        .chain(MORE_HEIGHT_FIELDS.iter().filter(|f| !f.starts_with("b3_")))
        .copied()
        .collect();
    let levels: Vec<&str> = LEVELS_FIELDS
        .iter()
        .chain(&MORE_LEVELS_FIELDS)
        .copied()
        .collect();
    let height_field =
        pick_field(&field_names, opts.named("height"), &heights).map_err(|reason| {
            InputError::Shapefile {
                path: dbf_path.clone(),
                reason,
            }
        })?;
    let levels_field =
        pick_field(&field_names, opts.named("levels"), &levels).map_err(|reason| {
            InputError::Shapefile {
                path: dbf_path.clone(),
                reason,
            }
        })?;
    for (what, f) in [
        ("height", &height_field),
        ("building:levels", &levels_field),
    ] {
        if let Some(f) = f {
            report.add(
                None,
                Outcome::Note,
                format!("{}: {what} taken from field {f}", path.display()),
            );
        }
    }

    let source_crs = source_crs(path, opts, &header)?;
    if source_crs.is_none() {
        report.add(
            None,
            Outcome::Note,
            format!(
                "{}: no .prj and no --src-crs; the coordinates look like longitude/latitude, read as WGS84",
                path.display()
            ),
        );
    }

    // A footprint shapefile has no streets (its buildings keep the thesis front) and no admin
    // boundaries (the KB's own zones place them). Rows with the same attributes share their
    // parsed tags.
    let interner = TagInterner::default();
    let mut result = ReadResult {
        footprints: Vec::new(),
        source_crs,
        streets: Default::default(),
        boundaries: Vec::new(),
        attributes: Default::default(),
    };
    let mut role_fixes = 0usize;
    let mut shape_iter = shapes.iter_shapes_as::<Shape>();
    let mut row_iter = table.iter_records();
    for index in 0..count {
        // The decoders are not expected to panic; a corrupt file must not bring the process
        // down if they do.
        let shape = match catch_unwind(AssertUnwindSafe(|| shape_iter.next())) {
            Ok(Some(Ok(s))) => s,
            Ok(Some(Err(e))) => return Err(record_error(path, index, e.to_string())),
            Ok(None) => return Err(record_error(path, index, "missing from the .shp".into())),
            Err(_) => return Err(record_error(path, index, "undecodable record".into())),
        };
        let row = match catch_unwind(AssertUnwindSafe(|| row_iter.next())) {
            Err(_) => return Err(record_error(&dbf_path, index, "undecodable row".into())),
            Ok(row) => row,
        };
        let row = match row {
            Some(Ok(r)) => r,
            Some(Err(e)) => return Err(record_error(&dbf_path, index, e.to_string())),
            // The dBASE reader skips rows flagged deleted; a shape without its row would shift
            // every attribute after it, so this is an error rather than a guess.
            None => {
                return Err(record_error(
                    &dbf_path,
                    index,
                    "no attribute row (deleted or missing rows in the .dbf)".into(),
                ))
            }
        };
        let id = SourceId::Shape(index as u64);
        report.read += 1;
        let rings: Vec<(Ring, bool)> = match shape {
            Shape::NullShape => {
                skip(report, id, "null shape (no geometry)".into());
                continue;
            }
            Shape::Polygon(p) => p
                .rings()
                .iter()
                .map(|r| {
                    let outer = matches!(r, shapefile::PolygonRing::Outer(_));
                    (r.points().iter().map(|q| (q.x, q.y)).collect(), outer)
                })
                .collect(),
            Shape::PolygonM(p) => p
                .rings()
                .iter()
                .map(|r| {
                    let outer = matches!(r, shapefile::PolygonRing::Outer(_));
                    (r.points().iter().map(|q| (q.x, q.y)).collect(), outer)
                })
                .collect(),
            // Z is dropped: footprints are 2D, heights come from the attributes.
            Shape::PolygonZ(p) => p
                .rings()
                .iter()
                .map(|r| {
                    let outer = matches!(r, shapefile::PolygonRing::Outer(_));
                    (r.points().iter().map(|q| (q.x, q.y)).collect(), outer)
                })
                .collect(),
            other => {
                skip(
                    report,
                    id,
                    format!("shape type {} is not a polygon", other.shapetype()),
                );
                continue;
            }
        };

        let got = match super::rings::polygons_of(rings) {
            Ok(g) => g,
            Err(why) => {
                skip(report, id, why);
                continue;
            }
        };
        role_fixes += got.role_fixes;
        if !got.problems.is_empty() {
            report.repaired += 1;
            report.add(Some(id), Outcome::Repaired, got.problems.join("; "));
        }

        let mut pairs: Vec<(&str, String)> = Vec::new();
        for (key, field) in [
            ("height", &height_field),
            ("building:levels", &levels_field),
        ] {
            if let Some(v) = field
                .as_deref()
                .and_then(|f| row.get(f))
                .and_then(field_text)
            {
                pairs.push((key, v));
            }
        }
        let tags = BuildingTags::from_pairs(pairs.iter().map(|(k, v)| (*k, v.as_str())));
        for (k, v, why) in &tags.ignored {
            report.add(Some(id), Outcome::Note, format!("{k}={v} ignored: {why}"));
        }
        let polygons = got.polygons;
        result.footprints.push(Footprint {
            id,
            kind: FootprintKind::Building,
            polygons,
            tags: interner.intern(tags),
        });
    }
    if role_fixes > 0 {
        report.add(
            None,
            Outcome::Note,
            format!(
                "{}: {role_fixes} ring(s) had an orientation that disagreed with how they nest (ESRI: outer rings clockwise, holes counter-clockwise); nesting was used",
                path.display()
            ),
        );
    }
    Ok(result)
}

fn skip(report: &mut Report, id: SourceId, why: String) {
    report.skipped += 1;
    report.add(Some(id), Outcome::Skipped, why);
}

fn record_error(path: &Path, record: usize, reason: String) -> InputError {
    InputError::ShapeRecord {
        path: path.to_path_buf(),
        record,
        reason,
    }
}

/// The companion file `stem.ext`, upper-cased when the `.shp`'s extension is (`X.SHP`).
fn companion(shp: &Path, ext: &str) -> PathBuf {
    let upper = shp
        .extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| e.chars().all(|c| c.is_ascii_uppercase()) && !e.is_empty());
    let ext = if upper {
        ext.to_ascii_uppercase()
    } else {
        ext.to_string()
    };
    shp.with_extension(ext)
}

fn open(path: &Path, what: &str) -> Result<BufReader<File>, InputError> {
    match File::open(path) {
        Ok(f) => Ok(BufReader::new(f)),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Err(InputError::Shapefile {
            path: path.to_path_buf(),
            reason: format!("{what} is missing; a shapefile needs its .shp, .shx and .dbf"),
        }),
        Err(source) => Err(InputError::Io {
            path: path.to_path_buf(),
            source,
        }),
    }
}

/// The field to read: the one named (matched case-insensitively; an error if absent), else
/// the first candidate present.
fn pick_field(
    fields: &[String],
    named: Option<&str>,
    candidates: &[&str],
) -> Result<Option<String>, String> {
    if let Some(n) = named {
        return fields
            .iter()
            .find(|f| f.eq_ignore_ascii_case(n))
            .cloned()
            .map(Some)
            .ok_or_else(|| format!("no field {n:?}; the fields are {}", fields.join(", ")));
    }
    Ok(candidates
        .iter()
        .find_map(|c| fields.iter().find(|f| f.eq_ignore_ascii_case(c)))
        .cloned())
}

/// A dBASE value as text for [`BuildingTags::from_pairs`]; `None` for empty values.
fn field_text(v: &FieldValue) -> Option<String> {
    match v {
        FieldValue::Character(s) => s.as_ref().map(|s| s.trim().to_string()),
        FieldValue::Numeric(n) => n.map(|n| n.to_string()),
        FieldValue::Float(n) => n.map(|n| n.to_string()),
        FieldValue::Integer(n) => Some(n.to_string()),
        FieldValue::Double(n) | FieldValue::Currency(n) => Some(n.to_string()),
        FieldValue::Memo(s) => Some(s.trim().to_string()),
        FieldValue::Logical(_) | FieldValue::Date(_) | FieldValue::DateTime(_) => None,
    }
}

/// `--src-crs`, else the `.prj`, else WGS84 when the bounds look like lon/lat.
fn source_crs(
    path: &Path,
    opts: &ShpOptions,
    header: &shapefile::header::Header,
) -> Result<Option<crate::crs::Crs>, InputError> {
    if let Some(c) = opts.src_crs {
        return Ok(Some(c));
    }
    let prj = companion(path, "prj");
    match File::open(&prj) {
        Ok(mut f) => {
            let mut bytes = Vec::new();
            f.read_to_end(&mut bytes).map_err(|source| InputError::Io {
                path: prj.clone(),
                source,
            })?;
            let text = String::from_utf8_lossy(&bytes);
            crate::crs::Crs::from_prj(&text)
                .map(Some)
                .map_err(|e| InputError::Crs {
                    path: prj,
                    reason: format!("{e}; give the CRS with --src-crs EPSG:n"),
                })
        }
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
            let (min, max) = (header.bbox.min, header.bbox.max);
            let lonlat = (-180.0..=180.0).contains(&min.x)
                && (-180.0..=180.0).contains(&max.x)
                && (-90.0..=90.0).contains(&min.y)
                && (-90.0..=90.0).contains(&max.y);
            if lonlat {
                Ok(None)
            } else {
                Err(InputError::Crs {
                    path: prj,
                    reason: "missing, and the coordinates are not longitude/latitude; give the CRS with --src-crs EPSG:n".into(),
                })
            }
        }
        Err(source) => Err(InputError::Io { path: prj, source }),
    }
}

#[cfg(test)]
mod tests;
