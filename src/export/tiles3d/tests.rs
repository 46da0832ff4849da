use std::collections::BTreeSet;
use std::path::Path;

use glam::{DVec2, DVec3};
use serde_json::Value;

use super::frame::{region_of_box, BuildingMap, EnuFrame, ModelFrame};
use super::tileset::write_tileset;
use super::*;
use crate::crs::{ecef_to_wgs84, wgs84_to_ecef, Crs};
use crate::export::fixtures;
use crate::export::lod3geom::samples;
use crate::model::{Building, Lod, SourceId};

/// Lambert-93, off the metre grid: Toulouse.
const ORIGIN: DVec3 = DVec3::new(574_000.25, 6_279_000.5, 140.0);

fn ctx(lod: Lod) -> OutputContext {
    OutputContext {
        crs: Crs::Lambert93,
        origin: ORIGIN,
        origin_lonlat: (1.44, 43.6),
        lod,
        source_name: "tiles.osm.pbf".into(),
        seed: 5,
        vertical_datum: None,
        terrain: None,
    }
}

/// The LOD4 fixtures with ids of their own, `dx` metres east.
fn buildings(dx: f64) -> Vec<Building> {
    let mut all = fixtures::lod4_all();
    for (i, b) in all.iter_mut().enumerate() {
        b.id = SourceId::Way(7000 + i as i64);
        shift(b, DVec3::new(dx, 0.0, 0.0));
    }
    all
}

/// Moves a building (every point the writers read) by `d`.
fn shift(b: &mut Building, d: DVec3) {
    let d2 = d.truncate();
    let face = |f: &mut crate::model::Face| {
        f.outer.iter_mut().for_each(|p| *p += d);
        f.holes.iter_mut().flatten().for_each(|p| *p += d);
    };
    let poly = |p: &mut crate::geometry::Polygon| {
        p.outer.iter_mut().for_each(|q| *q += d2);
        p.holes.iter_mut().flatten().for_each(|q| *q += d2);
    };
    for part in &mut b.parts {
        poly(&mut part.footprint);
        for w in &mut part.walls {
            w.start += d2;
            w.end += d2;
            face(&mut w.outline);
        }
        part.roof.iter_mut().for_each(face);
        face(&mut part.ground);
        for s in &mut part.interior {
            s.rooms.iter_mut().for_each(|r| poly(&mut r.polygon));
            for w in &mut s.walls {
                w.a += d2;
                w.b += d2;
            }
            if let Some(st) = &mut s.stair {
                poly(&mut st.footprint);
            }
        }
    }
}

fn write(lod: Lod, detail: Detail, bs: &[Building], all: bool) -> (Vec<u8>, ContentInfo) {
    let (mut w, info) = Tiles3dWriter::new(Vec::new(), detail);
    w.begin(&ctx(lod)).unwrap();
    if all {
        w.write_all(bs).unwrap();
    } else {
        bs.iter().for_each(|b| w.write(b).unwrap());
    }
    assert!(info.get().is_none(), "no facts before finish");
    w.finish().unwrap();
    (w.into_inner(), info.get().expect("facts after finish"))
}

// ---- a GLB reader ----

struct Glb {
    json: Value,
    bin: Vec<u8>,
}

fn parse(glb: &[u8]) -> Glb {
    let u = |at: usize| u32::from_le_bytes(glb[at..at + 4].try_into().unwrap()) as usize;
    assert_eq!(&glb[0..4], b"glTF");
    assert_eq!(u(4), 2);
    assert_eq!(u(8), glb.len());
    let jlen = u(12);
    assert_eq!(&glb[16..20], b"JSON");
    assert_eq!(jlen % 4, 0);
    let json: Value = serde_json::from_slice(&glb[20..20 + jlen]).expect("JSON chunk parses");
    let mut bin = Vec::new();
    if glb.len() > 20 + jlen {
        let at = 20 + jlen;
        let blen = u(at);
        assert_eq!(&glb[at + 4..at + 8], b"BIN\0");
        assert_eq!(at + 8 + blen, glb.len());
        bin = glb[at + 8..].to_vec();
        assert!(json["buffers"][0]["byteLength"].as_u64().unwrap() as usize <= blen);
    }
    Glb { json, bin }
}

impl Glb {
    /// The bytes of buffer view `v`, checked to lie in the buffer and be 8-byte aligned.
    fn view(&self, v: u64) -> &[u8] {
        let view = &self.json["bufferViews"][v as usize];
        let off = view["byteOffset"].as_u64().unwrap_or(0) as usize;
        let len = view["byteLength"].as_u64().unwrap() as usize;
        assert_eq!(off % 8, 0, "view {v} aligned");
        assert!(off + len <= self.json["buffers"][0]["byteLength"].as_u64().unwrap() as usize);
        &self.bin[off..off + len]
    }

    /// Accessor `a` as f64 values (components flattened), checked to fit its view.
    fn accessor(&self, a: u64) -> (Vec<f64>, usize) {
        let acc = &self.json["accessors"][a as usize];
        let count = acc["count"].as_u64().unwrap() as usize;
        let comps = match acc["type"].as_str().unwrap() {
            "SCALAR" => 1,
            "VEC2" => 2,
            "VEC3" => 3,
            "VEC4" => 4,
            t => panic!("type {t}"),
        };
        let data = self.view(acc["bufferView"].as_u64().unwrap());
        let ct = acc["componentType"].as_u64().unwrap();
        let size = match ct {
            5126 | 5125 => 4,
            5123 => 2,
            _ => panic!("componentType {ct}"),
        };
        assert!(
            count * comps * size <= data.len(),
            "accessor {a} in its view"
        );
        let norm = acc["normalized"].as_bool().unwrap_or(false);
        let vals = (0..count * comps)
            .map(|i| {
                let b = &data[i * size..(i + 1) * size];
                match ct {
                    5126 => f32::from_le_bytes(b.try_into().unwrap()) as f64,
                    5125 => u32::from_le_bytes(b.try_into().unwrap()) as f64,
                    _ => {
                        let v = u16::from_le_bytes(b.try_into().unwrap()) as f64;
                        if norm {
                            v / 65535.0
                        } else {
                            v
                        }
                    }
                }
            })
            .collect();
        (vals, comps)
    }

    /// Column `key` of the property table as strings.
    fn strings(&self, key: &str) -> Vec<String> {
        let p = &self.json["extensions"]["EXT_structural_metadata"]["propertyTables"][0]
            ["properties"][key];
        assert_eq!(p["stringOffsetType"], "UINT32");
        let data = self.view(p["values"].as_u64().unwrap());
        let offs: Vec<usize> = self
            .view(p["stringOffsets"].as_u64().unwrap())
            .chunks(4)
            .map(|c| u32::from_le_bytes(c.try_into().unwrap()) as usize)
            .collect();
        offs.windows(2)
            .map(|w| String::from_utf8(data[w[0]..w[1]].to_vec()).expect("UTF-8"))
            .collect()
    }

    /// Column `key` of the property table as numbers (`size`-byte components).
    fn numbers(&self, key: &str, size: usize) -> Vec<f64> {
        let p = &self.json["extensions"]["EXT_structural_metadata"]["propertyTables"][0]
            ["properties"][key];
        self.view(p["values"].as_u64().unwrap())
            .chunks(size)
            .map(|c| match size {
                8 => f64::from_le_bytes(c.try_into().unwrap()),
                _ => u32::from_le_bytes(c.try_into().unwrap()) as f64,
            })
            .collect()
    }

    fn primitives(&self) -> Vec<Value> {
        self.json["meshes"][0]["primitives"]
            .as_array()
            .cloned()
            .unwrap_or_default()
    }
}

/// The ECEF point of a content position (glTF y-up, in the content's frame).
fn to_ecef(p: &Placement, q: [f64; 3]) -> DVec3 {
    let m = glam::DMat4::from_cols_array(&p.transform);
    m.transform_point3(DVec3::new(q[0], -q[2], q[1]))
}

fn in_region(r: &[f64; 6], p: DVec3) -> bool {
    let (lon, lat, h) = ecef_to_wgs84(p.to_array());
    let (lon, lat) = (lon.to_radians(), lat.to_radians());
    (r[0]..=r[2]).contains(&lon) && (r[1]..=r[3]).contains(&lat) && (r[4]..=r[5]).contains(&h)
}

// ---- frames ----

#[test]
fn ecef_of_known_points() {
    // The equator at Greenwich: X is the semi-major axis.
    let [x, y, z] = wgs84_to_ecef(0.0, 0.0, 0.0);
    assert!((x - 6_378_137.0).abs() < 1e-6 && y.abs() < 1e-6 && z.abs() < 1e-6);
    // The pole: Z is the semi-minor axis b = a (1 - f).
    let [_, _, z] = wgs84_to_ecef(0.0, 90.0, 0.0);
    assert!((z - 6_356_752.314_245).abs() < 1e-5, "{z}");
    // IOGP Guidance Note 7-2, 2.2.1 (EPSG:4979 to EPSG:4978): 53°48'33.82"N 2°07'46.38"E, 73 m.
    let lat = 53.0 + 48.0 / 60.0 + 33.82 / 3600.0;
    let lon = 2.0 + 7.0 / 60.0 + 46.38 / 3600.0;
    let p = DVec3::from(wgs84_to_ecef(lon, lat, 73.0));
    let expected = DVec3::new(3_771_793.968, 140_253.342, 5_124_304.349);
    assert!(p.distance(expected) < 2e-3, "{p} vs {expected}");
    let (lo, la, h) = ecef_to_wgs84(p.to_array());
    assert!((lo - lon).abs() < 1e-10 && (la - lat).abs() < 1e-10 && (h - 73.0).abs() < 1e-6);
}

#[test]
fn enu_frame_at_the_equator_and_at_monaco() {
    let f = EnuFrame::at(0.0, 0.0, 0.0);
    assert!(f.east.distance(DVec3::Y) < 1e-15);
    assert!(f.north.distance(DVec3::Z) < 1e-15);
    assert!(f.up.distance(DVec3::X) < 1e-15);
    let t = f.transform();
    assert_eq!(t[12..16], [6_378_137.0, 0.0, 0.0, 1.0]);

    // Monaco, the Prince's Palace, 60 m.
    let (lon, lat, h) = (7.4203, 43.7314, 60.0);
    let f = EnuFrame::at(lon, lat, h);
    for (a, b) in [(f.east, f.north), (f.north, f.up), (f.up, f.east)] {
        assert!(a.dot(b).abs() < 1e-15 && (a.length() - 1.0).abs() < 1e-15);
    }
    assert!(f.east.cross(f.north).distance(f.up) < 1e-15, "right-handed");
    // 100 m up the frame is 100 m higher at the same place; 100 m north is north.
    let (lo, la, hh) = ecef_to_wgs84(f.to_ecef(DVec3::new(0.0, 0.0, 100.0)).to_array());
    assert!((lo - lon).abs() < 1e-12 && (la - lat).abs() < 1e-12 && (hh - 160.0).abs() < 1e-6);
    let (lo, la, _) = ecef_to_wgs84(f.to_ecef(DVec3::new(0.0, 100.0, 0.0)).to_array());
    assert!((lo - lon).abs() < 1e-12 && la > lat);
    // The transform is the frame.
    let m = glam::DMat4::from_cols_array(&f.transform());
    let q = DVec3::new(12.0, -34.0, 5.0);
    assert!(m.transform_point3(q).distance(f.to_ecef(q)) < 1e-8);
    assert!(f.to_enu(f.to_ecef(q)).distance(q) < 1e-8);
}

#[test]
fn a_building_map_is_exact_at_its_anchor_and_within_micrometres_nearby() {
    let model = ModelFrame::new(&ctx(Lod::Lod2));
    let anchor = DVec3::new(-300.0, 420.0, 12.0);
    let map = BuildingMap::at(&model, anchor);
    assert!(map.anchor_ecef.distance(model.to_ecef(anchor)) < 1e-9);
    for r in [50.0, 150.0, 400.0] {
        let (mut worst, mut affine): (f64, f64) = (0.0, 0.0);
        for k in 0..16 {
            let a = f64::from(k) * std::f64::consts::PI / 8.0;
            let p = anchor + DVec3::new(r * a.cos(), r * a.sin(), 40.0);
            let exact = model.to_ecef(p);
            worst = worst.max((map.anchor_ecef + map.offset(p)).distance(exact));
            affine = affine.max((map.anchor_ecef + map.affine_offset(p)).distance(exact));
        }
        eprintln!("{r} m: second order {worst:e} m, first order {affine:e} m");
        assert!(worst < 1e-5, "{worst} m at {r} m from the anchor");
        // The curvature a first-order map misses: about r^2 / R.
        assert!(affine > 0.5 * r * r / 6.4e6, "{affine} m at {r} m");
    }
    // A normal stays a unit vector, and up stays (nearly) the ellipsoid's up.
    let n = map.normal(DVec3::Z);
    let (lon, lat, _) = model.to_wgs84(anchor);
    assert!((n.length() - 1.0).abs() < 1e-12);
    assert!(n.dot(EnuFrame::at(lon, lat, 0.0).up) > 1.0 - 1e-9);
}

#[test]
fn a_region_holds_its_box() {
    let f = EnuFrame::at(7.42, 43.73, 0.0);
    let (lo, hi) = (
        DVec3::new(-400.0, -250.0, -3.0),
        DVec3::new(350.0, 500.0, 80.0),
    );
    let r = region_of_box(&f, lo, hi);
    for i in 0..=10 {
        for j in 0..=10 {
            for z in [lo.z, hi.z] {
                let t = DVec2::new(f64::from(i), f64::from(j)) / 10.0;
                let p = DVec3::new(lo.x + (hi.x - lo.x) * t.x, lo.y + (hi.y - lo.y) * t.y, z);
                assert!(in_region(&r, f.to_ecef(p)), "{p}");
            }
        }
    }
    // Not much more: the margin is 5 cm, the curvature over 500 m about 2 cm.
    assert!((r[5] - r[4]) < (hi.z - lo.z) + 0.2, "{r:?}");
}

// ---- contents ----

#[test]
fn full_content_structure_features_and_metadata() {
    let bs = buildings(0.0);
    for lod in [Lod::Lod3, Lod::Lod4] {
        let (glb, info) = write(lod, Detail::Full, &bs, true);
        assert_eq!(info.detail, Detail::Full);
        assert_eq!(info.buildings, bs.len());
        assert_eq!(info.bytes, glb.len() as u64);
        let g = parse(&glb);
        let used: Vec<&str> = g.json["extensionsUsed"]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_str().unwrap())
            .collect();
        assert_eq!(used, ["EXT_mesh_features", "EXT_structural_metadata"]);
        assert!(g.json.get("extensionsRequired").is_none());
        let table = &g.json["extensions"]["EXT_structural_metadata"]["propertyTables"][0];
        assert_eq!(table["class"], "building");
        assert_eq!(table["count"].as_u64().unwrap() as usize, bs.len());
        let schema = &g.json["extensions"]["EXT_structural_metadata"]["schema"];
        for key in table["properties"].as_object().unwrap().keys() {
            assert!(
                schema["classes"]["building"]["properties"]
                    .get(key)
                    .is_some(),
                "{key}"
            );
        }

        // Strings and numbers decode to the buildings' values, in write order.
        let ids: Vec<String> = bs.iter().map(|b| b.id.to_string()).collect();
        assert_eq!(g.strings("id"), ids);
        assert_eq!(g.strings("name")[0], "Maison \"LOD4\" & co");
        assert_eq!(
            g.strings("zone"),
            bs.iter().map(|b| b.zone.clone()).collect::<Vec<_>>()
        );
        assert_eq!(
            g.strings("roofShape"),
            bs.iter()
                .map(|b| b.roof_shape.osm_name().to_owned())
                .collect::<Vec<_>>()
        );
        let heights = g.numbers("height", 8);
        let storeys = g.numbers("storeys", 4);
        let bases = g.numbers("baseHeight", 8);
        for (i, b) in bs.iter().enumerate() {
            assert_eq!(heights[i], b.measured_height);
            assert_eq!(storeys[i], f64::from(b.storeys_above_ground));
            assert_eq!(bases[i], b.base_z + ORIGIN.z);
        }

        // Every primitive: accessors in range, min/max exact, normals unit, indices in range,
        // feature ids valid and counted.
        let placement = info.placement.clone().expect("something drawn");
        let mut features = BTreeSet::new();
        let mut triangles = 0;
        let prims = g.primitives();
        assert!(!prims.is_empty() && prims.len() <= 4);
        for p in &prims {
            let a = &p["attributes"];
            let (pos, _) = g.accessor(a["POSITION"].as_u64().unwrap());
            let (nrm, _) = g.accessor(a["NORMAL"].as_u64().unwrap());
            let (col, comps) = g.accessor(a["COLOR_0"].as_u64().unwrap());
            let (fid, _) = g.accessor(a["_FEATURE_ID_0"].as_u64().unwrap());
            let (idx, _) = g.accessor(p["indices"].as_u64().unwrap());
            let n = fid.len();
            assert_eq!((pos.len(), nrm.len(), col.len()), (3 * n, 3 * n, comps * n));
            let acc = &g.json["accessors"][a["POSITION"].as_u64().unwrap() as usize];
            for k in 0..3 {
                let lo = pos
                    .iter()
                    .skip(k)
                    .step_by(3)
                    .fold(f64::INFINITY, |m, &v| m.min(v));
                let hi = pos
                    .iter()
                    .skip(k)
                    .step_by(3)
                    .fold(f64::NEG_INFINITY, |m, &v| m.max(v));
                assert_eq!(acc["min"][k].as_f64().unwrap() as f32, lo as f32);
                assert_eq!(acc["max"][k].as_f64().unwrap() as f32, hi as f32);
            }
            for c in nrm.chunks(3) {
                let l = (c[0] * c[0] + c[1] * c[1] + c[2] * c[2]).sqrt();
                assert!((l - 1.0).abs() < 1e-5, "normal length {l}");
            }
            assert!(idx.iter().all(|&i| (i as usize) < n));
            assert_eq!(idx.len() % 3, 0);
            triangles += idx.len() as u64 / 3;
            let ids: BTreeSet<u64> = fid.iter().map(|&f| f as u64).collect();
            assert!(fid
                .iter()
                .all(|&f| f.fract() == 0.0 && (f as usize) < bs.len()));
            let fc = &p["extensions"]["EXT_mesh_features"]["featureIds"][0];
            assert_eq!(fc["featureCount"].as_u64().unwrap() as usize, ids.len());
            assert_eq!(fc["attribute"], 0);
            assert_eq!(fc["propertyTable"], 0);
            features.extend(ids);
            // Every position lies in the content's region.
            for q in pos.chunks(3) {
                let e = to_ecef(&placement, [q[0], q[1], q[2]]);
                assert!(in_region(&placement.region, e), "{q:?} outside the region");
            }
        }
        assert_eq!(triangles, info.triangles);
        // The walls' colour is there, linear, per vertex.
        let (col, _) = g.accessor(prims[0]["attributes"]["COLOR_0"].as_u64().unwrap());
        let wall = bs[1].parts[0].wall_color;
        let want = [wall.r, wall.g, wall.b].map(|c| f64::from(crate::color::srgb_to_linear(c)));
        assert!(
            col.chunks(4)
                .any(|c| (0..3).all(|k| (c[k] - want[k]).abs() < 1e-4) && c[3] == 1.0),
            "wall colour {want:?} not among the vertex colours"
        );
        assert_eq!(features.len(), bs.len(), "every building drawn");
    }
}

#[test]
fn a_footprint_corner_lands_where_the_crs_puts_it() {
    let bs = buildings(0.0);
    let (glb, info) = write(Lod::Lod2, Detail::Blocks, &bs, false);
    let g = parse(&glb);
    let placement = info.placement.unwrap();
    let model = ModelFrame::new(&ctx(Lod::Lod2));
    let part = &bs[0].parts[0];
    let corner = part.footprint.outer[0].extend(part.top_z);
    let want = model.to_ecef(corner);
    let mut best = f64::INFINITY;
    for p in g.primitives() {
        let (pos, _) = g.accessor(p["attributes"]["POSITION"].as_u64().unwrap());
        for q in pos.chunks(3) {
            best = best.min(to_ecef(&placement, [q[0], q[1], q[2]]).distance(want));
        }
    }
    assert!(best < 2e-3, "nearest vertex {best} m from the corner");
}

#[test]
fn blocks_are_few_triangles_with_the_tiles_frame() {
    let bs = buildings(0.0);
    let (_, full) = write(Lod::Lod3, Detail::Full, &bs, true);
    let (glb, blocks) = write(Lod::Lod3, Detail::Blocks, &bs, true);
    assert!(
        blocks.triangles * 5 < full.triangles,
        "{} vs {}",
        blocks.triangles,
        full.triangles
    );
    let (fp, bp) = (full.placement.unwrap(), blocks.placement.unwrap());
    assert_eq!(fp.transform, bp.transform, "one frame per tile");
    assert_eq!(full.blocks_error, blocks.blocks_error);
    assert!(blocks.blocks_error >= 0.5);
    // The gabled sample's roof rises above its eaves: the error is at least that.
    let roof = bs
        .iter()
        .flat_map(|b| &b.parts)
        .map(|p| p.top_z - p.eave_z)
        .fold(0.0, f64::max);
    assert!(
        blocks.blocks_error >= roof && roof > 1.0,
        "{}",
        blocks.blocks_error
    );
    let g = parse(&glb);
    assert_eq!(
        g.numbers("height", 8).len(),
        bs.len(),
        "Blocks have the features too"
    );
}

#[test]
fn output_is_deterministic_and_write_all_is_write() {
    let bs = buildings(0.0);
    for detail in [Detail::Full, Detail::Blocks] {
        let one = write(Lod::Lod4, detail, &bs, false);
        let all = write(Lod::Lod4, detail, &bs, true);
        assert!(one == all, "{detail:?}: write_all differs from write");
        assert!(write(Lod::Lod4, detail, &bs, true) == all);
    }
}

/// A [`Tiles3dWriter::pair`]'s two contents of `bs` (by `write_all` or by `write`), and
/// their facts.
fn write_pair(c: &OutputContext, bs: &[Building], all: bool) -> [(Vec<u8>, ContentInfo); 2] {
    let [(mut full, full_info), (mut blocks, blocks_info)] =
        Tiles3dWriter::pair(Vec::new(), Vec::new());
    for w in [&mut full, &mut blocks] {
        w.begin(c).unwrap();
        if all {
            w.write_all(bs).unwrap();
        } else {
            bs.iter().for_each(|b| w.write(b).unwrap());
        }
    }
    full.finish().unwrap();
    blocks.finish().unwrap();
    [
        (full.into_inner(), full_info.get().unwrap()),
        (blocks.into_inner(), blocks_info.get().unwrap()),
    ]
}

#[test]
fn a_pair_writes_the_bytes_of_two_writers() {
    let bs = buildings(0.0);
    for lod in [Lod::Lod2, Lod::Lod4] {
        for all in [true, false] {
            let [full, blocks] = write_pair(&ctx(lod), &bs, all);
            assert!(full == write(lod, Detail::Full, &bs, all), "{lod:?} Full");
            assert!(
                blocks == write(lod, Detail::Blocks, &bs, all),
                "{lod:?} Blocks"
            );
        }
    }
    // Buildings over several parallel chunks, orthometric heights (a lift per building).
    let (mut c, tiles) = monaco(Lod::Lod2, 150);
    c.vertical_datum = Some(crate::model::VerticalDatum::Orthometric {
        epsg: Some(5773),
        name: "EGM96 height".into(),
    });
    let town: Vec<Building> = tiles.into_iter().flat_map(|(_, bs)| bs).collect();
    // Monaco-Ville four times over: more buildings than one parallel chunk.
    let bs: Vec<Building> = (0..4).flat_map(|_| town.iter().cloned()).collect();
    assert!(bs.len() > PARALLEL_CHUNK, "{} buildings", bs.len());
    let [full, blocks] = write_pair(&c, &bs, true);
    assert!(full == write_in(&c, Detail::Full, &bs), "Monaco Full");
    assert!(blocks == write_in(&c, Detail::Blocks, &bs), "Monaco Blocks");
    // A bad building: both refuse it, and both keep the buildings before it.
    let mut bad = samples::house();
    bad.measured_height = f64::NAN;
    let [(mut full, full_info), (mut blocks, blocks_info)] =
        Tiles3dWriter::pair(Vec::new(), Vec::new());
    for w in [&mut full, &mut blocks] {
        w.begin(&ctx(Lod::Lod2)).unwrap();
        let e = w.write_all(&[samples::house(), bad.clone()]).unwrap_err();
        assert!(e.to_string().contains("not finite"), "{e}");
        assert!(w.write(&bad).is_err());
    }
    full.finish().unwrap();
    blocks.finish().unwrap();
    assert_eq!(full_info.get().unwrap().buildings, 1);
    assert_eq!(blocks_info.get().unwrap().buildings, 1);
}

#[test]
fn an_empty_tile_is_an_empty_scene_and_has_no_placement() {
    let (glb, info) = write(Lod::Lod2, Detail::Full, &[], true);
    let g = parse(&glb);
    assert_eq!(g.json["asset"]["version"], "2.0");
    assert!(g.json.get("meshes").is_none() && g.bin.is_empty());
    assert_eq!(
        (info.buildings, info.triangles, info.placement),
        (0, 0, None)
    );
}

#[test]
fn call_order_and_bad_buildings_are_errors() {
    let (mut w, info) = Tiles3dWriter::new(Vec::new(), Detail::Full);
    assert!(w.write(&samples::house()).is_err());
    assert!(w.finish().is_err());
    w.begin(&ctx(Lod::Lod2)).unwrap();
    assert!(w.begin(&ctx(Lod::Lod2)).is_err());
    let mut bad = samples::house();
    bad.measured_height = f64::NAN;
    let e = w.write_all(&[samples::house(), bad]).unwrap_err();
    assert!(e.to_string().contains("not finite"), "{e}");
    w.finish().unwrap();
    assert_eq!(
        info.get().unwrap().buildings,
        1,
        "the building before the bad one"
    );
    assert!(w.finish().is_err());
    assert!(w.write(&samples::house()).is_err());
    let (mut geo, _) = Tiles3dWriter::new(Vec::new(), Detail::Full);
    let e = geo
        .begin(&OutputContext {
            crs: Crs::Wgs84,
            ..ctx(Lod::Lod2)
        })
        .unwrap_err();
    assert!(e.to_string().contains("projected"), "{e}");
}

#[test]
fn content_info_round_trips_through_json() {
    let (_, info) = write(Lod::Lod2, Detail::Blocks, &buildings(0.0), true);
    let text = serde_json::to_string(&info).unwrap();
    assert!(text.contains("\"detail\":\"blocks\"") && text.contains("\"box\":"));
    let back: ContentInfo = serde_json::from_str(&text).unwrap();
    assert_eq!(back, info);
}

// ---- tilesets ----

/// Tiles of 100 m: the fixtures written into `cells`, each its own pair of contents.
fn entries(cells: &[(i64, i64)]) -> Vec<TileEntry> {
    cells
        .iter()
        .map(|&(x, y)| {
            let mut bs = buildings(0.0);
            for b in &mut bs {
                shift(b, DVec3::new(100.0 * x as f64, 100.0 * y as f64, 0.0));
            }
            let (_, full) = write(Lod::Lod3, Detail::Full, &bs, true);
            let (_, blocks) = write(Lod::Lod3, Detail::Blocks, &bs, true);
            TileEntry {
                terrain: None,
                cell: (x, y),
                full: TileContent {
                    uri: format!("content/{x}_{y}.glb"),
                    info: full,
                },
                blocks: TileContent {
                    uri: format!("content/{x}_{y}-blocks.glb"),
                    info: blocks,
                },
            }
        })
        .collect()
}

fn region(v: &Value) -> [f64; 6] {
    let r = v["boundingVolume"]["region"].as_array().unwrap();
    std::array::from_fn(|i| r[i].as_f64().unwrap())
}

/// Walks the tree: children inside parents, errors decreasing; returns the contents' URIs.
fn walk(t: &Value, parent: Option<([f64; 6], f64)>, uris: &mut Vec<String>) {
    let r = region(t);
    let e = t["geometricError"].as_f64().unwrap();
    assert!(r[0] <= r[2] && r[1] <= r[3] && r[4] <= r[5]);
    if let Some((pr, pe)) = parent {
        assert!(
            pr[0] <= r[0] && pr[1] <= r[1] && pr[2] >= r[2] && pr[3] >= r[3],
            "child {r:?} not in parent {pr:?}"
        );
        assert!(pr[4] <= r[4] && pr[5] >= r[5]);
        assert!(e < pe, "error {e} not below the parent's {pe}");
    }
    if let Some(c) = t.get("content") {
        let cr = region(c);
        assert!(r[0] <= cr[0] && r[1] <= cr[1] && r[2] >= cr[2] && r[3] >= cr[3]);
        uris.push(c["uri"].as_str().unwrap().to_owned());
    }
    for c in t["children"].as_array().into_iter().flatten() {
        walk(c, Some((r, e)), uris);
    }
}

#[test]
fn tileset_is_a_quadtree_with_nested_volumes_and_decreasing_errors() {
    let cells = [(0, 0), (1, 0), (0, 1), (3, 2), (-1, 0)];
    let tiles = entries(&cells);
    let text = tileset_json(&tiles).unwrap();
    let doc: Value = serde_json::from_str(&text).unwrap();
    assert_eq!(doc["asset"]["version"], "1.1");
    assert_eq!(doc["root"]["refine"], "REPLACE");
    let top = doc["geometricError"].as_f64().unwrap();
    assert!(top >= doc["root"]["geometricError"].as_f64().unwrap());
    let mut uris = Vec::new();
    walk(&doc["root"], None, &mut uris);
    assert_eq!(uris.len(), 2 * cells.len());
    for t in &tiles {
        assert!(uris.contains(&t.full.uri) && uris.contains(&t.blocks.uri));
    }
    // A grid tile: Blocks with the transform, one Full child without, refined by REPLACE.
    fn find<'a>(t: &'a Value, uri: &str) -> Option<&'a Value> {
        if t["content"]["uri"] == uri {
            return Some(t);
        }
        t["children"]
            .as_array()
            .into_iter()
            .flatten()
            .find_map(|c| find(c, uri))
    }
    let node = find(&doc["root"], "content/3_2-blocks.glb").unwrap();
    assert_eq!(node["refine"], "REPLACE");
    assert_eq!(node["transform"].as_array().unwrap().len(), 16);
    let child = &node["children"][0];
    assert_eq!(child["content"]["uri"], "content/3_2.glb");
    assert!(child.get("transform").is_none());
    assert_eq!(child["geometricError"].as_f64().unwrap(), 0.0);
    // The same text from entries read back from JSON (a shard's manifest).
    let json = serde_json::to_string(&tiles).unwrap();
    let back: Vec<TileEntry> = serde_json::from_str(&json).unwrap();
    assert_eq!(tileset_json(&back).unwrap(), text);
    // Deterministic whatever the order of the entries.
    let mut reversed = tiles.clone();
    reversed.reverse();
    assert_eq!(tileset_json(&reversed).unwrap(), text);
}

#[test]
fn tileset_of_one_tile_refuses_duplicates_and_skips_empty_tiles() {
    let tiles = entries(&[(5, 5)]);
    let doc: Value = serde_json::from_str(&tileset_json(&tiles).unwrap()).unwrap();
    assert_eq!(doc["root"]["content"]["uri"], "content/5_5-blocks.glb");
    assert!(
        doc["geometricError"].as_f64().unwrap() > 10.0,
        "the root's size"
    );
    assert_eq!(TileEntry::cell_of((-300, 4_842_900), 150), (-2, 32_286));
    assert_eq!(TileEntry::cell_of((-301, 0), 150), (-3, 0));
    let twice = [tiles[0].clone(), tiles[0].clone()];
    let e = tileset_json(&twice).unwrap_err();
    assert!(e.to_string().contains("twice"), "{e}");
    let (_, empty) = write(Lod::Lod2, Detail::Full, &[], true);
    let mut with_empty = tiles.clone();
    with_empty.push(TileEntry {
        terrain: None,
        cell: (9, 9),
        full: TileContent {
            uri: "content/9_9.glb".into(),
            info: empty.clone(),
        },
        blocks: TileContent {
            uri: "content/9_9-blocks.glb".into(),
            info: ContentInfo {
                detail: Detail::Blocks,
                ..empty.clone()
            },
        },
    });
    assert_eq!(
        tileset_json(&with_empty).unwrap(),
        tileset_json(&tiles).unwrap()
    );
    assert!(tileset_json(&with_empty[1..]).is_err(), "nothing to draw");
}

#[test]
fn contents_with_different_frames_get_a_relative_transform() {
    let mut tiles = entries(&[(0, 0)]);
    let other = entries(&[(2, 0)]);
    // Blocks of cell (0, 0) with the Full of cell (2, 0): frames 200 m apart.
    tiles[0].full = other[0].full.clone();
    let doc: Value = serde_json::from_str(&tileset_json(&tiles).unwrap()).unwrap();
    let parent = glam::DMat4::from_cols_array(&std::array::from_fn(|i| {
        doc["root"]["transform"][i].as_f64().unwrap()
    }));
    let rel = glam::DMat4::from_cols_array(&std::array::from_fn(|i| {
        doc["root"]["children"][0]["transform"][i].as_f64().unwrap()
    }));
    let want =
        glam::DMat4::from_cols_array(&other[0].full.info.placement.as_ref().unwrap().transform);
    let q = DVec3::new(10.0, 20.0, 30.0);
    assert!(
        (parent * rel)
            .transform_point3(q)
            .distance(want.transform_point3(q))
            < 1e-6
    );
}

#[test]
fn write_tileset_is_atomic_and_ends_with_a_newline() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("tileset.json");
    let tiles = entries(&[(0, 0)]);
    write_tileset(&path, &tiles).unwrap();
    let text = std::fs::read_to_string(&path).unwrap();
    assert!(text.ends_with("}\n"));
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
    assert!(write_tileset(&path, &[]).is_err());
    assert_eq!(
        std::fs::read_to_string(&path).unwrap(),
        text,
        "kept on error"
    );
}

// ---- Monaco, through the reference validator ----

/// Monaco-Ville's buildings at `lod` and the run's context, grouped into tiles of `size` m.
fn monaco(lod: Lod, size: u32) -> (OutputContext, Vec<(crate::prepare::Tile, Vec<Building>)>) {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut report = crate::report::Report::default();
    let read =
        crate::input::osm::read_osm(&root.join("data/monaco/monaco.osm.pbf"), &mut report).unwrap();
    let mut site = crate::prepare::prepare(read.footprints, None, None, &mut report);
    crate::prepare::assign_fronts(&mut site, &read.streets, None);
    crate::prepare::retain_in_bbox(&mut site, [7.4180, 43.7290, 7.4240, 43.7330], &mut report)
        .unwrap();
    let tiles = crate::prepare::group_into_tiles(&mut site, size);
    let (kb, _) = crate::kb::KnowledgeBase::load(&root.join("knowledge_base/kb.xml")).unwrap();
    let caps = crate::grammar::Caps {
        facades: lod >= Lod::Lod3,
        ..Default::default()
    };
    let generator = crate::derive::Generator::new(kb, crate::derive::Rules::Kb, lod, 0, caps);
    let out = tiles
        .into_iter()
        .map(|t| {
            let bs = site.lots[t.range.clone()]
                .iter()
                .filter_map(|lot| generator.generate(lot).ok().map(|(b, _)| b))
                .collect();
            (t, bs)
        })
        .collect();
    let ctx = OutputContext {
        crs: site.crs,
        origin: DVec3::new(site.origin.x, site.origin.y, 0.0),
        origin_lonlat: site.origin_lonlat,
        lod,
        source_name: "monaco".into(),
        seed: 0,
        vertical_datum: None,
        terrain: None,
    };
    (ctx, out)
}

/// Writes a tileset of Monaco-Ville at `lod` into `dir` as a run would: per tile
/// `content/{suffix}.glb` and `content/{suffix}-blocks.glb`, then `tileset.json`.
/// Heights are in `datum` (orthometric: lifted by the geoid) when it is given.
fn write_monaco_in(
    dir: &Path,
    lod: Lod,
    size: u32,
    datum: Option<crate::model::VerticalDatum>,
) -> Vec<TileEntry> {
    let (mut ctx, tiles) = monaco(lod, size);
    ctx.vertical_datum = datum;
    let mut entries = Vec::new();
    for (t, bs) in &tiles {
        let content = |detail: Detail, name: String| {
            let (mut w, info) = Tiles3dWriter::new(Vec::new(), detail);
            w.begin(&ctx).unwrap();
            w.write_all(bs).unwrap();
            w.finish().unwrap();
            std::fs::create_dir_all(dir.join("content")).unwrap();
            std::fs::write(dir.join(&name), w.into_inner()).unwrap();
            TileContent {
                uri: name,
                info: info.get().unwrap(),
            }
        };
        let s = t.suffix();
        entries.push(TileEntry {
            terrain: None,
            cell: TileEntry::cell_of(t.corner, size),
            full: content(Detail::Full, format!("content/{s}.glb")),
            blocks: content(Detail::Blocks, format!("content/{s}-blocks.glb")),
        });
    }
    write_tileset(&dir.join("tileset.json"), &entries).unwrap();
    entries
}

/// Runs `validate-outputs` on Monaco-Ville tilesets at LOD2 and LOD3 (tiles of 150 m), and at
/// LOD2 with EGM96 heights (lifted by the geoid): no error, no warning but gltf-validator's
/// note that it does not know the two metadata extensions. `CITYGEN_TILES3D_KEEP=DIR` keeps
/// them in DIR/lod2, DIR/lod3, DIR/lod2-egm96.
#[test]
fn monaco_tilesets_pass_the_reference_validator() {
    let Some(validator) = fixtures::validator("3D Tiles (Monaco-Ville LOD2, LOD3)") else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let keep = std::env::var_os("CITYGEN_TILES3D_KEEP").map(std::path::PathBuf::from);
    let out = keep.as_deref().unwrap_or(dir.path());
    let egm96 = crate::model::VerticalDatum::Orthometric {
        epsg: Some(5773),
        name: "EGM96 height".into(),
    };
    for (lod, datum) in [
        (Lod::Lod2, None),
        (Lod::Lod3, None),
        (Lod::Lod2, Some(egm96)),
    ] {
        let lifted = datum.is_some();
        let sub = out.join(format!(
            "lod{}{}",
            lod.number(),
            if lifted { "-egm96" } else { "" }
        ));
        let entries = write_monaco_in(&sub, lod, 150, datum);
        // Monaco's buildings stand on z = 0; with EGM96 heights they are lifted by N there
        // (48.7 m): every content's lowest height is N within a few decimetres.
        for e in &entries {
            let low = e
                .full
                .info
                .placement
                .as_ref()
                .map_or(f64::NAN, |p| p.region[4]);
            let want = if lifted { 48.7 } else { 0.0 };
            assert!((low - want).abs() < 0.5, "{}: lowest {low}", e.full.uri);
        }
        let buildings: usize = entries.iter().map(|e| e.full.info.buildings).sum();
        assert!(
            entries.len() >= 4 && buildings > 50,
            "{} tiles, {buildings} buildings",
            entries.len()
        );
        let run = std::process::Command::new(&validator)
            .arg(sub.join("tileset.json"))
            .output()
            .unwrap();
        let text = String::from_utf8_lossy(&run.stdout);
        eprintln!("{text}");
        assert!(
            run.status.success() && text.contains("1 passed, 0 failed"),
            "{text}\n{}",
            String::from_utf8_lossy(&run.stderr)
        );
        assert!(!text.contains("errors="), "{text}");
        let warnings: Vec<&str> = text
            .lines()
            .filter(|l| l.contains("warning") && !l.contains("is not supported by gltf-validator"))
            .filter(|l| !l.contains("warnings="))
            .collect();
        assert!(warnings.is_empty(), "{warnings:?}");
    }
}

/// Provenance is in the property table: sources as strings, uncertainties as FLOAT32 with the
/// schema's noData (-1) where unknown.
#[test]
fn provenance_is_in_the_property_table() {
    let mut bs = buildings(0.0);
    bs[0].provenance = crate::export::fixtures::model_provenance();
    bs[1].provenance = crate::model::Provenance::default();
    let (glb, _) = write(Lod::Lod2, Detail::Full, &bs, true);
    let g = parse(&glb);
    let schema = &g.json["extensions"]["EXT_structural_metadata"]["schema"]["classes"]["building"]
        ["properties"];
    for key in ["storeysSource", "heightSource", "roofSource"] {
        assert_eq!(schema[key]["type"], "STRING", "{key}");
    }
    let floats = |key: &str| -> Vec<f32> {
        assert_eq!(schema[key]["componentType"], "FLOAT32", "{key}");
        assert_eq!(schema[key]["noData"].as_f64(), Some(-1.0), "{key}");
        let p = &g.json["extensions"]["EXT_structural_metadata"]["propertyTables"][0]["properties"]
            [key];
        g.view(p["values"].as_u64().unwrap())
            .chunks(4)
            .map(|c| f32::from_le_bytes(c.try_into().unwrap()))
            .collect()
    };
    assert_eq!(g.strings("storeysSource")[..2], ["model", "kb"]);
    assert_eq!(g.strings("heightSource")[..2], ["model", "kb"]);
    assert_eq!(g.strings("roofSource")[..2], ["kb", "kb"]);
    assert_eq!(floats("storeysError")[..2], [0.75, -1.0]);
    assert_eq!(floats("heightError")[..2], [2.25, -1.0]);
    assert_eq!(floats("roofProbability")[..2], [0.8, -1.0]);
}

// ---- heights in a vertical datum (issue 44) ----

/// A tile's content written in `c`.
fn write_in(c: &OutputContext, detail: Detail, bs: &[Building]) -> (Vec<u8>, ContentInfo) {
    let (mut w, info) = Tiles3dWriter::new(Vec::new(), detail);
    w.begin(c).unwrap();
    w.write_all(bs).unwrap();
    w.finish().unwrap();
    (w.into_inner(), info.get().expect("facts after finish"))
}

/// The ellipsoidal heights of every position of a content.
fn heights(glb: &[u8], placement: &Placement) -> Vec<f64> {
    let g = parse(glb);
    let mut hs = Vec::new();
    for p in g.primitives() {
        let (pos, _) = g.accessor(p["attributes"]["POSITION"].as_u64().unwrap());
        for q in pos.chunks(3) {
            let (_, _, h) = ecef_to_wgs84(to_ecef(placement, [q[0], q[1], q[2]]).to_array());
            hs.push(h);
        }
    }
    hs
}

/// With a vertical datum the model's heights are orthometric (H, above the geoid) and the
/// contents are at h = H + N: at NGA's published EGM96 test points (N from -31.6 m in the
/// eastern US to +50.1 m in Spain, and near 0 in Brazil) the lowest base is at the origin's
/// H plus that N within 0.1 m (the acceptance asks 1 m), the regions hold every position, and
/// the `baseHeight` column says the same. Without a datum, heights are the model's as before.
#[test]
fn orthometric_heights_become_ellipsoidal_with_the_geoid() {
    // (latitude, longitude, N) from NGA's OUTINTPT.DAT, and the point's UTM zone.
    let places = [
        (38.628_155, -90.220_845, -31.628, 15, true),
        (38.625_473, -0.000_500, 50.066, 30, true),
        (-23.617_446, 133.874_712, 15.871, 53, false),
        (-14.621_217, -54.978_886, -2.969, 21, false),
    ];
    let bs = buildings(0.0);
    let lowest = bs
        .iter()
        .flat_map(|b| b.parts.iter().map(|p| p.base_z))
        .fold(f64::INFINITY, f64::min);
    for (lat, lon, n, zone, north) in places {
        let crs = Crs::Utm { zone, north };
        let (x, y) = crs.from_lonlat(lon, lat);
        let mut c = ctx(Lod::Lod4);
        c.crs = crs;
        c.origin = DVec3::new(x.round(), y.round(), 230.0);
        c.origin_lonlat = (lon, lat);
        let (plain_glb, plain) = write_in(&c, Detail::Full, &bs);
        c.vertical_datum = Some(crate::model::VerticalDatum::Orthometric {
            epsg: Some(5773),
            name: "EGM96 height".into(),
        });
        for detail in [Detail::Full, Detail::Blocks] {
            let (glb, info) = write_in(&c, detail, &bs);
            let placement = info.placement.unwrap();
            let hs = heights(&glb, &placement);
            let low = hs.iter().copied().fold(f64::INFINITY, f64::min);
            let high = hs.iter().copied().fold(f64::NEG_INFINITY, f64::max);
            let want = 230.0 + lowest + n;
            assert!(
                (low - want).abs() < 0.1,
                "({lat}, {lon}) {detail:?}: lowest base at {low}, H + N = {want}"
            );
            let r = placement.region;
            assert!(
                r[4] <= low && high <= r[5],
                "region {r:?} holds {low}..{high}"
            );
            assert!(r[4] > low - 0.1 && r[5] < high + 0.1, "and is tight");
            let base = parse(&glb).numbers("baseHeight", 8);
            for (b, got) in bs.iter().zip(&base) {
                let want = 230.0 + b.base_z + n;
                assert!((got - want).abs() < 0.1, "baseHeight {got} vs {want}");
            }
        }
        // Without the datum: the model's heights, as ellipsoidal ones.
        let low = heights(&plain_glb, plain.placement.as_ref().unwrap())
            .into_iter()
            .fold(f64::INFINITY, f64::min);
        assert!((low - (230.0 + lowest)).abs() < 0.01, "{low}");
    }
}

/// One N per building (at its anchor) is exact there and within the geoid's slope times the
/// distance elsewhere: in the steepest EGM96 (the Himalaya's southern edge, 9.7 m between
/// posts) a vertex 60 m from its anchor is within 3 cm of its own H + N.
#[test]
fn one_undulation_per_building_is_close_everywhere_on_it() {
    let crs = Crs::Utm {
        zone: 44,
        north: true,
    };
    let (x, y) = crs.from_lonlat(79.5, 30.0);
    let mut c = ctx(Lod::Lod2);
    c.crs = crs;
    c.origin = DVec3::new(x.round(), y.round(), 3000.0);
    c.vertical_datum = Some(crate::model::VerticalDatum::Orthometric {
        epsg: None,
        name: "DEM".into(),
    });
    let model = ModelFrame::new(&c);
    let anchor = DVec3::new(20.0, -30.0, 5.0);
    let map = BuildingMap::at(&model, anchor);
    for d in [
        DVec3::new(60.0, 0.0, 0.0),
        DVec3::new(0.0, 60.0, 0.0),
        DVec3::new(-42.0, 42.0, 20.0),
    ] {
        let p = anchor + d;
        let got = map.anchor_ecef + map.offset(p);
        let (lon, lat, _) = model.to_wgs84(p);
        let (_, _, h) = ecef_to_wgs84(got.to_array());
        let want = c.origin.z + p.z + crate::crs::geoid::undulation(lon, lat);
        assert!((h - want).abs() < 0.03, "{d:?}: {h} vs {want}");
    }
}

// ---- textures (issue 49, `--textures`) ----

/// The test buildings in brick with a rhythm of bays (so that LOD2 walls get bay pictures).
fn brick_bays() -> Vec<Building> {
    let mut bs = buildings(0.0);
    for b in &mut bs {
        for p in &mut b.parts {
            p.wall_material = crate::color::material::Material::Brick;
            p.rhythm = Some(crate::model::Rhythm {
                bay: 3.0,
                window: 1.2,
                sill: 0.25,
                height: 0.6,
            });
        }
    }
    bs
}

/// `bs` written as a `detail` content at `lod` with `--textures`.
fn textured(bs: &[Building], lod: Lod, detail: Detail) -> (Vec<u8>, ContentInfo) {
    let (w, info) = Tiles3dWriter::new(Vec::new(), detail);
    let mut w = w.with_textures(true);
    w.begin(&ctx(lod)).unwrap();
    w.write_all(bs).unwrap();
    w.finish().unwrap();
    (w.into_inner(), info.get().unwrap())
}

/// The content's image names, after checking that each is a PNG.
fn image_names(g: &Glb) -> Vec<String> {
    let images = g.json["images"].as_array().unwrap();
    for i in images {
        let png = g.view(i["bufferView"].as_u64().unwrap());
        assert_eq!(&png[..8], &crate::export::png::SIGNATURE);
    }
    images
        .iter()
        .map(|i| i["name"].as_str().unwrap().to_string())
        .collect()
}

/// How many primitives are textured, after checking that exactly the textured materials' have
/// finite coordinates, one a vertex.
fn textured_prims(g: &Glb) -> usize {
    let mut n = 0;
    for p in g.json["meshes"][0]["primitives"].as_array().unwrap() {
        let m = &g.json["materials"][p["material"].as_u64().unwrap() as usize];
        let has_tex = m["pbrMetallicRoughness"].get("baseColorTexture").is_some();
        assert_eq!(has_tex, p["attributes"].get("TEXCOORD_0").is_some());
        if has_tex {
            n += 1;
            let (uv, comps) = g.accessor(p["attributes"]["TEXCOORD_0"].as_u64().unwrap());
            let (pos, _) = g.accessor(p["attributes"]["POSITION"].as_u64().unwrap());
            assert_eq!((comps, uv.len() / 2), (2, pos.len() / 3));
            assert!(uv.iter().all(|c| c.is_finite()));
        }
    }
    n
}

/// The brick buildings as a LOD2 `detail` content with `--textures`, after checking that
/// without it the content has no picture and that with it two writes give the same bytes.
fn textured_lod2(detail: Detail) -> (Vec<Building>, Vec<u8>, ContentInfo) {
    let bs = brick_bays();
    let (plain, _) = write(Lod::Lod2, detail, &bs, true);
    assert!(parse(&plain).json.get("images").is_none());
    let (glb, info) = textured(&bs, Lod::Lod2, detail);
    assert_eq!(glb, textured(&bs, Lod::Lod2, detail).0, "deterministic");
    (bs, glb, info)
}

#[test]
fn textured_contents_carry_one_picture_per_kind_and_coordinates() {
    let (_, glb, info) = textured_lod2(Detail::Full);
    assert!(info.triangles > 0);
    let g = parse(&glb);
    let names = image_names(&g);
    // Every building's walls share the one bay picture; roofs their material's.
    assert_eq!(
        names.iter().filter(|n| n.starts_with("bay brick")).count(),
        1,
        "{names:?}"
    );
    assert!(textured_prims(&g) >= 2);
}

#[test]
fn textured_blocks_carry_the_full_contents_pictures() {
    // The far tiles (Blocks) look like the near ones: the walls' bay picture below the eaves,
    // the brick pattern above (the block rises to the ridge), the roof material on the top.
    let (bs, glb, info) = textured_lod2(Detail::Blocks);
    let g = parse(&glb);
    let blocks = image_names(&g);
    let (full, _) = textured(&bs, Lod::Lod2, Detail::Full);
    let full = image_names(&parse(&full));
    assert!(
        blocks.iter().any(|n| n.starts_with("bay brick")),
        "{blocks:?}"
    );
    assert!(
        blocks.iter().all(|n| full.contains(n)),
        "{blocks:?} not in {full:?}"
    );
    assert!(textured_prims(&g) >= 2);
    // Still a few triangles a building: the pictures, not the geometry, carry the bays.
    let (_, plain_info) = write(Lod::Lod2, Detail::Blocks, &bs, true);
    assert!(
        info.triangles <= 2 * plain_info.triangles,
        "{} vs {}",
        info.triangles,
        plain_info.triangles
    );
}
