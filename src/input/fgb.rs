//! FlatGeobuf footprints (flatgeobuf.org, version 3): the features of the file read in order
//! with the `flatgeobuf` crate (its HTTP client off), the spatial index skipped.
//!
//! - **Geometry**: `Polygon` and `MultiPolygon` (z and m dropped); a file or feature of
//!   unknown type may hold either, or a `GeometryCollection` of them. Empty geometries and
//!   other types are skipped report entries.
//! - **Attributes**: the columns, read as `input::features` reads GeoJSON properties (OSM
//!   keys, Overture's names, municipal height/levels columns); the others kept typed (the
//!   integer types, `Float`/`Double`, `Bool`, `String`/`Json` as text, `DateTime` as a date;
//!   `Binary` left out).
//! - **Ids**: an id column (`--field id=COLUMN`, else `id`, `objectid`, `fid`, `osm_id`,
//!   `gml_id`) with a non-negative integer, else the feature's position (`feature/0`).
//! - **CRS**: `--src-crs`, else the header's CRS: an EPSG code (organisation `EPSG` or none),
//!   else its WKT read as a `.prj`; a file without one needs `--src-crs`.
//!
//! Before the crate reads a feature, the file's framing is checked here (header size, index
//! size, each feature's size within the file), so a corrupt or hostile file is an error naming
//! the feature, never a huge allocation or a panic.

use std::fs::File;
use std::io::{BufReader, Read, Seek, SeekFrom};
use std::path::Path;

use flatgeobuf::geozero::{error::GeozeroError, ColumnValue, PropertyProcessor};
use flatgeobuf::packed_r_tree::PackedRTree;
use flatgeobuf::{
    ColumnType, FallibleStreamingIterator, FeatureProperties, FgbReader, Geometry, GeometryType,
};
use serde_json::{Map, Value};

use super::features::{ShpOptions, Sink};
use super::{InputError, ReadResult, Ring};
use crate::report::Report;

/// Nested geometry collections deeper than this are refused.
const MAX_DEPTH: usize = 4;

/// The largest header the format allows (the crate's limit, 10 MB).
const MAX_HEADER: u64 = 10 * 1024 * 1024;

/// Whether the file starts with FlatGeobuf's magic bytes (`fgb`, the major version, `fgb`, a
/// patch byte).
pub(crate) fn looks_like_fgb(path: &Path) -> bool {
    let mut head = [0u8; 8];
    File::open(path)
        .and_then(|mut f| f.read_exact(&mut head))
        .is_ok_and(|()| &head[..3] == b"fgb" && &head[4..7] == b"fgb" && head[3] <= 3)
}

/// Reads the footprints of a FlatGeobuf file. See the module documentation.
pub fn read_fgb(
    path: &Path,
    opts: &ShpOptions,
    report: &mut Report,
) -> Result<ReadResult, InputError> {
    let bad = |reason: String| InputError::Shapefile {
        path: path.to_path_buf(),
        reason: format!("FlatGeobuf: {reason}"),
    };
    let io = |source: std::io::Error| InputError::Io {
        path: path.to_path_buf(),
        source,
    };
    check_framing(path).map_err(|e| match e {
        Framing::Io(e) => io(e),
        Framing::Bad(r) => bad(r),
    })?;
    let file = BufReader::new(File::open(path).map_err(io)?);
    let reader = FgbReader::open(file).map_err(|e| bad(e.to_string()))?;
    let header = reader.header();
    let file_type = header.geometry_type();
    let columns: Vec<(String, ColumnType)> = header
        .columns()
        .map(|cs| {
            cs.iter()
                .map(|c| (c.name().to_string(), c.type_()))
                .collect()
        })
        .unwrap_or_default();
    let header_crs = header.crs().map(|c| {
        (
            c.org().map(str::to_string),
            c.code(),
            c.wkt().map(str::to_string),
        )
    });
    let source_crs = match opts.src_crs {
        Some(c) => Some(c),
        None => crs_of(header_crs).map_err(|reason| InputError::Crs {
            path: path.to_path_buf(),
            reason,
        })?,
    };
    let mut sink = Sink::new(path, opts, report);
    for (name, ty) in &columns {
        if *ty == ColumnType::DateTime {
            sink.date_column(name);
        }
    }
    let mut features = reader.select_all_seq().map_err(|e| bad(e.to_string()))?;
    let mut n = 0usize;
    while let Some(feature) = features
        .next()
        .map_err(|e| bad(format!("feature {n}: {e}")))?
    {
        let mut props = Props(Map::new());
        feature
            .process_properties(&mut props)
            .map_err(|e| bad(format!("feature {n}: {e}")))?;
        let rings = match feature.geometry() {
            None => Err("no geometry".to_string()),
            Some(g) => {
                let mut out = Vec::new();
                geometry(&g, file_type, &mut out, 0).map(|()| out)
            }
        };
        sink.add(None, rings, &props.0);
        n += 1;
    }
    sink.finish(source_crs)
}

/// The header's CRS: `None` for WGS84 longitude/latitude.
fn crs_of(
    crs: Option<(Option<String>, i32, Option<String>)>,
) -> Result<Option<crate::crs::Crs>, String> {
    let advice = "give the CRS with --src-crs EPSG:n";
    let Some((org, code, wkt)) = crs else {
        return Err(format!("the file names no CRS; {advice}"));
    };
    let epsg = org
        .as_deref()
        .is_none_or(|o| o.eq_ignore_ascii_case("epsg"));
    let found = if epsg && code > 0 {
        crate::crs::Crs::from_epsg(code as u32).map_err(|e| format!("{e}; {advice}"))
    } else if let Some(w) = wkt.filter(|w| !w.trim().is_empty()) {
        crate::crs::Crs::from_prj(&w).map_err(|e| format!("{e}; {advice}"))
    } else {
        Err(format!(
            "the CRS {}:{code} is not an EPSG code; {advice}",
            org.unwrap_or_default()
        ))
    }?;
    Ok(Some(found).filter(|c| *c != crate::crs::Crs::Wgs84))
}

/// A feature's columns as JSON properties for [`Sink::add`].
struct Props(Map<String, Value>);

impl PropertyProcessor for Props {
    fn property(
        &mut self,
        _idx: usize,
        name: &str,
        value: &ColumnValue,
    ) -> Result<bool, GeozeroError> {
        let v = match *value {
            ColumnValue::Byte(x) => Value::from(x),
            ColumnValue::UByte(x) => Value::from(x),
            ColumnValue::Bool(x) => Value::from(x),
            ColumnValue::Short(x) => Value::from(x),
            ColumnValue::UShort(x) => Value::from(x),
            ColumnValue::Int(x) => Value::from(x),
            ColumnValue::UInt(x) => Value::from(x),
            ColumnValue::Long(x) => Value::from(x),
            ColumnValue::ULong(x) => Value::from(x),
            ColumnValue::Float(x) => match serde_json::Number::from_f64(f64::from(x)) {
                Some(n) => Value::Number(n),
                None => return Ok(false),
            },
            ColumnValue::Double(x) => match serde_json::Number::from_f64(x) {
                Some(n) => Value::Number(n),
                None => return Ok(false),
            },
            ColumnValue::String(s) | ColumnValue::Json(s) | ColumnValue::DateTime(s) => {
                Value::from(s)
            }
            ColumnValue::Binary(_) => return Ok(false),
        };
        self.0.insert(name.to_string(), v);
        Ok(false)
    }
}

/// The rings of a geometry with their declared roles (the first ring of each polygon outer).
fn geometry(
    g: &Geometry,
    declared: GeometryType,
    out: &mut Vec<(Ring, bool)>,
    depth: usize,
) -> Result<(), String> {
    if depth > MAX_DEPTH {
        return Err("geometry collections nested too deep".into());
    }
    let kind = if declared == GeometryType::Unknown {
        g.type_()
    } else {
        declared
    };
    match kind {
        GeometryType::Polygon => polygon(g, out),
        GeometryType::MultiPolygon
        | GeometryType::GeometryCollection
        | GeometryType::MultiSurface => {
            let Some(parts) = g.parts() else {
                // A multipolygon of one polygon may be written flat.
                return if kind == GeometryType::MultiPolygon {
                    polygon(g, out)
                } else {
                    Err("an empty geometry".into())
                };
            };
            for p in parts.iter() {
                let inner = if kind == GeometryType::MultiPolygon {
                    GeometryType::Polygon
                } else {
                    GeometryType::Unknown
                };
                geometry(&p, inner, out, depth + 1)?;
            }
            Ok(())
        }
        GeometryType::Point | GeometryType::MultiPoint => {
            Err("a point geometry is not a polygon".into())
        }
        GeometryType::LineString | GeometryType::MultiLineString => {
            Err("a line geometry is not a polygon".into())
        }
        other => Err(format!("a {other:?} geometry is not a polygon")),
    }
}

/// The rings of one polygon: `xy` split at `ends` (one ring without them).
fn polygon(g: &Geometry, out: &mut Vec<(Ring, bool)>) -> Result<(), String> {
    let Some(xy) = g.xy() else {
        return Err("an empty geometry".into());
    };
    let points = xy.len() / 2;
    let ends: Vec<usize> = match g.ends() {
        Some(e) if !e.is_empty() => e.iter().map(|e| e as usize).collect(),
        _ => vec![points],
    };
    let mut start = 0usize;
    for (i, &end) in ends.iter().enumerate() {
        if end < start || end > points {
            return Err(format!(
                "ring {i} ends at point {end}, outside {start}..={points}"
            ));
        }
        let ring: Ring = (start..end)
            .map(|p| (xy.get(2 * p), xy.get(2 * p + 1)))
            .collect();
        out.push((ring, i == 0));
        start = end;
    }
    Ok(())
}

/// Why the file's framing is refused.
enum Framing {
    Io(std::io::Error),
    Bad(String),
}

/// Checks the file's framing before the crate reads it: the magic bytes, a header size within
/// the format's limit, a node size the index can have (the crate asserts it), an index within
/// the file, and each feature's size within what is left of the file.
fn check_framing(path: &Path) -> Result<(), Framing> {
    let mut f = BufReader::new(File::open(path).map_err(Framing::Io)?);
    let len = f.get_ref().metadata().map_err(Framing::Io)?.len();
    let mut magic = [0u8; 8];
    let mut word = [0u8; 4];
    f.read_exact(&mut magic)
        .and_then(|()| f.read_exact(&mut word))
        .map_err(|_| Framing::Bad("the file ends inside its header".into()))?;
    if &magic[..3] != b"fgb" || &magic[4..7] != b"fgb" {
        return Err(Framing::Bad(
            "not a FlatGeobuf file (no magic bytes)".into(),
        ));
    }
    let header_size = u64::from(u32::from_le_bytes(word));
    if !(8..=MAX_HEADER).contains(&header_size) || 12 + header_size > len {
        return Err(Framing::Bad(format!(
            "a header of {header_size} bytes in a file of {len}"
        )));
    }
    let mut header = vec![0u8; header_size as usize + 4];
    header[..4].copy_from_slice(&word);
    f.read_exact(&mut header[4..]).map_err(Framing::Io)?;
    let h = flatgeobuf::size_prefixed_root_as_header(&header)
        .map_err(|e| Framing::Bad(format!("the header cannot be decoded: {e}")))?;
    let count = h.features_count();
    let node = h.index_node_size();
    let mut at = 12 + header_size;
    if node > 0 && count > 0 {
        if node < 2 {
            return Err(Framing::Bad(format!("an index node size of {node}")));
        }
        // Every feature takes at least 4 bytes: more than the file can hold is a lie.
        if count > len / 4 {
            return Err(Framing::Bad(format!(
                "{count} features in a file of {len} bytes"
            )));
        }
        at += PackedRTree::index_size(count as usize, node) as u64;
        if at > len {
            return Err(Framing::Bad(format!(
                "the spatial index of {count} features ends past the end of the file"
            )));
        }
    }
    f.seek(SeekFrom::Start(at)).map_err(Framing::Io)?;
    let mut n = 0u64;
    while at < len {
        if at + 4 > len {
            return Err(Framing::Bad(format!(
                "feature {n}: the file ends inside its size"
            )));
        }
        f.read_exact(&mut word).map_err(Framing::Io)?;
        let size = u64::from(u32::from_le_bytes(word));
        if at + 4 + size > len {
            return Err(Framing::Bad(format!(
                "feature {n}: {size} bytes at byte {at}, past the end of the file ({len} bytes)"
            )));
        }
        f.seek_relative(size as i64).map_err(Framing::Io)?;
        at += 4 + size;
        n += 1;
    }
    Ok(())
}
