use super::*;
use crate::crs::Crs;
use crate::model::SourceId;
use shapefile::dbase::{FieldName, Record, TableWriterBuilder};
use shapefile::{Point, Polygon, PolygonRing};

fn clifton() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("data/clifton/clifton_test.shp")
}

/// Options that never call the `.prj` parser (the CRS module is tested on its own).
fn bng() -> ShpOptions {
    ShpOptions {
        src_crs: Some(Crs::BritishNationalGrid),
        ..ShpOptions::default()
    }
}

fn area(r: &[(f64, f64)]) -> f64 {
    super::super::rings::signed_area(r)
}

#[test]
fn clifton_every_record_is_accounted_for() {
    let mut report = Report::default();
    let r = read_shp(&clifton(), &bng(), &mut report).unwrap();
    assert_eq!(r.source_crs, Some(Crs::BritishNationalGrid));
    assert_eq!(report.read, 2989);
    assert_eq!(r.footprints.len() + report.skipped, 2989);
    let skipped = report
        .entries
        .iter()
        .filter(|e| e.outcome == Outcome::Skipped)
        .count();
    assert_eq!(skipped, report.skipped);
    // Record order; the ids are the OBJECTID column's (whole numbers, unique), the ID column
    // (hexadecimal text) kept as an attribute.
    for w in r.footprints.windows(2) {
        assert!(w[0].id < w[1].id);
    }
    assert_eq!(r.footprints[0].id, SourceId::Feature(3_932_040));
    let first = &r.attributes[&SourceId::Feature(3_932_040)];
    assert!(first.iter().any(|(k, _)| &**k == "ID"), "{first:?}");
    assert!(!first.iter().any(|(k, _)| &**k == "OBJECTID"), "{first:?}");
    // The first row: MEAN_mean 5.037, MAX_max 7.
    assert_eq!(r.footprints[0].tags.height, Some(7.0));
    assert!(report
        .entries
        .iter()
        .any(|e| e.id.is_empty() && e.reason.contains("height taken from field MAX_max")));

    // Heights: every record with MAX_max > 0 has its height, the others a note.
    let mut table = dbase::Reader::from_path(clifton().with_extension("dbf")).unwrap();
    let max: std::collections::HashMap<u64, f64> = table
        .iter_records()
        .map(|r| {
            let r = r.unwrap();
            match (r.get("OBJECTID"), r.get("MAX_max")) {
                (Some(FieldValue::Numeric(Some(id))), Some(FieldValue::Numeric(Some(v)))) => {
                    (*id as u64, *v)
                }
                other => panic!("{other:?}"),
            }
        })
        .collect();
    for f in &r.footprints {
        let SourceId::Feature(i) = f.id else { panic!() };
        let m = max[&i];
        if m > 0.0 {
            assert_eq!(f.tags.height, Some(m), "{}", f.id);
        } else {
            assert_eq!(f.tags.height, None);
            assert!(report
                .entries
                .iter()
                .any(|e| e.id == f.id.to_string() && e.reason.contains("height")));
        }
    }

    // Geometry: oriented, usable, in British National Grid range (Clifton, Nottingham).
    let mut holes = 0;
    for f in &r.footprints {
        for p in &f.polygons {
            assert!(area(&p.outer) > 0.0);
            assert!(super::super::rings::ring_problem(&p.outer).is_none());
            for h in &p.holes {
                assert!(area(h) < 0.0);
                holes += 1;
            }
            for &(x, y) in &p.outer {
                assert!((450_000.0..460_000.0).contains(&x) && (330_000.0..340_000.0).contains(&y));
            }
        }
    }
    assert_eq!(holes, 12, "Clifton has 12 courtyard rings");
    for e in report.entries.iter().filter(|e| e.id.is_empty()) {
        eprintln!("  {}", e.reason);
    }
    eprintln!(
        "clifton: footprints {}, skipped {}, repaired {}, holes {holes}, multi-polygon records {}, height notes {}",
        r.footprints.len(),
        report.skipped,
        report.repaired,
        r.footprints.iter().filter(|f| f.polygons.len() > 1).count(),
        report.entries.iter().filter(|e| e.outcome == Outcome::Note && !e.id.is_empty()).count()
    );
}

#[test]
fn height_and_levels_fields_by_name() {
    let opts = ShpOptions {
        height_field: Some("mean_MEAN".into()),
        levels_field: Some("OBJECTID".into()),
        ..bng()
    };
    let mut report = Report::default();
    let r = read_shp(&clifton(), &opts, &mut report).unwrap();
    let h = r.footprints[0].tags.height.unwrap();
    assert!((h - 5.03703703704).abs() < 1e-9, "{h}");
    // OBJECTID 3932040 is no level count: ignored with a reason.
    assert_eq!(r.footprints[0].tags.levels, None);
    assert!(report
        .entries
        .iter()
        .any(|e| e.id == "feature/3932040" && e.reason.contains("building:levels")));

    let opts = ShpOptions {
        height_field: Some("hauteur".into()),
        ..bng()
    };
    let err = read_shp(&clifton(), &opts, &mut Report::default()).unwrap_err();
    let msg = err.to_string();
    assert!(
        msg.contains("clifton_test.dbf") && msg.contains("hauteur") && msg.contains("MAX_max"),
        "{msg}"
    );
}

// ---- a tiny shapefile written here ---------------------------------------------------------

fn pts(c: &[(f64, f64)]) -> Vec<Point> {
    c.iter().map(|&(x, y)| Point::new(x, y)).collect()
}

fn sq(x: f64, y: f64, s: f64) -> Vec<(f64, f64)> {
    vec![(x, y), (x + s, y), (x + s, y + s), (x, y + s)]
}

/// Writes `t.shp/.shx/.dbf` with a HEIGHT (numeric) and LEVELS (character) field.
fn write_tiny(dir: &Path, shapes: &[Polygon], rows: &[(f64, &str)]) -> PathBuf {
    let path = dir.join("t.shp");
    let table = TableWriterBuilder::new()
        .add_numeric_field(FieldName::try_from("HEIGHT").unwrap(), 10, 2)
        .add_character_field(FieldName::try_from("Levels").unwrap(), 10);
    let mut w = shapefile::Writer::from_path(&path, table).unwrap();
    for (s, (h, l)) in shapes.iter().zip(rows) {
        let mut rec = Record::default();
        rec.insert("HEIGHT".into(), FieldValue::Numeric(Some(*h)));
        rec.insert("Levels".into(), FieldValue::Character(Some(l.to_string())));
        w.write_shape_and_record(s, &rec).unwrap();
    }
    drop(w);
    path
}

fn tiny_shapes() -> Vec<Polygon> {
    vec![
        // 0: a courtyard building, ESRI orientation (the writer enforces it).
        Polygon::with_rings(vec![
            PolygonRing::Outer(pts(&sq(0.0, 0.0, 10.0))),
            PolygonRing::Inner(pts(&sq(3.0, 3.0, 4.0))),
        ]),
        // 1: two outers, the hole listed first and belonging to the second outer.
        Polygon::with_rings(vec![
            PolygonRing::Inner(pts(&sq(22.0, 2.0, 2.0))),
            PolygonRing::Outer(pts(&sq(0.0, 20.0, 5.0))),
            PolygonRing::Outer(pts(&sq(20.0, 0.0, 6.0))),
        ]),
        // 2: roles swapped (big ring written as a hole): nesting wins.
        Polygon::with_rings(vec![
            PolygonRing::Inner(pts(&sq(40.0, 0.0, 10.0))),
            PolygonRing::Outer(pts(&sq(42.0, 2.0, 2.0))),
        ]),
        // 3: only a degenerate ring.
        Polygon::new(PolygonRing::Outer(pts(&[
            (0.0, 0.0),
            (1.0, 1.0),
            (2.0, 2.0),
        ]))),
        // 4: a good ring and a degenerate one: repaired.
        Polygon::with_rings(vec![
            PolygonRing::Outer(pts(&sq(60.0, 0.0, 5.0))),
            PolygonRing::Outer(pts(&[(70.0, 0.0), (70.0, 0.0), (70.0, 0.0)])),
        ]),
        // 5: will be turned into a null shape.
        Polygon::new(PolygonRing::Outer(pts(&sq(80.0, 0.0, 5.0)))),
    ]
}

const ROWS: [(f64, &str); 6] = [
    (12.5, "4"),
    (0.0, "2;3"),
    (7.0, "many"),
    (3.0, "1"),
    (9.0, "3"),
    (5.0, "1"),
];

#[test]
fn tiny_shapefile_holes_multi_outers_and_repairs() {
    let dir = tempfile::tempdir().unwrap();
    let path = write_tiny(dir.path(), &tiny_shapes(), &ROWS);
    // Turn record 5 into a null shape: the .shx tells where it starts; the shape type follows
    // the 8-byte record header.
    let shx = std::fs::read(path.with_extension("shx")).unwrap();
    let at = 100 + 5 * 8;
    let off = 2 * u32::from_be_bytes(shx[at..at + 4].try_into().unwrap()) as usize;
    let mut shp = std::fs::read(&path).unwrap();
    shp[off + 8..off + 12].copy_from_slice(&0i32.to_le_bytes());
    std::fs::write(&path, &shp).unwrap();

    let mut report = Report::default();
    let opts = ShpOptions {
        src_crs: Some(Crs::Lambert93),
        ..ShpOptions::default()
    };
    let r = read_shp(&path, &opts, &mut report).unwrap();
    let ids: Vec<SourceId> = r.footprints.iter().map(|f| f.id).collect();
    assert_eq!(
        ids,
        [0u64, 1, 2, 4].map(SourceId::Shape).to_vec(),
        "{:?}",
        report.entries
    );
    assert_eq!((report.read, report.skipped, report.repaired), (6, 2, 1));

    let f0 = &r.footprints[0];
    assert_eq!(f0.polygons.len(), 1);
    assert_eq!(f0.polygons[0].holes.len(), 1);
    assert!(area(&f0.polygons[0].outer) > 0.0 && area(&f0.polygons[0].holes[0]) < 0.0);
    assert_eq!((f0.tags.height, f0.tags.levels), (Some(12.5), Some(4.0)));

    let f1 = &r.footprints[1];
    assert_eq!(f1.polygons.len(), 2);
    let with_hole: Vec<usize> = f1.polygons.iter().map(|p| p.holes.len()).collect();
    assert_eq!(with_hole, vec![0, 1]);
    let min_x = f1.polygons[1]
        .outer
        .iter()
        .map(|p| p.0)
        .fold(f64::INFINITY, f64::min);
    assert_eq!(min_x, 20.0, "the hole went to the outer around it");
    assert_eq!((f1.tags.height, f1.tags.levels), (None, Some(2.0)));

    let f2 = &r.footprints[2];
    assert_eq!(f2.polygons.len(), 1);
    assert_eq!(f2.polygons[0].holes.len(), 1);
    assert!((area(&f2.polygons[0].outer) - 100.0).abs() < 1e-9);

    let f4 = &r.footprints[3];
    assert_eq!(f4.polygons.len(), 1);

    let reason = |id: &str, o: Outcome| {
        report
            .entries
            .iter()
            .filter(|e| e.id == id && e.outcome == o)
            .map(|e| e.reason.clone())
            .collect::<Vec<_>>()
            .join(" | ")
    };
    // HEIGHT has two decimals: read as the real 0.0.
    assert!(reason("shp/1", Outcome::Note).contains("height=0.0 ignored"));
    assert!(reason("shp/2", Outcome::Note).contains("building:levels=many ignored"));
    assert!(reason("shp/3", Outcome::Skipped).contains("zero area"));
    assert!(reason("shp/4", Outcome::Repaired).contains("ring 1 dropped"));
    assert!(reason("shp/5", Outcome::Skipped).contains("null shape"));
    assert!(reason("", Outcome::Note).contains("2 ring(s) had an orientation"));
    assert!(reason("", Outcome::Note).contains("height taken from field HEIGHT"));
    assert!(reason("", Outcome::Note).contains("building:levels taken from field Levels"));
}

#[test]
fn no_prj_lonlat_is_wgs84_and_projected_is_an_error() {
    let dir = tempfile::tempdir().unwrap();
    let path = write_tiny(dir.path(), &tiny_shapes()[..1], &ROWS[..1]);
    let mut report = Report::default();
    let r = read_shp(&path, &ShpOptions::default(), &mut report).unwrap();
    assert_eq!(r.source_crs, None);
    assert!(report
        .entries
        .iter()
        .any(|e| e.reason.contains("read as WGS84")));

    let far = Polygon::new(PolygonRing::Outer(pts(&sq(500_000.0, 6_000_000.0, 10.0))));
    let dir2 = tempfile::tempdir().unwrap();
    let path = write_tiny(dir2.path(), &[far], &ROWS[..1]);
    let err = read_shp(&path, &ShpOptions::default(), &mut Report::default()).unwrap_err();
    let msg = err.to_string();
    assert!(msg.contains("t.prj") && msg.contains("--src-crs"), "{msg}");
}

#[test]
fn missing_and_broken_companions_are_errors() {
    let dir = tempfile::tempdir().unwrap();
    let path = write_tiny(dir.path(), &tiny_shapes(), &ROWS);
    let read = |p: &Path| {
        read_shp(p, &bng(), &mut Report::default())
            .unwrap_err()
            .to_string()
    };

    // Missing .shp
    let msg = read(&dir.path().join("none.shp"));
    assert!(msg.contains("none.shp") && msg.contains("missing"), "{msg}");

    // Broken .dbf
    let dbf = path.with_extension("dbf");
    let good_dbf = std::fs::read(&dbf).unwrap();
    std::fs::write(&dbf, b"this is not a table").unwrap();
    let msg = read(&path);
    assert!(msg.contains("t.dbf"), "{msg}");
    // A .dbf with fewer rows than shapes.
    let mut short = good_dbf.clone();
    short[4..8].copy_from_slice(&3u32.to_le_bytes());
    std::fs::write(&dbf, &short).unwrap();
    let msg = read(&path);
    assert!(msg.contains("t.dbf") && msg.contains("3 rows"), "{msg}");
    // Missing .dbf
    std::fs::remove_file(&dbf).unwrap();
    let msg = read(&path);
    assert!(msg.contains("t.dbf") && msg.contains("missing"), "{msg}");
    std::fs::write(&dbf, &good_dbf).unwrap();

    // Truncated .shp: the record that runs off the end is named.
    let shp = std::fs::read(&path).unwrap();
    std::fs::write(&path, &shp[..shp.len() - 20]).unwrap();
    let msg = read(&path);
    assert!(msg.contains("t.shp") && msg.contains("record 5"), "{msg}");
    // Text instead of a .shp.
    std::fs::write(
        &path,
        "hello, this is no shapefile at all, but long enough for a header. ".repeat(3),
    )
    .unwrap();
    let msg = read(&path);
    assert!(
        msg.contains("t.shp") && msg.contains("not a shapefile"),
        "{msg}"
    );
    std::fs::write(&path, &shp).unwrap();

    // Missing .shx
    std::fs::remove_file(path.with_extension("shx")).unwrap();
    let msg = read(&path);
    assert!(msg.contains("t.shx") && msg.contains("missing"), "{msg}");
}

proptest::proptest! {
    #![proptest_config(proptest::prelude::ProptestConfig::with_cases(32))]
    /// Corrupting any bytes of the .shp or .dbf gives a result or an error, never a panic.
    #[test]
    fn corrupted_files_never_panic(
        edits in proptest::collection::vec((0usize..2, 0usize..2000, proptest::num::u8::ANY), 1..6)
    ) {
        let dir = tempfile::tempdir().unwrap();
        let path = write_tiny(dir.path(), &tiny_shapes(), &ROWS);
        for (file, at, byte) in edits {
            let p = if file == 0 { path.clone() } else { path.with_extension("dbf") };
            let mut d = std::fs::read(&p).unwrap();
            let n = d.len();
            d[at % n] = byte;
            std::fs::write(&p, &d).unwrap();
        }
        let opts = ShpOptions { src_crs: Some(Crs::Lambert93), ..ShpOptions::default() };
        if let Err(e) = read_shp(&path, &opts, &mut Report::default()) {
            let msg = e.to_string();
            proptest::prop_assert!(msg.contains("t.shp") || msg.contains("t.dbf") || msg.contains("t.shx"), "{}", msg);
        }
    }
}
