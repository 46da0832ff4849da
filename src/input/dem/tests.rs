use std::path::PathBuf;

use glam::DVec2;

use super::*;
use crate::testkit::geotiff::{GeoTiff, Packing, SampleType};

/// UTM 32N (EPSG:32632) around (500 000, 5 000 000).
const UTM: Crs = Crs::Utm {
    zone: 9,
    north: true,
};

fn plane(x: f64, y: f64) -> f64 {
    100.0 + 0.1 * (x - 500_000.0) + 0.05 * (y - 5_000_000.0)
}

fn write(dir: &Path, name: &str, t: &GeoTiff) -> PathBuf {
    let p = dir.join(name);
    t.write(&p).unwrap();
    p
}

fn value(s: Sample) -> f64 {
    match s {
        Sample::Value(z) => z,
        other => panic!("no value: {other:?}"),
    }
}

#[test]
fn plane_is_read_back_in_every_sample_format_and_packing() {
    let dir = tempfile::tempdir().unwrap();
    let origin = DVec2::new(500_000.0, 5_000_000.0);
    for (k, (sample, packing)) in [
        (SampleType::F32, Packing::None),
        (SampleType::F64, Packing::Deflate),
        (SampleType::I32, Packing::Lzw),
        (SampleType::I16, Packing::Deflate),
        (SampleType::U16, Packing::None),
    ]
    .into_iter()
    .enumerate()
    {
        let mut t = GeoTiff::projected(32609, (499_900.0, 5_000_100.0), 2.0, (100, 100), plane);
        t.sample = sample;
        t.packing = packing;
        if matches!(sample, SampleType::I16 | SampleType::I32 | SampleType::U16) {
            // Whole metres: a plane of slope 1 in 10 rounded.
            t.values.iter_mut().for_each(|v| *v = v.round());
        }
        let p = write(dir.path(), &format!("d{k}.tif"), &t);
        let set = DemSet::open(&[p]).unwrap();
        let f = set.framed(UTM, origin);
        assert!((f.cell_size() - 2.0).abs() < 1e-9);
        let mut s = f.sampler();
        let tol = if matches!(sample, SampleType::F32 | SampleType::F64) {
            1e-3
        } else {
            0.5
        };
        for q in [
            DVec2::new(0.0, 0.0),
            DVec2::new(-37.3, 41.9),
            DVec2::new(80.2, -60.7),
        ] {
            let z = value(s.sample(q).unwrap());
            let want = plane(origin.x + q.x, origin.y + q.y);
            assert!((z - want).abs() < tol, "{sample:?}: {z} vs {want} at {q}");
        }
        assert_eq!(s.sample(DVec2::new(150.0, 0.0)).unwrap(), Sample::Outside);
    }
}

#[test]
fn pixel_is_point_puts_the_tiepoint_on_the_first_centre() {
    let dir = tempfile::tempdir().unwrap();
    let origin = DVec2::new(500_000.0, 5_000_000.0);
    // The same heights at the same centres, written both ways.
    let area = GeoTiff::projected(32609, (499_900.0, 5_000_100.0), 2.0, (100, 100), plane);
    let mut point = area.clone();
    point.pixel_is_point = true;
    point.tiepoint = (499_901.0, 5_000_099.0);
    let pa = write(dir.path(), "area.tif", &area);
    let pp = write(dir.path(), "point.tif", &point);
    for p in [pa, pp] {
        let set = DemSet::open(&[p]).unwrap();
        let f = set.framed(UTM, origin);
        let z = value(f.sampler().sample(DVec2::new(3.3, -7.1)).unwrap());
        assert!((z - plane(500_003.3, 4_999_992.9)).abs() < 1e-3, "{z}");
    }
}

#[test]
fn nodata_is_skipped_and_two_tiles_meet() {
    let dir = tempfile::tempdir().unwrap();
    let origin = DVec2::new(500_000.0, 5_000_000.0);
    let mut west = GeoTiff::projected(32609, (499_900.0, 5_000_100.0), 2.0, (50, 100), plane);
    west.nodata = Some(-9999.0);
    // A hole of 3 x 3 pixels around local (-50, 50): centres 499949..499953.
    for j in 23..26 {
        for i in 24..27 {
            west.values[j * 50 + i] = -9999.0;
        }
    }
    let east = GeoTiff::projected(32609, (500_000.0, 5_000_100.0), 2.0, (50, 100), plane);
    let pw = write(dir.path(), "west.tif", &west);
    let pe = write(dir.path(), "east.tif", &east);
    let set = DemSet::open(&[pw, pe]).unwrap();
    let f = set.framed(UTM, origin);
    let mut s = f.sampler();
    // In the hole's middle: nothing known around.
    assert_eq!(s.sample(DVec2::new(-49.0, 51.0)).unwrap(), Sample::NoData);
    // Across the seam between the tiles, within half a pixel of each edge.
    for x in [-0.9, -0.2, 0.0, 0.3, 0.9] {
        let z = value(s.sample(DVec2::new(x, 10.0)).unwrap());
        let want = plane(500_000.0 + x, 5_000_010.0);
        assert!((z - want).abs() < 0.11, "{x}: {z} vs {want}");
    }
    assert_eq!(s.sample(DVec2::new(100.6, 10.0)).unwrap(), Sample::Outside);
}

#[test]
fn geographic_dem_samples_in_a_utm_frame() {
    let dir = tempfile::tempdir().unwrap();
    // 0.0001° cells around (7.4°E, 43.7°N) (Monaco, UTM 32N).
    let crs = Crs::Utm {
        zone: 32,
        north: true,
    };
    let (lon0, lat0) = (7.40, 43.74);
    let h = |lon: f64, lat: f64| 50.0 + 1000.0 * (lon - lon0) + 2000.0 * (lat0 - lat);
    let (w, hgt, cell) = (200u32, 200u32, 0.0001);
    let mut values = Vec::new();
    for j in 0..hgt {
        for i in 0..w {
            let lon = lon0 + (f64::from(i) + 0.5) * cell;
            let lat = lat0 - (f64::from(j) + 0.5) * cell;
            values.push(h(lon, lat));
        }
    }
    let t = GeoTiff {
        width: w,
        height: hgt,
        values,
        tiepoint: (lon0, lat0),
        scale: (cell, cell),
        epsg: 4326,
        geographic: true,
        pixel_is_point: false,
        nodata: None,
        vertical: Some(5773),
        sample: SampleType::F32,
        packing: Packing::Deflate,
        rows_per_strip: 16,
    };
    let p = write(dir.path(), "geo.tif", &t);
    let set = DemSet::open(&[p]).unwrap();
    assert_eq!(set.vertical_epsg().unwrap(), Some(5773));
    let (ox, oy) = crs.from_lonlat(7.41, 43.73);
    let origin = DVec2::new(ox.round(), oy.round());
    let f = set.framed(crs, origin);
    // About 8 m by 11 m cells: the smaller side.
    assert!((f.cell_size() - 8.0).abs() < 0.5, "{}", f.cell_size());
    let q = DVec2::new(12.0, -7.0);
    let (lon, lat) = crs.to_lonlat(origin.x + q.x, origin.y + q.y);
    let z = value(f.sampler().sample(q).unwrap());
    assert!((z - h(lon, lat)).abs() < 1e-3, "{z} vs {}", h(lon, lat));
}

#[test]
fn refusals_name_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let mut t = GeoTiff::projected(3035, (0.0, 0.0), 1.0, (4, 4), |_, _| 1.0);
    let p = write(dir.path(), "laea.tif", &t);
    let e = DemSet::open(std::slice::from_ref(&p))
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("laea.tif") && e.contains("EPSG:3035") && e.contains("gdalwarp"),
        "{e}"
    );
    t.epsg = 32632;
    t.vertical = Some(5773);
    let a = write(dir.path(), "a.tif", &t);
    t.vertical = Some(3855);
    let b = write(dir.path(), "b.tif", &t);
    let e = DemSet::open(&[a, b]).unwrap_err().to_string();
    assert!(e.contains("EGM96") && e.contains("EGM2008"), "{e}");
    let text = dir.path().join("text.tif");
    std::fs::write(&text, "not a tiff").unwrap();
    let e = DemSet::open(&[text]).unwrap_err().to_string();
    assert!(
        e.contains("text.tif") && e.contains("not a readable GeoTIFF"),
        "{e}"
    );
    let e = DemSet::open(&[dir.path().join("missing.tif")])
        .unwrap_err()
        .to_string();
    assert!(e.contains("missing.tif"), "{e}");
}

/// The files GDAL made (`scripts/make_dem_fixtures.py`: tiled with deflate and the float
/// predictor and a nodata hole, PixelIsPoint int16 in LZW strips, WGS84 degrees with EGM96
/// heights): at the pixel centres where GDAL places them, citygen reads the pixels' values.
#[test]
fn georeferencing_agrees_with_gdal() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/dem");
    let points: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.join("points.json")).unwrap()).unwrap();
    let crs = Crs::Utm {
        zone: 32,
        north: true,
    };
    let files = points.as_object().unwrap();
    assert_eq!(files.len(), 3);
    for (name, pts) in files {
        let set = DemSet::open(&[dir.join(name)]).unwrap();
        let f = set.framed(crs, DVec2::ZERO);
        let mut s = f.sampler();
        let pts = pts.as_array().unwrap();
        assert!(pts.len() >= 3, "{name}");
        for p in pts {
            let (x, y, v) = (
                p[0].as_f64().unwrap(),
                p[1].as_f64().unwrap(),
                p[2].as_f64().unwrap(),
            );
            let local = if name.starts_with("geo") {
                let (e, n) = crs.from_lonlat(x, y);
                DVec2::new(e, n)
            } else {
                DVec2::new(x, y)
            };
            let z = value(s.sample(local).unwrap());
            assert!((z - v).abs() < 1e-3, "{name} at ({x}, {y}): {z}, GDAL {v}");
        }
        if name.starts_with("geo") {
            assert_eq!(set.vertical_epsg().unwrap(), Some(5773), "{name}");
        }
        // GDAL wrote the raster type the file's name says.
        assert_eq!(
            set.dems[0].georef.pixel_is_point,
            name.contains("point"),
            "{name}"
        );
    }
    // The tiled file's hole (pixels 30..34 of rows 20..24, 2 m from (370000, 4842000)).
    let set = DemSet::open(&[dir.join("utm_tiled_deflate.tif")]).unwrap();
    let f = set.framed(crs, DVec2::ZERO);
    assert_eq!(
        f.sampler()
            .sample(DVec2::new(370_064.0, 4_841_956.0))
            .unwrap(),
        Sample::NoData
    );
}
