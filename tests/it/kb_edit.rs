//! `citygen kb edit` through the real binary and plain HTTP: the session's defences (token,
//! Host, Origin), writes confined to the KB and its folder, refused edits that leave the file
//! as it was, and an edit saved that `kb check --strict` and `kb explain` then read.

use std::io::{BufRead, BufReader, Read, Write};
use std::net::TcpStream;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use crate::common::{citygen, root, KB, MONACO};
use serde_json::{json, Value};

/// A running editor, stopped when dropped.
struct Session {
    child: Child,
    port: u16,
    token: String,
}

impl Drop for Session {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

fn start(kb: &Path, osm: bool) -> Session {
    start_with(Command::new(env!("CARGO_BIN_EXE_citygen")), kb, osm)
}

/// The editor started by `cmd` (the binary itself, or a shell that execs it).
fn start_with(mut cmd: Command, kb: &Path, osm: bool) -> Session {
    cmd.current_dir(root()).arg("kb").arg("edit").arg(kb);
    if osm {
        cmd.args(["--osm", MONACO]);
    }
    let mut child = cmd
        .stdout(Stdio::piped())
        .stderr(Stdio::inherit())
        .spawn()
        .expect("start citygen kb edit");
    let mut line = String::new();
    BufReader::new(child.stdout.take().expect("stdout"))
        .read_line(&mut line)
        .expect("the address line");
    let url = line.trim();
    let rest = url
        .strip_prefix("http://127.0.0.1:")
        .unwrap_or_else(|| panic!("printed {url:?}"));
    let (port, token) = rest.split_once("/?token=").expect("port and token");
    assert_eq!(token.len(), 32, "128 bits in hex");
    Session {
        child,
        port: port.parse().expect("port"),
        token: token.to_string(),
    }
}

/// One raw request; the status and body of the answer.
fn raw(port: u16, request: &str) -> (u16, Vec<u8>) {
    let mut s = TcpStream::connect(("127.0.0.1", port)).expect("connect");
    s.write_all(request.as_bytes()).expect("send");
    let mut out = Vec::new();
    s.read_to_end(&mut out).expect("answer");
    let head_end = out
        .windows(4)
        .position(|w| w == b"\r\n\r\n")
        .unwrap_or_else(|| {
            panic!(
                "no HTTP head in the answer to {:?} ({} bytes: {:?})",
                request.lines().next().unwrap_or(""),
                out.len(),
                String::from_utf8_lossy(&out)
            )
        });
    let head = String::from_utf8_lossy(&out[..head_end]).to_string();
    let status = head
        .split(' ')
        .nth(1)
        .and_then(|s| s.parse().ok())
        .expect("a status");
    (status, out[head_end + 4..].to_vec())
}

impl Session {
    fn host(&self) -> String {
        format!("127.0.0.1:{}", self.port)
    }

    fn get(&self, path: &str, headers: &[(&str, &str)]) -> (u16, Vec<u8>) {
        let mut req = format!("GET {path} HTTP/1.1\r\n");
        for (k, v) in headers {
            req.push_str(&format!("{k}: {v}\r\n"));
        }
        req.push_str("\r\n");
        raw(self.port, &req)
    }

    fn api_get(&self, path: &str) -> (u16, Value) {
        let host = self.host();
        let (status, body) = self.get(path, &[("Host", &host), ("X-Citygen-Token", &self.token)]);
        (status, serde_json::from_slice(&body).unwrap_or(Value::Null))
    }

    fn post_with(&self, path: &str, body: &Value, headers: &[(&str, &str)]) -> (u16, Value) {
        let body = body.to_string();
        let mut req = format!(
            "POST {path} HTTP/1.1\r\nContent-Type: application/json\r\nContent-Length: {}\r\n",
            body.len()
        );
        for (k, v) in headers {
            req.push_str(&format!("{k}: {v}\r\n"));
        }
        req.push_str("\r\n");
        req.push_str(&body);
        let (status, out) = raw(self.port, &req);
        (status, serde_json::from_slice(&out).unwrap_or(Value::Null))
    }

    fn post(&self, path: &str, body: &Value) -> (u16, Value) {
        let host = self.host();
        let origin = format!("http://{host}");
        self.post_with(
            path,
            body,
            &[
                ("Host", &host),
                ("Origin", &origin),
                ("X-Citygen-Token", &self.token),
            ],
        )
    }
}

const SMALL_KB: &str = r##"<?xml version="1.0" encoding="UTF-8"?>
<earth>
  <!-- A comment the editor keeps. -->
  <info nbfloor="2" color="white"/>
  <country designation="Monaco">
    <info lat="43.7384" lon="7.4246" dist="3" rooftype="hipped"/>
    <appearance>
      <values proba="1" color="#f3e5c0"/>
    </appearance>
    <town designation="Fontvieille">
      <!-- Reclaimed land. -->
      <info lat="43.7283" lon="7.4150" dist="0.5" nbfloor="9"/>
    </town>
  </country>
</earth>
"##;

fn small_kb() -> (tempfile::TempDir, PathBuf) {
    let dir = tempfile::tempdir().expect("temp dir");
    let kb = dir.path().join("kb").join("kb.xml");
    std::fs::create_dir_all(kb.parent().unwrap()).unwrap();
    std::fs::write(&kb, SMALL_KB).unwrap();
    (dir, kb)
}

#[test]
fn requests_without_the_token_or_from_another_host_or_origin_are_refused() {
    let (_dir, kb) = small_kb();
    let s = start(&kb, false);
    let host = s.host();
    let tok = s.token.clone();
    let page = format!("/?token={tok}");
    // The page and the API with everything right.
    let (status, body) = s.get(&page, &[("Host", &host)]);
    assert_eq!(status, 200);
    let html = String::from_utf8_lossy(&body);
    assert!(html.contains(&format!("app.js?token={tok}")), "{html}");
    let (status, state) = s.api_get("/api/state");
    assert_eq!(status, 200);
    assert_eq!(state["zones"].as_array().map(Vec::len), Some(3));
    let localhost = format!("localhost:{}", s.port);
    assert_eq!(s.get(&page, &[("Host", &localhost)]).0, 200);

    let refused = |path: &str, headers: &[(&str, &str)]| {
        let (status, body) = s.get(path, headers);
        let msg = String::from_utf8_lossy(&body).to_string();
        assert_eq!(status, 403, "{path} {headers:?}: {msg}");
        assert!(msg.contains("refused"), "{msg}");
        msg
    };
    // No token, a wrong one, the page's token on the API in the query instead of the header.
    refused("/", &[("Host", &host)]);
    refused("/app.js", &[("Host", &host)]);
    refused("/api/state", &[("Host", &host)]);
    let wrong = "0".repeat(32);
    refused(&format!("/?token={wrong}"), &[("Host", &host)]);
    refused(
        "/api/state",
        &[("Host", &host), ("X-Citygen-Token", &wrong)],
    );
    refused(&format!("/api/state?token={tok}"), &[("Host", &host)]);
    // A rebound name, another port, no Host at all.
    let msg = refused(&page, &[("Host", &format!("attacker.example:{}", s.port))]);
    assert!(msg.contains("Host"), "{msg}");
    refused(
        &page,
        &[("Host", &format!("127.0.0.1:{}", s.port.wrapping_add(1)))],
    );
    refused(&page, &[]);
    // A foreign Origin, even with the token (a page elsewhere that learnt it).
    let msg = refused(
        "/api/state",
        &[
            ("Host", &host),
            ("X-Citygen-Token", &tok),
            ("Origin", "http://attacker.example"),
        ],
    );
    assert!(msg.contains("Origin"), "{msg}");
    refused(
        "/api/state",
        &[
            ("Host", &host),
            ("X-Citygen-Token", &tok),
            (
                "Origin",
                &format!("http://127.0.0.1:{}", s.port.wrapping_add(1)),
            ),
        ],
    );
    // And the writes: a foreign origin's save and edit change nothing.
    let edit = json!({"op": "set_info", "zone": "earth", "values": [["nbfloor", "5"]]});
    let (status, _) = s.post_with(
        "/api/edit",
        &edit,
        &[
            ("Host", &host),
            ("X-Citygen-Token", &tok),
            ("Origin", "null"),
        ],
    );
    assert_eq!(status, 403);
    let (status, _) = s.post_with(
        "/api/save",
        &json!({}),
        &[("Host", &host), ("Origin", &format!("http://{host}"))],
    );
    assert_eq!(status, 403);
    assert_eq!(std::fs::read_to_string(&kb).unwrap(), SMALL_KB);
    // Nothing but loopback is bound: the port refuses on another address of this machine.
    // (The listener's address is 127.0.0.1 itself: the printed URL says so.)
}

#[test]
fn rulesets_are_written_only_inside_the_kb_folder() {
    let (dir, kb) = small_kb();
    let outside = dir.path().join("outside");
    std::fs::create_dir_all(&outside).unwrap();
    #[cfg(unix)]
    std::os::unix::fs::symlink(&outside, kb.parent().unwrap().join("escape")).unwrap();
    let s = start(&kb, false);
    let rules = "lot -> extrude(10){building:color=red}\n";
    let absolute = outside.join("x.cga").to_string_lossy().into_owned();
    for file in [
        "../x.cga",
        "sub/../../x.cga",
        absolute.as_str(),
        "escape/x.cga",
        "./x.cga",
        "x.txt",
        "",
    ] {
        let (status, body) = s.post("/api/ruleset", &json!({"file": file, "text": rules}));
        assert_eq!(status, 422, "{file:?}: {body}");
        assert!(body["error"].as_str().is_some_and(|m| !m.is_empty()));
    }
    assert!(!dir.path().join("x.cga").exists());
    assert!(!outside.join("x.cga").exists());
    // A ruleset that does not parse is refused too; a good one inside is written.
    let (status, _) = s.post(
        "/api/ruleset",
        &json!({"file": "bad.cga", "text": "lot ->"}),
    );
    assert_eq!(status, 422);
    let (status, body) = s.post("/api/ruleset", &json!({"file": "good.cga", "text": rules}));
    assert_eq!(status, 200, "{body}");
    assert_eq!(
        std::fs::read_to_string(kb.parent().unwrap().join("good.cga")).unwrap(),
        rules
    );
    // An appearance naming a ruleset outside the folder is what `kb check` calls an error.
    let app = json!({"values": [["proba", "1"]], "ruleset": "../x.cga"});
    let (status, body) = s.post(
        "/api/edit",
        &json!({"op": "add_appearance", "zone": "earth/Monaco/Fontvieille", "appearance": app}),
    );
    assert_eq!(status, 422, "{body}");
    assert!(
        body["error"].as_str().unwrap().contains("outside"),
        "{body}"
    );
    assert_eq!(std::fs::read_to_string(&kb).unwrap(), SMALL_KB);
}

#[test]
fn an_invalid_edit_leaves_the_draft_and_the_file_untouched() {
    let (_dir, kb) = small_kb();
    let s = start(&kb, false);
    let (_, before) = s.api_get("/api/state");
    let zone = "earth/Monaco/Fontvieille";
    let bad = [
        json!({"op": "set_info", "zone": zone, "values": [["nbfloor", "many"]]}),
        json!({"op": "set_info", "zone": zone, "values": [["color", "not a colour"]]}),
        json!({"op": "set_info", "zone": zone, "values": [["x\"/><evil a=\"", "1"]]}),
        json!({"op": "set_circle", "zone": zone, "circle": {"lat": 95.0, "lon": 7.0, "dist": 1.0}}),
        json!({"op": "set_polygon", "zone": zone, "points": [[7.41, 43.72], [7.42, 43.73], [7.42, 43.72], [7.41, 43.73]]}),
        json!({"op": "add_zone", "parent": zone, "element": "district", "designation": "a/b",
               "polygon": [[7.41, 43.72], [7.42, 43.72], [7.42, 43.73]]}),
        json!({"op": "add_zone", "parent": zone, "element": "info", "designation": "D",
               "polygon": [[7.41, 43.72], [7.42, 43.72], [7.42, 43.73]]}),
        json!({"op": "add_appearance", "zone": zone, "appearance": {"values": [["proba", "1"]],
               "opening": {"root": "w", "splits": [{"axis": "Q", "parent": "w", "children": ["a", "b"], "values": [1, 1]}], "terms": ["a", "b"]}}}),
        json!({"op": "delete_appearance", "zone": zone, "index": 3}),
        json!({"op": "delete_zone", "zone": "earth"}),
        json!({"op": "set_info", "zone": "earth/Nowhere", "values": [["nbfloor", "3"]]}),
        json!({"op": "no_such_op"}),
    ];
    for e in &bad {
        let (status, body) = s.post("/api/edit", e);
        assert!(status == 422 || status == 400, "{e}: {status} {body}");
        let msg = body["error"].as_str().unwrap_or("");
        assert!(!msg.is_empty(), "{e}: a message");
        let (_, now) = s.api_get("/api/state");
        assert_eq!(now, before, "{e} changed the draft");
    }
    // Saving the untouched draft writes the same bytes.
    let (status, _) = s.post("/api/save", &json!({}));
    assert_eq!(status, 200);
    assert_eq!(std::fs::read_to_string(&kb).unwrap(), SMALL_KB);
}

/// The Monaco acceptance flow without a browser: a polygon district with an appearance whose
/// window is split, saved, then read by `kb check --strict` and `kb explain`.
#[test]
fn a_drawn_district_is_saved_strict_and_explained() {
    let dir = tempfile::tempdir().expect("temp dir");
    let kb = dir.path().join("kb.xml");
    let original = std::fs::read_to_string(root().join(KB)).unwrap();
    std::fs::write(&kb, &original).unwrap();
    let s = start(&kb, true);
    let (status, footprints) = s.api_get("/api/footprints");
    assert_eq!(status, 200);
    let footprints = footprints.as_array().cloned().unwrap_or_default();
    assert!(footprints.len() > 1000, "{} footprints", footprints.len());
    // A box around Fontvieille's buildings.
    let (w, so, e, n) = (7.4140, 43.7265, 7.4175, 43.7290);
    let inside: Vec<&Value> = footprints
        .iter()
        .filter(|f| {
            let (lon, lat) = (f["at"][0].as_f64().unwrap(), f["at"][1].as_f64().unwrap());
            lon > w && lon < e && lat > so && lat < n
        })
        .collect();
    assert!(inside.len() >= 3, "{} buildings in the box", inside.len());
    let parent = "earth/Mediterranean Europe/Monaco/Fontvieille";
    let zone = format!("{parent}/Test district");
    let (status, body) = s.post(
        "/api/edit",
        &json!({"op": "add_zone", "parent": parent, "element": "district",
                "designation": "Test district", "polygon": [[w, so], [e, so], [e, n], [w, n]]}),
    );
    assert_eq!(status, 200, "{body}");
    let app = json!({
        "values": [["proba", "1"], ["color", "#aa2222"], ["bdRooftype", "hipped"],
                   ["roofColor", "#b85a38"], ["windowheight", "tall"], ["minFloors", "3"], ["maxFloors", "3"]],
        "opening": {"root": "w", "terms": ["w_l", "w_t", "w_b"], "splits": [
            {"axis": "X", "parent": "w", "children": ["w_l", "w_r"], "values": [0.5, 0.5]},
            {"axis": "Z", "parent": "w_r", "children": ["w_b", "w_t"], "values": [0.7, 0.3]}]}
    });
    let (status, body) = s.post(
        "/api/edit",
        &json!({"op": "add_appearance", "zone": zone, "appearance": app}),
    );
    assert_eq!(status, 200, "{body}");
    // The page's view of the building: the new zone and appearance.
    let id = inside[0]["id"].as_str().unwrap().to_string();
    let (status, b) = s.api_get(&format!("/api/building?id={id}"));
    assert_eq!(status, 200, "{b}");
    assert_eq!(b["zone"], zone.as_str());
    assert_eq!(b["appearance"], format!("{zone}#1").as_str());
    assert!(b["provenance"]["storeys"].is_string(), "{b}");
    // The preview is a GLB.
    let (status, glb) = s.get(
        &format!("/api/preview?id={id}&lod=3"),
        &[("Host", &s.host()), ("X-Citygen-Token", &s.token)],
    );
    assert_eq!(status, 200);
    assert_eq!(&glb[..4], b"glTF");
    assert_eq!(
        std::fs::read_to_string(&kb).unwrap(),
        original,
        "not saved yet"
    );
    let (status, body) = s.post("/api/save", &json!({}));
    assert_eq!(status, 200, "{body}");
    drop(s);

    let saved = std::fs::read_to_string(&kb).unwrap();
    let check = citygen(&["kb", "check", "--strict", kb.to_str().unwrap()]);
    let out = String::from_utf8_lossy(&check.stdout);
    assert!(check.status.success(), "{out}");
    assert!(out.contains("0 errors"), "{out}");
    // Everything else of the file byte for byte: the saved text is the original with one
    // block of lines added.
    let (a, b): (Vec<&str>, Vec<&str>) = (original.lines().collect(), saved.lines().collect());
    let first = a.iter().zip(&b).take_while(|(x, y)| x == y).count();
    let last = a
        .iter()
        .rev()
        .zip(b.iter().rev())
        .take_while(|(x, y)| x == y)
        .count();
    assert_eq!(first + last, a.len(), "only lines added");
    let added = b[first..b.len() - last].join("\n");
    assert!(
        added.contains("<district designation=\"Test district\">"),
        "{added}"
    );
    assert!(added.contains("splitvalues=\"0.7,0.3\""), "{added}");
    let explain = citygen(&[
        "kb",
        "explain",
        kb.to_str().unwrap(),
        "--osm",
        MONACO,
        "--id",
        &id,
    ]);
    let text = String::from_utf8_lossy(&explain.stdout);
    assert!(explain.status.success(), "{text}");
    assert!(text.contains("Test district"), "{text}");
    assert!(text.contains(&format!("{zone}#1")), "{text}");
}

#[test]
fn a_lenient_kb_is_saved_in_the_strict_format_with_its_repairs_shown_first() {
    use citygen::kb::{KnowledgeBase, ReadMode, Zone};
    let dir = tempfile::tempdir().expect("temp dir");
    let kb = dir.path().join("annex.xml");
    let original = std::fs::read_to_string(root().join("tests/data/thesis_annex.xml")).unwrap();
    std::fs::write(&kb, &original).unwrap();
    let s = start(&kb, false);
    let (status, st) = s.api_get("/api/state");
    assert_eq!(status, 200);
    assert_eq!(st["mode"], "lenient", "{st}");
    assert!(st["strict_error"].as_str().is_some(), "{st}");
    let repairs = st["repairs"].as_array().cloned().unwrap_or_default();
    assert!(repairs.len() > 10, "{st}");
    assert!(repairs
        .iter()
        .any(|r| r["line"] == 74 && r["what"].as_str().unwrap_or("").contains("missing '<'")));
    assert!(st["conversion"].is_array(), "{st}");
    assert_eq!(std::fs::read_to_string(&kb).unwrap(), original);

    let (status, body) = s.post("/api/save", &json!({}));
    assert_eq!(status, 200, "{body}");
    let (_, st) = s.api_get("/api/state");
    assert_eq!(st["mode"], "strict", "{st}");
    assert_eq!(st["dirty"], false);
    assert_eq!(st["repairs"].as_array().map(Vec::len), Some(0), "{st}");
    // Later edits are text edits of the strict file: one line changes.
    let saved = std::fs::read_to_string(&kb).unwrap();
    let (status, body) = s.post(
        "/api/edit",
        &json!({"op": "set_info", "zone": "earth/France/Midi-Pyrenees/Paris",
                "values": [["nbfloor", "6"]]}),
    );
    assert_eq!(status, 200, "{body}");
    drop(s);
    assert_eq!(
        std::fs::read_to_string(&kb).unwrap(),
        saved,
        "edited, not saved"
    );

    let check = citygen(&["kb", "check", "--strict", kb.to_str().unwrap()]);
    let out = String::from_utf8_lossy(&check.stdout);
    assert!(check.status.success(), "{out}");
    assert!(out.contains("0 errors"), "{out}");
    // The same zones and appearances as the lenient reading of the original.
    let (before, _) = KnowledgeBase::load_with(
        &root().join("tests/data/thesis_annex.xml"),
        ReadMode::Lenient,
    )
    .unwrap();
    let (after, repairs) = KnowledgeBase::load_with(&kb, ReadMode::Strict).unwrap();
    assert!(repairs.is_empty());
    let unlined = |z: &Zone| {
        let mut z = z.clone();
        z.line = 0;
        z.appearances.iter_mut().for_each(|a| a.line = 0);
        z
    };
    assert_eq!(before.zones().len(), after.zones().len());
    for (a, b) in before.zones().iter().zip(after.zones()) {
        assert_eq!(unlined(a), unlined(b), "{}", a.path);
    }
    let appearances =
        |k: &KnowledgeBase| k.zones().iter().map(|z| z.appearances.len()).sum::<usize>();
    assert_eq!((appearances(&before), appearances(&after)), (4, 4));
}

/// The resident memory of process `pid`, bytes (`VmRSS` of /proc/PID/status).
fn rss_bytes(pid: u32) -> u64 {
    let status = std::fs::read_to_string(format!("/proc/{pid}/status")).expect("proc status");
    let kb: u64 = status
        .lines()
        .find_map(|l| l.strip_prefix("VmRSS:"))
        .and_then(|v| v.trim().trim_end_matches("kB").trim().parse().ok())
        .expect("VmRSS");
    kb * 1024
}

/// The page, timed: its status and how long the answer took (a client giving up at 2 s).
fn timed_page(s: &Session) -> (u16, Duration) {
    let t = Instant::now();
    let req = format!(
        "GET /?token={} HTTP/1.1\r\nHost: {}\r\n\r\n",
        s.token,
        s.host()
    );
    let status = TcpStream::connect(("127.0.0.1", s.port))
        .and_then(|mut c| {
            c.set_read_timeout(Some(Duration::from_secs(2)))?;
            c.write_all(req.as_bytes())?;
            let mut out = Vec::new();
            c.read_to_end(&mut out)?;
            Ok(out)
        })
        .ok()
        .filter(|out| String::from_utf8_lossy(out).contains("app.js?token="))
        .and_then(|out| {
            String::from_utf8_lossy(&out)
                .split(' ')
                .nth(1)
                .and_then(|c| c.parse().ok())
        })
        .unwrap_or(0);
    (status, t.elapsed())
}

/// The editor under an idle flood and slow clients (the issue's 130 idle connections took a
/// thread each and, in a 2 GiB address space, stopped it): run in that address space, it
/// keeps answering its page within 2 s with 500 idle loopback connections and 30 clients
/// sending a byte a second, its memory stays under 200 MiB, the KB is untouched, and the idle
/// connections are closed (cap or head timeout) rather than held.
#[test]
fn the_page_is_answered_under_500_idle_connections_and_30_slow_clients() {
    let (_dir, kb) = small_kb();
    let mut sh = Command::new("sh");
    sh.args([
        "-c",
        "ulimit -v 2097152 && exec \"$0\" \"$@\"",
        env!("CARGO_BIN_EXE_citygen"),
    ]);
    let mut s = start_with(sh, &kb, false);
    let pid = s.child.id();
    let idle: Vec<TcpStream> = (0..500)
        .map(|_| TcpStream::connect(("127.0.0.1", s.port)).expect("an idle connection"))
        .collect();
    let slow: Vec<TcpStream> = (0..30)
        .map(|_| TcpStream::connect(("127.0.0.1", s.port)).expect("a slow connection"))
        .collect();
    let stop = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    let dripping = {
        let stop = std::sync::Arc::clone(&stop);
        let request = format!(
            "GET /?token={} HTTP/1.1\r\nHost: {}\r\n\r\n",
            s.token,
            s.host()
        );
        std::thread::spawn(move || {
            let mut slow = slow;
            for byte in request.bytes().cycle() {
                if stop.load(std::sync::atomic::Ordering::Relaxed) {
                    break;
                }
                for c in &mut slow {
                    let _ = c.write_all(&[byte]);
                }
                std::thread::sleep(Duration::from_secs(1));
            }
        })
    };
    // Past the 5 s head timeout, so that both the held and the dropped phases are seen.
    let (mut worst, mut peak) = (Duration::ZERO, 0u64);
    let start = Instant::now();
    while start.elapsed() < Duration::from_secs(8) {
        let (status, took) = timed_page(&s);
        assert_eq!(
            status,
            200,
            "the page after {:?} (took {took:?})",
            start.elapsed()
        );
        worst = worst.max(took);
        peak = peak.max(rss_bytes(pid));
        std::thread::sleep(Duration::from_millis(250));
    }
    stop.store(true, std::sync::atomic::Ordering::Relaxed);
    let _ = dripping.join();
    eprintln!(
        "kb edit under load: slowest page {worst:?}, peak RSS {} KiB",
        peak / 1024
    );
    assert!(worst < Duration::from_secs(2), "slowest page {worst:?}");
    assert!(peak < 200 << 20, "peak RSS {peak} bytes");
    // Every idle connection has been answered and closed by now (503 over the cap, 408 past
    // the head timeout): none is held open.
    for (i, mut c) in idle.into_iter().enumerate() {
        c.set_read_timeout(Some(Duration::from_secs(1))).unwrap();
        let mut out = Vec::new();
        let closed = match c.read_to_end(&mut out) {
            Ok(_) => true,
            Err(e) => e.kind() == std::io::ErrorKind::ConnectionReset,
        };
        assert!(closed, "idle connection {i} still open after 8 s");
        let head = String::from_utf8_lossy(&out);
        assert!(
            out.is_empty() || head.starts_with("HTTP/1.1 408") || head.starts_with("HTTP/1.1 503"),
            "idle connection {i}: {head}"
        );
    }
    assert!(s.child.try_wait().unwrap().is_none(), "the editor ended");
    assert_eq!(std::fs::read_to_string(&kb).unwrap(), SMALL_KB);
}

/// A KB swapped for a symlink to a file outside its folder while it is edited (the outside
/// file a copy, so that it looks unchanged): the save is refused naming the KB, the outside
/// file and the symlink stay as they were, and nothing else is left in the folder.
#[test]
fn a_save_through_a_kb_swapped_for_a_symlink_is_refused() {
    let (dir, kb) = small_kb();
    let s = start(&kb, false);
    let edit = json!({"op": "set_info", "zone": "earth", "values": [["nbfloor", "5"]]});
    assert_eq!(s.post("/api/edit", &edit).0, 200);
    let outside = dir.path().join("elsewhere.xml");
    std::fs::write(&outside, SMALL_KB).unwrap();
    std::fs::remove_file(&kb).unwrap();
    std::os::unix::fs::symlink(&outside, &kb).unwrap();
    let (status, answer) = s.post("/api/save", &json!({}));
    assert_eq!(status, 409, "{answer}");
    let msg = answer["error"].as_str().unwrap_or_default();
    assert!(
        msg.contains(&kb.display().to_string()) && msg.contains("symlink"),
        "{msg}"
    );
    assert_eq!(std::fs::read_to_string(&outside).unwrap(), SMALL_KB);
    assert!(std::fs::symlink_metadata(&kb)
        .unwrap()
        .file_type()
        .is_symlink());
    let names: Vec<_> = std::fs::read_dir(kb.parent().unwrap())
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(names, ["kb.xml"], "no temporary left");
    // Its folder swapped for a symlink to another folder holding a copy: refused too.
    std::fs::remove_file(&kb).unwrap();
    std::fs::write(&kb, SMALL_KB).unwrap();
    let folder = kb.parent().unwrap();
    let moved = dir.path().join("moved");
    std::fs::rename(folder, &moved).unwrap();
    let other = dir.path().join("other");
    std::fs::create_dir_all(&other).unwrap();
    std::fs::write(other.join("kb.xml"), SMALL_KB).unwrap();
    std::os::unix::fs::symlink(&other, folder).unwrap();
    let (status, answer) = s.post("/api/save", &json!({}));
    assert_eq!(status, 409, "{answer}");
    assert_eq!(
        std::fs::read_to_string(other.join("kb.xml")).unwrap(),
        SMALL_KB
    );
    assert_eq!(
        std::fs::read_to_string(moved.join("kb.xml")).unwrap(),
        SMALL_KB
    );
}
