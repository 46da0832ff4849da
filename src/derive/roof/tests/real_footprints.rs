//! Regression tests on real footprints (OSM Monaco, Clifton shapefile) on which the straight
//! skeleton used to fail: nearly parallel and antiparallel edges, nearly simultaneous events,
//! nearly collinear vertices and edges of a few centimetres.

use glam::DVec2;

use super::check_hipped;
use crate::geometry::Polygon;

/// Parses the fixture format: a JSON array of `{id, outer: [[x, y], ...], holes: [[[x, y]...]]}`.
fn load(text: &str) -> Vec<(String, Polygon)> {
    let v: serde_json::Value = serde_json::from_str(text).unwrap_or(serde_json::Value::Null);
    let ring = |r: &serde_json::Value| -> Vec<DVec2> {
        r.as_array()
            .into_iter()
            .flatten()
            .map(|p| {
                DVec2::new(
                    p[0].as_f64().unwrap_or(f64::NAN),
                    p[1].as_f64().unwrap_or(f64::NAN),
                )
            })
            .collect()
    };
    v.as_array()
        .into_iter()
        .flatten()
        .map(|c| {
            let holes = c["holes"]
                .as_array()
                .into_iter()
                .flatten()
                .map(ring)
                .collect();
            (
                c["id"].as_str().unwrap_or("?").to_string(),
                Polygon::new(ring(&c["outer"]), holes),
            )
        })
        .collect()
}

fn run_all(cases: &[(String, Polygon)]) -> Vec<String> {
    let mut bad = Vec::new();
    for (id, p) in cases {
        for pitch in [30.0, 45.0] {
            if let Err(e) = check_hipped(p, pitch) {
                let n: usize = p.rings().map(|r| r.len()).sum();
                bad.push(format!("{id} ({n} vertices, pitch {pitch}): {e}"));
                break;
            }
        }
    }
    bad
}

#[test]
fn real_footprints_build_valid_hipped_roofs() {
    let cases = load(include_str!("fixtures/real_footprints.json"));
    assert!(cases.len() >= 15, "fixture has {} cases", cases.len());
    let bad = run_all(&cases);
    assert!(
        bad.is_empty(),
        "{} failures:\n{}",
        bad.len(),
        bad.join("\n")
    );
}

/// Development aid: `SKEL_FAIL_JSON=failures.json cargo test --lib real_dump -- --ignored
/// --nocapture` checks every polygon of a dump written by the `roof_survey` example.
#[test]
#[ignore]
fn real_dump() {
    let Ok(path) = std::env::var("SKEL_FAIL_JSON") else {
        return;
    };
    let text = std::fs::read_to_string(&path).unwrap_or_default();
    let mut cases = load(&text);
    cases.sort_by_key(|(_, p)| p.rings().map(|r| r.len()).sum::<usize>());
    let bad = run_all(&cases);
    for b in &bad {
        println!("{b}");
    }
    println!("{} of {} fail", bad.len(), cases.len());
}
