//! GeoPackage footprints (OGC 12-128r18): the features of one polygon layer, read row by row
//! from the SQLite file opened read-only.
//!
//! - **Layer**: the one named with `--layer` (an error naming the file's layers when it has no
//!   such features layer), else the only features layer, else the first (by name) whose
//!   geometry type is a polygon, multipolygon or generic geometry; a note names the layer read
//!   and the others.
//! - **Geometry**: the GeoPackage binary header (magic `GP`, flags, envelope) then ISO WKB
//!   (`Polygon`, `MultiPolygon`, `GeometryCollection`, with Z, M or ZM: z and m dropped; the
//!   EWKB high-bit flags too). Empty geometries and other types are skipped report entries.
//! - **Attributes**: every other column, read as `input::features` reads GeoJSON properties
//!   (OSM keys, Overture's names, municipal height/levels columns); the others kept typed
//!   (`INTEGER`, `REAL`, `TEXT`, and `DATE`/`DATETIME` columns as dates).
//! - **Ids**: the layer's integer primary key (the `fid`), `feature/<fid>`.
//! - **CRS**: `--src-crs`, else the layer's `srs_id` looked up in `gpkg_spatial_ref_sys`
//!   (an `EPSG` organisation code); an undefined SRS needs `--src-crs`.
//!
//! Errors name the file (and the layer, row and column where one is known).

use std::io::Read;
use std::path::Path;

use rusqlite::types::ValueRef;
use rusqlite::{Connection, OpenFlags};
use serde_json::{Map, Value};

use super::features::ShpOptions;
use super::features::Sink;
use super::{InputError, ReadResult, Ring, SourceId};
use crate::report::{Outcome, Report};

/// The 16 bytes every SQLite 3 database starts with.
const MAGIC: &[u8; 16] = b"SQLite format 3\0";

/// Nested WKB collections deeper than this are refused (a hostile file could nest without end).
const MAX_DEPTH: usize = 4;

/// Whether the file is an SQLite database (a GeoPackage is one).
pub(crate) fn looks_like_gpkg(path: &Path) -> bool {
    let mut head = [0u8; 16];
    std::fs::File::open(path)
        .and_then(|mut f| f.read_exact(&mut head))
        .is_ok_and(|()| &head == MAGIC)
}

/// Reads the footprints of a GeoPackage's polygon layer. See the module documentation.
pub fn read_gpkg(
    path: &Path,
    opts: &ShpOptions,
    report: &mut Report,
) -> Result<ReadResult, InputError> {
    let bad = |reason: String| InputError::Shapefile {
        path: path.to_path_buf(),
        reason,
    };
    let sql = |e: rusqlite::Error| bad(format!("GeoPackage: {e}"));
    let db = Connection::open_with_flags(
        path,
        OpenFlags::SQLITE_OPEN_READ_ONLY | OpenFlags::SQLITE_OPEN_NO_MUTEX,
    )
    .map_err(sql)?;
    // Views could run without end (a recursive CTE); tables cannot, and triggers do not fire
    // on reads: every table read is checked to be one.
    for t in [
        "gpkg_contents",
        "gpkg_geometry_columns",
        "gpkg_spatial_ref_sys",
    ] {
        if !is_table(&db, t).map_err(sql)? {
            return Err(bad(format!(
                "not a GeoPackage: no table {t} (an SQLite file without the GeoPackage tables)"
            )));
        }
    }
    let layers = layers(&db).map_err(sql)?;
    if let Some(name) = &opts.layer {
        if !layers.iter().any(|l| &l.0 == name) {
            return Err(bad(format!(
                "GeoPackage: no features layer {name:?} (--layer); the layers are {}",
                names(&layers)
            )));
        }
    }
    let Some((table, column, srs_id)) = pick_layer(&layers, opts.layer.as_deref()) else {
        return Err(bad(format!(
            "GeoPackage: no polygon features layer (layers: {})",
            names(&layers)
        )));
    };
    if layers.len() > 1 && opts.layer.is_none() {
        report.add(
            None,
            Outcome::Note,
            format!(
                "{}: GeoPackage layer {table:?} read; the file's layers are {}",
                path.display(),
                names(&layers)
            ),
        );
    }
    let source_crs = match opts.src_crs {
        Some(c) => Some(c),
        None => layer_crs(&db, srs_id).map_err(|reason| InputError::Crs {
            path: path.to_path_buf(),
            reason: format!("GeoPackage layer {table:?}: {reason}"),
        })?,
    };
    if !is_table(&db, &table).map_err(sql)? {
        return Err(bad(format!(
            "GeoPackage layer {table:?} is not a table (a view or missing)"
        )));
    }
    let pk = primary_key(&db, &table).map_err(sql)?;
    let mut stmt = db
        .prepare(&format!("SELECT * FROM {}", quote(&table)))
        .map_err(sql)?;
    let cols: Vec<String> = stmt.column_names().map(|c| c.to_string()).collect();
    let mut sink = Sink::new(path, opts, report);
    let (dates, booleans) = typed_columns(&db, &table).map_err(sql)?;
    for c in &dates {
        sink.date_column(c);
    }
    let mut rows = stmt.query([]).map_err(sql)?;
    let mut row_no = 0usize;
    while let Some(row) = rows
        .next()
        .map_err(|e| bad(format!("GeoPackage layer {table:?}, row {row_no}: {e}")))?
    {
        let mut props = Map::new();
        let mut id = None;
        let mut rings = Err("no geometry".to_string());
        for (i, name) in cols.iter().enumerate() {
            let v = row
                .get_ref(i)
                .map_err(|e| bad(format!("GeoPackage layer {table:?}, row {row_no}: {e}")))?;
            if name.eq_ignore_ascii_case(&column) {
                rings = match v {
                    ValueRef::Blob(b) => geometry(b),
                    ValueRef::Null => Err("no geometry".into()),
                    _ => Err("the geometry column holds no blob".into()),
                };
            } else if pk.as_deref() == Some(name.as_str()) {
                if let ValueRef::Integer(n) = v {
                    id = u64::try_from(n).ok().map(SourceId::Feature);
                }
            } else if let (ValueRef::Integer(n), true) = (v, booleans.contains(name)) {
                props.insert(name.clone(), Value::Bool(n != 0));
            } else if let Some(value) = json(v) {
                props.insert(name.clone(), value);
            }
        }
        sink.add(id, rings, &props);
        row_no += 1;
    }
    sink.finish(source_crs)
}

/// Whether `name` is a table of the database (not a view).
fn is_table(db: &Connection, name: &str) -> rusqlite::Result<bool> {
    db.query_row(
        "SELECT count(*) FROM sqlite_master WHERE type = 'table' AND name = ?1",
        [name],
        |r| r.get::<_, i64>(0),
    )
    .map(|n| n > 0)
}

/// The features layers: table, geometry column, geometry type name, srs_id; by table name.
fn layers(db: &Connection) -> rusqlite::Result<Vec<(String, String, String, i64)>> {
    let mut stmt = db.prepare(
        "SELECT c.table_name, g.column_name, g.geometry_type_name, g.srs_id \
         FROM gpkg_contents c JOIN gpkg_geometry_columns g ON g.table_name = c.table_name \
         WHERE c.data_type = 'features' ORDER BY c.table_name",
    )?;
    let rows = stmt.query_map([], |r| Ok((r.get(0)?, r.get(1)?, r.get(2)?, r.get(3)?)))?;
    rows.collect()
}

fn names(layers: &[(String, String, String, i64)]) -> String {
    if layers.is_empty() {
        return "none".into();
    }
    layers
        .iter()
        .map(|l| format!("{:?} ({})", l.0, l.2))
        .collect::<Vec<_>>()
        .join(", ")
}

/// The layer `named`, else the only layer, else the first whose geometry type can hold
/// polygons.
fn pick_layer(
    layers: &[(String, String, String, i64)],
    named: Option<&str>,
) -> Option<(String, String, i64)> {
    let polygonal = |t: &str| {
        matches!(
            t.to_ascii_uppercase().as_str(),
            "POLYGON"
                | "MULTIPOLYGON"
                | "GEOMETRY"
                | "GEOMETRYCOLLECTION"
                | "MULTISURFACE"
                | "SURFACE"
                | "CURVEPOLYGON"
        )
    };
    let l = if let Some(n) = named {
        layers.iter().find(|l| l.0 == n)
    } else if layers.len() == 1 {
        layers.first()
    } else {
        layers.iter().find(|l| polygonal(&l.2))
    }?;
    Some((l.0.clone(), l.1.clone(), l.3))
}

/// The layer's CRS: `None` for WGS84 longitude/latitude.
fn layer_crs(db: &Connection, srs_id: i64) -> Result<Option<crate::crs::Crs>, String> {
    let found: Option<(String, i64)> = db
        .query_row(
            "SELECT organization, organization_coordsys_id FROM gpkg_spatial_ref_sys WHERE srs_id = ?1",
            [srs_id],
            |r| Ok((r.get(0)?, r.get(1)?)),
        )
        .ok();
    let advice = "give the CRS with --src-crs EPSG:n";
    match found {
        Some((org, code)) if org.eq_ignore_ascii_case("epsg") => {
            let code = u32::try_from(code).map_err(|_| format!("EPSG:{code}; {advice}"))?;
            crate::crs::Crs::from_epsg(code)
                .map(|c| Some(c).filter(|c| *c != crate::crs::Crs::Wgs84))
                .map_err(|e| format!("{e}; {advice}"))
        }
        Some((org, code)) => Err(format!(
            "the SRS {srs_id} is {org}:{code}, not an EPSG code; {advice}"
        )),
        None => Err(format!("the SRS {srs_id} is undefined; {advice}")),
    }
}

/// The table's integer primary key column, if it has one.
fn primary_key(db: &Connection, table: &str) -> rusqlite::Result<Option<String>> {
    let mut stmt = db.prepare(&format!("PRAGMA table_info({})", quote(table)))?;
    let cols = stmt.query_map([], |r| {
        Ok((
            r.get::<_, String>(1)?,
            r.get::<_, String>(2)?,
            r.get::<_, i64>(5)?,
        ))
    })?;
    for c in cols {
        let (name, ty, pk) = c?;
        if pk == 1 && ty.eq_ignore_ascii_case("integer") {
            return Ok(Some(name));
        }
    }
    Ok(None)
}

/// The table's columns declared `DATE` or `DATETIME`, and those declared `BOOLEAN`
/// (GeoPackage's date and boolean types, stored as text and as 0/1).
fn typed_columns(db: &Connection, table: &str) -> rusqlite::Result<(Vec<String>, Vec<String>)> {
    let mut stmt = db.prepare(&format!("PRAGMA table_info({})", quote(table)))?;
    let cols = stmt.query_map([], |r| Ok((r.get::<_, String>(1)?, r.get::<_, String>(2)?)))?;
    let (mut dates, mut booleans) = (Vec::new(), Vec::new());
    for c in cols {
        let (name, ty) = c?;
        if ty.eq_ignore_ascii_case("date") || ty.eq_ignore_ascii_case("datetime") {
            dates.push(name);
        } else if ty.eq_ignore_ascii_case("boolean") {
            booleans.push(name);
        }
    }
    Ok((dates, booleans))
}

/// An SQL identifier, quoted.
fn quote(name: &str) -> String {
    format!("\"{}\"", name.replace('"', "\"\""))
}

/// A column's value as a property: text, integers and reals; blobs and nulls are not tags.
fn json(v: ValueRef) -> Option<Value> {
    match v {
        ValueRef::Text(t) => Some(Value::String(String::from_utf8_lossy(t).into_owned())),
        ValueRef::Integer(n) => Some(Value::from(n)),
        ValueRef::Real(x) => serde_json::Number::from_f64(x).map(Value::Number),
        ValueRef::Null | ValueRef::Blob(_) => None,
    }
}

/// The rings of a GeoPackage geometry blob with their declared roles.
pub(crate) fn geometry(blob: &[u8]) -> Result<Vec<(Ring, bool)>, String> {
    if blob.len() < 8 || &blob[..2] != b"GP" {
        return Err("not a GeoPackage geometry (no GP header)".into());
    }
    let flags = blob[3];
    if flags & 0x10 != 0 {
        return Err("an empty geometry".into());
    }
    let envelope = match (flags >> 1) & 0x07 {
        0 => 0,
        1 => 32,
        2 | 3 => 48,
        4 => 64,
        e => return Err(format!("a GeoPackage header with envelope code {e}")),
    };
    let wkb = blob
        .get(8 + envelope..)
        .ok_or("a GeoPackage geometry shorter than its header")?;
    let mut r = Wkb { b: wkb, at: 0 };
    let mut out = Vec::new();
    r.geometry(&mut out, 0)?;
    Ok(out)
}

/// A cursor over ISO (or EWKB-flagged) well-known binary.
struct Wkb<'a> {
    b: &'a [u8],
    at: usize,
}

impl Wkb<'_> {
    fn bytes<const N: usize>(&mut self) -> Result<[u8; N], String> {
        let s = self
            .b
            .get(self.at..self.at + N)
            .ok_or("the WKB ends early")?;
        self.at += N;
        let mut a = [0u8; N];
        a.copy_from_slice(s);
        Ok(a)
    }

    fn u32(&mut self, little: bool) -> Result<u32, String> {
        let a = self.bytes::<4>()?;
        Ok(if little {
            u32::from_le_bytes(a)
        } else {
            u32::from_be_bytes(a)
        })
    }

    fn f64(&mut self, little: bool) -> Result<f64, String> {
        let a = self.bytes::<8>()?;
        Ok(if little {
            f64::from_le_bytes(a)
        } else {
            f64::from_be_bytes(a)
        })
    }

    /// A count that the rest of the blob can hold (`each` bytes at least per item).
    fn count(&mut self, little: bool, each: usize) -> Result<usize, String> {
        let n = self.u32(little)? as usize;
        if n.saturating_mul(each) > self.b.len() - self.at {
            return Err(format!("a WKB count of {n} past the end of the blob"));
        }
        Ok(n)
    }

    fn geometry(&mut self, out: &mut Vec<(Ring, bool)>, depth: usize) -> Result<(), String> {
        if depth > MAX_DEPTH {
            return Err("WKB collections nested too deep".into());
        }
        let little = match self.bytes::<1>()?[0] {
            0 => false,
            1 => true,
            b => return Err(format!("a WKB byte order of {b}")),
        };
        let raw = self.u32(little)?;
        // EWKB flags (Z 0x80000000, M 0x40000000, SRID 0x20000000), else ISO thousands.
        let (z_e, m_e, srid) = (
            raw & 0x8000_0000 != 0,
            raw & 0x4000_0000 != 0,
            raw & 0x2000_0000 != 0,
        );
        let base = raw & 0x0FFF_FFFF;
        if srid {
            self.u32(little)?;
        }
        let (kind, dims) = match base / 1000 {
            0 => (base, 2 + z_e as usize + m_e as usize),
            1 | 2 => (base % 1000, 3),
            3 => (base % 1000, 4),
            _ => return Err(format!("WKB geometry type {raw}")),
        };
        match kind {
            3 => self.polygon(little, dims, out),
            6 | 7 => {
                let n = self.count(little, 5)?;
                for _ in 0..n {
                    self.geometry(out, depth + 1)?;
                }
                Ok(())
            }
            1 | 4 => Err("a point geometry is not a polygon".into()),
            2 | 5 => Err("a line geometry is not a polygon".into()),
            k => Err(format!("WKB geometry type {k} is not a polygon")),
        }
    }

    fn polygon(
        &mut self,
        little: bool,
        dims: usize,
        out: &mut Vec<(Ring, bool)>,
    ) -> Result<(), String> {
        let rings = self.count(little, 4)?;
        for i in 0..rings {
            let n = self.count(little, 8 * dims)?;
            let mut ring = Vec::with_capacity(n);
            for _ in 0..n {
                let x = self.f64(little)?;
                let y = self.f64(little)?;
                for _ in 2..dims {
                    self.f64(little)?;
                }
                ring.push((x, y));
            }
            out.push((ring, i == 0));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn wkb_square(x: f64, y: f64, z: bool) -> Vec<u8> {
        let mut b = vec![1u8];
        b.extend((if z { 1003u32 } else { 3u32 }).to_le_bytes());
        b.extend(1u32.to_le_bytes());
        b.extend(5u32.to_le_bytes());
        for (px, py) in [
            (x, y),
            (x + 10.0, y),
            (x + 10.0, y + 8.0),
            (x, y + 8.0),
            (x, y),
        ] {
            b.extend(px.to_le_bytes());
            b.extend(py.to_le_bytes());
            if z {
                b.extend(0.0f64.to_le_bytes());
            }
        }
        b
    }

    fn gp(wkb: &[u8]) -> Vec<u8> {
        // Little-endian header, envelope code 1 (minx, maxx, miny, maxy).
        let mut b = vec![b'G', b'P', 0, 0b0000_0011];
        b.extend(27700i32.to_le_bytes());
        for v in [0.0f64, 1.0, 0.0, 1.0] {
            b.extend(v.to_le_bytes());
        }
        b.extend(wkb);
        b
    }

    #[test]
    fn blobs_give_rings_and_hostile_blobs_errors() {
        let r = geometry(&gp(&wkb_square(5.0, 6.0, false))).unwrap();
        assert_eq!(r.len(), 1);
        assert_eq!(r[0].0[2], (15.0, 14.0));
        let r = geometry(&gp(&wkb_square(5.0, 6.0, true))).unwrap();
        assert_eq!(r[0].0[1], (15.0, 6.0));
        let mut multi = vec![1u8];
        multi.extend(6u32.to_le_bytes());
        multi.extend(2u32.to_le_bytes());
        multi.extend(wkb_square(0.0, 0.0, false));
        multi.extend(wkb_square(20.0, 0.0, false));
        assert_eq!(geometry(&gp(&multi)).unwrap().len(), 2);
        // Truncated, a count past the end, nesting without end, not GP.
        let whole = gp(&wkb_square(5.0, 6.0, false));
        assert!(geometry(&whole[..whole.len() - 3]).is_err());
        let mut huge = gp(&[1u8]);
        huge.extend(3u32.to_le_bytes());
        huge.extend(u32::MAX.to_le_bytes());
        assert!(geometry(&huge).unwrap_err().contains("past the end"));
        let mut deep = Vec::new();
        for _ in 0..10 {
            deep.push(1u8);
            deep.extend(7u32.to_le_bytes());
            deep.extend(1u32.to_le_bytes());
        }
        assert!(geometry(&gp(&deep)).unwrap_err().contains("too deep"));
        assert!(geometry(b"XXXXXXXXXXXX").is_err());
    }

    #[test]
    fn a_geopackage_layer_is_read_with_its_fids_columns_and_crs() {
        let dir = std::env::temp_dir().join(format!("citygen-gpkg-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let p = dir.join("b.gpkg");
        std::fs::remove_file(&p).ok();
        {
            let db = Connection::open(&p).unwrap();
            db.execute_batch(
                "CREATE TABLE gpkg_spatial_ref_sys (srs_name TEXT, srs_id INTEGER PRIMARY KEY, organization TEXT, organization_coordsys_id INTEGER, definition TEXT, description TEXT);
                 INSERT INTO gpkg_spatial_ref_sys VALUES ('BNG', 27700, 'EPSG', 27700, '', '');
                 CREATE TABLE gpkg_contents (table_name TEXT PRIMARY KEY, data_type TEXT, identifier TEXT, description TEXT, last_change TEXT, min_x REAL, min_y REAL, max_x REAL, max_y REAL, srs_id INTEGER);
                 INSERT INTO gpkg_contents (table_name, data_type, srs_id) VALUES ('batiments', 'features', 27700);
                 CREATE TABLE gpkg_geometry_columns (table_name TEXT, column_name TEXT, geometry_type_name TEXT, srs_id INTEGER, z INTEGER, m INTEGER);
                 INSERT INTO gpkg_geometry_columns VALUES ('batiments', 'geom', 'MULTIPOLYGON', 27700, 0, 0);
                 CREATE TABLE batiments (fid INTEGER PRIMARY KEY AUTOINCREMENT, geom BLOB, HAUTEUR REAL, nom TEXT);",
            )
            .unwrap();
            for (fid, h) in [(7i64, 9.5f64), (9, 4.25)] {
                db.execute(
                    "INSERT INTO batiments (fid, geom, HAUTEUR, nom) VALUES (?1, ?2, ?3, 'x')",
                    rusqlite::params![
                        fid,
                        gp(&wkb_square(455_000.0 + fid as f64 * 20.0, 334_000.0, false)),
                        h
                    ],
                )
                .unwrap();
            }
            db.execute(
                "INSERT INTO batiments (fid, geom, HAUTEUR) VALUES (11, NULL, 3)",
                [],
            )
            .unwrap();
        }
        assert!(looks_like_gpkg(&p));
        let mut report = Report::default();
        let r = read_gpkg(&p, &ShpOptions::default(), &mut report).unwrap();
        assert_eq!(r.source_crs, Some(crate::crs::Crs::BritishNationalGrid));
        let got: Vec<(String, Option<f64>)> = r
            .footprints
            .iter()
            .map(|f| (f.id.to_string(), f.tags.height))
            .collect();
        assert_eq!(
            got,
            [
                ("feature/7".to_string(), Some(9.5)),
                ("feature/9".to_string(), Some(4.25))
            ]
        );
        assert_eq!((report.read, report.skipped), (3, 1));
        // Not a GeoPackage: an SQLite file without its tables.
        let q = dir.join("plain.sqlite");
        std::fs::remove_file(&q).ok();
        Connection::open(&q)
            .unwrap()
            .execute_batch("CREATE TABLE t (a INTEGER);")
            .unwrap();
        let e = read_gpkg(&q, &ShpOptions::default(), &mut Report::default()).unwrap_err();
        assert!(
            e.to_string().contains("plain.sqlite") && e.to_string().contains("gpkg_contents"),
            "{e}"
        );
        std::fs::remove_dir_all(&dir).ok();
    }
}
