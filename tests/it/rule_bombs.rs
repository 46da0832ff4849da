//! Rule bombs through the real binary (issue 18, builds 5 and 8): `rules check` and `rules
//! derive` on generated and hostile rule files, each under a 2 GiB address-space cap
//! (`ulimit -v`), where every one of the first group used to abort with "memory allocation
//! failed"; and the bomb lints with their file:line:col.

use crate::common;

use std::path::Path;
use std::process::{Command, Output};

use crate::common::root;

/// The address-space cap the held-out corpus ran under: 2 GiB, in KiB for `ulimit -v`.
const ADDRESS_SPACE_KIB: u64 = 2 * 1024 * 1024;

/// Runs citygen from the repository root under the address-space cap (through `sh`, whose
/// `ulimit -v` sets RLIMIT_AS for the exec'd binary).
fn citygen_capped(args: &[&str]) -> Output {
    Command::new("sh")
        .arg("-c")
        .arg(format!(
            "ulimit -v {ADDRESS_SPACE_KIB} && exec \"$0\" \"$@\""
        ))
        .arg(env!("CARGO_BIN_EXE_citygen"))
        .args(args)
        .current_dir(root())
        .output()
        .expect("run citygen under sh")
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// A failure of the run itself (a signal, an allocation failure) rather than an answer.
fn assert_answered(o: &Output) {
    let err = stderr(o);
    assert!(
        o.status.code().is_some(),
        "killed by a signal: {:?}\n{}",
        o.status,
        &err[..err.len().min(2000)]
    );
    assert!(
        !err.contains("memory allocation"),
        "{}",
        &err[..err.len().min(2000)]
    );
}

fn write(dir: &Path, name: &str, text: &str) -> String {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p.to_str().unwrap().to_string()
}

/// A WKT polygon of a comb: a 1 m base with `teeth` teeth 1 m wide and 100 m long, 1 m apart.
fn comb_wkt(teeth: usize) -> String {
    let w = 2 * teeth;
    let mut p = vec![(0, 0), (w, 0), (w, 1)];
    for i in (0..teeth).rev() {
        let x = 2 * i;
        p.extend([(x + 1, 1), (x + 1, 101), (x, 101)]);
        if i > 0 {
            p.push((x, 1));
        }
    }
    p.push((0, 0));
    let pts: Vec<String> = p.iter().map(|(x, y)| format!("{x} {y}")).collect();
    format!("POLYGON (({}))", pts.join(","))
}

/// A WKT star of `n` points alternating between radius 100 and 130 m.
fn star_wkt(n: usize) -> String {
    let mut pts: Vec<String> = (0..n)
        .map(|i| {
            let a = std::f64::consts::TAU * i as f64 / n as f64;
            let r = if i % 2 == 0 { 100.0 } else { 130.0 };
            format!("{:.2} {:.2}", r * a.cos(), r * a.sin())
        })
        .collect();
    pts.push(pts[0].clone());
    format!("POLYGON (({}))", pts.join(","))
}

#[test]
fn rules_check_on_a_split_with_50000_new_symbols_answers_within_the_cap() {
    // Was: a symbol × symbol table (2.5 GB) and a copy of the 439 KB line per diagnostic.
    let dir = tempfile::tempdir().unwrap();
    let n = 50_000;
    let sizes = vec!["1"; n].join(",");
    let succ: Vec<String> = (0..n).map(|i| format!("s{i}")).collect();
    let f = write(
        dir.path(),
        "wide.cga",
        &format!("lot -> split(X,{sizes}){{{}}}\n", succ.join("|")),
    );
    let out = citygen_capped(&["rules", "check", &f]);
    assert_answered(&out);
    let err = stderr(&out);
    assert_eq!(
        out.status.code(),
        Some(0),
        "{}",
        &err[..err.len().min(2000)]
    );
    assert!(
        err.contains("49900 more `undefined-symbol` findings from here on are not shown"),
        "{}",
        &err[err.len().saturating_sub(2000)..]
    );
    assert!(
        err.contains("wide.cga: 1 rules, 0 errors, 101 warnings"),
        "{err}"
    );
    // Every source line shown is a window, not the whole line.
    assert!(err.lines().all(|l| l.chars().count() < 400));
}

#[test]
fn rules_check_refuses_a_file_over_the_size_cap_without_reading_it_all() {
    let dir = tempfile::tempdir().unwrap();
    // 40 MB of successors: the lexer alone used to need more than 2 GiB.
    let f = write(
        dir.path(),
        "huge.cga",
        &format!("lot -> {{a{}}}\n", "|a".repeat(20 * 1024 * 1024)),
    );
    let out = citygen_capped(&["rules", "check", &f]);
    assert_answered(&out);
    assert_eq!(out.status.code(), Some(1));
    assert!(
        stderr(&out).contains("more than 4194304 bytes, the cap on rule files"),
        "{}",
        stderr(&out)
    );
}

#[test]
fn rules_derive_refuses_a_comb_cut_into_millions_of_pieces_before_making_them() {
    // 5,050 slabs across 1,000 teeth: 5 million pieces were made before max_shapes was
    // checked (an abort at 1.3 GB RSS after 37 s).
    let dir = tempfile::tempdir().unwrap();
    let rules = write(dir.path(), "comb.cga", "lot -> repeat(Y, 0.02){a}\n");
    let wkt = comb_wkt(1_000);
    let glb = dir.path().join("comb.glb");
    let out = citygen_capped(&[
        "rules",
        "derive",
        &rules,
        "--wkt",
        &wkt,
        "--gltf",
        glb.to_str().unwrap(),
    ]);
    assert_answered(&out);
    let err = stderr(&out);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(
        err.contains("comb.cga:1:1 (lot -> repeat): derivation exceeds max_pieces = 10000: repeat would make at least"),
        "{err}"
    );
    assert!(!glb.exists());
}

#[test]
fn rules_derive_refuses_ten_thousand_storeys_of_a_large_footprint() {
    // 10,000 copies of a 5,000-vertex footprint (800 MB in the tree, then a 7 GB wall list
    // at LOD3): under max_shapes, so only max_points stops it.
    let dir = tempfile::tempdir().unwrap();
    let rules = write(
        dir.path(),
        "tower.cga",
        "lot -> extrude(1000){b}\nb -> repeat(Z, 0.1){c}\n",
    );
    let wkt = star_wkt(5_000);
    let glb = dir.path().join("tower.glb");
    let out = citygen_capped(&[
        "rules",
        "derive",
        &rules,
        "--wkt",
        &wkt,
        "--lod",
        "3",
        "--gltf",
        glb.to_str().unwrap(),
    ]);
    assert_answered(&out);
    let err = stderr(&out);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(
        err.contains("tower.cga:2:1 (b -> repeat): derivation exceeds max_points = 1000000: repeat would make 10000 pieces holding 50000000 points"),
        "{err}"
    );
}

#[test]
fn rules_derive_counts_astronomical_repeats_and_relabels_before_making_them() {
    let dir = tempfile::tempdir().unwrap();
    let glb = dir.path().join("out.glb");
    let derive = |rules: &str, lot: &str| {
        citygen_capped(&[
            "rules",
            "derive",
            rules,
            "--lot",
            lot,
            "--gltf",
            glb.to_str().unwrap(),
        ])
    };
    let tiny = write(dir.path(), "tiny.cga", "lot -> repeat(X, 0.0001){a}\n");
    let out = derive(&tiny, "100000x20");
    assert_answered(&out);
    assert!(
        stderr(&out).contains("tiny.cga:1:1 (lot -> repeat): derivation exceeds max_pieces = 10000: repeat would make 1000000000 pieces"),
        "{}",
        stderr(&out)
    );
    let wide = write(
        dir.path(),
        "wide.cga",
        &format!("lot -> {{a{}}}\n", "|a".repeat(299_999)),
    );
    let out = derive(&wide, "20x20");
    assert_answered(&out);
    assert!(
        stderr(&out).contains("wide.cga:1:1 (lot -> relabel): derivation exceeds max_pieces = 10000: its successors would make 300000 pieces"),
        "{}",
        stderr(&out)
    );
}

/// (file, line:col, code) of each `file:line:col: warning[code]` line of `rules check`.
fn findings(err: &str) -> Vec<String> {
    err.lines()
        .filter(|l| l.contains(": warning[") || l.contains(": error["))
        .map(|l| l.split("]:").next().unwrap_or_default().to_string())
        .collect()
}

#[test]
fn rules_check_warns_where_a_rule_can_exceed_the_caps_and_derive_agrees() {
    let dir = tempfile::tempdir().unwrap();
    let glb = dir.path().join("out.glb");
    // (file, rules, the warning, its consequence, the cap the derivation then stops at)
    let cases = [
        (
            "repeat.cga",
            // The bomb: every copy of a 1 m pattern on a 1-2 m piece is itself again.
            "lot -> extrude(10){a}\na -> repeat(X, 1){a}\n",
            "repeat.cga:2:1: warning[non-terminating",
            "may not terminate; the derivation stops at the depth cap (max_depth, 64 by default)",
            "repeat.cga:2:1 (a -> repeat): derivation exceeds max_depth = 64",
        ),
        (
            "halves.cga",
            "lot -> extrude(10){a}\na -> split(X, sx/2, sx/2){a|a}\n",
            "halves.cga:2:1: warning[exponential-growth",
            "may reach 2^depth shapes; the derivation stops at the shape cap (max_shapes, 100000 \
             by default) about 17 levels down",
            "halves.cga:2:1 (a -> split): derivation exceeds max_shapes = 100000",
        ),
        (
            "faces.cga",
            "lot -> extrude(10){v}\nv -> comp(){side:f}\nf -> extrude(1){v}\n",
            "faces.cga:2:1: warning[exponential-growth",
            "at LOD3 and LOD4 (where comp is applied)",
            "faces.cga:2:1 (v -> comp): derivation exceeds max_shapes = 100000",
        ),
    ];
    for (name, text, warning, consequence, cap) in cases {
        let f = write(dir.path(), name, text);
        let out = citygen_capped(&["rules", "check", &f]);
        assert_answered(&out);
        let err = stderr(&out);
        assert_eq!(out.status.code(), Some(0), "warnings only: {err}");
        let found = findings(&err);
        assert_eq!(found.len(), 1, "{err}");
        assert!(found[0].ends_with(warning), "{err}");
        assert!(err.contains(consequence), "{err}");
        // The caret line under the rule.
        assert!(
            err.contains(&format!("\n{}\n^", text.lines().nth(1).unwrap())),
            "{err}"
        );
        let out = citygen_capped(&[
            "rules",
            "derive",
            &f,
            "--lot",
            "20x12",
            "--lod",
            "3",
            "--gltf",
            glb.to_str().unwrap(),
        ]);
        assert_answered(&out);
        assert!(stderr(&out).contains(cap), "{}", stderr(&out));
    }
    // A bounded recursion: a fixed metre off each trip. Clean, and it derives.
    let f = write(
        dir.path(),
        "bounded.cga",
        "lot -> extrude(10){v}\nv -> comp(){side:f}\nf -> split(X, 1, sx - 1){window|f}\n",
    );
    let out = citygen_capped(&["rules", "check", &f]);
    assert!(findings(&stderr(&out)).is_empty(), "{}", stderr(&out));
    let out = citygen_capped(&[
        "rules",
        "derive",
        &f,
        "--lot",
        "20x12",
        "--lod",
        "3",
        "--gltf",
        glb.to_str().unwrap(),
    ]);
    assert_eq!(out.status.code(), Some(0), "{}", stderr(&out));
}

#[test]
fn shipped_rulesets_and_compiled_kb_rules_get_no_cap_warnings() {
    for f in [
        "knowledge_base/rules/fig3_19.cga",
        "knowledge_base/rules/toulouse_downtown.cga",
    ] {
        let out = citygen_capped(&["rules", "check", f]);
        let err = stderr(&out);
        assert_eq!(out.status.code(), Some(0), "{err}");
        assert!(
            !err.contains("exponential-growth") && !err.contains("non-terminating"),
            "{err}"
        );
    }
    // The rules the KB compiler writes, as `kb compile` prints them (one block per appearance).
    let dir = tempfile::tempdir().unwrap();
    let mut checked = 0;
    for zone in [
        "earth",
        "France/Occitanie/Toulouse",
        "France/Occitanie/Toulouse/Capitole",
        "France/Ile-de-France/Paris",
        "Monaco/Monte-Carlo",
        "Monaco/Fontvieille",
        "United Kingdom/England/Nottingham/Clifton",
    ] {
        let out = common::citygen(&["kb", "compile", "--zone", zone, common::KB]);
        assert!(out.status.success(), "{zone}: {}", stderr(&out));
        let text = String::from_utf8_lossy(&out.stdout).into_owned();
        for (i, block) in text.split("\n\n").filter(|b| b.contains("->")).enumerate() {
            let f = write(dir.path(), &format!("z{checked}_{i}.cga"), block);
            let out = citygen_capped(&["rules", "check", &f]);
            let err = stderr(&out);
            assert_eq!(out.status.code(), Some(0), "{zone}: {err}");
            assert!(
                findings(&err).is_empty(),
                "{zone} block {i}: {err}\n{block}"
            );
            checked += 1;
        }
    }
    assert!(checked >= 10, "{checked} rulesets");
}
