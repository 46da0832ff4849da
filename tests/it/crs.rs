//! Any EPSG CRS (issue 47, `crs::generic`): footprints in a State Plane CRS in US survey feet
//! (EPSG:2263, how New York publishes its footprints), in RD New (EPSG:28992, oblique
//! stereographic) and in LV95 (EPSG:2056, oblique Mercator) are read from GeoJSON's `crs`
//! member, written in the input's CRS (the foot CRS's metre edition, EPSG:32118), and land
//! where PROJ puts them. The reference figures are PROJ 9.5.1's (pyproj 3.7.2, docs/crs.md).

use super::common::{citygen, KB};
use citygen::crs::Crs;

/// One square footprint of side `2 half` around (`cx`, `cy`) in EPSG:`code`, `height` metres.
fn square(code: u32, cx: f64, cy: f64, half: f64, height: f64) -> String {
    let (x0, y0, x1, y1) = (cx - half, cy - half, cx + half, cy + half);
    format!(
        r#"{{"type": "FeatureCollection", "crs": {{"type": "name", "properties": {{"name": "urn:ogc:def:crs:EPSG::{code}"}}}},
"features": [{{"type": "Feature", "id": 1, "properties": {{"height": {height}, "building": "yes"}}, "geometry": {{"type": "Polygon", "coordinates": [[[{x0}, {y0}], [{x1}, {y0}], [{x1}, {y1}], [{x0}, {y1}], [{x0}, {y0}]]]}}}}]}}
"#
    )
}

/// Runs citygen at LOD1 on `geojson` with `extra` flags, writing CityJSON (and whatever
/// `extra` asks); the CityJSON, or the failed run's stderr.
fn run(dir: &std::path::Path, geojson: &str, extra: &[&str]) -> Result<serde_json::Value, String> {
    let gj = dir.join("in.geojson");
    std::fs::write(&gj, geojson).unwrap();
    let cj = dir.join("out.city.json");
    let mut args = vec![
        "--footprints",
        gj.to_str().unwrap(),
        "--kb",
        KB,
        "--lod",
        "1",
        "--cityjson",
        cj.to_str().unwrap(),
        "--quiet",
    ];
    args.extend_from_slice(extra);
    let out = citygen(&args);
    if !out.status.success() {
        return Err(String::from_utf8_lossy(&out.stderr).into_owned());
    }
    Ok(serde_json::from_str(&std::fs::read_to_string(&cj).unwrap()).unwrap())
}

/// The EPSG code of the CityJSON's referenceSystem, the centre of its vertices' bounds (x, y),
/// their height span and their width (x span), in real coordinates.
fn placed(cj: &serde_json::Value) -> (u32, f64, f64, f64, f64) {
    let rs = cj["metadata"]["referenceSystem"].as_str().unwrap();
    let code = rs.rsplit('/').next().unwrap().parse().unwrap();
    let t = &cj["transform"];
    let f = |v: &serde_json::Value, k: usize| v.as_array().unwrap()[k].as_f64().unwrap();
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for v in cj["vertices"].as_array().unwrap() {
        for k in 0..3 {
            let r = f(v, k) * f(&t["scale"], k) + f(&t["translate"], k);
            lo[k] = lo[k].min(r);
            hi[k] = hi[k].max(r);
        }
    }
    let centre = (0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1]));
    (code, centre.0, centre.1, hi[2] - lo[2], hi[0] - lo[0])
}

/// Metres between two lon/lat points a few metres apart.
fn metres_apart(a: (f64, f64), b: (f64, f64)) -> f64 {
    let m = 111_320.0;
    ((a.0 - b.0) * m * a.1.to_radians().cos()).hypot((a.1 - b.1) * m)
}

#[test]
fn a_state_plane_file_in_feet_lands_where_proj_puts_it() {
    let dir = tempfile::tempdir().unwrap();
    // The Empire State Building's point, (-73.98566, 40.74844), in EPSG:2263 by PROJ: 988223.3180,
    // 211953.8537 ftUS; in EPSG:32118 (the same zone in metres): 301211.0697, 64603.6638.
    let text = square(2263, 988223.318, 211953.8537, 50.0, 30.0);
    let cj = run(dir.path(), &text, &[]).unwrap();
    let (code, x, y, h, w) = placed(&cj);
    assert_eq!(code, 32118, "the input's CRS, in metres");
    assert!((x - 301211.0697).hypot(y - 64603.6638) < 0.03, "{x}, {y}");
    let ll = Crs::from_epsg_str("EPSG:32118").unwrap().to_lonlat(x, y);
    let d = metres_apart(ll, (-73.98566, 40.74844));
    assert!(d < 0.03, "{ll:?}: {d} m from PROJ's point");
    assert!((h - 30.0).abs() < 0.05, "height {h}");
    // 100 ftUS is 30.48 m: the footprint's side in the output (the grid's scale is 1 - 2e-5).
    assert!((w - 30.48).abs() < 0.01, "width {w}");
    // Naming the metre edition gives the same file; the foot CRS itself is refused.
    let named = run(dir.path(), &text, &["--crs", "EPSG:32118"]).unwrap();
    assert_eq!(named, cj);
    let feet = run(dir.path(), &text, &["--crs", "EPSG:2263"]).unwrap_err();
    assert!(
        feet.contains("US survey foot") && feet.contains("EPSG:32118"),
        "{feet}"
    );
}

#[test]
fn rd_new_and_lv95_files_stay_in_their_crs() {
    // (code, centre in the CRS by PROJ, lon/lat): Amsterdam's Dam and Bern's Bundeshaus.
    let cases = [
        (28992, (121358.613, 487361.8119), (4.8932, 52.3731)),
        (2056, (2600439.0938, 1199501.659), (7.4444, 46.9466)),
    ];
    for (epsg, (cx, cy), lonlat) in cases {
        let dir = tempfile::tempdir().unwrap();
        let cj = run(dir.path(), &square(epsg, cx, cy, 6.0, 12.5), &[]).unwrap();
        let (code, x, y, h, w) = placed(&cj);
        assert_eq!(code, epsg);
        assert!((w - 12.0).abs() < 2e-3, "EPSG:{epsg}: width {w}");
        assert!((x - cx).hypot(y - cy) < 2e-3, "EPSG:{epsg}: {x}, {y}");
        let ll = Crs::from_epsg_str(&format!("EPSG:{epsg}"))
            .unwrap()
            .to_lonlat(x, y);
        let d = metres_apart(ll, lonlat);
        assert!(d < 0.03, "EPSG:{epsg}: {ll:?} is {d} m from PROJ's point");
        assert!((h - 12.5).abs() < 0.05, "EPSG:{epsg}: height {h}");
    }
}

/// A shapefile in geographic degrees on NAD83 and on ETRS89, with ArcGIS's `.prj` (no code):
/// read (EPSG:4269, EPSG:4258), written in a projected CRS, where the point is.
#[test]
fn a_geographic_prj_on_nad83_or_etrs89_is_read() {
    use shapefile::dbase::{FieldName, FieldValue, Record, TableWriterBuilder};
    use shapefile::{Point, Polygon, PolygonRing};
    let cases = [
        (
            "GCS_North_American_1983",
            "D_North_American_1983",
            (-73.98566, 40.74844),
        ),
        ("GCS_ETRS_1989", "D_ETRS_1989", (11.5755, 48.1374)),
    ];
    for (g, d, (lon, lat)) in cases {
        let dir = tempfile::tempdir().unwrap();
        let shp = dir.path().join("geo.shp");
        let table = TableWriterBuilder::new().add_numeric_field(
            FieldName::try_from("HEIGHT").unwrap(),
            8,
            2,
        );
        let mut w = shapefile::Writer::from_path(&shp, table).unwrap();
        let (dx, dy) = (0.0001, 0.0001);
        let ring = [
            (lon - dx, lat - dy),
            (lon - dx, lat + dy),
            (lon + dx, lat + dy),
            (lon + dx, lat - dy),
            (lon - dx, lat - dy),
        ]
        .map(|(x, y)| Point::new(x, y))
        .to_vec();
        let mut rec = Record::default();
        rec.insert("HEIGHT".into(), FieldValue::Numeric(Some(9.5)));
        w.write_shape_and_record(&Polygon::new(PolygonRing::Outer(ring)), &rec)
            .unwrap();
        drop(w);
        std::fs::write(
            shp.with_extension("prj"),
            format!(r#"GEOGCS["{g}",DATUM["{d}",SPHEROID["GRS_1980",6378137.0,298.257222101]],PRIMEM["Greenwich",0.0],UNIT["Degree",0.0174532925199433]]"#),
        )
        .unwrap();
        let cj = dir.path().join("o.city.json");
        let out = citygen(&[
            "--footprints",
            shp.to_str().unwrap(),
            "--kb",
            KB,
            "--lod",
            "1",
            "--cityjson",
            cj.to_str().unwrap(),
            "--quiet",
        ]);
        assert!(
            out.status.success(),
            "{g}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        let cj: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&cj).unwrap()).unwrap();
        let (code, x, y, h, _) = placed(&cj);
        let crs = Crs::from_epsg_str(&format!("EPSG:{code}")).unwrap();
        let ll = crs.to_lonlat(x, y);
        let m = metres_apart(ll, (lon, lat));
        assert!(m < 0.5, "{g}: EPSG:{code} {ll:?} is {m} m from the point");
        assert!((h - 9.5).abs() < 0.05, "{g}: height {h}");
    }
}
