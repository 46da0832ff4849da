//! ESRI shapefile reader: Polygon, PolygonZ and PolygonM records with their `.dbf` attributes.
//!
//! Each record is one footprint, however many outer rings it has. ESRI declares ring roles by
//! orientation (outer clockwise, holes counter-clockwise), but files written by other tools
//! often get it wrong, so rings are grouped by how they nest (see `input::rings`) and
//! disagreements are counted in one file-level note.
//!
//! Ids: the file's id column (`--field id=COLUMN`, else the first of `id`, `objectid`, `fid`,
//! `osm_id`, `gml_id` (case-insensitively) holding whole numbers, else the first of them at
//! all) names the records `feature/<value>` when every record has a non-negative whole number
//! there and no two the same; otherwise every record is `shp/<record index>` with one note
//! saying why, and the column is kept as an attribute.
//!
//! Attributes are read as the other GIS readers read them (`input::features`): citygen's
//! fields (height, levels, roof shape and height, colours, ...) by their common names or
//! `--field TARGET=COLUMN` (`--shp-height-field`/`--shp-levels-field` too), every other
//! column carried typed into the outputs: `C` text (trimmed; empty is no value), `N`/`F`
//! numbers (whole when the column has no decimals), `L` booleans, `D` dates (ISO 8601).
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

use serde_json::{Map, Value};
use shapefile::dbase::{self, FieldValue};
use shapefile::{Shape, ShapeReader, ShapeType};

use super::features::{Sink, ID_COLUMNS};
use super::{InputError, ReadResult, Ring};
use crate::report::{Outcome, Report};

pub use super::features::ShpOptions;

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
    let fields: Vec<(String, dbase::FieldType)> = table
        .fields()
        .iter()
        .map(|f| (f.name().to_string(), f.field_type()))
        .collect();
    let decimals = decimal_counts(&dbf_path);
    // A column named (`--field`, `--shp-height-field`, `--shp-levels-field`) must exist.
    let named = opts
        .fields
        .iter()
        .map(|(_, c)| c.as_str())
        .chain(opts.height_field.as_deref())
        .chain(opts.levels_field.as_deref());
    for n in named {
        if !fields.iter().any(|(f, _)| f.eq_ignore_ascii_case(n)) {
            let names: Vec<&str> = fields.iter().map(|(f, _)| f.as_str()).collect();
            return Err(InputError::Shapefile {
                path: dbf_path.clone(),
                reason: format!("no field {n:?}; the fields are {}", names.join(", ")),
            });
        }
    }
    // The id column: `--field id=`, else the first of the id names holding whole numbers
    // (`N` or `F` without decimals, `I`), else the first of them at all (a text column of
    // digits names the records too; one of other text numbers none, see `Sink::shapefile`).
    let mut opts = opts.clone();
    if opts.named("id").is_none() {
        let whole = |i: usize, ty: &dbase::FieldType| match ty {
            dbase::FieldType::Integer => true,
            dbase::FieldType::Numeric | dbase::FieldType::Float => decimals.get(i) == Some(&0),
            _ => false,
        };
        let candidates = |numeric: bool| {
            ID_COLUMNS.iter().find_map(|c| {
                fields.iter().enumerate().find_map(|(i, (name, ty))| {
                    (name.eq_ignore_ascii_case(c) && (!numeric || whole(i, ty)))
                        .then(|| name.clone())
                })
            })
        };
        if let Some(c) = candidates(true).or_else(|| candidates(false)) {
            opts.fields.push(("id".to_string(), c));
        }
    }
    let opts = &opts;

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
    // boundaries (the KB's own zones place them). Columns are read as the other GIS readers
    // read them (`input::features`): citygen's fields by their common names or `--field`, the
    // id column, every other column kept typed.
    let mut sink = Sink::shapefile(path, opts, report);
    for (name, ty) in &fields {
        if matches!(ty, dbase::FieldType::Date | dbase::FieldType::DateTime) {
            sink.date_column(name);
        }
    }
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
        let rings: Result<Vec<(Ring, bool)>, String> = match shape {
            Shape::NullShape => Err("null shape (no geometry)".into()),
            Shape::Polygon(p) => Ok(p
                .rings()
                .iter()
                .map(|r| {
                    let outer = matches!(r, shapefile::PolygonRing::Outer(_));
                    (r.points().iter().map(|q| (q.x, q.y)).collect(), outer)
                })
                .collect()),
            Shape::PolygonM(p) => Ok(p
                .rings()
                .iter()
                .map(|r| {
                    let outer = matches!(r, shapefile::PolygonRing::Outer(_));
                    (r.points().iter().map(|q| (q.x, q.y)).collect(), outer)
                })
                .collect()),
            // Z is dropped: footprints are 2D, heights come from the attributes.
            Shape::PolygonZ(p) => Ok(p
                .rings()
                .iter()
                .map(|r| {
                    let outer = matches!(r, shapefile::PolygonRing::Outer(_));
                    (r.points().iter().map(|q| (q.x, q.y)).collect(), outer)
                })
                .collect()),
            other => Err(format!("shape type {} is not a polygon", other.shapetype())),
        };
        let mut props = Map::new();
        for (i, (name, _)) in fields.iter().enumerate() {
            if let Some(v) = row.get(name) {
                let whole = decimals.get(i).is_some_and(|&d| d == 0);
                props.insert(name.clone(), field_value(v, whole));
            }
        }
        sink.add(None, rings, &props);
    }
    sink.finish(source_crs)
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

/// A dBASE value as a property: text trimmed (empty text is null), `N`/`F` numbers whole
/// when the column has no decimals (`whole`) and the value is whole, logicals as booleans,
/// dates as ISO 8601 text (`YYYY-MM-DD`; the column is marked a date column).
fn field_value(v: &FieldValue, whole: bool) -> Value {
    let real = |x: f64| -> Value {
        if whole && x.fract() == 0.0 && x.abs() < 9.0e15 {
            Value::from(x as i64)
        } else {
            serde_json::Number::from_f64(x).map_or(Value::Null, Value::Number)
        }
    };
    match v {
        FieldValue::Character(Some(s)) | FieldValue::Memo(s) if !s.trim().is_empty() => {
            Value::String(s.trim().to_string())
        }
        FieldValue::Character(_) | FieldValue::Memo(_) => Value::Null,
        FieldValue::Numeric(Some(x)) => real(*x),
        FieldValue::Float(Some(x)) => real(f64::from(*x)),
        FieldValue::Numeric(None) | FieldValue::Float(None) => Value::Null,
        FieldValue::Integer(n) => Value::from(*n),
        FieldValue::Double(x) | FieldValue::Currency(x) => {
            serde_json::Number::from_f64(*x).map_or(Value::Null, Value::Number)
        }
        FieldValue::Logical(b) => b.map_or(Value::Null, Value::Bool),
        FieldValue::Date(Some(d)) => {
            Value::String(format!("{:04}-{:02}-{:02}", d.year(), d.month(), d.day()))
        }
        FieldValue::Date(None) => Value::Null,
        FieldValue::DateTime(t) => {
            let (d, c) = (t.date(), t.time());
            Value::String(format!(
                "{:04}-{:02}-{:02}T{:02}:{:02}:{:02}",
                d.year(),
                d.month(),
                d.day(),
                c.hours(),
                c.minutes(),
                c.seconds()
            ))
        }
    }
}

/// Each field's decimal count from the `.dbf` header's field descriptors (byte 17 of each
/// 32-byte descriptor after the 32-byte header, up to the `0x0D` terminator), in field
/// order; empty when unreadable (every number is then read as a real).
fn decimal_counts(dbf: &Path) -> Vec<u8> {
    let Ok(f) = File::open(dbf) else {
        return Vec::new();
    };
    let mut head = Vec::new();
    // At most 255 descriptors of 32 bytes after the header: bounded.
    if f.take(32 + 32 * 256).read_to_end(&mut head).is_err() {
        return Vec::new();
    }
    head.get(32..)
        .unwrap_or_default()
        .chunks_exact(32)
        .take_while(|d| d[0] != 0x0D)
        .map(|d| d[17])
        .collect()
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
