//! LOD3 on slopes (issue 44; docs/terrain.md, "LOD3 on slopes") through the binary: a district
//! on a steep synthetic hill (a plane rising 22 % to the north, 4 % to the east, written as a
//! GeoTIFF in code) with a street along its top, at LOD3 with `--dem`, read back from the
//! CityJSON: every building has its entrance, every door's sill is at the terrain under it
//! (at most the step of `derive::frontage::slope` above its lowest point, never below its
//! highest), no window or door is below the terrain, the building whose street wall stands
//! a storey up the hill has its door there, on that storey; the CityGML solids pass the
//! ISO 19107 checks, the bytes are the same at 1 and 3 threads and the LOD4 floors are level.
//! Monaco-Ville on a wavy hill at LOD3: its solids valid (its IFC on the SRTM crop goes through
//! `validate-outputs --geometry` in .ci/run, the `monaco-ville-lod3` sample).

use std::path::Path;

use citygen::crs::Crs;
use citygen::testkit::geotiff::GeoTiff;
use citygen::testkit::pbf_write::PbfWriter;
use serde_json::Value;

use super::common::{citygen, root, KB};

const UTM32: Crs = Crs::Utm {
    zone: 32,
    north: true,
};
const LON0: f64 = 7.43;
const LAT0: f64 = 43.74;
/// The highest a sill may stand above the lowest terrain under its door: the step (0.25 m)
/// and the millimetres of the outputs.
const STEP: f64 = 0.26;
/// How far below the terrain an opening's bottom may be: the outputs' millimetre.
const TOUCH: f64 = 0.005;

/// The UTM origin of the district (whole metres).
fn origin() -> (f64, f64) {
    let (x, y) = UTM32.from_lonlat(LON0, LAT0);
    (x.round(), y.round())
}

/// The hill at local (u, v): a plane (exact under bilinear sampling).
fn hill(u: f64, v: f64) -> f64 {
    100.0 + 0.22 * v + 0.04 * u
}

/// A footprint's corners (local, counter-clockwise), its `height` and its `building:levels`.
type Footprint = (Vec<(f64, f64)>, &'static str, &'static str);

/// The footprints (local, counter-clockwise) and their tags' height and levels: way 100 + k.
/// Building 1's north wall is 14 m up the slope: 3.1-3.6 m above its base, the second storey's
/// floor (3 m storeys); building 3 is turned 30°.
fn footprints() -> Vec<Footprint> {
    let rect =
        |x: f64, y: f64, w: f64, h: f64| vec![(x, y), (x + w, y), (x + w, y + h), (x, y + h)];
    let (s, c) = 30f64.to_radians().sin_cos();
    let turned: Vec<(f64, f64)> = [(0.0, 0.0), (12.0, 0.0), (12.0, 9.0), (0.0, 9.0)]
        .iter()
        .map(|(x, y)| (60.0 + x * c - y * s, 2.0 + x * s + y * c))
        .collect();
    vec![
        (rect(0.0, 0.0, 16.0, 10.0), "12", "4"),
        (rect(30.0, 0.0, 12.0, 14.0), "15", "5"),
        (rect(0.0, -30.0, 20.0, 8.0), "9", "3"),
        (turned, "12", "4"),
    ]
}

/// The district as an OSM PBF: the buildings, flat roofs, and a street along v = 22.
fn write_pbf(path: &Path) {
    let (x0, y0) = origin();
    let ll = |x: f64, y: f64| UTM32.to_lonlat(x0 + x, y0 + y);
    let mut w = PbfWriter::new(std::fs::File::create(path).unwrap()).unwrap();
    let mut node = 1i64;
    let mut ways = Vec::new();
    for (k, (f, height, levels)) in footprints().into_iter().enumerate() {
        let mut refs = Vec::new();
        for (x, y) in f {
            let (lon, lat) = ll(x, y);
            w.node(node, lon, lat, &[]).unwrap();
            refs.push(node);
            node += 1;
        }
        refs.push(refs[0]);
        ways.push((100 + k as i64, refs, height, levels));
    }
    let mut street = Vec::new();
    for x in [-20.0, 100.0] {
        let (lon, lat) = ll(x, 22.0);
        w.node(node, lon, lat, &[]).unwrap();
        street.push(node);
        node += 1;
    }
    for (id, refs, height, levels) in ways {
        let tags = [
            ("building", "yes"),
            ("height", height),
            ("building:levels", levels),
            ("roof:shape", "flat"),
        ];
        w.way(id, &refs, &tags).unwrap();
    }
    w.way(900, &street, &[("highway", "residential")]).unwrap();
    w.finish().unwrap();
}

/// The hill as a UTM GeoTIFF of 1 m pixels over local (-40..120, -60..60).
fn write_dem(path: &Path) {
    let (x0, y0) = origin();
    let t = GeoTiff::projected(32632, (x0 - 40.0, y0 + 60.0), 1.0, (160, 120), |x, y| {
        hill(x - x0, y - y0)
    });
    t.write(path).unwrap();
}

fn ok(out: &std::process::Output) {
    assert!(
        out.status.success(),
        "citygen failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
}

/// One window or door read from the CityJSON: its building, kind, and its corners (local
/// metres).
struct Opening {
    building: String,
    kind: String,
    corners: Vec<[f64; 3]>,
}

/// What the CityJSON of a run holds that the checks look at.
#[derive(Default)]
struct Read {
    /// Every window and door surface.
    openings: Vec<Opening>,
    /// The floors of the LOD4 rooms.
    floors: Vec<Vec<[f64; 3]>>,
    /// Each balcony's building and its bounds (low and high corners).
    balconies: Vec<(String, [f64; 3], [f64; 3])>,
}

impl Read {
    /// Whether door `o` opens onto a balcony: its sill at a balcony's slab, its bottom corners
    /// along the balcony.
    fn on_balcony(&self, o: &Opening) -> bool {
        let sill = o.corners.iter().map(|p| p[2]).fold(f64::INFINITY, f64::min);
        self.balconies.iter().any(|(b, lo, hi)| {
            *b == o.building
                && (lo[2]..=lo[2] + 0.6).contains(&sill)
                && o.corners.iter().all(|p| {
                    (lo[0] - 0.05..=hi[0] + 0.05).contains(&p[0])
                        && (lo[1] - 0.05..=hi[1] + 0.05).contains(&p[1])
                })
        })
    }
}

/// The windows, doors, room floors and balconies of the CityJSON at `path`.
fn read_back(path: &Path) -> Read {
    let (x0, y0) = origin();
    let j: Value = serde_json::from_slice(&std::fs::read(path).unwrap()).unwrap();
    let (s, t) = (&j["transform"]["scale"], &j["transform"]["translate"]);
    let verts: Vec<[f64; 3]> = j["vertices"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| {
            let c =
                |i: usize| v[i].as_f64().unwrap() * s[i].as_f64().unwrap() + t[i].as_f64().unwrap();
            [c(0) - x0, c(1) - y0, c(2)]
        })
        .collect();
    let ring = |r: &Value| -> Vec<[f64; 3]> {
        r.as_array()
            .unwrap()
            .iter()
            .map(|i| verts[i.as_u64().unwrap() as usize])
            .collect()
    };
    let mut read = Read::default();
    let mut indices = Vec::new();
    fn all(v: &Value, out: &mut Vec<usize>) {
        match v {
            Value::Array(a) => a.iter().for_each(|x| all(x, out)),
            Value::Number(n) => out.push(n.as_u64().unwrap() as usize),
            _ => {}
        }
    }
    for (id, o) in j["CityObjects"].as_object().unwrap() {
        let building = id.split('_').take(3).collect::<Vec<_>>().join("_");
        if o["attributes"]["function"] == "balcony" {
            indices.clear();
            for g in o["geometry"].as_array().into_iter().flatten() {
                all(&g["boundaries"], &mut indices);
            }
            let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
            for &i in &indices {
                for c in 0..3 {
                    lo[c] = lo[c].min(verts[i][c]);
                    hi[c] = hi[c].max(verts[i][c]);
                }
            }
            read.balconies.push((building, lo, hi));
            continue;
        }
        for g in o["geometry"].as_array().into_iter().flatten() {
            let Some(surfaces) = g["semantics"]["surfaces"].as_array() else {
                continue;
            };
            // Solids: one shell; values per face of it.
            let (Some(shells), Some(values)) = (
                g["boundaries"].as_array(),
                g["semantics"]["values"].as_array(),
            ) else {
                continue;
            };
            for (shell, vals) in shells.iter().zip(values) {
                for (face, v) in shell
                    .as_array()
                    .unwrap()
                    .iter()
                    .zip(vals.as_array().unwrap())
                {
                    let Some(k) = v.as_u64() else { continue };
                    let kind = surfaces[k as usize]["type"].as_str().unwrap();
                    let outer = ring(&face[0]);
                    match kind {
                        "Window" | "Door" => read.openings.push(Opening {
                            building: building.clone(),
                            kind: kind.to_string(),
                            corners: outer,
                        }),
                        "FloorSurface" => read.floors.push(outer),
                        _ => {}
                    }
                }
            }
        }
    }
    read
}

/// The lowest and highest terrain along an opening's bottom edge (every 5 cm), and its sill.
fn terrain_under(o: &Opening) -> (f64, f64, f64) {
    let sill = o.corners.iter().map(|p| p[2]).fold(f64::INFINITY, f64::min);
    let bottom: Vec<&[f64; 3]> = o.corners.iter().filter(|p| p[2] < sill + 1e-3).collect();
    let (a, b) = (bottom[0], bottom[bottom.len() - 1]);
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for i in 0..=40 {
        let q = f64::from(i) / 40.0;
        let z = hill(a[0] + (b[0] - a[0]) * q, a[1] + (b[1] - a[1]) * q);
        lo = lo.min(z);
        hi = hi.max(z);
    }
    (lo, hi, sill)
}

#[test]
fn doors_stand_at_the_terrain_and_no_opening_is_under_it() {
    let dir = tempfile::tempdir().unwrap();
    let (pbf, dem) = (dir.path().join("hill.osm.pbf"), dir.path().join("hill.tif"));
    write_pbf(&pbf);
    write_dem(&dem);
    let out = |lod: &str, threads: &str| {
        let (json, gml) = (
            dir.path().join(format!("lod{lod}-{threads}.city.json")),
            dir.path().join(format!("lod{lod}-{threads}.gml")),
        );
        ok(&citygen(&[
            "--osm",
            pbf.to_str().unwrap(),
            "--kb",
            KB,
            "--lod",
            lod,
            "--dem",
            dem.to_str().unwrap(),
            "--cityjson",
            json.to_str().unwrap(),
            "--citygml",
            gml.to_str().unwrap(),
            "--threads",
            threads,
            "--quiet",
        ]));
        (json, gml)
    };
    let (json, gml) = out("3", "1");
    // The same bytes at another thread count.
    let (json3, gml3) = out("3", "3");
    assert!(std::fs::read(&json).unwrap() == std::fs::read(&json3).unwrap());
    assert!(std::fs::read(&gml).unwrap() == std::fs::read(&gml3).unwrap());
    let read = read_back(&json);
    let openings = &read.openings;
    assert!(
        !read.balconies.is_empty(),
        "no balcony to tell balcony doors by"
    );
    let mut doors = std::collections::BTreeMap::<String, usize>::new();
    let mut windows = 0;
    for o in openings {
        let (lo, hi, sill) = terrain_under(o);
        assert!(
            sill >= hi - TOUCH,
            "{}: a {} at {:.3} below the terrain's {hi:.3} under it ({:?})",
            o.building,
            o.kind,
            sill,
            o.corners
        );
        if o.kind == "Door" && !read.on_balcony(o) {
            *doors.entry(o.building.clone()).or_default() += 1;
            assert!(
                sill - lo <= STEP,
                "{}: the door's sill {sill:.3} is {:.3} m above the terrain's lowest {lo:.3} under it",
                o.building,
                sill - lo
            );
            // Building 1's door: on its street (north) wall, a storey up the hill.
            if o.building == "B_way_101" {
                assert!(
                    o.corners.iter().all(|p| (p[1] - 14.0).abs() < 0.01),
                    "building 1's door is not on its north wall: {:?}",
                    o.corners
                );
                let base = hill(30.0, 0.0);
                assert!(
                    sill - base > 3.0,
                    "building 1's door at {sill:.3}, base {base:.3}"
                );
            }
        } else if o.kind == "Window" {
            windows += 1;
        }
    }
    assert!(windows > 40, "{windows} windows");
    let want: Vec<String> = (100..104).map(|k| format!("B_way_{k}")).collect();
    assert_eq!(
        doors.keys().cloned().collect::<Vec<_>>(),
        want,
        "one entrance each: {doors:?}"
    );
    assert!(
        doors.values().all(|&n| n == 1),
        "one entrance each: {doors:?}"
    );
    // The hill side is blank up to the terrain: building 0's north wall keeps no window on
    // its ground storey (the terrain there is 2.2-2.8 m up).
    let buried_side = openings.iter().filter(|o| {
        o.building == "B_way_100"
            && o.corners.iter().all(|p| (p[1] - 10.0).abs() < 0.01)
            && o.corners.iter().any(|p| p[2] < hill(0.0, 0.0) + 2.5)
    });
    assert_eq!(buried_side.count(), 0);
    // The solids as written pass the ISO 19107 checks.
    let (n, defects) = super::iso19107::file_defects(&gml);
    assert!(n >= 4 && defects.is_empty(), "{n} solids: {defects:#?}");
    // LOD4: every floor level.
    let (json4, _) = out("4", "2");
    let floors = read_back(&json4).floors;
    assert!(floors.len() > 20, "{} floors", floors.len());
    for f in &floors {
        let (lo, hi) = f
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), p| {
                (a.min(p[2]), b.max(p[2]))
            });
        assert!(hi - lo < 1e-6, "a floor from {lo} to {hi}");
    }
}

/// Monaco-Ville on a wavy hill at LOD3: the solids valid (ISO 19107).
#[test]
fn monaco_ville_on_a_hill_at_lod3_is_valid() {
    let dir = tempfile::tempdir().unwrap();
    let dem = dir.path().join("hill.tif");
    // 10 m pixels over the rock and 500 m around, rising about 15 % to the south-east with
    // waves: no round grounds, walls with several metres of terrain along them.
    let (w, s) = UTM32.from_lonlat(7.4180, 43.7290);
    let (e, n) = UTM32.from_lonlat(7.4240, 43.7330);
    let (left, top) = ((w - 500.0).round(), (n + 500.0).round());
    let size = |a: f64, b: f64| ((b - a + 1000.0) / 10.0).ceil() as u32;
    GeoTiff::projected(
        32632,
        (left, top),
        10.0,
        (size(w, e), size(s, n)),
        |x, y| {
            0.1 * (x - left) + 0.11 * (top - y) + 4.3 * (x / 37.0).sin() * (y / 53.0).cos() + 20.7
        },
    )
    .write(&dem)
    .unwrap();
    let gml = dir.path().join("mv.gml");
    let report = dir.path().join("report.json");
    let status = std::process::Command::new(env!("CARGO_BIN_EXE_citygen"))
        .current_dir(root())
        .args([
            "--osm",
            "data/monaco/monaco.osm.pbf",
            "--kb",
            KB,
            "--lod",
            "3",
        ])
        .args(["--bbox", "7.4180,43.7290,7.4240,43.7330", "--quiet"])
        .arg("--dem")
        .arg(&dem)
        .arg("--citygml")
        .arg(&gml)
        .arg("--report")
        .arg(&report)
        .output()
        .unwrap();
    ok(&status);
    // The slope rules did something there: openings below the terrain left out.
    let report: Value = serde_json::from_slice(&std::fs::read(&report).unwrap()).unwrap();
    let notes = |what: &str| {
        report["entries"]
            .as_array()
            .unwrap()
            .iter()
            .filter(|e| e["reason"].as_str().unwrap_or("").contains(what))
            .count()
    };
    let (buried, raised) = (
        notes("below the terrain left out"),
        notes("above the terrain"),
    );
    eprintln!("Monaco-Ville on the hill: {buried} buildings lost openings below the terrain, {raised} entrances above it");
    assert!(
        buried > 10,
        "{buried} buildings with openings below the terrain"
    );
    let (n, defects) = super::iso19107::file_defects(&gml);
    assert!(n > 50 && defects.is_empty(), "{n} solids: {defects:#?}");
    // The IFC of Monaco-Ville at LOD3 on a DEM goes through `validate-outputs --geometry` in
    // .ci/run (the sample `monaco-ville-lod3` is drawn on the SRTM crop), where the release
    // build and the validators' parallel groups make it cheap; here it cost 3 min of `cargo test`.
}
