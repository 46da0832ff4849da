//! Outputs survive a killed run (issue 7): SIGKILL in the middle of writing leaves the previous
//! files intact, and the next run clears the killed run's temporaries.

use crate::common::*;

use std::path::Path;
use std::process::Command;
use std::time::{Duration, Instant};

fn temporaries(dir: &Path) -> Vec<String> {
    std::fs::read_dir(dir)
        .unwrap()
        .flatten()
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|n| n.ends_with(".tmp"))
        .collect()
}

#[test]
fn sigkill_mid_run_leaves_previous_outputs_intact() {
    let dir = tempfile::tempdir().unwrap();
    let names = ["out.ifc", "out.gml", "out.glb"];
    for n in names {
        std::fs::write(dir.path().join(n), format!("previous {n}")).unwrap();
    }
    let p = |n: &str| dir.path().join(n).display().to_string();
    let args = [
        "--osm".to_string(),
        MONACO.into(),
        "--kb".into(),
        KB.into(),
        "--lod".into(),
        "3".into(),
        "--ifc".into(),
        p("out.ifc"),
        "--citygml".into(),
        p("out.gml"),
        "--gltf".into(),
        p("out.glb"),
        "--quiet".into(),
    ];
    let mut child = Command::new(env!("CARGO_BIN_EXE_citygen"))
        .current_dir(root())
        .args(&args)
        .spawn()
        .unwrap();
    // Wait until the run is writing (its temporaries exist and grow), then kill it.
    let start = Instant::now();
    loop {
        let writing = temporaries(dir.path())
            .iter()
            .any(|t| std::fs::metadata(dir.path().join(t)).is_ok_and(|m| m.len() > 100_000));
        if writing {
            break;
        }
        assert!(
            child.try_wait().unwrap().is_none(),
            "the run ended before it could be killed"
        );
        assert!(
            start.elapsed() < Duration::from_secs(300),
            "never started writing"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
    child.kill().unwrap(); // SIGKILL on Unix
    child.wait().unwrap();
    for n in names {
        assert_eq!(
            std::fs::read_to_string(dir.path().join(n)).unwrap(),
            format!("previous {n}"),
            "{n} was touched by the killed run"
        );
    }
    assert!(
        !temporaries(dir.path()).is_empty(),
        "the killed run left its temporaries"
    );

    // The next run publishes complete files and clears the dead run's temporaries.
    let mut args = args.to_vec();
    args[5] = "1".into();
    let refs: Vec<&str> = args.iter().map(String::as_str).collect();
    let out = citygen(&refs);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert_eq!(temporaries(dir.path()), Vec::<String>::new());
    let gml = std::fs::read_to_string(dir.path().join("out.gml")).unwrap();
    assert!(gml.trim_end().ends_with("</core:CityModel>"));
}

#[test]
fn one_two_and_eight_threads_write_the_same_bytes() {
    // LOD3 on a district (the heaviest writers) and LOD2 on the whole sample.
    for extra in [
        &["--lod", "3", "--bbox", "7.4180,43.7290,7.4240,43.7330"][..],
        &["--lod", "2"][..],
    ] {
        let runs: Vec<Vec<Vec<u8>>> = ["1", "2", "8"]
            .iter()
            .map(|t| {
                let dir = tempfile::tempdir().unwrap();
                let p = |n: &str| dir.path().join(n).display().to_string();
                let mut args = vec![
                    "--osm".to_string(),
                    MONACO.into(),
                    "--kb".into(),
                    KB.into(),
                    "--threads".into(),
                    t.to_string(),
                    "--ifc".into(),
                    p("o.ifc"),
                    "--citygml".into(),
                    p("o.gml"),
                    "--gltf".into(),
                    p("o.glb"),
                    "--cityjson".into(),
                    p("o.city.json"),
                    "--cityjsonseq".into(),
                    p("o.city.jsonl"),
                    "--report".into(),
                    p("o.json"),
                    "--quiet".into(),
                ];
                args.extend(extra.iter().map(|s| s.to_string()));
                let refs: Vec<&str> = args.iter().map(String::as_str).collect();
                let out = citygen(&refs);
                assert!(
                    out.status.success(),
                    "{}",
                    String::from_utf8_lossy(&out.stderr)
                );
                [
                    "o.ifc",
                    "o.gml",
                    "o.glb",
                    "o.city.json",
                    "o.city.jsonl",
                    "o.json",
                ]
                .iter()
                .map(|n| std::fs::read(dir.path().join(n)).unwrap())
                .collect()
            })
            .collect();
        let names = [
            "IFC",
            "CityGML",
            "glTF",
            "CityJSON",
            "CityJSONSeq",
            "report",
        ];
        for (i, name) in names.iter().enumerate() {
            assert!(
                runs[0][i] == runs[1][i],
                "{name} differs between 1 and 2 threads ({extra:?})"
            );
            assert!(
                runs[0][i] == runs[2][i],
                "{name} differs between 1 and 8 threads ({extra:?})"
            );
        }
    }
}
