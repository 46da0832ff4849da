//! The bad-input corpus (issue 7): every case builds its input in a temporary folder (with
//! `PbfWriter`, by corrupting bytes of the Monaco extract, or by writing a small shapefile), runs
//! the real binary and asserts the outcome. Whatever the input, the process never panics; fatal
//! inputs exit 1 (2 for usage, 3 for outputs) with a message naming the file and the place;
//! per-footprint problems are repaired or reported with the source id, and the other buildings
//! of the same input are still written.

use crate::common;

use std::fs::File;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use crate::common::{citygen, KB, MONACO};
use citygen::testkit::pbf_write::{MemberKind, PbfWriter};
use serde_json::Value;

// ---- running and asserting ------------------------------------------------------------------

/// Text of a run for assertion messages.
fn show(out: &Output) -> String {
    format!(
        "exit {:?}\nstdout: {}\nstderr: {}",
        out.status.code(),
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    )
}

/// The process ended normally (no panic: exit code 101 or a "panicked" message).
fn no_panic(out: &Output) {
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        out.status.code().is_some() && out.status.code() != Some(101),
        "crashed: {}",
        show(out)
    );
    assert!(!err.contains("panicked"), "a panic message: {}", show(out));
}

/// A fatal case: exit `code` and a stderr naming every `needle` (the file, the place).
fn fatal(out: &Output, code: i32, needles: &[&str]) {
    no_panic(out);
    assert_eq!(out.status.code(), Some(code), "{}", show(out));
    let err = String::from_utf8_lossy(&out.stderr);
    for n in needles {
        assert!(err.contains(n), "stderr lacks {n:?}: {}", show(out));
    }
}

/// A run's output folder, report and exit status.
struct Ran {
    dir: PathBuf,
    out: Output,
}

impl Ran {
    fn report(&self) -> Value {
        let p = self.dir.join("report.json");
        let bytes = std::fs::read(&p).unwrap_or_else(|e| panic!("{e}: {}", show(&self.out)));
        serde_json::from_slice(&bytes).unwrap()
    }

    /// Entries (outcome, reason) about one source id.
    fn entries(&self, id: &str) -> Vec<(String, String)> {
        self.report()["entries"]
            .as_array()
            .unwrap()
            .iter()
            .filter(|e| e["id"] == id)
            .map(|e| {
                (
                    e["outcome"].as_str().unwrap().to_string(),
                    e["reason"].as_str().unwrap().to_string(),
                )
            })
            .collect()
    }

    fn count(&self, key: &str) -> u64 {
        self.report()[key].as_u64().unwrap()
    }

    /// Top-level nodes of the GLB scene: one per building written.
    fn glb_buildings(&self) -> usize {
        let (json, _) = common::glb_json(&self.dir.join("out.glb"));
        json["scenes"][0]["nodes"].as_array().map_or(0, Vec::len)
    }
}

/// Runs the main job on `input_flag input` with a GLB output and a report in `dir`.
fn run_in(dir: &Path, input_flag: &str, input: &Path, extra: &[&str]) -> Ran {
    let glb = dir.join("out.glb");
    let report = dir.join("report.json");
    let mut args = vec![
        input_flag,
        input.to_str().unwrap(),
        "--gltf",
        glb.to_str().unwrap(),
        "--report",
        report.to_str().unwrap(),
        "--quiet",
    ];
    if !extra.contains(&"--rules") && !extra.contains(&"--kb") {
        args.extend(["--kb", KB]);
    }
    if !extra.contains(&"--lod") {
        args.extend(["--lod", "1"]);
    }
    args.extend(extra);
    let out = citygen(&args);
    no_panic(&out);
    Ran {
        dir: dir.to_path_buf(),
        out,
    }
}

/// A successful run: exit 0.
fn ok_run(dir: &Path, input_flag: &str, input: &Path, extra: &[&str]) -> Ran {
    let r = run_in(dir, input_flag, input, extra);
    assert_eq!(r.out.status.code(), Some(0), "{}", show(&r.out));
    r
}

// ---- synthetic OSM input --------------------------------------------------------------------

/// Near Monaco (in the shipped knowledge base).
const LON0: f64 = 7.4200;
const LAT0: f64 = 43.7300;

/// A small OSM data set built in code, written with `PbfWriter`. Points are given in metres
/// east/north of (LON0, LAT0).
type OwnedTags = Vec<(String, String)>;
type OwnedMembers = Vec<(MemberKind, i64, String)>;

#[derive(Default)]
struct Osm {
    nodes: Vec<(i64, f64, f64)>,
    ways: Vec<(i64, Vec<i64>, OwnedTags)>,
    rels: Vec<(i64, OwnedMembers, OwnedTags)>,
}

fn owned(tags: &[(&str, &str)]) -> Vec<(String, String)> {
    tags.iter()
        .map(|(k, v)| (k.to_string(), v.to_string()))
        .collect()
}

impl Osm {
    /// New nodes at the points (metres), returned as a closed ref list (first repeated).
    fn ring(&mut self, pts: &[(f64, f64)]) -> Vec<i64> {
        let mut refs = self.open(pts);
        refs.push(refs[0]);
        refs
    }

    /// New nodes at the points (metres), returned as an open ref list.
    fn open(&mut self, pts: &[(f64, f64)]) -> Vec<i64> {
        let m_lon = 111_320.0 * LAT0.to_radians().cos();
        pts.iter()
            .map(|&(x, y)| {
                let id = 1 + self.nodes.len() as i64;
                self.nodes
                    .push((id, LON0 + x / m_lon, LAT0 + y / 110_574.0));
                id
            })
            .collect()
    }

    fn way(&mut self, id: i64, refs: Vec<i64>, tags: &[(&str, &str)]) {
        self.ways.push((id, refs, owned(tags)));
    }

    /// A building way on the ring `pts`.
    fn building(&mut self, id: i64, pts: &[(f64, f64)], tags: &[(&str, &str)]) {
        let refs = self.ring(pts);
        let mut t = vec![("building", "yes")];
        t.extend_from_slice(tags);
        self.way(id, refs, &t);
    }

    /// A good 12 x 10 m building, the `i`-th of a row far from the test footprints.
    fn good(&mut self, id: i64, i: usize) {
        let (x, y) = (
            -500.0 + 25.0 * (i % 20) as f64,
            -300.0 - 25.0 * (i / 20) as f64,
        );
        self.building(id, &square(x, y, 12.0, 10.0), &[("height", "9")]);
    }

    fn relation(&mut self, id: i64, members: &[(i64, &str)], tags: &[(&str, &str)]) {
        let m = members
            .iter()
            .map(|&(w, role)| (MemberKind::Way, w, role.to_string()))
            .collect();
        self.rels.push((id, m, owned(tags)));
    }

    fn write(&self, path: &Path) {
        let mut w = PbfWriter::new(File::create(path).unwrap()).unwrap();
        for &(id, lon, lat) in &self.nodes {
            w.node(id, lon, lat, &[]).unwrap();
        }
        let pairs = |t: &[(String, String)]| -> Vec<(String, String)> { t.to_vec() };
        for (id, refs, tags) in &self.ways {
            let t = pairs(tags);
            let t: Vec<(&str, &str)> = t.iter().map(|(k, v)| (k.as_str(), v.as_str())).collect();
            w.way(*id, refs, &t).unwrap();
        }
        for (id, members, tags) in &self.rels {
            let t: Vec<(&str, &str)> = tags.iter().map(|(k, v)| (k.as_str(), v.as_str())).collect();
            let m: Vec<(MemberKind, i64, &str)> = members
                .iter()
                .map(|(k, i, r)| (*k, *i, r.as_str()))
                .collect();
            w.relation(*id, &m, &t).unwrap();
        }
        w.finish().unwrap();
    }
}

/// An axis-aligned rectangle, counter-clockwise.
fn square(x: f64, y: f64, w: f64, h: f64) -> Vec<(f64, f64)> {
    vec![(x, y), (x + w, y), (x + w, y + h), (x, y + h)]
}

/// Writes `osm` plus two good buildings (way/1 and way/2), runs it at LOD 1 and checks that the
/// run succeeded and both good buildings are written beside whatever `osm` gave.
fn osm_case(build: impl FnOnce(&mut Osm), extra: &[&str]) -> (tempfile::TempDir, Ran) {
    let dir = tempfile::tempdir().unwrap();
    let mut osm = Osm::default();
    osm.good(1, 0);
    osm.good(2, 1);
    build(&mut osm);
    let pbf = dir.path().join("in.osm.pbf");
    osm.write(&pbf);
    let r = ok_run(dir.path(), "--osm", &pbf, extra);
    assert!(r.count("generated") >= 2, "{}", show(&r.out));
    assert_eq!(r.glb_buildings() as u64, r.count("generated"));
    assert!(r.entries("way/1").iter().all(|(o, _)| o == "note"));
    assert!(r.entries("way/2").iter().all(|(o, _)| o == "note"));
    (dir, r)
}

/// The one entry with outcome `outcome` about `id`, whose reason contains `needle`.
fn has_entry(r: &Ran, id: &str, outcome: &str, needle: &str) {
    let e = r.entries(id);
    assert!(
        e.iter()
            .any(|(o, why)| o == outcome && why.contains(needle)),
        "no {outcome} entry for {id} with {needle:?}: {e:?}"
    );
}

/// A per-footprint case whose defective building `id` is skipped with a reason containing
/// `needle`, and the 2 good ones are generated.
fn skipped_case(build: impl FnOnce(&mut Osm), id: &str, needle: &str) {
    let (_d, r) = osm_case(build, &[]);
    has_entry(&r, id, "skipped", needle);
    assert_eq!(r.count("generated"), 2);
    assert_eq!(r.count("skipped"), 1);
}

/// A per-footprint case whose defective building `id` is generated (3 buildings in all), with
/// a report entry of `outcome` containing `needle` (no entry needed when `outcome` is "").
fn generated_case(
    build: impl FnOnce(&mut Osm),
    id: &str,
    outcome: &str,
    needle: &str,
) -> (tempfile::TempDir, Ran) {
    let (d, r) = osm_case(build, &[]);
    assert_eq!(r.count("generated"), 3, "{:?}", r.report());
    assert_eq!(r.count("skipped"), 0, "{:?}", r.report());
    if !outcome.is_empty() {
        has_entry(&r, id, outcome, needle);
    }
    (d, r)
}

// ---- 1. not a PBF at all --------------------------------------------------------------------

fn bad_file(name: &str, bytes: &[u8]) -> (tempfile::TempDir, PathBuf) {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join(name);
    std::fs::write(&p, bytes).unwrap();
    (dir, p)
}

fn run_osm_file(p: &Path) -> Output {
    let out = p.with_extension("glb");
    // These cases test the reader: a file that yields no building is allowed to make an empty
    // run here (the empty-run rule has its own tests).
    citygen(&[
        "--osm",
        p.to_str().unwrap(),
        "--kb",
        KB,
        "--lod",
        "1",
        "--gltf",
        out.to_str().unwrap(),
        "--allow-empty",
        "--quiet",
    ])
}

/// Exit 1 naming the file and `needle`; no output written.
fn osm_fatal(name: &str, bytes: &[u8], needles: &[&str]) {
    let (_d, p) = bad_file(name, bytes);
    let out = run_osm_file(&p);
    let mut n = vec![name];
    n.extend_from_slice(needles);
    fatal(&out, 1, &n);
    assert!(!p.with_extension("glb").exists());
}

#[test]
fn pbf_empty_file() {
    osm_fatal("empty.osm.pbf", b"", &["not an OSM PBF file", "empty"]);
}

#[test]
fn pbf_text_file() {
    // OSM XML named as a PBF is read as XML (the content decides): this one's node has no
    // coordinates.
    osm_fatal(
        "text.osm.pbf",
        b"<?xml version='1.0'?>\n<osm version='0.6'><node id='1'/></osm>\n",
        &["OSM XML line 2", "node/1", "no lat attribute"],
    );
    osm_fatal(
        "text.osm.pbf",
        b"name,height\nA,12\n",
        &["not an OSM PBF file"],
    );
}

#[test]
fn pbf_random_bytes() {
    // A fixed xorshift stream: reproducible "random" bytes.
    let mut x = 0x9E37_79B9_7F4A_7C15u64;
    let bytes: Vec<u8> = (0..4096)
        .map(|_| {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            x as u8
        })
        .collect();
    osm_fatal("random.osm.pbf", &bytes, &["not an OSM PBF file"]);
}

#[test]
fn pbf_png_header() {
    let mut png = b"\x89PNG\r\n\x1a\n\0\0\0\rIHDR\0\0\0\x10\0\0\0\x10\x08\x06\0\0\0".to_vec();
    png.extend_from_slice(&[0u8; 64]);
    osm_fatal("image.osm.pbf", &png, &["not an OSM PBF file"]);
}

#[test]
fn pbf_missing_file_and_directory() {
    let dir = tempfile::tempdir().unwrap();
    let missing = dir.path().join("nowhere.osm.pbf");
    fatal(&run_osm_file(&missing), 1, &["nowhere.osm.pbf"]);
    let d = dir.path().join("folder.osm.pbf");
    std::fs::create_dir(&d).unwrap();
    fatal(&run_osm_file(&d), 1, &["folder.osm.pbf", "directory"]);
}

// ---- 2. truncated and corrupt PBF -----------------------------------------------------------

/// The blobs of a PBF file: (start offset, header length, data start, data length).
fn blobs(bytes: &[u8]) -> Vec<(usize, usize, usize, usize)> {
    let mut out = Vec::new();
    let mut pos = 0;
    while pos + 4 <= bytes.len() {
        let hlen = u32::from_be_bytes(bytes[pos..pos + 4].try_into().unwrap()) as usize;
        let h = &bytes[pos + 4..pos + 4 + hlen];
        // The last varint of our headers and of osmium's is field 3 (datasize).
        let i = h.iter().rposition(|&b| b == 0x18).unwrap();
        let mut size = 0usize;
        for (k, b) in h[i + 1..].iter().enumerate() {
            size |= ((b & 0x7f) as usize) << (7 * k);
        }
        out.push((pos, hlen, pos + 4 + hlen, size));
        pos += 4 + hlen + size;
    }
    assert_eq!(pos, bytes.len());
    out
}

fn monaco_bytes() -> Vec<u8> {
    std::fs::read(common::root().join(MONACO)).unwrap()
}

#[test]
fn pbf_truncated_mid_blob_header() {
    let b = monaco_bytes();
    let bl = blobs(&b);
    let (start, hlen, _, _) = bl[2];
    let cut = &b[..start + 4 + hlen / 2];
    osm_fatal(
        "cut_header.osm.pbf",
        cut,
        &[
            "corrupt or truncated PBF",
            "block 2",
            &format!("byte offset {start}"),
        ],
    );
}

#[test]
fn pbf_truncated_mid_blob() {
    let b = monaco_bytes();
    let bl = blobs(&b);
    let (start, _, data, len) = bl[3];
    osm_fatal(
        "cut_blob.osm.pbf",
        &b[..data + len / 2],
        &[
            "corrupt or truncated PBF",
            "block 3",
            &format!("byte offset {start}"),
        ],
    );
}

#[test]
fn pbf_truncated_after_header_length() {
    // Only the 4-byte length of the first blob header.
    let b = monaco_bytes();
    osm_fatal("four_bytes.osm.pbf", &b[..4], &["not an OSM PBF file"]);
}

#[test]
fn pbf_flipped_bytes_in_zlib_stream() {
    let mut b = monaco_bytes();
    let bl = blobs(&b);
    let (start, _, data, len) = bl[1];
    // Flip a run of bytes in the middle of the compressed stream.
    for x in &mut b[data + len / 2..data + len / 2 + 16] {
        *x ^= 0xA5;
    }
    osm_fatal(
        "flipped.osm.pbf",
        &b,
        &[
            "corrupt or truncated PBF",
            "block 1",
            &format!("byte offset {start}"),
        ],
    );
}

#[test]
fn pbf_absurd_blob_size() {
    // A blob header claiming a 2^31-byte blob (datasize is an int32: 2^31 overflows it).
    let mut b = monaco_bytes();
    let bl = blobs(&b);
    let (start, hlen, _, _) = bl[1];
    let h = &b[start + 4..start + 4 + hlen];
    let i = h.iter().rposition(|&x| x == 0x18).unwrap();
    let mut header = h[..=i].to_vec();
    header.extend_from_slice(&[0x80, 0x80, 0x80, 0x80, 0x08]); // 2^31
    let mut out = b[..start].to_vec();
    out.extend_from_slice(&(header.len() as u32).to_be_bytes());
    out.extend_from_slice(&header);
    out.extend_from_slice(&b[start + 4 + hlen..]);
    b = out;
    osm_fatal(
        "huge_blob.osm.pbf",
        &b,
        &[
            "corrupt or truncated PBF",
            "block 1",
            &format!("byte offset {start}"),
        ],
    );
}

#[test]
fn pbf_absurd_blob_header_length() {
    // The 4-byte header length of block 1 says 2^31 - 1.
    let mut b = monaco_bytes();
    let start = blobs(&b)[1].0;
    b[start..start + 4].copy_from_slice(&0x7fff_ffffu32.to_be_bytes());
    osm_fatal(
        "huge_header.osm.pbf",
        &b,
        &[
            "corrupt or truncated PBF",
            "block 1",
            &format!("byte offset {start}"),
        ],
    );
}

/// A tiny valid file (a header and one node block) as bytes.
fn tiny_pbf() -> Vec<u8> {
    let mut w = PbfWriter::new(Vec::new()).unwrap();
    w.node(1, LON0, LAT0, &[]).unwrap();
    w.finish().unwrap()
}

/// Replaces the type string of blob `k` by `t` (same length keeps the framing).
fn retype(bytes: &mut [u8], k: usize, t: &[u8]) {
    let (start, hlen, _, _) = blobs(bytes)[k];
    let h = &mut bytes[start + 4..start + 4 + hlen];
    // Field 1 (type), length-delimited: 0x0a, len, text.
    assert_eq!(h[0], 0x0a);
    let n = h[1] as usize;
    assert_eq!(n, t.len());
    h[2..2 + n].copy_from_slice(t);
}

#[test]
fn pbf_first_blob_is_data() {
    let mut b = tiny_pbf();
    retype(&mut b, 0, b"OSMData__");
    osm_fatal("no_header.osm.pbf", &b, &["not an OSM PBF file"]);
}

#[test]
fn pbf_unknown_first_blob_type() {
    let mut b = tiny_pbf();
    retype(&mut b, 0, b"OSMHeadeX");
    osm_fatal(
        "unknown_type.osm.pbf",
        &b,
        &["not an OSM PBF file", "OSMHeadeX"],
    );
}

#[test]
fn pbf_data_blob_typed_as_header() {
    // Block 1 says OSMHeader but holds a PrimitiveBlock.
    let mut b = tiny_pbf();
    retype(&mut b, 1, b"OSMHead");
    let (_d, p) = bad_file("two_headers.osm.pbf", &b);
    let out = run_osm_file(&p);
    no_panic(&out);
    // A PrimitiveBlock is not a valid HeaderBlock: either refused (block 1) or, decoded leniently,
    // a file without buildings. Never a crash, never a building.
    match out.status.code() {
        Some(1) => fatal(&out, 1, &["two_headers.osm.pbf", "block 1"]),
        _ => assert_eq!(out.status.code(), Some(0), "{}", show(&out)),
    }
}

#[test]
fn pbf_trailing_garbage() {
    let mut b = tiny_pbf();
    let len = b.len();
    b.extend_from_slice(b"\0\0");
    osm_fatal(
        "trailing.osm.pbf",
        &b,
        &["corrupt or truncated PBF", &format!("byte offset {len}")],
    );
}

#[test]
fn pbf_raw_size_lies() {
    // raw_size (Blob field 2) larger than the inflated data: refused, not trusted.
    let mut b = tiny_pbf();
    let (start, _, data, _) = blobs(&b)[1];
    assert_eq!(b[data], 0x10, "Blob starts with raw_size");
    b[data + 1] = 0x7f; // a one-byte varint: 127 bytes, more than the node block inflates to
    let out = {
        let (_d, p) = bad_file("raw_size.osm.pbf", &b);
        run_osm_file(&p)
    };
    // osmpbf may or may not check raw_size; either way no panic, and if refused, the place.
    no_panic(&out);
    if out.status.code() != Some(0) {
        fatal(
            &out,
            1,
            &[
                "raw_size.osm.pbf",
                "block 1",
                &format!("byte offset {start}"),
            ],
        );
    }
}

// ---- 3. per-footprint defects ---------------------------------------------------------------

#[test]
fn way_with_missing_nodes() {
    skipped_case(
        |o| {
            let mut refs = o.ring(&square(0.0, 0.0, 10.0, 10.0));
            refs[1] = 999_999;
            o.way(10, refs, &[("building", "yes")]);
        },
        "way/10",
        "nodes missing",
    );
}

#[test]
fn unclosed_way() {
    skipped_case(
        |o| {
            let refs = o.open(&square(0.0, 0.0, 10.0, 10.0));
            o.way(10, refs, &[("building", "yes")]);
        },
        "way/10",
        "unclosed way",
    );
}

#[test]
fn way_with_one_node() {
    skipped_case(
        |o| {
            let refs = o.open(&[(0.0, 0.0)]);
            o.way(10, refs, &[("building", "yes")]);
        },
        "way/10",
        "1 node",
    );
}

#[test]
fn way_with_no_node() {
    skipped_case(
        |o| o.way(10, vec![], &[("building", "yes")]),
        "way/10",
        "0 node",
    );
}

#[test]
fn bow_tie() {
    // The two triangles of a figure 8 crossing at (5, 5).
    generated_case(
        |o| {
            o.building(
                10,
                &[(0.0, 0.0), (10.0, 10.0), (10.0, 0.0), (0.0, 10.0)],
                &[],
            )
        },
        "way/10",
        "repaired",
        "",
    );
}

#[test]
fn self_intersecting_polygon() {
    // A square whose right edge loops back across the left part.
    generated_case(
        |o| {
            o.building(
                10,
                &[
                    (0.0, 0.0),
                    (20.0, 0.0),
                    (20.0, 10.0),
                    (5.0, 10.0),
                    (15.0, -5.0),
                    (0.0, 10.0),
                ],
                &[],
            )
        },
        "way/10",
        "repaired",
        "",
    );
}

#[test]
fn duplicate_vertices() {
    generated_case(
        |o| {
            let mut refs = o.ring(&square(0.0, 0.0, 10.0, 10.0));
            // Node 2 twice in a row, and a second node at the same place as node 3.
            refs.insert(2, refs[1]);
            let twin = o.open(&[(10.0, 10.0)])[0];
            refs.insert(4, twin);
            o.way(10, refs, &[("building", "yes")]);
        },
        "way/10",
        "",
        "",
    );
}

#[test]
fn collinear_vertices() {
    generated_case(
        |o| {
            let pts: Vec<(f64, f64)> = (0..10)
                .map(|i| (i as f64, 0.0))
                .chain([(10.0, 0.0), (10.0, 10.0), (5.0, 10.0), (0.0, 10.0)])
                .collect();
            o.building(10, &pts, &[]);
        },
        "way/10",
        "",
        "",
    );
}

#[test]
fn zero_area_footprint() {
    skipped_case(
        |o| o.building(10, &[(0.0, 0.0), (5.0, 0.0), (10.0, 0.0)], &[]),
        "way/10",
        "area",
    );
}

#[test]
fn sliver_footprint() {
    // 20 m long, 1 mm wide.
    skipped_case(
        |o| o.building(10, &square(0.0, 0.0, 20.0, 0.001), &[]),
        "way/10",
        "",
    );
}

#[test]
fn spike() {
    // A square with a 30 m needle out of its top edge.
    let _ = generated_case(
        |o| {
            o.building(
                10,
                &[
                    (0.0, 0.0),
                    (10.0, 0.0),
                    (10.0, 10.0),
                    (5.0, 10.0),
                    (5.0, 40.0),
                    (5.0, 10.0),
                    (0.0, 10.0),
                ],
                &[],
            )
        },
        "way/10",
        "repaired",
        "",
    );
}

#[test]
fn ten_thousand_vertex_footprint() {
    let pts: Vec<(f64, f64)> = (0..10_000)
        .map(|i| {
            let a = i as f64 / 10_000.0 * std::f64::consts::TAU;
            (15.0 * a.cos(), 15.0 * a.sin())
        })
        .collect();
    generated_case(|o| o.building(10, &pts, &[]), "way/10", "", "");
}

// ---- 4. broken multipolygons ----------------------------------------------------------------

const MP: [(&str, &str); 2] = [("type", "multipolygon"), ("building", "yes")];

#[test]
fn multipolygon_missing_member() {
    generated_case(
        |o| {
            let outer = o.ring(&square(0.0, 0.0, 20.0, 20.0));
            o.way(10, outer, &[]);
            o.relation(20, &[(10, "outer"), (11, "inner")], &MP);
        },
        "relation/20",
        "repaired",
        "missing from the file",
    );
}

#[test]
fn multipolygon_missing_outer_member() {
    skipped_case(
        |o| {
            let inner = o.ring(&square(5.0, 5.0, 5.0, 5.0));
            o.way(11, inner, &[]);
            o.relation(20, &[(10, "outer"), (11, "inner")], &MP);
        },
        "relation/20",
        "way/10",
    );
}

#[test]
fn multipolygon_overlapping_inners() {
    generated_case(
        |o| {
            let outer = o.ring(&square(0.0, 0.0, 30.0, 30.0));
            let a = o.ring(&square(5.0, 5.0, 10.0, 10.0));
            let b = o.ring(&square(10.0, 10.0, 10.0, 10.0));
            o.way(10, outer, &[]);
            o.way(11, a, &[]);
            o.way(12, b, &[]);
            o.relation(20, &[(10, "outer"), (11, "inner"), (12, "inner")], &MP);
        },
        "relation/20",
        "",
        "",
    );
}

#[test]
fn multipolygon_inner_outside_outer() {
    // The "inner" lies beside the outer: it becomes a second outer (role fixed by containment).
    generated_case(
        |o| {
            let outer = o.ring(&square(0.0, 0.0, 10.0, 10.0));
            let inner = o.ring(&square(20.0, 0.0, 5.0, 5.0));
            o.way(10, outer, &[]);
            o.way(11, inner, &[]);
            o.relation(20, &[(10, "outer"), (11, "inner")], &MP);
        },
        "relation/20",
        "repaired",
        "role",
    );
}

#[test]
fn multipolygon_without_outer() {
    // Only inner-role rings: the ring roles are fixed by containment.
    generated_case(
        |o| {
            let a = o.ring(&square(0.0, 0.0, 10.0, 10.0));
            o.way(11, a, &[]);
            o.relation(20, &[(11, "inner")], &MP);
        },
        "relation/20",
        "repaired",
        "role",
    );
}

#[test]
fn multipolygon_without_members() {
    skipped_case(|o| o.relation(20, &[], &MP), "relation/20", "");
}

#[test]
fn multipolygon_open_ring() {
    skipped_case(
        |o| {
            let a = o.open(&[(0.0, 0.0), (10.0, 0.0), (10.0, 10.0)]);
            let b = o.open(&[(0.0, 10.0), (-1.0, 5.0)]);
            o.way(10, a, &[]);
            o.way(11, b, &[]);
            o.relation(20, &[(10, "outer"), (11, "outer")], &MP);
        },
        "relation/20",
        "cannot be closed",
    );
}

// ---- 5. absurd tags -------------------------------------------------------------------------

/// A 10 x 10 m building way/10 with `tags`: generated, with a note naming `needle`.
fn tag_case(tags: &[(&str, &str)], needle: &str) {
    let _ = generated_case(
        |o| o.building(10, &square(0.0, 0.0, 10.0, 10.0), tags),
        "way/10",
        "note",
        needle,
    );
}

#[test]
fn height_negative() {
    tag_case(&[("height", "-5")], "height=-5");
}

#[test]
fn height_huge() {
    tag_case(&[("height", "1e9")], "height=1e9");
}

#[test]
fn height_nan_and_inf() {
    tag_case(&[("height", "NaN")], "height=NaN");
    tag_case(&[("height", "inf")], "height=inf");
}

#[test]
fn height_words() {
    tag_case(&[("height", "tall")], "height=tall");
}

#[test]
fn height_with_unit_is_read() {
    // "12 m" is a valid height: no note, and the building is 12 m tall.
    let (_d, r) = generated_case(
        |o| o.building(10, &square(0.0, 0.0, 10.0, 10.0), &[("height", "12 m")]),
        "way/10",
        "",
        "",
    );
    assert!(r
        .entries("way/10")
        .iter()
        .all(|(_, why)| !why.contains("height")));
}

#[test]
fn levels_absurd() {
    tag_case(&[("building:levels", "-3")], "building:levels=-3");
    tag_case(&[("building:levels", "1e6")], "building:levels=1e6");
}

#[test]
fn roof_shape_number() {
    tag_case(&[("roof:shape", "9.0")], "roof:shape=9.0");
}

#[test]
fn roof_height_above_height() {
    let _ = generated_case(
        |o| {
            o.building(
                10,
                &square(0.0, 0.0, 10.0, 10.0),
                &[
                    ("height", "8"),
                    ("roof:height", "20"),
                    ("roof:shape", "gabled"),
                ],
            )
        },
        "way/10",
        "note",
        "roof",
    );
}

/// The highest vertex of the GLB (glTF is y-up), from the POSITION accessors' bounds.
fn glb_top(r: &Ran) -> f64 {
    let (json, _) = common::glb_json(&r.dir.join("out.glb"));
    let accessors = json["accessors"].as_array().unwrap();
    let mut top = f64::NEG_INFINITY;
    for mesh in json["meshes"].as_array().unwrap() {
        for prim in mesh["primitives"].as_array().unwrap() {
            let a = prim["attributes"]["POSITION"].as_u64().unwrap() as usize;
            top = top.max(accessors[a]["max"][1].as_f64().unwrap());
        }
    }
    top
}

#[test]
fn roof_angle_near_vertical_is_bounded() {
    // roof:angle=89.9999 over a 10 m house would be a roof 2,858 km high.
    let (_d, r) = generated_case(
        |o| {
            o.building(
                10,
                &square(0.0, 0.0, 10.0, 10.0),
                &[
                    ("building:levels", "2"),
                    ("roof:angle", "89.9999"),
                    ("roof:shape", "gabled"),
                ],
            )
        },
        "way/10",
        "note",
        "roof:angle=89.9999",
    );
    // 85° over a 5 m half-width: 57 m of roof on 2 storeys.
    let top = glb_top(&r);
    assert!(top > 50.0 && top < 80.0, "top {top}");
}

#[test]
fn roof_height_absurd_is_bounded() {
    let (_d, r) = generated_case(
        |o| {
            o.building(
                10,
                &square(0.0, 0.0, 10.0, 10.0),
                &[("roof:height", "900"), ("roof:shape", "pyramidal")],
            )
        },
        "way/10",
        "note",
        "roof:height=900",
    );
    assert!(glb_top(&r) < 400.0, "top {}", glb_top(&r));
}

#[test]
fn min_height_above_height() {
    // Either skipped with a reason or generated with a note: never a panic or a lost building.
    let (_d, r) = osm_case(
        |o| {
            o.building(
                10,
                &square(0.0, 0.0, 10.0, 10.0),
                &[("height", "8"), ("min_height", "12")],
            )
        },
        &[],
    );
    assert!(!r.entries("way/10").is_empty(), "{:?}", r.report());
    assert!(r
        .entries("way/10")
        .iter()
        .any(|(_, why)| why.contains("min_height")));
}

// ---- shapefiles -----------------------------------------------------------------------------

/// A copy of the Clifton shapefile in a fresh folder, as `clifton.*`; `edit` may break it.
fn clifton_copy(edit: impl FnOnce(&Path)) -> (tempfile::TempDir, PathBuf) {
    let dir = tempfile::tempdir().unwrap();
    for ext in ["shp", "shx", "dbf", "prj", "cpg"] {
        std::fs::copy(
            common::root().join(format!("data/clifton/clifton_test.{ext}")),
            dir.path().join(format!("clifton.{ext}")),
        )
        .unwrap();
    }
    edit(dir.path());
    let shp = dir.path().join("clifton.shp");
    (dir, shp)
}

fn run_shp(shp: &Path, dir: &Path) -> Output {
    let out = dir.join("out.gml");
    citygen(&[
        "--shp",
        shp.to_str().unwrap(),
        "--kb",
        KB,
        "--lod",
        "1",
        "--citygml",
        out.to_str().unwrap(),
        "--quiet",
    ])
}

#[test]
fn shapefile_missing_shx() {
    let (d, shp) = clifton_copy(|d| std::fs::remove_file(d.join("clifton.shx")).unwrap());
    fatal(&run_shp(&shp, d.path()), 1, &["clifton"]);
}

#[test]
fn shapefile_missing_dbf() {
    let (d, shp) = clifton_copy(|d| std::fs::remove_file(d.join("clifton.dbf")).unwrap());
    fatal(&run_shp(&shp, d.path()), 1, &["clifton"]);
}

#[test]
fn shapefile_truncated_dbf() {
    let (d, shp) = clifton_copy(|d| {
        let p = d.join("clifton.dbf");
        let bytes = std::fs::read(&p).unwrap();
        std::fs::write(&p, &bytes[..bytes.len() / 2]).unwrap();
    });
    fatal(&run_shp(&shp, d.path()), 1, &["clifton"]);
}

#[test]
fn shapefile_garbage_dbf_header() {
    let (d, shp) =
        clifton_copy(|d| std::fs::write(d.join("clifton.dbf"), b"not a dbase file").unwrap());
    fatal(&run_shp(&shp, d.path()), 1, &["clifton"]);
}

#[test]
fn shapefile_of_points_is_refused() {
    // The header's shape type (offset 32, little endian) says Point.
    let (d, shp) = clifton_copy(|d| {
        let p = d.join("clifton.shp");
        let mut bytes = std::fs::read(&p).unwrap();
        bytes[32..36].copy_from_slice(&1i32.to_le_bytes());
        std::fs::write(&p, bytes).unwrap();
    });
    let out = run_shp(&shp, d.path());
    no_panic(&out);
    assert_ne!(out.status.code(), Some(0), "{}", show(&out));
}

#[test]
fn shapefile_truncated_shp() {
    let (d, shp) = clifton_copy(|d| {
        let p = d.join("clifton.shp");
        let bytes = std::fs::read(&p).unwrap();
        std::fs::write(&p, &bytes[..bytes.len() * 2 / 3]).unwrap();
    });
    let out = run_shp(&shp, d.path());
    no_panic(&out);
    assert!(
        matches!(out.status.code(), Some(0) | Some(1)),
        "a truncated .shp is an input error or a partial read: {}",
        show(&out)
    );
}

// ---- knowledge bases and grammars -----------------------------------------------------------

fn run_with(flag: &str, file: &Path, dir: &Path) -> Output {
    let out = dir.join("out.gml");
    citygen(&[
        "--osm",
        MONACO,
        flag,
        file.to_str().unwrap(),
        "--lod",
        "1",
        "--citygml",
        out.to_str().unwrap(),
        "--quiet",
    ])
}

fn kb_fatal(name: &str, text: &str, needles: &[&str]) {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join(name);
    std::fs::write(&p, text).unwrap();
    let mut all = vec![name];
    all.extend_from_slice(needles);
    fatal(&run_with("--kb", &p, dir.path()), 1, &all);
}

#[test]
fn kb_unclosed_tag() {
    kb_fatal(
        "unclosed.xml",
        "<earth name=\"earth\">\n  <country name=\"x\">\n</earth>\n",
        &[],
    );
}

#[test]
fn kb_entity_bomb() {
    let bomb = "<?xml version=\"1.0\"?>\n<!DOCTYPE lolz [<!ENTITY lol \"lol\"><!ENTITY lol2 \"&lol;&lol;&lol;&lol;\">]>\n<earth>&lol2;</earth>\n";
    kb_fatal("bomb.xml", bomb, &[]);
}

#[test]
fn kb_not_xml() {
    kb_fatal("binary.xml", "\u{1}\u{2}PNG garbage", &[]);
}

fn rules_fatal(name: &str, text: &str, needles: &[&str]) {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join(name);
    std::fs::write(&p, text).unwrap();
    let mut all = vec![name];
    all.extend_from_slice(needles);
    fatal(&run_with("--rules", &p, dir.path()), 1, &all);
}

#[test]
fn grammar_syntax_error_names_line_and_column() {
    rules_fatal("broken.cga", "lot -> extrude(10){ mass\n", &[":1:"]);
}

#[test]
fn grammar_unknown_operation() {
    rules_fatal("unknown.cga", "lot -> frobnicate(3){a}\n", &["frobnicate"]);
}

#[test]
fn grammar_rule_bomb_ends_with_a_report_entry_per_building() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("bomb.cga");
    std::fs::write(&p, "lot -> a\na -> split(X, 1, 1){a | a}\n").unwrap();
    let out = run_with("--rules", &p, dir.path());
    no_panic(&out);
}

#[test]
fn a_duplicate_way_id_is_reported_and_its_first_copy_used() {
    // way/3 twice (an extract merged twice): the first copy is the building.
    let (_d, r) = osm_case(
        |o| {
            o.building(3, &square(0.0, 0.0, 12.0, 10.0), &[("height", "9")]);
            o.building(3, &square(40.0, 0.0, 30.0, 30.0), &[("height", "30")]);
        },
        &[],
    );
    has_entry(
        &r,
        "way/3",
        "note",
        "appears 2 times in the file: the first is used",
    );
    assert_eq!(r.count("generated"), 3);
}

#[test]
fn coordinates_outside_the_earth_are_skipped_not_wrapped() {
    skipped_case(
        |o| {
            let mut refs = o.ring(&square(0.0, 0.0, 12.0, 10.0));
            // One corner at latitude 95: a broken writer, not a place.
            let id = 1 + o.nodes.len() as i64;
            o.nodes.push((id, LON0, 95.0));
            refs.insert(1, id);
            o.way(3, refs, &[("building", "yes")]);
        },
        "way/3",
        "outside the Earth (longitude 7.42000, latitude 95.00000",
    );
}

// ---- outputs --------------------------------------------------------------------------------

#[test]
fn output_into_a_directory_path_is_an_output_error() {
    let dir = tempfile::tempdir().unwrap();
    let target = dir.path().join("taken.gml");
    std::fs::create_dir(&target).unwrap();
    let out = citygen(&[
        "--osm",
        MONACO,
        "--kb",
        KB,
        "--lod",
        "1",
        "--citygml",
        target.to_str().unwrap(),
        "--quiet",
    ]);
    fatal(&out, 3, &["taken"]);
}

/// Files with known bytes at the given names in `dir`, to check that a refused run leaves them.
fn existing(dir: &Path, names: &[&str]) -> Vec<(PathBuf, Vec<u8>)> {
    names
        .iter()
        .map(|n| {
            let p = dir.join(n);
            let bytes = format!("old {n}\n").into_bytes();
            std::fs::write(&p, &bytes).unwrap();
            (p, bytes)
        })
        .collect()
}

fn unchanged(files: &[(PathBuf, Vec<u8>)]) {
    for (p, bytes) in files {
        assert_eq!(&std::fs::read(p).unwrap(), bytes, "{} changed", p.display());
    }
}

/// `citygen --osm MONACO --kb KB --lod 1` with `extra` arguments.
fn monaco_with(extra: &[&str]) -> Output {
    let mut args = vec!["--osm", MONACO, "--kb", KB, "--lod", "1", "--quiet"];
    args.extend(extra);
    citygen(&args)
}

#[test]
fn two_outputs_on_one_path_exit_2_before_writing_anything() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let files = existing(d, &["x.ifc"]);
    let x = d.join("x.ifc");
    let x = x.to_str().unwrap();
    // The report on the IFC's path: the extension says so first.
    let out = monaco_with(&["--ifc", x, "--report", x]);
    fatal(&out, 2, &["--report", "x.ifc", "must end in .json"]);
    unchanged(&files);
    // Same format, other spelling of the same file (through `..`), extensions waived.
    let again = d.join("sub/../x.ifc");
    let out = monaco_with(&[
        "--ifc",
        x,
        "--report",
        again.to_str().unwrap(),
        "--force-extension",
    ]);
    fatal(&out, 2, &["--ifc", "--report", "are the same file"]);
    unchanged(&files);
    // IFC and CityGML on one path.
    let out = monaco_with(&["--ifc", x, "--citygml", x]);
    fatal(&out, 2, &["--citygml", "x.ifc"]);
    unchanged(&files);
    assert_eq!(
        std::fs::read_dir(d).unwrap().count(),
        1,
        "a refused run left a file"
    );
}

/// A tiled run writes its manifest (`citygen-manifest.I-of-N.json`) beside its outputs:
/// `--report` (or `--preview`, extensions waived) on that path is refused before anything is
/// written, whichever spelling names it, and a file already there stays as it was.
#[test]
fn the_report_on_the_runs_own_manifest_is_refused_before_writing() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let files = existing(
        d,
        &[
            "citygen-manifest.0-of-1.json",
            "citygen-manifest.1-of-2.json",
        ],
    );
    let manifest = d.join("citygen-manifest.0-of-1.json");
    let m = manifest.to_str().unwrap();
    // The manifest goes into the report's folder, on the report's path.
    let city = d.join("models/x.city.json");
    let c = city.to_str().unwrap();
    let out = monaco_with(&["--tile", "500", "--cityjson", c, "--report", m]);
    fatal(
        &out,
        2,
        &["--report", m, "is the manifest this tiled run writes"],
    );
    unchanged(&files);
    // Spelled through `..`.
    let again = d.join("sub/../citygen-manifest.0-of-1.json");
    let out = monaco_with(&[
        "--tile",
        "500",
        "--cityjson",
        c,
        "--report",
        again.to_str().unwrap(),
    ]);
    fatal(
        &out,
        2,
        &[
            "--report",
            "sub/../citygen-manifest.0-of-1.json",
            "manifest",
        ],
    );
    unchanged(&files);
    // A shard's picture on its manifest (the shard's report is renamed, its picture is not).
    let shard_manifest = d.join("citygen-manifest.1-of-2.json");
    let out = monaco_with(&[
        "--tile",
        "500",
        "--shard",
        "1/2",
        "--cityjson",
        d.join("x.city.json").to_str().unwrap(),
        "--preview",
        shard_manifest.to_str().unwrap(),
        "--force-extension",
    ]);
    fatal(
        &out,
        2,
        &["--preview", "citygen-manifest.1-of-2.json", "manifest"],
    );
    unchanged(&files);
    assert_eq!(
        std::fs::read_dir(d).unwrap().count(),
        2,
        "a refused run left a file"
    );
    // The same run with the report elsewhere goes through and writes the manifest.
    let report = d.join("report.json");
    let out = monaco_with(&[
        "--tile",
        "500",
        "--cityjson",
        c,
        "--report",
        report.to_str().unwrap(),
    ]);
    assert!(out.status.success(), "{}", show(&out));
    assert_ne!(std::fs::read(&manifest).unwrap(), files[0].1);
}

#[test]
fn an_output_in_a_folder_that_is_a_file_or_of_the_wrong_format_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let files = existing(d, &["README.md"]);
    let under = d.join("README.md/x.ifc");
    let out = monaco_with(&["--ifc", under.to_str().unwrap()]);
    fatal(&out, 2, &["--ifc", "README.md", "is a file, not a folder"]);
    unchanged(&files);
    let gml = d.join("out.gml");
    let out = monaco_with(&["--ifc", gml.to_str().unwrap()]);
    fatal(&out, 2, &["--ifc", "out.gml", "must end in .ifc"]);
    assert!(!gml.exists());
}

#[test]
fn an_output_on_an_input_is_refused_and_the_input_is_untouched() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let pbf = d.join("in.osm.pbf");
    std::fs::copy(MONACO, &pbf).unwrap();
    let kb = d.join("kb.xml");
    std::fs::copy(KB, &kb).unwrap();
    let before = (std::fs::read(&pbf).unwrap(), std::fs::read(&kb).unwrap());
    let (p, k) = (pbf.to_str().unwrap(), kb.to_str().unwrap());
    let out = citygen(&[
        "--osm",
        p,
        "--kb",
        k,
        "--ifc",
        p,
        "--force-extension",
        "--quiet",
    ]);
    fatal(
        &out,
        2,
        &[
            "--ifc",
            "the file --osm reads",
            "refusing to overwrite an input",
        ],
    );
    let glb = d.join("o.glb");
    let g = glb.to_str().unwrap();
    let out = citygen(&[
        "--osm",
        p,
        "--kb",
        k,
        "--gltf",
        g,
        "--report",
        k,
        "--force-extension",
        "--quiet",
    ]);
    fatal(&out, 2, &["--report", "the file --kb reads"]);
    // Without --force-extension the extension refuses it first.
    let out = citygen(&["--osm", p, "--kb", k, "--ifc", p, "--quiet"]);
    fatal(&out, 2, &["--ifc", "must end in .ifc"]);
    assert_eq!(
        (std::fs::read(&pbf).unwrap(), std::fs::read(&kb).unwrap()),
        before
    );
    // A shapefile's parts count as inputs too.
    for ext in ["shp", "shx", "dbf", "prj"] {
        let from = common::root().join(format!("data/clifton/clifton_test.{ext}"));
        std::fs::copy(from, d.join(format!("c.{ext}"))).unwrap();
    }
    let dbf = std::fs::read(d.join("c.dbf")).unwrap();
    let out = citygen(&[
        "--shp",
        d.join("c.shp").to_str().unwrap(),
        "--kb",
        k,
        "--gltf",
        g,
        "--report",
        d.join("c.dbf").to_str().unwrap(),
        "--force-extension",
        "--quiet",
    ]);
    fatal(&out, 2, &["--report", "c.dbf", "the file --shp reads"]);
    assert_eq!(std::fs::read(d.join("c.dbf")).unwrap(), dbf);
    assert!(!glb.exists(), "a refused run wrote an output");
}

#[test]
fn a_failing_third_output_leaves_all_three_targets_unchanged() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let files = existing(d, &["x.ifc", "x.gml"]);
    std::fs::create_dir(d.join("x.glb")).unwrap();
    let out = monaco_with(&[
        "--ifc",
        d.join("x.ifc").to_str().unwrap(),
        "--citygml",
        d.join("x.gml").to_str().unwrap(),
        "--gltf",
        d.join("x.glb").to_str().unwrap(),
    ]);
    fatal(&out, 3, &["x.glb", "names a folder"]);
    unchanged(&files);
    assert!(d.join("x.glb").is_dir());
    assert_eq!(
        std::fs::read_dir(d).unwrap().count(),
        3,
        "a refused run left a file"
    );
}

#[test]
fn a_geographic_output_crs_is_refused_naming_the_projected_ones() {
    let dir = tempfile::tempdir().unwrap();
    let ifc = dir.path().join("x.ifc");
    let out = monaco_with(&["--ifc", ifc.to_str().unwrap(), "--crs", "EPSG:4326"]);
    fatal(
        &out,
        2,
        &["EPSG:4326 is geographic", "projected", "EPSG:2154", "UTM"],
    );
    assert!(!ifc.exists());
}

#[test]
fn ten_thousand_threads_run_as_a_few_per_core_with_a_note() {
    let dir = tempfile::tempdir().unwrap();
    let glb = dir.path().join("x.glb");
    let mut args = vec![
        "--osm",
        MONACO,
        "--kb",
        KB,
        "--lod",
        "1",
        "--threads",
        "10000",
    ];
    args.extend(["--gltf", glb.to_str().unwrap()]);
    let out = citygen(&args);
    no_panic(&out);
    assert_eq!(out.status.code(), Some(0), "{}", show(&out));
    assert!(
        String::from_utf8_lossy(&out.stderr).contains("--threads 10000 runs"),
        "{}",
        show(&out)
    );
    assert!(glb.exists());
}

#[test]
fn a_bbox_without_buildings_or_with_swapped_corners_is_an_error_naming_the_extent() {
    let dir = tempfile::tempdir().unwrap();
    let glb = dir.path().join("x.glb");
    let g = glb.to_str().unwrap();
    // Monaco is at 7.42 E, 43.73 N: latitude and longitude swapped.
    let out = monaco_with(&["--gltf", g, "--bbox", "43.7290,7.4180,43.7330,7.4240"]);
    fatal(
        &out,
        1,
        &[
            "--bbox 43.729,7.418,43.733,7.424 holds none of the 1159 buildings",
            "longitude 7.4",
            "look swapped",
        ],
    );
    assert!(!glb.exists());
    // A box in the sea off Monaco.
    let out = monaco_with(&["--gltf", g, "--bbox", "7.50,43.60,7.51,43.61"]);
    fatal(
        &out,
        1,
        &[
            "holds none of the 1159 buildings",
            "latitude 43.7",
            "--allow-empty",
        ],
    );
    assert!(!glb.exists());
    // Asked for, an empty run writes valid empty outputs and says why in the report.
    let report = dir.path().join("r.json");
    let out = monaco_with(&[
        "--gltf",
        g,
        "--report",
        report.to_str().unwrap(),
        "--bbox",
        "7.50,43.60,7.51,43.61",
        "--allow-empty",
    ]);
    assert_eq!(out.status.code(), Some(0), "{}", show(&out));
    assert!(
        glb.exists()
            && std::fs::read_to_string(&report)
                .unwrap()
                .contains("holds none of the 1159")
    );
}

#[test]
fn a_run_that_generates_no_building_fails_unless_allowed() {
    let dir = tempfile::tempdir().unwrap();
    let rules = dir.path().join("bomb.cga");
    // Every building hits the derivation caps and is skipped.
    std::fs::write(&rules, "lot -> repeat(X, 0.0001){lot}\n").unwrap();
    let glb = dir.path().join("x.glb");
    let args = [
        "--osm",
        MONACO,
        "--rules",
        rules.to_str().unwrap(),
        "--lod",
        "1",
        "--gltf",
        glb.to_str().unwrap(),
        "--quiet",
    ];
    let out = citygen(&args);
    fatal(
        &out,
        1,
        &[
            "generated 0 of 1159 buildings",
            "every building was skipped",
            "way/",
            "--allow-empty",
        ],
    );
    assert!(!glb.exists(), "an empty run published an output");
    let mut allowed = args.to_vec();
    allowed.push("--allow-empty");
    let out = citygen(&allowed);
    assert_eq!(out.status.code(), Some(0), "{}", show(&out));
    assert!(glb.exists());
}

// ---- everything at once ---------------------------------------------------------------------

#[test]
fn mixed_file_keeps_every_good_building_and_accounts_for_every_bad_one() {
    // 30 good buildings and one of each per-footprint defect in one file. The outputs are left
    // in target/corpus-mixed/ for CI to check with the validators.
    let out = common::root().join("target/corpus-mixed");
    let _ = std::fs::remove_dir_all(&out);
    std::fs::create_dir_all(&out).unwrap();
    let mut o = Osm::default();
    for i in 0..30 {
        o.good(1000 + i as i64, i);
    }
    // Skipped: missing nodes, no area, fewer than 3 points, a multipolygon without outer.
    let refs = o.ring(&square(0.0, 0.0, 10.0, 10.0));
    o.way(
        10,
        vec![refs[0], refs[1], 999_999, refs[2], refs[0]],
        &[("building", "yes")],
    );
    o.building(11, &[(20.0, 0.0), (30.0, 0.0), (40.0, 0.0)], &[]);
    let two = o.ring(&[(50.0, 0.0), (55.0, 5.0)]);
    o.way(12, two, &[("building", "yes")]);
    let inner = o.ring(&square(65.0, 5.0, 3.0, 3.0));
    o.way(13, inner, &[]);
    o.relation(
        20,
        &[(14, "outer"), (13, "inner")],
        &[("type", "multipolygon"), ("building", "yes")],
    );
    // Repaired or generated with notes: bow tie, spike, absurd tags.
    o.building(
        30,
        &[(0.0, 40.0), (10.0, 50.0), (10.0, 40.0), (0.0, 50.0)],
        &[],
    );
    o.building(
        31,
        &[
            (20.0, 40.0),
            (30.0, 40.0),
            (30.0, 50.0),
            (25.0, 50.0),
            (25.0, 80.0),
            (25.0, 50.0),
            (20.0, 50.0),
        ],
        &[],
    );
    o.building(
        32,
        &square(40.0, 40.0, 10.0, 10.0),
        &[("height", "-5"), ("roof:shape", "9.0")],
    );
    o.building(
        33,
        &square(60.0, 40.0, 10.0, 10.0),
        &[("height", "NaN"), ("building:levels", "1e6")],
    );
    o.building(
        34,
        &square(80.0, 40.0, 10.0, 10.0),
        &[("height", "8"), ("min_height", "12")],
    );
    let pbf = out.join("mixed.osm.pbf");
    o.write(&pbf);
    let p = |n: &str| out.join(n).display().to_string();
    let args = [
        "--osm".to_string(),
        pbf.display().to_string(),
        "--kb".into(),
        KB.into(),
        "--lod".into(),
        "2".into(),
        "--ifc".into(),
        p("mixed.ifc"),
        "--citygml".into(),
        p("mixed.gml"),
        "--gltf".into(),
        p("mixed.glb"),
        "--report".into(),
        p("mixed.json"),
        "--quiet".into(),
    ];
    let refs: Vec<&str> = args.iter().map(String::as_str).collect();
    let run = citygen(&refs);
    no_panic(&run);
    assert_eq!(run.status.code(), Some(0), "{}", show(&run));
    let report: Value =
        serde_json::from_slice(&std::fs::read(out.join("mixed.json")).unwrap()).unwrap();
    let mut skipped: Vec<String> = report["entries"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|e| e["outcome"] == "skipped")
        .map(|e| e["id"].as_str().unwrap().to_string())
        .collect();
    skipped.sort();
    skipped.dedup();
    assert_eq!(
        skipped,
        ["relation/20", "way/10", "way/11", "way/12"],
        "{report:#}"
    );
    assert_eq!(report["generated"], 30 + 5, "{report:#}");
    assert_eq!(report["read"], 30 + 9, "{report:#}");
    for id in ["way/30", "way/31"] {
        assert!(
            report["entries"]
                .as_array()
                .unwrap()
                .iter()
                .any(|e| e["id"] == id && e["outcome"] == "repaired"),
            "{id} is reported as repaired: {report:#}"
        );
    }
    let gml = std::fs::read_to_string(out.join("mixed.gml")).unwrap();
    assert_eq!(gml.matches("<bldg:Building gml:id=").count(), 35);
}

/// An OSM file of 10 m square buildings (`building=yes`), one at each lon/lat.
fn buildings_at(path: &Path, places: &[(f64, f64)]) {
    let mut osm = Osm::default();
    for (i, &(lon, lat)) in places.iter().enumerate() {
        let d = 1e-4;
        let first = osm.nodes.len() as i64 + 1;
        for (k, (x, y)) in [(0.0, 0.0), (d, 0.0), (d, d), (0.0, d)].iter().enumerate() {
            osm.nodes.push((first + k as i64, lon + x, lat + y));
        }
        let refs = vec![first, first + 1, first + 2, first + 3, first];
        osm.way(i as i64 + 1, refs, &[("building", "yes")]);
    }
    osm.write(path);
}

#[test]
fn data_too_wide_for_one_zone_is_refused_and_a_bbox_or_crs_takes_one_place() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let pbf = d.join("two-cities.osm.pbf");
    // Monaco and Lisbon, 16° of longitude apart: one UTM zone would stretch one of them by
    // several per cent.
    buildings_at(
        &pbf,
        &[(7.4200, 43.7300), (7.4210, 43.7300), (-9.1400, 38.7200)],
    );
    let glb = d.join("x.glb");
    let args = |extra: &[&str]| {
        let mut a = vec!["--osm", pbf.to_str().unwrap(), "--kb", KB, "--lod", "1"];
        a.extend(["--gltf", glb.to_str().unwrap(), "--quiet"]);
        a.extend_from_slice(extra);
        a.iter().map(|s| s.to_string()).collect::<Vec<_>>()
    };
    let run = |extra: &[&str]| {
        let a = args(extra);
        citygen(&a.iter().map(String::as_str).collect::<Vec<_>>())
    };
    let out = run(&[]);
    fatal(
        &out,
        1,
        &[
            // The path as given, not only the file name.
            pbf.to_str().unwrap(),
            "too wide for one projection",
            "UTM zones 29 to 32",
            "--bbox",
            "--crs",
        ],
    );
    assert!(!glb.exists());
    // The Lisbon building alone, in its own zone.
    let out = run(&[
        "--bbox=-9.5,38.5,-9.0,39.0",
        "--ifc",
        d.join("x.ifc").to_str().unwrap(),
    ]);
    assert_eq!(out.status.code(), Some(0), "{}", show(&out));
    let ifc = std::fs::read_to_string(d.join("x.ifc")).unwrap();
    assert!(ifc.contains("EPSG:32629"), "Lisbon is in UTM zone 29");
    // A chosen CRS is the user's call.
    let out = run(&["--crs", "EPSG:32632"]);
    assert_eq!(out.status.code(), Some(0), "{}", show(&out));
}

#[test]
fn data_across_the_antimeridian_gets_the_zone_there() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let pbf = d.join("taveuni.osm.pbf");
    // Taveuni, Fiji: buildings on both sides of 180°.
    buildings_at(&pbf, &[(179.9990, -16.8), (-179.9990, -16.8)]);
    let ifc = d.join("x.ifc");
    let out = citygen(&[
        "--osm",
        pbf.to_str().unwrap(),
        "--kb",
        KB,
        "--lod",
        "1",
        "--ifc",
        ifc.to_str().unwrap(),
        "--quiet",
    ]);
    assert_eq!(out.status.code(), Some(0), "{}", show(&out));
    let text = std::fs::read_to_string(&ifc).unwrap();
    assert!(
        text.contains("EPSG:32760") || text.contains("EPSG:32701"),
        "the zone at the antimeridian, not at Greenwich"
    );
}

#[test]
fn rulesets_the_kb_names_are_applied_or_reported_as_not_applied_or_refused() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let kb = d.join("kb.xml");
    std::fs::write(
        &kb,
        r#"<earth>
  <info nbfloor="2" rooftype="flat"/>
  <appearance><values proba="0.4"/><ruleset file="near.cga"/></appearance>
  <appearance><values proba="0.3"/><ruleset file="../far.cga"/></appearance>
  <appearance><values proba="0.3"/><ruleset file="broken.cga"/></appearance>
</earth>
"#,
    )
    .unwrap();
    std::fs::write(d.join("near.cga"), "lot -> extrude(7.5){building}\n").unwrap();
    std::fs::write(d.join("broken.cga"), "Lot --> extrude(3) Mass\n").unwrap();
    let pbf = d.join("in.osm.pbf");
    let mut osm = Osm::default();
    osm.good(1, 0);
    osm.write(&pbf);
    let r = ok_run(d, "--osm", &pbf, &["--kb", kb.to_str().unwrap()]);
    let notes: Vec<String> = r.report()["entries"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|e| e["id"] == "")
        .map(|e| e["reason"].as_str().unwrap().to_string())
        .collect();
    let about = |needle: &str| notes.iter().find(|n| n.contains(needle)).cloned();
    let near = about("near.cga").unwrap_or_else(|| panic!("no note on near.cga: {notes:?}"));
    assert!(
        near.contains("kb.xml:3") && near.contains("derived with it"),
        "{near}"
    );
    let far = about("far.cga").unwrap_or_else(|| panic!("no note on ../far.cga: {notes:?}"));
    assert!(far.contains("kb.xml:4") && far.contains("refused"), "{far}");
    let broken = notes
        .iter()
        .find(|n| n.contains("broken.cga") && n.contains("not applied"))
        .unwrap_or_else(|| panic!("no note on broken.cga not applied: {notes:?}"));
    assert!(broken.contains("kb.xml:5"), "{broken}");
}

/// A ruleset (or a SELEX program) symlinked to a file outside the KB's folder, or a FIFO, is
/// refused where it is read: the run notes it refused at the appearance's line and uses the
/// values, `kb check --strict` fails naming the KB file and the line, and the outside file's
/// content is in neither.
#[test]
fn a_ruleset_symlinked_out_of_the_kb_folder_is_refused_by_the_run_and_the_check() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let folder = d.join("kb");
    std::fs::create_dir_all(&folder).unwrap();
    let secret = "root-SECRET-7f3a:x:0:0:root:/root:/bin/sh";
    let outside = d.join("passwd");
    std::fs::write(&outside, format!("{secret}\n")).unwrap();
    std::os::unix::fs::symlink(&outside, folder.join("r.cga")).unwrap();
    std::os::unix::fs::symlink("../passwd", folder.join("p.selex")).unwrap();
    let fifo = folder.join("fifo.cga");
    assert!(Command::new("mkfifo")
        .arg(&fifo)
        .status()
        .unwrap()
        .success());
    let kb = folder.join("kb.xml");
    std::fs::write(
        &kb,
        r#"<earth>
  <info nbfloor="2" rooftype="flat"/>
  <appearance><values proba="0.5"/><ruleset file="r.cga"/></appearance>
  <appearance><values proba="0.5"/><ruleset file="fifo.cga"/></appearance>
</earth>
"#,
    )
    .unwrap();
    let pbf = d.join("in.osm.pbf");
    let mut osm = Osm::default();
    osm.good(1, 0);
    osm.write(&pbf);
    let r = ok_run(d, "--osm", &pbf, &["--kb", kb.to_str().unwrap()]);
    let text = std::fs::read_to_string(d.join("report.json")).unwrap();
    assert!(
        !text.contains("SECRET"),
        "the outside file in the report: {text}"
    );
    let notes: Vec<String> = r.report()["entries"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|e| e["id"] == "")
        .map(|e| e["reason"].as_str().unwrap().to_string())
        .collect();
    for (file, line) in [("r.cga", 3), ("fifo.cga", 4)] {
        let note = notes
            .iter()
            .find(|n| n.contains(file))
            .unwrap_or_else(|| panic!("no note on {file}: {notes:?}"));
        assert!(
            note.contains(&format!("kb.xml:{line}")) && note.contains("refused"),
            "{note}"
        );
    }
    let kb_arg = kb.to_str().unwrap();
    let out = citygen(&["kb", "check", "--strict", kb_arg]);
    no_panic(&out);
    assert_eq!(out.status.code(), Some(1), "{}", show(&out));
    let said = show(&out);
    assert!(!said.contains("SECRET"), "{said}");
    for (file, line) in [("r.cga", 3), ("fifo.cga", 4)] {
        let at = format!("{kb_arg}:{line}: error:");
        assert!(
            said.lines()
                .any(|l| l.contains(&at) && l.contains(file) && l.contains("refused")),
            "no error at {at} on {file}: {said}"
        );
    }
    // A SELEX program through the same kind of symlink: the check's error, the run refused
    // before any work, the content in neither.
    std::fs::write(
        &kb,
        "<earth>\n  <info nbfloor=\"2\"/>\n  <appearance><values proba=\"1\"/><selex file=\"p.selex\"/></appearance>\n</earth>\n",
    )
    .unwrap();
    let out = citygen(&["kb", "check", "--strict", kb_arg]);
    assert_eq!(out.status.code(), Some(1), "{}", show(&out));
    let said = show(&out);
    assert!(
        said.contains(&format!("{kb_arg}:3: error:")) && said.contains("refused"),
        "{said}"
    );
    assert!(!said.contains("SECRET"), "{said}");
    let r = run_in(d, "--osm", &pbf, &["--kb", kb_arg]);
    no_panic(&r.out);
    assert_ne!(r.out.status.code(), Some(0), "{}", show(&r.out));
    let said = show(&r.out);
    assert!(
        said.contains("refused") && !said.contains("SECRET"),
        "{said}"
    );
    assert_eq!(
        std::fs::read_to_string(&outside).unwrap(),
        format!("{secret}\n")
    );
}

#[test]
fn an_appearances_ruleset_file_derives_its_buildings() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let kb = d.join("kb.xml");
    let pbf = d.join("in.osm.pbf");
    let mut osm = Osm::default();
    osm.good(1, 0);
    osm.write(&pbf);
    let height = |ruleset: Option<&str>| {
        let app = match ruleset {
            Some(r) => {
                std::fs::write(d.join("r.cga"), r).unwrap();
                r#"<appearance><values proba="1"/><ruleset file="r.cga"/></appearance>"#
            }
            None => r#"<appearance><values proba="1"/></appearance>"#,
        };
        std::fs::write(
            &kb,
            format!("<earth>\n  <info nbfloor=\"2\" floorsize=\"3\" rooftype=\"flat\"/>\n  {app}\n</earth>\n"),
        )
        .unwrap();
        let seq = d.join("out.city.jsonl");
        ok_run(
            d,
            "--osm",
            &pbf,
            &[
                "--kb",
                kb.to_str().unwrap(),
                "--cityjsonseq",
                seq.to_str().unwrap(),
            ],
        );
        let text = std::fs::read_to_string(&seq).unwrap();
        let line = text.lines().nth(1).unwrap();
        let v: serde_json::Value = serde_json::from_str(line).unwrap();
        let objects = v["CityObjects"].as_object().unwrap();
        objects
            .values()
            .find_map(|o| o["attributes"]["measuredHeight"].as_f64())
            .unwrap()
    };
    // From the values (a flat roof: the eave is the height).
    let eave = height(None);
    assert!((height(Some("lot -> extrude(7.5){building}\n")) - 7.5).abs() < 1e-6);
    assert!((eave - 7.5).abs() > 0.1, "{eave}");
    // The values still give the axiom's attributes.
    let plus = height(Some("lot -> extrude(eave + 1){building}\n"));
    assert!((plus - (eave + 1.0)).abs() < 1e-6, "{plus} {eave}");
}

#[test]
fn a_citygml_file_past_the_validators_element_cap_is_named_and_tiles_fix_it() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // 19,600 plain LOD1 blocks (about 60 elements each): 1.2 million elements in one file.
    let mut osm = Osm::default();
    for i in 0..140 {
        for j in 0..140 {
            let id = 1 + (i * 140 + j) as i64;
            let (x, y) = (15.0 * i as f64, 15.0 * j as f64);
            osm.building(id, &square(x, y, 10.0, 10.0), &[("height", "6")]);
        }
    }
    let pbf = d.join("grid.osm.pbf");
    osm.write(&pbf);
    let gml = d.join("city.gml");
    let report = d.join("report.json");
    let run = |extra: &[&str]| {
        let mut a = vec!["--osm", pbf.to_str().unwrap(), "--kb", KB, "--lod", "1"];
        a.extend(["--citygml", gml.to_str().unwrap()]);
        a.extend(["--report", report.to_str().unwrap()]);
        a.extend_from_slice(extra);
        let out = citygen(&a);
        assert_eq!(out.status.code(), Some(0), "{}", show(&out));
        let r: serde_json::Value =
            serde_json::from_slice(&std::fs::read(&report).unwrap()).unwrap();
        let notes: Vec<String> = r["entries"]
            .as_array()
            .unwrap()
            .iter()
            .filter_map(|e| e["reason"].as_str())
            .filter(|t| t.contains("XML elements"))
            .map(str::to_string)
            .collect();
        (String::from_utf8_lossy(&out.stderr).into_owned(), notes)
    };
    let (stderr, notes) = run(&[]);
    assert!(
        stderr.contains("citygen: warning:")
            && stderr.contains("city.gml has 1")
            && stderr.contains("more than the 1000000")
            && stderr.contains("--tile"),
        "{stderr}"
    );
    assert_eq!(notes.len(), 1, "{notes:?}");
    // The warning's count is the file's: every start tag.
    let text = std::fs::read_to_string(&gml).unwrap();
    let starts = text
        .match_indices('<')
        .filter(|(i, _)| !matches!(text.as_bytes().get(i + 1), Some(b'/' | b'?' | b'!')));
    assert!(
        notes[0].contains(&format!("has {} XML", starts.count())),
        "{notes:?}"
    );
    // Tiled: the summary says so, and no tile is past the cap.
    let (stderr, notes) = run(&["--tile", "500"]);
    assert!(stderr.contains("tiles of 500 m)"), "{stderr}");
    assert!(!stderr.contains("warning"), "{stderr}");
    assert!(notes.is_empty(), "{notes:?}");
}
