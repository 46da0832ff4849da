//! Budgets for super-linear work (issue 43): inputs whose size used to cost quadratic (or
//! worse) time. A SELEX program of many rules, a `type=building` relation of many parts and a
//! building multipolygon of many courtyards, each generated in code and run through the real
//! binary at two sizes n and 4n: linear work takes about 4 times as long, quadratic 16 times.
//! The test asks for a ratio of CPU times (the child's own, so other work on the machine does
//! not move it) under 8 (the smaller run also pays the start-up, which only lowers the ratio),
//! and for the larger size to finish within a generous bound.

use std::path::Path;
use std::process::Output;
use std::time::Duration;

use crate::common::*;
use citygen::testkit::pbf_write::{MemberKind, PbfWriter};

/// Near Monaco (in the shipped knowledge base).
const LON0: f64 = 7.4200;
const LAT0: f64 = 43.7300;

/// Runs citygen, returning its output and the CPU time (user + system) of that one child,
/// read from its own `wait4` rusage: unlike wall time, it does not grow when other tests or
/// other jobs share the cores.
#[allow(clippy::zombie_processes)] // reaped by wait4 below, which std cannot do with rusage
fn timed(args: &[&str]) -> (Output, Duration) {
    use std::io::Read;
    use std::os::unix::process::ExitStatusExt;
    use std::process::{Command, Stdio};
    let mut child = Command::new(env!("CARGO_BIN_EXE_citygen"))
        .current_dir(root())
        .args(args)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("run citygen");
    let drain = |r: Option<Box<dyn Read + Send>>| {
        std::thread::spawn(move || {
            let mut buf = Vec::new();
            if let Some(mut r) = r {
                let _ = r.read_to_end(&mut buf);
            }
            buf
        })
    };
    let out = drain(
        child
            .stdout
            .take()
            .map(|r| Box::new(r) as Box<dyn Read + Send>),
    );
    let err = drain(
        child
            .stderr
            .take()
            .map(|r| Box::new(r) as Box<dyn Read + Send>),
    );
    let pid = child.id() as libc::pid_t;
    let mut status = 0;
    // SAFETY: an all-zero rusage is a valid value, filled by wait4.
    let mut usage: libc::rusage = unsafe { std::mem::zeroed() };
    // SAFETY: waits for our own child, whose pid std gave; std's Child is not waited again.
    let rc = unsafe { libc::wait4(pid, &mut status, 0, &mut usage) };
    assert_eq!(rc, pid, "wait4: {}", std::io::Error::last_os_error());
    let cpu = |t: libc::timeval| Duration::new(t.tv_sec as u64, t.tv_usec as u32 * 1000);
    let output = Output {
        status: std::process::ExitStatus::from_raw(status),
        stdout: out.join().unwrap_or_default(),
        stderr: err.join().unwrap_or_default(),
    };
    (output, cpu(usage.ru_utime) + cpu(usage.ru_stime))
}

fn ok(out: &Output) {
    assert!(
        out.status.success(),
        "exit {:?}\n{}",
        out.status.code(),
        String::from_utf8_lossy(&out.stderr)
    );
}

/// A SELEX program of `n` rules on a box: each rule selects one cell of a 10 x 10 grid by a
/// label path from the root (`descendant()`, which used to walk and de-duplicate the whole
/// tree, every element placed so far included) and places an element there.
pub fn selex_rules(n: usize) -> String {
    let mut s = String::from(
        "{<> -> createShape(\"building\", 30, 20, 30)};\n\
         {< descendant() [label == \"building_front\"] > -> createGrid(\"g\", 10, 10)};\n",
    );
    for i in 0..n {
        let (r, c) = (i % 10 + 1, (i / 10) % 10 + 1);
        s += &format!(
            "{{< descendant() [label == \"building\"] / [label == \"building_front\"] / [label == \"g\"] / [type == \"cell\"] [rowIdx == {r}] [colIdx == {c}] > -> addFacade(\"w{}\")}};\n",
            i % 7
        );
    }
    s
}

/// Points `(x, y)` metres east and north of (LON0, LAT0) in degrees.
fn lonlat(x: f64, y: f64) -> (f64, f64) {
    let m_lon = 111_320.0 * LAT0.to_radians().cos();
    (LON0 + x / m_lon, LAT0 + y / 110_574.0)
}

/// Tags as written.
type Tags = Vec<(&'static str, &'static str)>;

/// Nodes, ways and one relation, written nodes first.
#[derive(Default)]
struct Osm {
    nodes: Vec<(i64, f64, f64)>,
    ways: Vec<(i64, Vec<i64>, Tags)>,
}

impl Osm {
    /// A closed way on the square at (x, y) of side `s`, counter-clockwise.
    fn square(&mut self, id: i64, x: f64, y: f64, s: f64, tags: &[(&'static str, &'static str)]) {
        let mut refs = Vec::new();
        for (px, py) in [(x, y), (x + s, y), (x + s, y + s), (x, y + s)] {
            let (lon, lat) = lonlat(px, py);
            let nid = self.nodes.len() as i64 + 1;
            self.nodes.push((nid, lon, lat));
            refs.push(nid);
        }
        refs.push(refs[0]);
        self.ways.push((id, refs, tags.to_vec()));
    }

    fn write(&self, path: &Path, members: &[(MemberKind, i64, &str)], tags: &[(&str, &str)]) {
        let mut w = PbfWriter::new(std::fs::File::create(path).unwrap()).unwrap();
        for &(id, lon, lat) in &self.nodes {
            w.node(id, lon, lat, &[]).unwrap();
        }
        for (id, refs, tags) in &self.ways {
            w.way(*id, refs, tags).unwrap();
        }
        w.relation(1, members, tags).unwrap();
        w.finish().unwrap();
    }
}

/// The side of the square holding `n` cells of 5 m.
fn cells_side(n: usize) -> usize {
    (n as f64).sqrt().ceil() as usize
}

/// A `type=building` relation: an outline way (way/1, `building=yes`) and `n` small
/// `building:part` ways, 4 m squares 5 m apart, inside it.
pub fn many_parts(path: &Path, n: usize) {
    let k = cells_side(n);
    let mut osm = Osm::default();
    osm.square(
        1,
        0.0,
        0.0,
        5.0 * k as f64,
        &[("building", "yes"), ("height", "12")],
    );
    let mut members = vec![(MemberKind::Way, 1, "outline")];
    for i in 0..n {
        let (x, y) = (5.0 * (i % k) as f64 + 0.5, 5.0 * (i / k) as f64 + 0.5);
        osm.square(
            2 + i as i64,
            x,
            y,
            4.0,
            &[("building:part", "yes"), ("height", "9")],
        );
        members.push((MemberKind::Way, 2 + i as i64, "part"));
    }
    osm.write(path, &members, &[("type", "building"), ("building", "yes")]);
}

/// A building multipolygon: one outer way and `n` courtyards (inner ways), 3 m squares 5 m
/// apart.
pub fn many_courtyards(path: &Path, n: usize) {
    let k = cells_side(n);
    let mut osm = Osm::default();
    osm.square(1, 0.0, 0.0, 5.0 * k as f64, &[]);
    let mut members = vec![(MemberKind::Way, 1, "outer")];
    for i in 0..n {
        let (x, y) = (5.0 * (i % k) as f64 + 1.0, 5.0 * (i / k) as f64 + 1.0);
        osm.square(2 + i as i64, x, y, 3.0, &[]);
        members.push((MemberKind::Way, 2 + i as i64, "inner"));
    }
    let tags = [
        ("type", "multipolygon"),
        ("building", "yes"),
        ("height", "9"),
    ];
    osm.write(path, &members, &tags);
}

/// Runs an OSM file at LOD 1 into a CityJSON file; the number of buildings and parts written.
fn run_osm(dir: &Path, pbf: &Path) -> (Output, Duration) {
    let out = dir.join("out.city.json");
    timed(&[
        "--osm",
        pbf.to_str().unwrap(),
        "--kb",
        KB,
        "--lod",
        "1",
        "--cityjson",
        out.to_str().unwrap(),
        "--quiet",
    ])
}

/// Times `run(n)` and `run(4 n)` (CPU seconds of the child); fails when the ratio is not
/// clearly below quadratic.
fn scales_linearly(
    what: &str,
    n: usize,
    (max_ratio, limit): (f64, Duration),
    run: impl Fn(usize) -> Duration,
) {
    let small = run(n);
    let large = run(4 * n);
    let ratio = large.as_secs_f64() / small.as_secs_f64().max(1e-3);
    eprintln!("{what}: n = {n}: {small:?}; 4n: {large:?}; ratio {ratio:.1}");
    assert!(
        ratio < max_ratio,
        "{what}: {n} took {small:?}, {} took {large:?}: {ratio:.1} times (quadratic is 16)",
        4 * n
    );
    assert!(large < limit, "{what}: {} took {large:?}", 4 * n);
}

#[test]
fn selex_rules_cost_linear_time() {
    let dir = tempfile::tempdir().unwrap();
    scales_linearly("selex rules", 1_500, (8.0, Duration::from_secs(60)), |n| {
        let slx = dir.path().join(format!("r{n}.slx"));
        std::fs::write(&slx, selex_rules(n)).unwrap();
        let (out, t) = timed(&["selex", "derive", slx.to_str().unwrap()]);
        ok(&out);
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains(&format!("{n} elements")), "{err}");
        t
    });
}

#[test]
fn a_multipolygon_of_many_courtyards_costs_n_log_n() {
    let dir = tempfile::tempdir().unwrap();
    // The relation is assembled and its rings grouped in O(n log n); the building of one
    // polygon with n holes afterwards is still somewhat super-linear (ratio 8.4 in debug):
    // quadratic would be 16.
    scales_linearly("courtyards", 750, (12.0, Duration::from_secs(90)), |n| {
        let pbf = dir.path().join(format!("c{n}.osm.pbf"));
        many_courtyards(&pbf, n);
        let (out, t) = run_osm(dir.path(), &pbf);
        ok(&out);
        t
    });
}

#[test]
fn a_relation_of_many_parts_costs_n_log_n() {
    let dir = tempfile::tempdir().unwrap();
    // Parts grouped under their outline, the outline's rest cut out in one boolean operation,
    // the pieces' overlaps and covered roofs looked up in R-trees, the rest's rings checked
    // and put on the grid in O(n log n): quadratic would be 16.
    scales_linearly("parts", 400, (8.0, Duration::from_secs(60)), |n| {
        let pbf = dir.path().join(format!("p{n}.osm.pbf"));
        many_parts(&pbf, n);
        let (out, t) = run_osm(dir.path(), &pbf);
        ok(&out);
        // Every part is drawn, and the outline's rest around them.
        let city: serde_json::Value =
            serde_json::from_slice(&std::fs::read(dir.path().join("out.city.json")).unwrap())
                .unwrap();
        let objects = city["CityObjects"].as_object().unwrap();
        let parts = objects
            .values()
            .filter(|o| o["type"] == "BuildingPart")
            .count();
        assert_eq!(parts, n + 1, "{n} parts and the rest");
        t
    });
}

/// `selex derive` of a 1e300 m box with an output is refused, naming the program, the
/// volume and the limit, instead of aborting on the storeys' allocation; nothing is written.
#[test]
fn selex_derive_refuses_a_box_too_large_to_build() {
    let dir = tempfile::tempdir().unwrap();
    let slx = dir.path().join("huge.slx");
    std::fs::write(
        &slx,
        "h = 1e300;\n{<> -> createShape(\"tower\", 10, 10, h)};\n",
    )
    .unwrap();
    let glb = dir.path().join("out.glb");
    let out = citygen(&[
        "selex",
        "derive",
        slx.to_str().unwrap(),
        "--gltf",
        glb.to_str().unwrap(),
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(err.contains(slx.to_str().unwrap()), "{err}");
    assert!(
        err.contains("volume `tower`") && err.contains("1e300"),
        "{err}"
    );
    assert!(err.contains("limit of 10000 m"), "{err}");
    assert!(!glb.exists());
}

/// Writes the acceptance sizes' inputs (20,000 rules, 10,000 parts, 10,000 courtyards) and the
/// smaller ones the issue timed (1,000 and 3,000 parts, 3,000 courtyards) into
/// `$CITYGEN_BUDGET_DIR`, to time the release binary on them by hand.
#[test]
#[ignore]
fn write_acceptance_inputs() {
    let Some(dir) = std::env::var_os("CITYGEN_BUDGET_DIR") else {
        panic!("set CITYGEN_BUDGET_DIR");
    };
    let dir = Path::new(&dir);
    std::fs::write(dir.join("rules20000.slx"), selex_rules(20_000)).unwrap();
    many_parts(&dir.join("parts10000.osm.pbf"), 10_000);
    many_courtyards(&dir.join("courtyards10000.osm.pbf"), 10_000);
    many_parts(&dir.join("parts3000.osm.pbf"), 3_000);
    many_parts(&dir.join("parts1000.osm.pbf"), 1_000);
    many_courtyards(&dir.join("courtyards3000.osm.pbf"), 3_000);
}
