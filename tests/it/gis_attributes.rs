//! GIS attributes through the binary (issue 47): FlatGeobuf and GeoPackage footprints with
//! German municipal column names (`tests/data/gis`, made by `make_fixtures.py` there) and a
//! GeoJSON with Overture's, 3DBAG's and New York's: heights honoured within 5 cm, storeys and
//! ids kept, and every other column in every output, typed (CityJSON attributes, CityGML
//! generic attributes, the IFC `Citygen_Attributes` property set, glTF extras). `--layer`
//! chooses the GeoPackage layer, `--field` names a column, an unknown target is refused.

use super::common::{citygen, glb_json, root, KB};

const FGB: &str = "tests/data/gis/municipal.fgb";
const GPKG: &str = "tests/data/gis/municipal.gpkg";

/// OBJECTID, HOEHE, GESCHOSSE, NUTZUNG, BAUJAHR, FLAECHE, DENKMAL, ERFASST.
type Row = (u64, f64, u64, &'static str, i64, f64, bool, &'static str);

/// The fixtures' rows (DACHFORM left out).
const ROWS: [Row; 5] = [
    (501, 7.2, 2, "Wohnen", 1965, 80.0, false, "2021-05-04"),
    (502, 9.9, 3, "Gewerbe", 1990, 80.5, true, "2019-11-30"),
    (
        503,
        12.34,
        4,
        "Wohnen & Büro",
        2004,
        79.25,
        false,
        "2020-01-15",
    ),
    (504, 5.0, 1, "Garage", 1978, 80.0, false, "2018-07-01"),
    (505, 15.5, 5, "Schule", 1931, 81.75, true, "2022-03-09"),
];

struct Outputs {
    _dir: tempfile::TempDir,
    cityjson: serde_json::Value,
    gml: String,
    ifc: String,
    glb: serde_json::Value,
    files: Vec<std::path::PathBuf>,
}

/// Runs citygen on `input` with `extra` arguments, writing CityJSON, CityGML, IFC and glTF.
fn run(input: &str, extra: &[&str]) -> Outputs {
    let dir = tempfile::tempdir().unwrap();
    let p = |n: &str| dir.path().join(n).display().to_string();
    let (cj, gml, ifc, glb) = (p("o.city.json"), p("o.gml"), p("o.ifc"), p("o.glb"));
    let mut args = vec![
        "--footprints",
        input,
        "--kb",
        KB,
        "--lod",
        "2",
        "--cityjson",
        &cj,
        "--citygml",
        &gml,
        "--ifc",
        &ifc,
        "--gltf",
        &glb,
        "--quiet",
    ];
    args.extend_from_slice(extra);
    let out = citygen(&args);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let files = [&cj, &gml, &ifc, &glb]
        .map(std::path::PathBuf::from)
        .to_vec();
    Outputs {
        cityjson: serde_json::from_slice(&std::fs::read(&cj).unwrap()).unwrap(),
        gml: std::fs::read_to_string(&gml).unwrap(),
        ifc: std::fs::read_to_string(&ifc).unwrap(),
        glb: glb_json(std::path::Path::new(&glb)).0,
        files,
        _dir: dir,
    }
}

/// The buildings of a CityJSON file: attributes by source id.
fn buildings(cj: &serde_json::Value) -> std::collections::BTreeMap<String, serde_json::Value> {
    cj["CityObjects"]
        .as_object()
        .unwrap()
        .values()
        .filter(|o| o["type"] == "Building")
        .map(|o| {
            let a = o["attributes"].clone();
            (a["sourceId"].as_str().unwrap().to_string(), a)
        })
        .collect()
}

/// Checks the five municipal buildings in every output.
fn check_municipal(o: &Outputs) {
    let b = buildings(&o.cityjson);
    assert_eq!(b.len(), 5, "{:?}", b.keys().collect::<Vec<_>>());
    for (id, h, storeys, use_, year, area, listed, date) in ROWS {
        let a = &b[&format!("feature/{id}")];
        let got = a["measuredHeight"].as_f64().unwrap();
        assert!((got - h).abs() < 0.05, "feature/{id}: {got} for {h}");
        assert_eq!(a["storeysAboveGround"], storeys, "feature/{id}");
        // Typed as the file types them.
        assert_eq!(a["NUTZUNG"], use_, "{a}");
        assert_eq!(a["BAUJAHR"].as_i64(), Some(year), "{a}");
        assert!(
            a["FLAECHE"].is_f64() && a["FLAECHE"].as_f64() == Some(area),
            "{a}"
        );
        assert_eq!(a["DENKMAL"].as_bool(), Some(listed), "{a}");
        assert!(a["ERFASST"].as_str().unwrap().starts_with(date), "{a}");
        // Read into citygen's fields: not repeated as attributes.
        for used in ["HOEHE", "GESCHOSSE", "DACHFORM", "OBJECTID"] {
            assert!(a.get(used).is_none(), "{used} in {a}");
        }
        // CityGML: the generic attributes, typed.
        for needle in [
            format!("<gen:intAttribute name=\"BAUJAHR\">\n<gen:value>{year}</gen:value>"),
            format!("<gen:doubleAttribute name=\"FLAECHE\">\n<gen:value>{area}</gen:value>"),
            format!("<gen:stringAttribute name=\"DENKMAL\">\n<gen:value>{listed}</gen:value>"),
            format!(
                "<gen:stringAttribute name=\"NUTZUNG\">\n<gen:value>{}</gen:value>",
                use_.replace('&', "&amp;")
            ),
        ] {
            assert!(o.gml.contains(&needle), "no {needle} in the CityGML");
        }
        // IFC: the Citygen_Attributes property set.
        for needle in [
            format!("'BAUJAHR',$,IFCINTEGER({year}),$"),
            format!(
                "'DENKMAL',$,IFCBOOLEAN(.{}.),$",
                if listed { "T" } else { "F" }
            ),
        ] {
            assert!(o.ifc.contains(&needle), "no {needle} in the IFC");
        }
        // glTF: the building node's extras.
        let node = o.glb["nodes"]
            .as_array()
            .unwrap()
            .iter()
            .find(|n| n["extras"]["id"] == format!("feature/{id}"))
            .unwrap_or_else(|| panic!("no glTF node of feature/{id}"));
        let x = &node["extras"]["attributes"];
        assert_eq!(x["BAUJAHR"].as_i64(), Some(year), "{x}");
        assert_eq!(x["DENKMAL"].as_bool(), Some(listed), "{x}");
        assert_eq!(x["FLAECHE"].as_f64(), Some(area), "{x}");
        assert_eq!(x["NUTZUNG"], use_, "{x}");
    }
    assert_eq!(o.ifc.matches("'Citygen_Attributes'").count(), 5);
    assert!(o
        .ifc
        .contains("'NUTZUNG',$,IFCLABEL('Wohnen & B\\X2\\00FC\\X0\\ro'),$"));
    // A date column: an xs:date in CityGML.
    assert!(
        o.gml
            .contains("<gen:dateAttribute name=\"ERFASST\">\n<gen:value>2021-05-04</gen:value>")
            || o.gml
                .contains("<gen:stringAttribute name=\"ERFASST\">\n<gen:value>2021-05-04T")
    );
}

#[test]
fn a_flatgeobuf_keeps_heights_storeys_ids_and_every_column() {
    let o = run(FGB, &[]);
    check_municipal(&o);
    if let Ok(dir) = std::env::var("CITYGEN_KEEP_OUTPUTS") {
        for f in &o.files {
            std::fs::copy(f, std::path::Path::new(&dir).join(f.file_name().unwrap())).unwrap();
        }
    }
}

#[test]
fn a_geopackage_layer_is_chosen_by_name_and_the_id_column_by_field() {
    // Without --layer: the first polygon layer by name, the one outbuilding of `anbau`.
    let o = run(GPKG, &[]);
    assert_eq!(buildings(&o.cityjson).len(), 1);
    let o = run(GPKG, &["--layer", "gebaeude", "--field", "id=OBJECTID"]);
    check_municipal(&o);
    let tmp = tempfile::tempdir().unwrap();
    let cj = tmp.path().join("o.city.json");
    let out = citygen(&[
        "--footprints",
        GPKG,
        "--kb",
        KB,
        "--layer",
        "strassen",
        "--cityjson",
        cj.to_str().unwrap(),
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(
        err.contains("strassen") && err.contains("\"gebaeude\"") && err.contains("\"anbau\""),
        "{err}"
    );
}

#[test]
fn field_targets_are_checked_and_columns_must_exist() {
    let dir = tempfile::tempdir().unwrap();
    let cj = dir.path().join("o.city.json");
    let out = citygen(&[
        "--footprints",
        FGB,
        "--kb",
        KB,
        "--field",
        "hight=HOEHE",
        "--cityjson",
        cj.to_str().unwrap(),
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(
        err.contains("hight") && err.contains("height, min_height"),
        "{err}"
    );
    let out = citygen(&[
        "--footprints",
        FGB,
        "--kb",
        KB,
        "--field",
        "height=HOEHE_M",
        "--cityjson",
        cj.to_str().unwrap(),
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(
        err.contains("municipal.fgb") && err.contains("HOEHE_M") && err.contains("GESCHOSSE"),
        "{err}"
    );
    assert!(!cj.exists());
}

/// Overture's, 3DBAG's and New York's names in one GeoJSON, and a column named with --field.
#[test]
fn overture_3dbag_and_new_york_names_are_read_and_a_field_can_be_named() {
    let dir = tempfile::tempdir().unwrap();
    let gj = dir.path().join("mixed.geojson");
    let square = |i: usize| {
        let (x, y) = (455_000.0 + 20.0 * i as f64, 334_000.0);
        format!(
            r#"[[[{x}, {y}], [{}, {y}], [{}, {}], [{x}, {}], [{x}, {y}]]]"#,
            x + 10.0,
            x + 10.0,
            y + 8.0,
            y + 8.0
        )
    };
    let props = [
        // Overture: height, num_floors, roof_shape, class; `sources` (an array) is left out.
        r#"{"id": 11, "height": 10.5, "num_floors": 3, "roof_shape": "flat", "class": "residential", "sources": [1], "update_time": "2024-01-02"}"#,
        // 3DBAG: an absolute roof height over the ground's elevation.
        r#"{"fid": 12, "b3_h_dak_max": 14.25, "b3_h_maaiveld": 2.0, "b3_bouwlagen": 4, "b3_dak_type": "horizontal", "identificatie": "NL.IMBAG.Pand.0363100012"}"#,
        // New York: heightroof in feet.
        r#"{"objectid": 13, "heightroof": 30.0, "cnstrct_yr": 1931}"#,
        // A height column named on the command line.
        r#"{"objectid": 14, "HGT_X": 8.8, "NUM_FLOORS": 2}"#,
    ];
    let features: Vec<String> = props
        .iter()
        .enumerate()
        .map(|(i, p)| {
            format!(
                r#"{{"type": "Feature", "properties": {p}, "geometry": {{"type": "Polygon", "coordinates": {}}}}}"#,
                square(i)
            )
        })
        .collect();
    std::fs::write(
        &gj,
        format!(
            r#"{{"type": "FeatureCollection", "crs": {{"type": "name", "properties": {{"name": "EPSG:27700"}}}}, "features": [{}]}}"#,
            features.join(",")
        ),
    )
    .unwrap();
    let run = |extra: &[&str]| {
        let cj = dir.path().join("o.city.json");
        let mut args = vec![
            "--footprints",
            gj.to_str().unwrap(),
            "--kb",
            KB,
            "--cityjson",
            cj.to_str().unwrap(),
            "--quiet",
        ];
        args.extend_from_slice(extra);
        let out = citygen(&args);
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        buildings(&serde_json::from_slice(&std::fs::read(&cj).unwrap()).unwrap())
    };
    let b = run(&[]);
    let h = |id: &str| b[id]["measuredHeight"].as_f64().unwrap();
    assert!((h("feature/11") - 10.5).abs() < 0.05, "{}", h("feature/11"));
    assert_eq!(b["feature/11"]["storeysAboveGround"], 3);
    assert_eq!(b["feature/11"]["update_time"], "2024-01-02");
    assert!(b["feature/11"].get("sources").is_none());
    assert!(b["feature/11"].get("class").is_none());
    assert!(
        (h("feature/12") - 12.25).abs() < 0.05,
        "{}",
        h("feature/12")
    );
    assert_eq!(b["feature/12"]["storeysAboveGround"], 4);
    assert_eq!(b["feature/12"]["roofType"], "1000");
    assert_eq!(b["feature/12"]["identificatie"], "NL.IMBAG.Pand.0363100012");
    assert!(
        (h("feature/13") - 30.0 * 0.3048).abs() < 0.05,
        "{}",
        h("feature/13")
    );
    assert_eq!(b["feature/13"]["cnstrct_yr"], 1931);
    // Not a known name: an attribute, and the height comes from the storeys.
    assert_eq!(b["feature/14"]["HGT_X"], 8.8);
    assert_eq!(b["feature/14"]["storeysAboveGround"], 2);
    // Named: its height, for every feature (one without the column has no height of its own).
    let b = run(&["--field", "height=hgt_x"]);
    let h = |id: &str| b[id]["measuredHeight"].as_f64().unwrap();
    assert!((h("feature/14") - 8.8).abs() < 0.05, "{}", h("feature/14"));
    assert!(b["feature/14"].get("HGT_X").is_none());
    assert_eq!(b["feature/14"]["storeysAboveGround"], 2);
    assert_eq!(b["feature/12"]["b3_h_dak_max"], 14.25);
}

/// A truncated FlatGeobuf is refused with the file and the feature named, nothing written.
#[test]
fn a_truncated_flatgeobuf_is_an_error_naming_the_feature() {
    let bytes = std::fs::read(root().join(FGB)).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let bad = dir.path().join("cut.fgb");
    std::fs::write(&bad, &bytes[..bytes.len() - 30]).unwrap();
    let cj = dir.path().join("o.city.json");
    let out = citygen(&[
        "--footprints",
        bad.to_str().unwrap(),
        "--kb",
        KB,
        "--cityjson",
        cj.to_str().unwrap(),
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(
        err.contains("cut.fgb") && err.contains("feature 4"),
        "{err}"
    );
    assert!(!cj.exists());
}

/// ESRI's `.prj` of New York Long Island State Plane in US survey feet: no EPSG code.
const NY_LI_FEET_ESRI: &str = r#"PROJCS["NAD_1983_StatePlane_New_York_Long_Island_FIPS_3104_Feet",GEOGCS["GCS_North_American_1983",DATUM["D_North_American_1983",SPHEROID["GRS_1980",6378137.0,298.257222101]],PRIMEM["Greenwich",0.0],UNIT["Degree",0.0174532925199433]],PROJECTION["Lambert_Conformal_Conic"],PARAMETER["False_Easting",984250.0],PARAMETER["False_Northing",0.0],PARAMETER["Central_Meridian",-74.0],PARAMETER["Standard_Parallel_1",40.66666666666666],PARAMETER["Standard_Parallel_2",41.03333333333333],PARAMETER["Latitude_Of_Origin",40.16666666666666],UNIT["Foot_US",0.3048006096012192]]"#;

/// Writes the five municipal rows as a shapefile in New York's State Plane (US survey feet)
/// with ESRI's `.prj`: OBJECTID `N` (no decimals), HOEHE `N` (2 decimals), GESCHOSSE `N`,
/// DACHFORM and NUTZUNG `C`, BAUJAHR `N`, FLAECHE `N` (2 decimals), DENKMAL `L`, ERFASST `D`;
/// `ids` replaces the OBJECTID values. Returns the `.shp`.
fn municipal_shapefile(dir: &std::path::Path, ids: [f64; 5]) -> std::path::PathBuf {
    use shapefile::dbase::{Date, FieldName, FieldValue, Record, TableWriterBuilder};
    use shapefile::{Point, Polygon, PolygonRing};
    let name = |n: &str| FieldName::try_from(n).unwrap();
    let table = TableWriterBuilder::new()
        .add_numeric_field(name("OBJECTID"), 10, 0)
        .add_numeric_field(name("HOEHE"), 10, 2)
        .add_numeric_field(name("GESCHOSSE"), 4, 0)
        .add_character_field(name("DACHFORM"), 20)
        .add_character_field(name("NUTZUNG"), 40)
        .add_numeric_field(name("BAUJAHR"), 6, 0)
        .add_numeric_field(name("FLAECHE"), 10, 2)
        .add_logical_field(name("DENKMAL"))
        .add_date_field(name("ERFASST"));
    let path = dir.join("gebaeude.shp");
    let mut w = shapefile::Writer::from_path(&path, table).unwrap();
    let ft = 1200.0 / 3937.0;
    for (i, (row, id)) in ROWS.iter().zip(ids).enumerate() {
        let (_, h, storeys, use_, year, area, listed, date) = *row;
        // 10 x 8 m, clockwise (ESRI's outer ring), near the Empire State Building.
        let (x, y) = (988_000.0 + 120.0 * i as f64, 211_900.0);
        let (dx, dy) = (10.0 / ft, 8.0 / ft);
        let ring = vec![
            Point::new(x, y),
            Point::new(x, y + dy),
            Point::new(x + dx, y + dy),
            Point::new(x + dx, y),
            Point::new(x, y),
        ];
        let mut rec = Record::default();
        rec.insert("OBJECTID".into(), FieldValue::Numeric(Some(id)));
        rec.insert("HOEHE".into(), FieldValue::Numeric(Some(h)));
        rec.insert(
            "GESCHOSSE".into(),
            FieldValue::Numeric(Some(storeys as f64)),
        );
        rec.insert(
            "DACHFORM".into(),
            FieldValue::Character(Some("Flachdach".into())),
        );
        // dBASE text is ASCII here: the crate's default code page.
        rec.insert(
            "NUTZUNG".into(),
            FieldValue::Character(Some(use_.replace('ü', "ue"))),
        );
        rec.insert("BAUJAHR".into(), FieldValue::Numeric(Some(year as f64)));
        rec.insert("FLAECHE".into(), FieldValue::Numeric(Some(area)));
        rec.insert("DENKMAL".into(), FieldValue::Logical(Some(listed)));
        let d: Vec<u32> = date.split('-').map(|p| p.parse().unwrap()).collect();
        rec.insert(
            "ERFASST".into(),
            FieldValue::Date(Some(Date::new(d[2], d[1], d[0]).unwrap())),
        );
        w.write_shape_and_record(&Polygon::new(PolygonRing::Outer(ring)), &rec)
            .unwrap();
    }
    drop(w);
    std::fs::write(path.with_extension("prj"), NY_LI_FEET_ESRI).unwrap();
    path
}

/// The EPSG code of a CityJSON file's referenceSystem.
fn epsg_of(cj: &serde_json::Value) -> u32 {
    let rs = cj["metadata"]["referenceSystem"].as_str().unwrap();
    rs.rsplit('/').next().unwrap().parse().unwrap()
}

#[test]
fn a_shapefile_in_state_plane_feet_keeps_its_ids_heights_and_every_column() {
    let dir = tempfile::tempdir().unwrap();
    let shp = municipal_shapefile(dir.path(), ROWS.map(|r| r.0 as f64));
    let o = run(shp.to_str().unwrap(), &[]);
    // The ESRI .prj without a code is New York Long Island (ftUS), EPSG:2263: the outputs go
    // to its metre edition, EPSG:32118.
    assert_eq!(epsg_of(&o.cityjson), 32118);
    let b = buildings(&o.cityjson);
    for (id, ..) in ROWS {
        let a = &b[&format!("feature/{id}")];
        assert_eq!(a["DACHFORM"], serde_json::Value::Null, "{a}");
        assert_eq!(a["roofType"], "1000", "Flachdach is flat: {a}");
    }
    // Placed in the input's CRS: x about 988,000 ftUS = 301,147 m.
    let verts = o.cityjson["vertices"].as_array().unwrap();
    let (scale, translate) = (
        &o.cityjson["transform"]["scale"],
        &o.cityjson["transform"]["translate"],
    );
    let x0 =
        verts[0][0].as_f64().unwrap() * scale[0].as_f64().unwrap() + translate[0].as_f64().unwrap();
    assert!((x0 - 301_147.0).abs() < 700.0, "{x0}");
    // NUTZUNG was written in ASCII: compare with the fixture's umlaut spelled out.
    let mut ascii = o.cityjson.clone();
    for obj in ascii["CityObjects"].as_object_mut().unwrap().values_mut() {
        if let Some(n) = obj["attributes"].get_mut("NUTZUNG") {
            *n = n.as_str().unwrap().replace("ue", "ü").into();
        }
    }
    let o = Outputs {
        cityjson: ascii,
        gml: o.gml.replace("Wohnen &amp; Buero", "Wohnen &amp; Büro"),
        ifc: o
            .ifc
            .replace("'Wohnen & Buero'", "'Wohnen & B\\X2\\00FC\\X0\\ro'"),
        glb: {
            let mut g = o.glb.clone();
            for n in g["nodes"].as_array_mut().unwrap() {
                if let Some(v) = n["extras"]["attributes"].get_mut("NUTZUNG") {
                    *v = v.as_str().unwrap().replace("ue", "ü").into();
                }
            }
            g
        },
        files: o.files,
        _dir: o._dir,
    };
    check_municipal(&o);
}

#[test]
fn a_shapefile_without_unique_ids_names_its_records_by_index_and_keeps_the_column() {
    let dir = tempfile::tempdir().unwrap();
    let shp = municipal_shapefile(dir.path(), [7.0, 8.0, 7.0, 9.0, 10.0]);
    let o = run(shp.to_str().unwrap(), &[]);
    let b = buildings(&o.cityjson);
    let ids: Vec<&String> = b.keys().collect();
    assert_eq!(ids, ["shp/0", "shp/1", "shp/2", "shp/3", "shp/4"]);
    assert_eq!(b["shp/2"]["OBJECTID"].as_i64(), Some(7), "{}", b["shp/2"]);
    assert!((b["shp/2"]["measuredHeight"].as_f64().unwrap() - 12.34).abs() < 0.05);

    // Named with --field id=: a unique column gives the ids, the column is not repeated.
    let shp = municipal_shapefile(dir.path(), [1.0, 2.0, 3.0, 4.0, 5.0]);
    let o = run(shp.to_str().unwrap(), &["--field", "id=GESCHOSSE"]);
    let b = buildings(&o.cityjson);
    assert_eq!(b.len(), 5);
    // The third row: GESCHOSSE 4, OBJECTID 3.
    assert_eq!(
        b["feature/4"]["OBJECTID"].as_i64(),
        Some(3),
        "{}",
        b["feature/4"]
    );
    assert!(b["feature/4"].get("GESCHOSSE").is_none());
}

#[test]
fn the_3d_tiles_metadata_carries_every_column_as_text() {
    let dir = tempfile::tempdir().unwrap();
    let shp = municipal_shapefile(dir.path(), ROWS.map(|r| r.0 as f64));
    let tiles = dir.path().join("tiles");
    let out = citygen(&[
        "--footprints",
        shp.to_str().unwrap(),
        "--kb",
        KB,
        "--lod",
        "2",
        "--tiles3d",
        tiles.to_str().unwrap(),
        "--quiet",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let (json, bin) = glb_json(&tiles.join("content/all.glb"));
    let meta = &json["extensions"]["EXT_structural_metadata"];
    let props = &meta["schema"]["classes"]["building"]["properties"];
    for column in ["NUTZUNG", "BAUJAHR", "FLAECHE", "DENKMAL", "ERFASST"] {
        let p = &props[format!("attr_{column}")];
        assert_eq!(p["type"], "STRING", "{column}: {p}");
        assert_eq!(p["name"], column);
    }
    // Read into citygen's fields: no property.
    for used in ["HOEHE", "GESCHOSSE", "DACHFORM", "OBJECTID"] {
        assert!(props.get(format!("attr_{used}")).is_none(), "{used}");
    }
    // The column's strings, in the table's row order (the `id` column's).
    let table = &meta["propertyTables"][0];
    let strings = |key: &str| -> Vec<String> {
        let p = &table["properties"][key];
        let view = |i: &serde_json::Value| {
            let v = &json["bufferViews"][i.as_u64().unwrap() as usize];
            let o = v["byteOffset"].as_u64().unwrap_or(0) as usize;
            &bin[o..o + v["byteLength"].as_u64().unwrap() as usize]
        };
        let (values, offsets) = (view(&p["values"]), view(&p["stringOffsets"]));
        let offs: Vec<usize> = offsets
            .chunks(4)
            .map(|c| u32::from_le_bytes(c.try_into().unwrap()) as usize)
            .collect();
        offs.windows(2)
            .map(|w| String::from_utf8(values[w[0]..w[1]].to_vec()).unwrap())
            .collect()
    };
    let ids = strings("id");
    let years = strings("attr_BAUJAHR");
    let dates = strings("attr_ERFASST");
    assert_eq!(ids.len(), 5);
    for (id, _, _, _, year, _, _, date) in ROWS {
        let row = ids
            .iter()
            .position(|i| *i == format!("feature/{id}"))
            .unwrap();
        assert_eq!(years[row], year.to_string());
        assert_eq!(dates[row], date);
    }
}

/// A text id's key as `SourceId::key` makes it: the text when it holds only ASCII letters,
/// digits, `_`, `-` and `.`, else (here, a braced GUID) a prefix that check.
fn key_prefix(id: &str) -> String {
    id.chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || matches!(c, '_' | '-' | '.') {
                c
            } else {
                '_'
            }
        })
        .collect()
}

/// Checks that each of `ids` (with its height in metres and storeys) is a building's identity
/// in every output of `o`: the CityJSON object's id and `sourceId`, the CityGML `gml:id` and
/// `sourceId`, the IFC building's Name (its GlobalIds derive from it) and Description, the
/// glTF node's extras; the attribute `extra` kept; the outputs in EPSG:`epsg`.
fn check_text_ids(o: &Outputs, ids: &[(&str, f64, u64)], extra: &str, epsg: u32) {
    assert_eq!(epsg_of(&o.cityjson), epsg);
    let b = buildings(&o.cityjson);
    assert_eq!(b.len(), ids.len(), "{:?}", b.keys().collect::<Vec<_>>());
    let objects = o.cityjson["CityObjects"].as_object().unwrap();
    for &(id, h, storeys) in ids {
        let a = &b[id];
        let got = a["measuredHeight"].as_f64().unwrap();
        assert!((got - h).abs() < 0.05, "{id}: {got} for {h}");
        assert_eq!(a["storeysAboveGround"], storeys, "{id}");
        assert!(a.get(extra).is_some(), "{extra} not in {a}");
        let prefix = format!("B_{}", key_prefix(id));
        let (key, _) = objects
            .iter()
            .find(|(_, v)| v["type"] == "Building" && v["attributes"]["sourceId"] == id)
            .unwrap();
        assert!(key.starts_with(&prefix), "{key} for {id}");
        if key_prefix(id) == id {
            assert_eq!(*key, prefix);
        } else {
            // The text's hash after the sanitised text: `_h` and eight hex digits.
            let tail = &key[prefix.len()..];
            assert!(tail.len() == 10 && tail.starts_with("_h"), "{key}");
        }
        // The same id in CityGML (an NCName: it starts with B_ and holds no other character).
        assert!(o.gml.contains(&format!("gml:id=\"{key}\"")), "{key}");
        assert!(
            o.gml.contains(&format!(
                "<gen:stringAttribute name=\"sourceId\">\n<gen:value>{id}</gen:value>"
            )),
            "{id}"
        );
        // IFC: the building's Name is the key, its Description the text.
        let line = o
            .ifc
            .lines()
            .find(|l| l.contains("IFCBUILDING(") && l.contains(&format!(",'{}',", &key[2..])))
            .unwrap_or_else(|| panic!("no IfcBuilding named {key}"));
        assert!(line.contains(&format!(",'{id} (")), "{line}");
        assert!(o.glb["nodes"]
            .as_array()
            .unwrap()
            .iter()
            .any(|n| n["extras"]["id"] == id));
    }
}

/// Text ids (issue 47): braced GUIDs in a FlatGeobuf in State Plane feet (EPSG:2263), the BAG's
/// `identificatie` in a GeoPackage in RD New (EPSG:28992), beside its row keys; fixtures by
/// `tests/data/gis/make_text_id_fixtures.py` (GDAL).
#[test]
fn text_ids_from_a_flatgeobuf_and_a_geopackage_are_every_output_s_ids() {
    let o = run("tests/data/gis/guids.fgb", &[]);
    let ft = 1200.0 / 3937.0;
    check_text_ids(
        &o,
        &[
            ("{3F2504E0-4F89-11D3-9A0C-0305E82C3301}", 30.0 * ft, 3),
            ("{3F2504E0-4F89-11D3-9A0C-0305E82C3302}", 45.5 * ft, 4),
            ("{7C9E6679-7425-40DE-944B-E07FC1F90AE7}", 62.0 * ft, 6),
            ("{A1B2C3D4-0000-4000-8000-00000000BEEF}", 20.0 * ft, 2),
        ],
        "bin",
        32118,
    );
    // Same inputs, same bytes: a text id's seed is its text's.
    let again = run("tests/data/gis/guids.fgb", &[]);
    for (a, b) in o.files.iter().zip(&again.files) {
        assert!(
            std::fs::read(a).unwrap() == std::fs::read(b).unwrap(),
            "{a:?}"
        );
    }
    let o = run("tests/data/gis/bag.gpkg", &[]);
    check_text_ids(
        &o,
        &[
            ("NL.IMBAG.Pand.0599100000012345", 10.5, 3),
            ("NL.IMBAG.Pand.0599100000012346", 13.5, 4),
            ("NL.IMBAG.Pand.0599100000670001", 15.5, 5),
            ("NL.IMBAG.Pand.0599100000670002", 8.25, 2),
        ],
        "status",
        28992,
    );
    if let Ok(dir) = std::env::var("CITYGEN_KEEP_OUTPUTS") {
        for f in &o.files {
            let name = format!("bag-{}", f.file_name().unwrap().to_str().unwrap());
            std::fs::copy(f, std::path::Path::new(&dir).join(name)).unwrap();
        }
    }
}

/// Text ids in a shapefile in the British National Grid (Ordnance Survey TOIDs in `TOID`, no
/// whole-number id column) and in a GeoJSON in State Plane feet (the features' own `id`s):
/// kept in every output, the 3D Tiles `id` property included.
#[test]
fn text_ids_from_a_shapefile_and_a_geojson_are_every_output_s_ids() {
    use shapefile::dbase::{FieldName, FieldValue, Record, TableWriterBuilder};
    use shapefile::{Point, Polygon, PolygonRing};
    let dir = tempfile::tempdir().unwrap();
    let toids = [
        "osgb1000012345678",
        "osgb1000012345679",
        "osgb5000005123456789",
    ];
    let name = |n: &str| FieldName::try_from(n).unwrap();
    let table = TableWriterBuilder::new()
        .add_character_field(name("TOID"), 24)
        .add_numeric_field(name("HEIGHT"), 8, 2)
        .add_character_field(name("THEME"), 20);
    let shp = dir.path().join("toids.shp");
    let mut w = shapefile::Writer::from_path(&shp, table).unwrap();
    for (i, toid) in toids.iter().enumerate() {
        let (x, y) = (456_000.0 + 20.0 * i as f64, 335_000.0);
        let ring = [
            (x, y),
            (x, y + 8.0),
            (x + 10.0, y + 8.0),
            (x + 10.0, y),
            (x, y),
        ]
        .map(|(x, y)| Point::new(x, y))
        .to_vec();
        let mut rec = Record::default();
        rec.insert("TOID".into(), FieldValue::Character(Some(toid.to_string())));
        rec.insert("HEIGHT".into(), FieldValue::Numeric(Some(6.5 + i as f64)));
        rec.insert(
            "THEME".into(),
            FieldValue::Character(Some("Buildings".into())),
        );
        w.write_shape_and_record(&Polygon::new(PolygonRing::Outer(ring)), &rec)
            .unwrap();
    }
    drop(w);
    std::fs::copy(
        root().join("data/clifton/clifton_test.prj"),
        shp.with_extension("prj"),
    )
    .unwrap();
    let o = run(shp.to_str().unwrap(), &[]);
    let ids: Vec<(&str, f64, u64)> = toids
        .iter()
        .enumerate()
        .map(|(i, t)| (*t, 6.5 + i as f64, 2))
        .collect();
    let b = buildings(&o.cityjson);
    let storeys = |id: &str| b[id]["storeysAboveGround"].as_u64().unwrap();
    let ids: Vec<_> = ids.iter().map(|&(t, h, _)| (t, h, storeys(t))).collect();
    check_text_ids(&o, &ids, "THEME", 27700);
    assert!(b.values().all(|a| a.get("TOID").is_none()));

    // GeoJSON in EPSG:2263 (US survey feet): the features' own text ids.
    let gj = dir.path().join("ny.geojson");
    let ft = 1200.0 / 3937.0;
    let features: Vec<String> = ["BIN:1001001/A", "nyc-bldg-2"]
        .iter()
        .enumerate()
        .map(|(i, id)| {
            let (x, y) = (988_000.0 + 120.0 * i as f64, 211_900.0);
            let (x1, y1) = (x + 10.0 / ft, y + 8.0 / ft);
            format!(
                r#"{{"type": "Feature", "id": "{id}", "properties": {{"heightroof": 40.0, "cnstrct_yr": 1931}}, "geometry": {{"type": "Polygon", "coordinates": [[[{x}, {y}], [{x1}, {y}], [{x1}, {y1}], [{x}, {y1}], [{x}, {y}]]]}}}}"#
            )
        })
        .collect();
    std::fs::write(
        &gj,
        format!(
            r#"{{"type": "FeatureCollection", "crs": {{"type": "name", "properties": {{"name": "urn:ogc:def:crs:EPSG::2263"}}}}, "features": [{}]}}"#,
            features.join(",")
        ),
    )
    .unwrap();
    let o = run(gj.to_str().unwrap(), &[]);
    let b = buildings(&o.cityjson);
    let storeys = |id: &str| b[id]["storeysAboveGround"].as_u64().unwrap();
    check_text_ids(
        &o,
        &[
            ("BIN:1001001/A", 40.0 * ft, storeys("BIN:1001001/A")),
            ("nyc-bldg-2", 40.0 * ft, storeys("nyc-bldg-2")),
        ],
        "cnstrct_yr",
        32118,
    );

    // 3D Tiles: the `id` property holds the texts.
    let tiles = dir.path().join("tiles");
    let out = citygen(&[
        "--footprints",
        shp.to_str().unwrap(),
        "--kb",
        KB,
        "--lod",
        "2",
        "--tiles3d",
        tiles.to_str().unwrap(),
        "--quiet",
    ]);
    assert!(out.status.success());
    let (json, bin) = glb_json(&tiles.join("content/all.glb"));
    let table = &json["extensions"]["EXT_structural_metadata"]["propertyTables"][0];
    let p = &table["properties"]["id"];
    let view = |i: &serde_json::Value| {
        let v = &json["bufferViews"][i.as_u64().unwrap() as usize];
        let o = v["byteOffset"].as_u64().unwrap_or(0) as usize;
        &bin[o..o + v["byteLength"].as_u64().unwrap() as usize]
    };
    let values = String::from_utf8(view(&p["values"]).to_vec()).unwrap();
    for t in toids {
        assert!(values.contains(t), "{values}");
    }
}

/// `--previous` with text ids (the incremental path keys buildings by their ids): one BAG
/// building's height edited, it alone is `changed`, named by its text, and every tile has the
/// full run's bytes.
#[test]
fn an_incremental_run_names_a_changed_text_id_building_and_gives_the_full_run_s_bytes() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let write = |name: &str, edited: f64| {
        let features: Vec<String> = (0..6)
            .map(|i| {
                let (x, y) = (92_500.0 + 20.0 * i as f64, 437_000.0);
                let h = if i == 2 { edited } else { 8.0 + i as f64 };
                format!(
                    r#"{{"type": "Feature", "properties": {{"identificatie": "NL.IMBAG.Pand.05991000000{i:05}", "height": {h}}}, "geometry": {{"type": "Polygon", "coordinates": [[[{x}, {y}], [{}, {y}], [{}, {}], [{x}, {}], [{x}, {y}]]]}}}}"#,
                    x + 10.0,
                    x + 10.0,
                    y + 8.0,
                    y + 8.0
                )
            })
            .collect();
        let p = d.join(name);
        std::fs::write(
            &p,
            format!(
                r#"{{"type": "FeatureCollection", "crs": {{"type": "name", "properties": {{"name": "EPSG:28992"}}}}, "features": [{}]}}"#,
                features.join(",")
            ),
        )
        .unwrap();
        p
    };
    let (d1, d2) = (write("d1.geojson", 15.0), write("d2.geojson", 21.0));
    let run = |input: &std::path::Path, out: &str, extra: &[&str]| {
        let o = d.join(out);
        std::fs::create_dir_all(&o).unwrap();
        let p = |n: &str| o.join(n).display().to_string();
        let mut args: Vec<String> = [
            "--footprints",
            input.to_str().unwrap(),
            "--kb",
            KB,
            "--lod",
            "2",
            "--tile",
            "50",
            "--quiet",
        ]
        .iter()
        .map(|s| s.to_string())
        .collect();
        args.extend([
            "--cityjsonseq".into(),
            p("t.city.jsonl"),
            "--ifc".into(),
            p("t.ifc"),
            "--gltf".into(),
            p("t.glb"),
            "--report".into(),
            p("report.json"),
        ]);
        args.extend(extra.iter().map(|s| s.to_string()));
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        let out = citygen(&args);
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        o
    };
    let o1 = run(&d1, "o1", &[]);
    let full = run(&d2, "full", &[]);
    let inc = run(&d2, "inc", &["--previous", o1.to_str().unwrap()]);
    let report: serde_json::Value =
        serde_json::from_slice(&std::fs::read(inc.join("report.json")).unwrap()).unwrap();
    let c = &report["changes"];
    assert_eq!(
        c["changed"],
        serde_json::json!(["NL.IMBAG.Pand.0599100000000002"])
    );
    assert_eq!(c["added"], serde_json::json!([]));
    assert_eq!(c["removed"], serde_json::json!([]));
    let mut n = 0;
    for e in std::fs::read_dir(&full).unwrap() {
        let name = e.unwrap().file_name();
        let name = name.to_str().unwrap();
        if name.starts_with("t_") {
            n += 1;
            assert!(
                std::fs::read(full.join(name)).unwrap() == std::fs::read(inc.join(name)).unwrap(),
                "{name}"
            );
        }
    }
    assert!(n >= 3, "{n} tile files");
}
