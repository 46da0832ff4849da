use std::io::Read;

use glam::DVec3;

use super::*;
use crate::crs::Crs;
use crate::export::fixtures;
use crate::export::gltf::GltfWriter;
use crate::export::lod3geom::samples;

// ---- helpers ----

/// A box from `lo` to `hi` as 12 triangles, counter-clockwise from outside, in two colours:
/// the four walls in `walls`, the roof (and the floor) in `roof`.
fn add_box(scene: &mut Scene, lo: [f32; 3], hi: [f32; 3], walls: [u8; 3], roof: [u8; 3]) {
    let p = |i: usize| {
        [
            if i & 1 == 0 { lo[0] } else { hi[0] },
            if i & 2 == 0 { lo[1] } else { hi[1] },
            if i & 4 == 0 { lo[2] } else { hi[2] },
        ]
    };
    let positions: Vec<[f32; 3]> = (0..8).map(p).collect();
    // Quads as corner indices (bit 0 x, bit 1 y, bit 2 z), CCW from outside.
    let quad = |q: [u32; 4]| [q[0], q[1], q[2], q[0], q[2], q[3]];
    let walls_ix: Vec<u32> = [
        [0, 1, 5, 4], // south (y = lo)
        [1, 3, 7, 5], // east
        [3, 2, 6, 7], // north
        [2, 0, 4, 6], // west
    ]
    .into_iter()
    .flat_map(quad)
    .collect();
    let roof_ix: Vec<u32> = [[4, 5, 7, 6], [0, 2, 3, 1]]
        .into_iter()
        .flat_map(quad)
        .collect();
    scene.add(walls, &positions, &walls_ix);
    scene.add(roof, &positions, &roof_ix);
}

fn pixel(img: &Image, x: u32, y: u32) -> [u8; 3] {
    let i = 3 * (y as usize * img.width() as usize + x as usize);
    [img.rgb()[i], img.rgb()[i + 1], img.rgb()[i + 2]]
}

fn luma(c: [u8; 3]) -> u32 {
    c.iter().map(|&v| u32::from(v)).sum()
}

/// The chunks of a PNG (type, data), checking the signature, lengths and every CRC.
fn png_chunks(png: &[u8]) -> Vec<([u8; 4], Vec<u8>)> {
    assert_eq!(&png[..8], &png::SIGNATURE);
    let mut at = 8;
    let mut out = Vec::new();
    while at < png.len() {
        let len = u32::from_be_bytes(png[at..at + 4].try_into().unwrap()) as usize;
        let kind: [u8; 4] = png[at + 4..at + 8].try_into().unwrap();
        let data = png[at + 8..at + 8 + len].to_vec();
        let crc = u32::from_be_bytes(png[at + 8 + len..at + 12 + len].try_into().unwrap());
        let mut h = crc32fast::Hasher::new();
        h.update(&kind);
        h.update(&data);
        assert_eq!(
            h.finalize(),
            crc,
            "CRC of {}",
            String::from_utf8_lossy(&kind)
        );
        out.push((kind, data));
        at += 12 + len;
    }
    assert_eq!(at, png.len());
    out
}

/// Decodes our PNG back to pixels: IHDR, the inflated IDAT (its size checked), unfiltered.
fn decode_png(png: &[u8]) -> (u32, u32, Vec<u8>) {
    let chunks = png_chunks(png);
    let kinds: Vec<&[u8; 4]> = chunks.iter().map(|(k, _)| k).collect();
    assert_eq!(kinds, [b"IHDR", b"IDAT", b"IEND"]);
    let ihdr = &chunks[0].1;
    let w = u32::from_be_bytes(ihdr[0..4].try_into().unwrap());
    let h = u32::from_be_bytes(ihdr[4..8].try_into().unwrap());
    assert_eq!(&ihdr[8..], &[8, 2, 0, 0, 0]);
    let mut raw = Vec::new();
    flate2::read::ZlibDecoder::new(&chunks[1].1[..])
        .read_to_end(&mut raw)
        .unwrap();
    let row = 3 * w as usize;
    assert_eq!(raw.len(), h as usize * (1 + row));
    let mut rgb = vec![0u8; row * h as usize];
    for y in 0..h as usize {
        let kind = raw[y * (1 + row)];
        for i in 0..row {
            let a = if i >= 3 { rgb[y * row + i - 3] } else { 0 };
            let b = if y > 0 { rgb[(y - 1) * row + i] } else { 0 };
            let c = if y > 0 && i >= 3 {
                rgb[(y - 1) * row + i - 3]
            } else {
                0
            };
            let pred = match kind {
                0 => 0,
                1 => a,
                2 => b,
                3 => ((u16::from(a) + u16::from(b)) / 2) as u8,
                4 => {
                    let p = i16::from(a) + i16::from(b) - i16::from(c);
                    let (pa, pb, pc) = (
                        (p - i16::from(a)).abs(),
                        (p - i16::from(b)).abs(),
                        (p - i16::from(c)).abs(),
                    );
                    if pa <= pb && pa <= pc {
                        a
                    } else if pb <= pc {
                        b
                    } else {
                        c
                    }
                }
                k => panic!("filter type {k}"),
            };
            rgb[y * row + i] = raw[y * (1 + row) + 1 + i].wrapping_add(pred);
        }
    }
    (w, h, rgb)
}

fn two_boxes() -> Scene {
    let mut s = Scene::new();
    add_box(
        &mut s,
        [0.0, 0.0, 0.0],
        [20.0, 20.0, 12.0],
        [220, 40, 40],
        [220, 40, 40],
    );
    add_box(
        &mut s,
        [100.0, 0.0, 0.0],
        [120.0, 20.0, 12.0],
        [40, 40, 220],
        [40, 40, 220],
    );
    s
}

fn small_view() -> View {
    View {
        width: 320,
        height: 200,
        ..View::default()
    }
}

fn ctx(lod: Lod) -> OutputContext {
    OutputContext {
        crs: Crs::Lambert93,
        origin: DVec3::new(574_000.0, 6_279_000.0, 0.0),
        origin_lonlat: (1.44, 43.6),
        lod,
        source_name: "test".into(),
        seed: 0,
        vertical_datum: None,
        terrain: None,
    }
}

fn glb_of(buildings: &[Building], lod: Lod) -> Vec<u8> {
    let mut w = GltfWriter::new(Vec::new(), tempfile::tempfile().unwrap());
    w.begin(&ctx(lod)).unwrap();
    w.write_all(buildings).unwrap();
    w.finish().unwrap();
    w.into_inner()
}

/// The triangles a GLB's JSON declares (every mesh node's primitives' index counts / 3).
fn declared_triangles(glb: &[u8]) -> usize {
    let len = u32::from_le_bytes(glb[12..16].try_into().unwrap()) as usize;
    let doc: serde_json::Value = serde_json::from_slice(&glb[20..20 + len]).unwrap();
    doc["nodes"]
        .as_array()
        .unwrap()
        .iter()
        .filter_map(|n| n["mesh"].as_u64())
        .flat_map(|m| doc["meshes"][m as usize]["primitives"].as_array().unwrap())
        .map(|p| {
            doc["accessors"][p["indices"].as_u64().unwrap() as usize]["count"]
                .as_u64()
                .unwrap() as usize
                / 3
        })
        .sum()
}

/// A GLB made of `json` and `bin` (each padded as GLB requires).
fn make_glb(json: &str, bin: &[u8]) -> Vec<u8> {
    let mut j = json.as_bytes().to_vec();
    while j.len() % 4 != 0 {
        j.push(b' ');
    }
    let mut b = bin.to_vec();
    while b.len() % 4 != 0 {
        b.push(0);
    }
    let total = 12 + 8 + j.len() + if b.is_empty() { 0 } else { 8 + b.len() };
    let mut out = Vec::new();
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&(total as u32).to_le_bytes());
    out.extend_from_slice(&(j.len() as u32).to_le_bytes());
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(&j);
    if !b.is_empty() {
        out.extend_from_slice(&(b.len() as u32).to_le_bytes());
        out.extend_from_slice(b"BIN\0");
        out.extend_from_slice(&b);
    }
    out
}

// ---- PNG ----

#[test]
fn png_is_well_formed_and_decodes_to_the_pixels() {
    let img = two_boxes().render(&small_view());
    let png = img.to_png();
    let (w, h, rgb) = decode_png(&png);
    assert_eq!((w, h), (320, 200));
    assert_eq!(rgb, img.rgb());
    // Odd sizes, one pixel, and noise (every filter type chosen somewhere).
    for (w, h) in [(1u32, 1u32), (3, 7), (17, 5)] {
        let rgb: Vec<u8> = (0..w * h * 3)
            .map(|i| (i.wrapping_mul(2_654_435_761) >> 13) as u8)
            .collect();
        let png = png::encode_rgb(w, h, &rgb).unwrap();
        assert_eq!(decode_png(&png), (w, h, rgb));
    }
}

#[test]
fn png_refuses_sizes_that_do_not_match() {
    assert!(png::encode_rgb(0, 1, &[]).is_none());
    assert!(png::encode_rgb(2, 2, &[0; 11]).is_none());
    assert!(png::encode_rgb(2, 2, &[0; 13]).is_none());
    assert!(png::encode_rgb(1 << 31, 1, &[]).is_none());
}

// ---- rendering ----

#[test]
fn render_is_deterministic_whatever_the_thread_count() {
    let scene = two_boxes();
    let one = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap()
        .install(|| scene.render(&small_view()).to_png());
    let four = rayon::ThreadPoolBuilder::new()
        .num_threads(4)
        .build()
        .unwrap()
        .install(|| scene.render(&small_view()).to_png());
    assert_eq!(one, four);
    assert_eq!(one, scene.render(&small_view()).to_png());
}

#[test]
fn boxes_land_where_the_camera_puts_them() {
    // Looking north: the west box (red) on the left, the east box (blue) on the right.
    let view = View {
        azimuth: Some(0.0),
        ..small_view()
    };
    let img = two_boxes().render(&view);
    let (mut red, mut blue) = (Vec::new(), Vec::new());
    for y in 0..img.height() {
        for x in 0..img.width() {
            let [r, g, b] = pixel(&img, x, y).map(u16::from);
            if r > 2 * g.max(b) {
                red.push(x);
            }
            if b > 2 * r.max(g) {
                blue.push(x);
            }
        }
    }
    assert!(
        red.len() > 200 && blue.len() > 200,
        "{} {}",
        red.len(),
        blue.len()
    );
    let mean = |v: &[u32]| v.iter().sum::<u32>() as f64 / v.len() as f64;
    assert!(mean(&red) < 0.3 * 320.0, "red at {}", mean(&red));
    assert!(mean(&blue) > 0.7 * 320.0, "blue at {}", mean(&blue));
    // Fitted with the margin: nothing drawn in the outer columns but sky and ground.
    let corner = pixel(&img, 0, 0);
    assert!(corner[2] > corner[0], "sky at the top left: {corner:?}");
    // Looking east instead: the west box (red) is the near one, lower in the picture.
    let east = two_boxes().render(&View {
        azimuth: Some(90.0),
        ..small_view()
    });
    let rows = |f: &dyn Fn([u8; 3]) -> bool| {
        let ys: Vec<u32> = (0..east.height())
            .flat_map(|y| (0..east.width()).map(move |x| (x, y)))
            .filter(|&(x, y)| f(pixel(&east, x, y)))
            .map(|(_, y)| y)
            .collect();
        mean(&ys)
    };
    let red_y = rows(&|c| {
        let [r, g, b] = c.map(u16::from);
        r > 2 * g.max(b)
    });
    let blue_y = rows(&|c| {
        let [r, g, b] = c.map(u16::from);
        b > 2 * r.max(g)
    });
    assert!(
        red_y > blue_y + 20.0,
        "red at row {red_y}, blue at {blue_y}"
    );
}

#[test]
fn roof_and_walls_are_shaded_apart() {
    // One white box seen from the south-west: roof, west wall and south wall in three tones.
    let mut s = Scene::new();
    add_box(
        &mut s,
        [0.0, 0.0, 0.0],
        [30.0, 30.0, 20.0],
        [255; 3],
        [255; 3],
    );
    let img = s.render(&View {
        azimuth: Some(45.0),
        ground: false,
        ..small_view()
    });
    let mut tones = std::collections::BTreeMap::<[u8; 3], usize>::new();
    for y in 0..img.height() {
        for x in 0..img.width() {
            let c = pixel(&img, x, y);
            // Grey (the box), not the bluish sky.
            if c[0] == c[1] && c[1] == c[2] {
                *tones.entry(c).or_default() += 1;
            }
        }
    }
    let big: Vec<([u8; 3], usize)> = tones.into_iter().filter(|(_, n)| *n > 500).collect();
    assert_eq!(big.len(), 3, "three large flat tones: {big:?}");
    // The roof is seen from 45° above, the walls obliquely: the roof has the most pixels of
    // the three and is the brightest; the wall facing the sun side is lighter than the other.
    let roof = big.iter().max_by_key(|(_, n)| *n).unwrap().0;
    assert_eq!(roof, big[2].0, "{big:?}");
    assert!(
        luma(big[0].0) + 30 < luma(big[1].0),
        "walls too alike: {big:?}"
    );
}

#[test]
fn empty_and_degenerate_scenes_render() {
    let img = Scene::new().render(&small_view());
    assert_eq!((img.width(), img.height()), (320, 200));
    // Sky only: bluer at the top than at the bottom.
    assert!(pixel(&img, 0, 0)[0] < pixel(&img, 0, 199)[0]);
    // Sizes are clamped, NaN angles fall back.
    let mut s = Scene::new();
    s.add(
        [9; 3],
        &[[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
        &[0, 1, 2],
    );
    let img = s.render(&View {
        width: 0,
        height: 100_000,
        azimuth: Some(f64::NAN),
        elevation: f64::NAN,
        margin: f64::INFINITY,
        supersample: 99,
        ..View::default()
    });
    assert_eq!((img.width(), img.height()), (1, MAX_SIDE));
    // A single point, a flat scene.
    let mut s = Scene::new();
    s.add([9; 3], &[[5.0; 3]; 3], &[0, 1, 2]);
    s.render(&small_view());
}

#[test]
fn scene_skips_bad_triangles_and_splits_large_meshes() {
    let mut s = Scene::new();
    let p = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, f32::NAN]];
    // Out of range, non-finite, a trailing pair: nothing kept.
    s.add([1; 3], &p, &[0, 1, 7, 0, 1, 2, 0, 1]);
    assert_eq!((s.triangle_count(), s.vertex_count()), (0, 0));
    assert!(s.bounds().is_none());
    // 40,000 separate triangles: 120,000 vertices, more than a run holds.
    let positions: Vec<[f32; 3]> = (0..120_000)
        .map(|i| [(i / 3) as f32, (i % 3) as f32, (i % 2) as f32])
        .collect();
    let indices: Vec<u32> = (0..120_000).collect();
    s.add([7; 3], &positions, &indices);
    assert_eq!(s.triangle_count(), 40_000);
    assert_eq!(s.vertex_count(), 120_000);
    assert!(s.runs.len() >= 2);
    for r in &s.runs {
        let next = s.triangles[r.first_triangle..r.end_triangle]
            .iter()
            .flatten()
            .map(|&i| r.first_vertex + usize::from(i))
            .max()
            .unwrap();
        assert!(next < s.positions.len());
    }
    // Every triangle's corners are its own, in order.
    let mut k = 0;
    for r in &s.runs {
        for t in &s.triangles[r.first_triangle..r.end_triangle] {
            for &i in t {
                assert_eq!(s.positions[r.first_vertex + usize::from(i)], positions[k]);
                k += 1;
            }
        }
    }
    // Welding: a box's 36 corners are 8 vertices.
    let mut b = Scene::new();
    add_box(&mut b, [0.0; 3], [1.0; 3], [1; 3], [1; 3]);
    assert_eq!((b.triangle_count(), b.vertex_count()), (12, 16));
}

// ---- the writer ----

#[test]
fn writer_draws_what_the_gltf_writer_draws() {
    let buildings = samples::all();
    let mut w = PreviewWriter::new(Vec::new()).with_view(small_view());
    assert!(w.write(&buildings[0]).is_err(), "write before begin");
    assert!(w.finish().is_err(), "finish before begin");
    w.begin(&ctx(Lod::Lod3)).unwrap();
    assert!(w.begin(&ctx(Lod::Lod3)).is_err());
    w.write_all(&buildings).unwrap();
    let by_batch = w.scene().clone();
    w.finish().unwrap();
    assert!(w.finish().is_err() && w.write(&buildings[0]).is_err());
    let png = w.into_inner();
    assert_eq!(decode_png(&png).0, 320);

    // One at a time: the same scene, the same picture.
    let mut one = PreviewWriter::new(Vec::new()).with_view(small_view());
    one.begin(&ctx(Lod::Lod3)).unwrap();
    for b in &buildings {
        one.write(b).unwrap();
    }
    assert_eq!(one.scene().positions, by_batch.positions);
    assert_eq!(one.scene().triangles, by_batch.triangles);
    one.finish().unwrap();
    assert_eq!(one.into_inner(), png);

    // The GLB of the same buildings holds these triangles plus the grounds'.
    let glb = glb_of(&buildings, Lod::Lod3);
    let grounds: usize = buildings
        .iter()
        .flat_map(|b| &b.parts)
        .map(|p| {
            let holes = &p.ground.holes;
            p.ground.outer.len() + holes.iter().map(Vec::len).sum::<usize>() + 2 * holes.len() - 2
        })
        .sum();
    assert_eq!(
        by_batch.triangle_count() + grounds,
        declared_triangles(&glb)
    );

    // A building with a NaN is refused, naming the writer.
    let mut bad = buildings[0].clone();
    bad.parts[0].walls[0].outline.outer[0].x = f64::NAN;
    let mut w = PreviewWriter::new(Vec::new());
    w.begin(&ctx(Lod::Lod2)).unwrap();
    let e = w.write_all(&[bad]).unwrap_err().to_string();
    assert!(e.contains("glTF writer"), "{e}");
}

// ---- the GLB reader ----

#[test]
fn glb_reader_reads_every_triangle_of_the_gltf_writer() {
    for (buildings, lod) in [
        (samples::all(), Lod::Lod3),
        (fixtures::lod4_all(), Lod::Lod4),
    ] {
        let glb = glb_of(&buildings, lod);
        let meshes = glb_triangles(&glb, &|p| p).unwrap();
        let read: usize = meshes.iter().map(|m| m.indices.len() / 3).sum();
        assert_eq!(read, declared_triangles(&glb));
        // Back in the model frame (the identity after the Y-up turn): within the buildings.
        let (lo, hi) = meshes.iter().flat_map(|m| &m.positions).fold(
            ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]),
            |(lo, hi), p| {
                (
                    std::array::from_fn(|k| lo[k].min(p[k])),
                    std::array::from_fn(|k| hi[k].max(p[k])),
                )
            },
        );
        let model: Vec<DVec3> = buildings
            .iter()
            .flat_map(|b| &b.parts)
            .flat_map(|p| p.walls.iter().flat_map(|w| w.outline.outer.iter().copied()))
            .collect();
        let mlo = model.iter().fold(DVec3::INFINITY, |a, p| a.min(*p));
        let mhi = model.iter().fold(DVec3::NEG_INFINITY, |a, p| a.max(*p));
        assert!((lo[2] - mlo.z).abs() < 1e-3, "{lo:?} vs {mlo}");
        // Balconies stand out of their walls.
        assert!(
            lo[0] >= mlo.x - 2.0 && hi[0] <= mhi.x + 2.0,
            "{lo:?} {hi:?}"
        );
        assert!(
            lo[1] >= mlo.y - 2.0 && hi[1] <= mhi.y + 2.0,
            "{lo:?} {hi:?}"
        );
        // The closure is applied to every point.
        let moved = glb_triangles(&glb, &|p| [p[0] + 1000.0, p[1], p[2]]).unwrap();
        assert_eq!(moved[0].positions[0][0], meshes[0].positions[0][0] + 1000.0);
    }
}

#[test]
fn glb_reader_applies_node_transforms_and_the_y_up_turn() {
    // One triangle (0,0,0), (1,0,0), (0,1,0) in glTF space, no indices, a red material;
    // node 0 (translation, scale) has child 1 (the mesh, rotated 90° about glTF's y).
    let mut bin = Vec::new();
    for v in [0f32, 0., 0., 1., 0., 0., 0., 1., 0.] {
        bin.extend_from_slice(&v.to_le_bytes());
    }
    let json = r#"{"asset":{"version":"2.0"},"scene":0,"scenes":[{"nodes":[0]}],
        "nodes":[{"translation":[10,2,-3],"scale":[2,2,2],"children":[1]},
                 {"mesh":0,"rotation":[0,0.7071067811865476,0,0.7071067811865476]}],
        "meshes":[{"primitives":[{"attributes":{"POSITION":0},"material":0}]}],
        "materials":[{"pbrMetallicRoughness":{"baseColorFactor":[1,0,0,1]}}],
        "accessors":[{"bufferView":0,"componentType":5126,"count":3,"type":"VEC3"}],
        "bufferViews":[{"buffer":0,"byteLength":36}],
        "buffers":[{"byteLength":36}]}"#;
    let meshes = glb_triangles(&make_glb(json, &bin), &|p| p).unwrap();
    assert_eq!(meshes.len(), 1);
    assert_eq!(meshes[0].color, [255, 0, 0]);
    assert_eq!(meshes[0].indices, [0, 1, 2]);
    // glTF: x (1,0,0) turned 90° about y is (0,0,-1), scaled 2, moved: (10, 2, -5); Z up:
    // (x, -z, y) = (10, 5, 2). y (0,1,0) stays: (10, 4, -3) -> (10, 3, 4).
    let expect = [[10.0, 3.0, 2.0], [10.0, 5.0, 2.0], [10.0, 3.0, 4.0]];
    for (p, e) in meshes[0].positions.iter().zip(expect) {
        for k in 0..3 {
            assert!((p[k] - e[k]).abs() < 1e-9, "{p:?} vs {e:?}");
        }
    }

    // A strip of 4 vertices is 2 triangles, u8 indices; no scenes: the root nodes.
    let mut bin = Vec::new();
    for v in [0f32, 0., 0., 1., 0., 0., 0., 1., 0., 1., 1., 0.] {
        bin.extend_from_slice(&v.to_le_bytes());
    }
    bin.extend_from_slice(&[0, 1, 2, 3]);
    let json = r#"{"asset":{"version":"2.0"},
        "nodes":[{"mesh":0,"matrix":[1,0,0,0, 0,1,0,0, 0,0,1,0, 5,0,0,1]}],
        "meshes":[{"primitives":[{"attributes":{"POSITION":0},"indices":1,"mode":5}]}],
        "accessors":[{"bufferView":0,"componentType":5126,"count":4,"type":"VEC3"},
                     {"bufferView":1,"componentType":5121,"count":4,"type":"SCALAR"}],
        "bufferViews":[{"buffer":0,"byteLength":48},{"buffer":0,"byteOffset":48,"byteLength":4}],
        "buffers":[{"byteLength":52}]}"#;
    let meshes = glb_triangles(&make_glb(json, &bin), &|p| p).unwrap();
    assert_eq!(meshes[0].indices, [0, 1, 2, 2, 1, 3]);
    assert_eq!(meshes[0].color, [255; 3], "no material: white");
    assert_eq!(meshes[0].positions[1], [6.0, 0.0, 0.0]);
}

#[test]
fn glb_reader_refuses_bad_input_without_panicking() {
    let glb = glb_of(&samples::all(), Lod::Lod3);
    // Every truncation (the header's length then exceeds the file).
    for len in (0..glb.len())
        .step_by(97)
        .chain([0, 1, 11, 12, 19, 20, glb.len() - 1])
    {
        assert!(
            glb_triangles(&glb[..len], &|p| p).is_err(),
            "truncated at {len}"
        );
    }
    // Garbage.
    let noise: Vec<u8> = (0..5000u32)
        .map(|i| (i.wrapping_mul(2_654_435_761) >> 11) as u8)
        .collect();
    assert!(glb_triangles(&noise, &|p| p).is_err());
    let mut fake = b"glTF".to_vec();
    fake.extend_from_slice(&noise);
    assert!(glb_triangles(&fake, &|p| p).is_err());
    // Bytes changed anywhere: an error or triangles, never a panic.
    for at in (0..glb.len()).step_by(13) {
        let mut bad = glb.clone();
        bad[at] ^= 0xA5;
        let _ = glb_triangles(&bad, &|p| p);
    }
    // JSON that is wrong in each way the reader checks.
    // Zeros, then 0xFF: the indices of the third case read 65535.
    let bin: Vec<u8> = (0..36).map(|i| if i < 24 { 0 } else { 0xFF }).collect();
    let cases = [
        // Accessor past its view.
        r#"{"nodes":[{"mesh":0}],"meshes":[{"primitives":[{"attributes":{"POSITION":0}}]}],
           "accessors":[{"bufferView":0,"componentType":5126,"count":4,"type":"VEC3"}],
           "bufferViews":[{"buffer":0,"byteLength":36}],"buffers":[{"byteLength":36}]}"#,
        // View past the binary chunk.
        r#"{"nodes":[{"mesh":0}],"meshes":[{"primitives":[{"attributes":{"POSITION":0}}]}],
           "accessors":[{"bufferView":0,"componentType":5126,"count":3,"type":"VEC3"}],
           "bufferViews":[{"buffer":0,"byteOffset":8,"byteLength":36}],"buffers":[{"byteLength":36}]}"#,
        // Index out of range.
        r#"{"nodes":[{"mesh":0}],"meshes":[{"primitives":[{"attributes":{"POSITION":0},"indices":1}]}],
           "accessors":[{"bufferView":0,"componentType":5126,"count":2,"type":"VEC3"},
                        {"bufferView":0,"byteOffset":24,"componentType":5123,"count":3,"type":"SCALAR"}],
           "bufferViews":[{"buffer":0,"byteLength":36}],"buffers":[{"byteLength":36}]}"#,
        // A node cycle.
        r#"{"nodes":[{"children":[1]},{"children":[0]}],"scenes":[{"nodes":[0]}]}"#,
        // An external buffer.
        r#"{"nodes":[{"mesh":0}],"meshes":[{"primitives":[{"attributes":{"POSITION":0}}]}],
           "accessors":[{"bufferView":0,"componentType":5126,"count":3,"type":"VEC3"}],
           "bufferViews":[{"buffer":0,"byteLength":36}],"buffers":[{"byteLength":36,"uri":"x.bin"}]}"#,
        // A mesh that does not exist; a stride shorter than the element; NaN in a matrix.
        r#"{"nodes":[{"mesh":3}],"meshes":[]}"#,
        r#"{"nodes":[{"mesh":0}],"meshes":[{"primitives":[{"attributes":{"POSITION":0}}]}],
           "accessors":[{"bufferView":0,"componentType":5126,"count":3,"type":"VEC3"}],
           "bufferViews":[{"buffer":0,"byteLength":36,"byteStride":4}],"buffers":[{"byteLength":36}]}"#,
        r#"{"nodes":[{"translation":[1,"a",2]}]}"#,
        r#"{"nodes":5}"#,
        "not json",
    ];
    for json in cases {
        let r = glb_triangles(&make_glb(json, &bin), &|p| p);
        assert!(r.is_err(), "accepted {json}");
        assert!(r.unwrap_err().to_string().starts_with("GLB: "));
    }
}
