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
fn tiles_that_share_a_column_are_bilinear_across_the_seam() {
    // West: centres 499 901..499 999; east: 499 999..500 197, the column at 499 999 shared (as
    // SRTM tiles share their edge samples). Between 499 999 and 500 000 the west tile only has
    // its half-pixel margin (its edge's values held flat), the east tile real pixels.
    let dir = tempfile::tempdir().unwrap();
    let origin = DVec2::new(500_000.0, 5_000_000.0);
    let west = GeoTiff::projected(32609, (499_900.0, 5_000_100.0), 2.0, (50, 100), plane);
    let east = GeoTiff::projected(32609, (499_998.0, 5_000_100.0), 2.0, (100, 100), plane);
    let pw = write(dir.path(), "west.tif", &west);
    let pe = write(dir.path(), "east.tif", &east);
    for paths in [[&pw, &pe], [&pe, &pw]] {
        let set = DemSet::open(&[paths[0].clone(), paths[1].clone()]).unwrap();
        let f = set.framed(UTM, origin);
        let mut s = f.sampler();
        for x in [-3.0, -1.5, -1.0, -0.9, -0.5, -0.1, 0.0, 0.5, 3.0] {
            let z = value(s.sample(DVec2::new(x, 10.0)).unwrap());
            let want = plane(500_000.0 + x, 5_000_010.0);
            assert!((z - want).abs() < 1e-4, "{x}: {z} vs {want}");
        }
    }
    // One file alone still holds its edge flat in its margin.
    let set = DemSet::open(&[pw]).unwrap();
    let f = set.framed(UTM, origin);
    let z = value(f.sampler().sample(DVec2::new(-0.5, 10.0)).unwrap());
    assert!((z - plane(499_999.0, 5_000_010.0)).abs() < 1e-4, "{z}");
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
    // A code no table knows (EPSG:3035, LAEA Europe, is read since issue 47's any-EPSG CRS).
    let mut t = GeoTiff::projected(9999, (0.0, 0.0), 1.0, (4, 4), |_, _| 1.0);
    let p = write(dir.path(), "laea.tif", &t);
    let e = DemSet::open(std::slice::from_ref(&p))
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("laea.tif") && e.contains("EPSG:9999") && e.contains("gdalwarp"),
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

/// An SRTM3 tile's heights: `f(column, row)` rounded, big-endian `i16`, rows from the north.
fn hgt_bytes(f: impl Fn(u32, u32) -> f64) -> Vec<u8> {
    let mut out = Vec::with_capacity(1201 * 1201 * 2);
    for r in 0..1201 {
        for c in 0..1201 {
            out.extend_from_slice(&(f(c, r).round() as i16).to_be_bytes());
        }
    }
    out
}

/// A plane over N43E007 in whole metres: 1 m a column east, 2 m a row south.
fn hgt_plane(c: u32, r: u32) -> f64 {
    10.0 + f64::from(c) + 2.0 * f64::from(r)
}

#[test]
fn srtm_hgt_tile_is_read_on_its_whole_degree_grid() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("N43E007.hgt");
    let mut bytes = hgt_bytes(hgt_plane);
    // Voids: 3 x 3 samples around column 500, row 600.
    for r in 599..602 {
        for c in 499..502 {
            let k = 2 * (r * 1201 + c);
            bytes[k..k + 2].copy_from_slice(&(-32768i16).to_be_bytes());
        }
    }
    std::fs::write(&p, &bytes).unwrap();
    let set = DemSet::open(std::slice::from_ref(&p)).unwrap();
    assert_eq!(set.vertical_epsg().unwrap(), Some(5773));
    let crs = Crs::Utm {
        zone: 32,
        north: true,
    };
    let (ox, oy) = crs.from_lonlat(7.42, 43.735);
    let origin = DVec2::new(ox.round(), oy.round());
    let f = set.framed(crs, origin);
    // 3" is about 67 m east and 93 m north at 43.7°N.
    assert!((f.cell_size() - 67.0).abs() < 1.5, "{}", f.cell_size());
    let mut s = f.sampler();
    let local = |lon: f64, lat: f64| {
        let (x, y) = crs.from_lonlat(lon, lat);
        DVec2::new(x, y) - origin
    };
    // The plane at any point: column = (lon - 7) * 1200, row = (44 - lat) * 1200.
    let want = |lon: f64, lat: f64| 10.0 + (lon - 7.0) * 1200.0 + 2.0 * (44.0 - lat) * 1200.0;
    for (lon, lat) in [
        (7.42, 43.735),
        (7.0004, 43.9996),
        (7.9999, 43.0001),
        (7.5, 43.5),
    ] {
        let z = value(s.sample(local(lon, lat)).unwrap());
        assert!((z - want(lon, lat)).abs() < 1e-3, "({lon}, {lat}): {z}");
    }
    // A void's centre has nothing around it; beside the voids the plane goes on.
    let (lon, lat) = (7.0 + 500.0 / 1200.0, 44.0 - 600.0 / 1200.0);
    assert_eq!(s.sample(local(lon, lat)).unwrap(), Sample::NoData);
    let z = value(s.sample(local(lon + 3.0 / 1200.0, lat)).unwrap());
    assert!((z - want(lon + 3.0 / 1200.0, lat)).abs() < 1e-3, "{z}");
    assert_eq!(s.sample(local(8.01, 43.5)).unwrap(), Sample::Outside);
}

/// The same tile as a GeoTIFF the way `gdal_translate` writes one (PixelIsArea, the corner
/// half a sample beyond the whole degree): the same heights everywhere.
#[test]
fn srtm_hgt_agrees_with_its_geotiff() {
    let dir = tempfile::tempdir().unwrap();
    let hgt = dir.path().join("s12w077.HGT");
    let f = |c: u32, r: u32| (f64::from(c * 7 + r * 13) % 500.0) - 20.0;
    std::fs::write(&hgt, hgt_bytes(f)).unwrap();
    let step = 1.0 / 1200.0;
    let mut values = Vec::new();
    for r in 0..1201 {
        for c in 0..1201 {
            values.push(f(c, r).round());
        }
    }
    let t = GeoTiff {
        width: 1201,
        height: 1201,
        values,
        tiepoint: (-77.0 - step / 2.0, -11.0 + step / 2.0),
        scale: (step, step),
        epsg: 4326,
        geographic: true,
        pixel_is_point: false,
        nodata: Some(-32768.0),
        vertical: None,
        sample: SampleType::I16,
        packing: Packing::Deflate,
        rows_per_strip: 3,
    };
    let tif = write(dir.path(), "s12w077.tif", &t);
    let crs = Crs::Utm {
        zone: 18,
        north: false,
    };
    let (ox, oy) = crs.from_lonlat(-76.5, -11.5);
    let origin = DVec2::new(ox.round(), oy.round());
    let (a, b) = (DemSet::open(&[hgt]).unwrap(), DemSet::open(&[tif]).unwrap());
    let (fa, fb) = (a.framed(crs, origin), b.framed(crs, origin));
    let (mut sa, mut sb) = (fa.sampler(), fb.sampler());
    for k in 0..200 {
        let q = DVec2::new(
            f64::from(k * 523 % 100_000) - 50_000.0,
            f64::from(k * 811 % 100_000) - 50_000.0,
        );
        let (za, zb) = (value(sa.sample(q).unwrap()), value(sb.sample(q).unwrap()));
        assert!((za - zb).abs() < 1e-3, "{q}: hgt {za}, tiff {zb}");
    }
}

#[test]
fn hostile_hgt_files_are_refused_naming_them() {
    let dir = tempfile::tempdir().unwrap();
    let plane = hgt_bytes(hgt_plane);
    let cases: [(&str, &[u8], &str); 5] = [
        ("N43E007.hgt", &plane[..plane.len() - 2], "2884800 bytes"),
        ("N43E007.hgt", &[], "0 bytes"),
        ("monaco.hgt", &plane, "named after its tile"),
        ("N93E007.hgt", &plane, "named after its tile"),
        (
            "N43E007.hgt",
            &[plane.as_slice(), &[0, 0]].concat(),
            "2884804 bytes",
        ),
    ];
    for (k, (name, bytes, what)) in cases.iter().enumerate() {
        let sub = dir.path().join(format!("case{k}"));
        std::fs::create_dir(&sub).unwrap();
        let p = sub.join(name);
        std::fs::write(&p, bytes).unwrap();
        let e = DemSet::open(std::slice::from_ref(&p)).unwrap_err();
        assert!(matches!(e, DemError::Hgt { .. }), "{name}: {e:?}");
        let e = e.to_string();
        assert!(
            e.contains(&p.display().to_string()) && e.contains(what),
            "{e}"
        );
    }
    // A folder named like a tile.
    let folder = dir.path().join("N10E010.hgt");
    std::fs::create_dir(&folder).unwrap();
    let e = DemSet::open(&[folder]).unwrap_err().to_string();
    assert!(e.contains("N10E010.hgt") && e.contains("directory"), "{e}");
    // Truncated after it was opened: the strip that is gone fails, naming the file.
    let p = dir.path().join("N43E007.hgt");
    std::fs::write(&p, &plane).unwrap();
    let set = DemSet::open(std::slice::from_ref(&p)).unwrap();
    std::fs::File::options()
        .write(true)
        .open(&p)
        .unwrap()
        .set_len(1000)
        .unwrap();
    let crs = Crs::Wgs84;
    let f = set.framed(crs, DVec2::ZERO);
    let e = f.sampler().sample(DVec2::new(7.5, 43.5)).unwrap_err();
    assert!(matches!(e, DemError::Io { .. }), "{e:?}");
    assert!(e.to_string().contains(&p.display().to_string()), "{e}");
}

/// A web-mercator DEM (EPSG:3857, as `gdalwarp -t_srs EPSG:3857` writes for web maps) is read
/// through its own projection.
#[test]
fn pseudo_mercator_dem_samples_in_a_utm_frame() {
    let dir = tempfile::tempdir().unwrap();
    let h = |lon: f64, lat: f64| 50.0 + 1000.0 * (lon - 7.4) + 2000.0 * (43.74 - lat);
    let (x0, y0) = crate::crs::webmerc::from_lonlat(7.40, 43.75);
    let t = GeoTiff::projected(3857, (x0, y0), 10.0, (200, 200), |x, y| {
        let (lon, lat) = crate::crs::webmerc::to_lonlat(x, y);
        h(lon, lat)
    });
    let p = write(dir.path(), "web.tif", &t);
    let set = DemSet::open(&[p]).unwrap();
    let crs = Crs::Utm {
        zone: 32,
        north: true,
    };
    let (ox, oy) = crs.from_lonlat(7.41, 43.74);
    let origin = DVec2::new(ox.round(), oy.round());
    let f = set.framed(crs, origin);
    // 10 m of web mercator is 10 cos φ on the ground.
    let want_cell = 10.0 * 43.74f64.to_radians().cos();
    assert!((f.cell_size() - want_cell).abs() < 0.1, "{}", f.cell_size());
    let mut s = f.sampler();
    for q in [DVec2::new(12.0, -7.0), DVec2::new(-300.0, 250.0)] {
        let (lon, lat) = crs.to_lonlat(origin.x + q.x, origin.y + q.y);
        let z = value(s.sample(q).unwrap());
        // Linear in lon/lat, nearly linear in mercator metres over a pixel.
        assert!((z - h(lon, lat)).abs() < 1e-2, "{z} vs {}", h(lon, lat));
    }
}

/// Every strip of `p` as the `tiff` crate's own decoder reads it.
fn strips_by_tiff(p: &Path) -> Vec<Vec<f32>> {
    let mut dec = Decoder::new(BufReader::new(File::open(p).unwrap())).unwrap();
    (0..dec.strip_count().unwrap())
        .map(|k| match dec.read_chunk(k).unwrap() {
            DecodingResult::F32(v) => v,
            _ => panic!("not f32"),
        })
        .collect()
}

#[test]
fn deflated_f32_strips_are_inflated_to_the_tiff_crates_values() {
    let dir = tempfile::tempdir().unwrap();
    // 7 rows a strip over 100 rows: a short last strip; nodata kept as NaN.
    let mut t = GeoTiff::projected(32609, (499_900.0, 5_000_100.0), 2.0, (100, 100), |x, y| {
        150.0 + 20.0 * ((x / 7.0).sin() + (y / 9.0).cos())
    });
    t.packing = Packing::Deflate;
    t.nodata = Some(-9999.0);
    t.values[4321] = -9999.0;
    let p = write(dir.path(), "d.tif", &t);
    let dem = Dem::open(&p).unwrap();
    assert!(
        matches!(dem.source, Source::Tiff(_, Some(_))),
        "fast path not taken"
    );
    let want = strips_by_tiff(&p);
    assert_eq!(want.len(), 15);
    for (k, w) in want.iter().enumerate() {
        // Into a fresh buffer, and into a used one of another size.
        for spare in [Vec::new(), vec![7.0; 1234]] {
            let got = dem.decode(k as u32, spare).unwrap();
            assert_eq!(got.w, 100);
            assert_eq!(got.z.len(), w.len(), "strip {k}");
            for (a, b) in got.z.iter().zip(w) {
                assert!(a.to_bits() == b.to_bits() || (a.is_nan() && *b == -9999.0));
            }
        }
    }
    // Other layouts keep the `tiff` crate's path.
    for (sample, packing) in [
        (SampleType::F32, Packing::None),
        (SampleType::F32, Packing::Lzw),
        (SampleType::F64, Packing::Deflate),
        (SampleType::I16, Packing::Deflate),
    ] {
        let mut t = GeoTiff::projected(32609, (499_900.0, 5_000_100.0), 2.0, (10, 10), plane);
        t.sample = sample;
        t.packing = packing;
        let p = write(dir.path(), "o.tif", &t);
        let dem = Dem::open(&p).unwrap();
        assert!(
            matches!(dem.source, Source::Tiff(_, None)),
            "{sample:?} {packing:?}"
        );
    }
}

#[test]
fn a_strip_that_does_not_inflate_goes_to_the_tiff_crate() {
    let dir = tempfile::tempdir().unwrap();
    let mut t = GeoTiff::projected(32609, (499_900.0, 5_000_100.0), 2.0, (50, 30), plane);
    t.packing = Packing::Deflate;
    let p = write(dir.path(), "d.tif", &t);
    let dem = Dem::open(&p).unwrap();
    let Source::Tiff(dec, Some(deflated)) = &dem.source else {
        panic!("fast path not taken");
    };
    // Asked for more rows than the strip holds: refused, the buffer given back.
    let spare = vec![1.0; 10];
    let back = deflated.inflate(dec, 0, (50, 8), spare).unwrap_err();
    assert!(back.capacity() >= 10);
    assert!(deflated.inflate(dec, 99, (50, 7), Vec::new()).is_err());
    // Corrupt the first strip's bytes: both paths fail, with the tiff crate's message.
    let mut bytes = std::fs::read(&p).unwrap();
    let at = deflated.offsets[0] as usize;
    bytes[at + 2..at + 40].fill(0xff);
    let q = dir.path().join("bad.tif");
    std::fs::write(&q, &bytes).unwrap();
    let bad = Dem::open(&q).unwrap();
    let e = bad
        .decode(0, Vec::new())
        .err()
        .expect("corrupt strip decoded");
    assert!(e.to_string().contains("bad.tif"), "{e}");
    assert!(e.to_string().contains("strip or tile 0"), "{e}");
    // The other strips still read.
    assert!(bad.decode(1, Vec::new()).is_ok());
}
