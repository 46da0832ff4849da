//! The job templates of deploy/ (deploy/README.md): every YAML file parses and the Jobs have
//! what Kubernetes needs to run a region in shards and merge it; every shell script parses
//! (`bash -n`); and the templates themselves run the Monaco sample in 3 shards with local
//! processes, each followed by its merge: the Kubernetes container's command with `$(NAME)`
//! expanded from its env as the kubelet expands it and `JOB_COMPLETION_INDEX` set, the Slurm
//! scripts with `SLURM_ARRAY_TASK_ID` and `SLURM_ARRAY_TASK_COUNT` set (stand-ins for `srun`
//! and `sbatch` on the PATH), and the xargs script for one machine.

use crate::common::*;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use yaml_rust2::{Yaml, YamlLoader};

const SHARDS: usize = 3;

/// The variables a template's index could come from: cleared for every run, so that a test
/// run inside a Slurm job or a Kubernetes pod sees only what the test sets.
const INDEX_VARS: [&str; 5] = [
    "JOB_COMPLETION_INDEX",
    "SLURM_ARRAY_TASK_ID",
    "SLURM_ARRAY_TASK_COUNT",
    "SLURM_ARRAY_TASK_MIN",
    "SLURM_CPUS_PER_TASK",
];

fn deploy() -> PathBuf {
    root().join("deploy")
}

/// Every file under `dir` (sorted), recursively.
fn files(dir: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    let mut entries: Vec<_> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    entries.sort();
    for p in entries {
        if p.is_dir() {
            out.extend(files(&p));
        } else {
            out.push(p);
        }
    }
    out
}

fn load_yaml(path: &Path) -> Yaml {
    let text = std::fs::read_to_string(path).unwrap();
    let mut docs =
        YamlLoader::load_from_str(&text).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    assert_eq!(docs.len(), 1, "{}: one document", path.display());
    docs.remove(0)
}

/// The value at `path` (keys and list indices) in `y`, with the path in the panic.
fn at<'a>(y: &'a Yaml, path: &[&str]) -> &'a Yaml {
    let mut cur = y;
    for (i, key) in path.iter().enumerate() {
        cur = match key.parse::<usize>() {
            Ok(n) => &cur[n],
            Err(_) => &cur[*key],
        };
        assert!(!cur.is_badvalue(), "no {}", path[..=i].join("."));
    }
    cur
}

fn strings(y: &Yaml) -> Vec<String> {
    y.as_vec()
        .unwrap_or_else(|| panic!("not a list: {y:?}"))
        .iter()
        .map(|v| match v {
            Yaml::String(s) => s.clone(),
            Yaml::Integer(i) => i.to_string(),
            other => panic!("not a string: {other:?}"),
        })
        .collect()
}

/// The `citygen` container of a Job: (env as written, command, args).
fn container(job: &Yaml) -> (BTreeMap<String, String>, Vec<String>, Vec<String>) {
    let containers = at(job, &["spec", "template", "spec", "containers"])
        .as_vec()
        .unwrap();
    let c = containers
        .iter()
        .find(|c| c["name"].as_str() == Some("citygen"))
        .expect("a container named citygen");
    let env = c["env"]
        .as_vec()
        .map(|v| {
            v.iter()
                .map(|e| {
                    let name = e["name"].as_str().expect("env name").to_string();
                    let value = e["value"]
                        .as_str()
                        .expect("env value (a string)")
                        .to_string();
                    (name, value)
                })
                .collect()
        })
        .unwrap_or_default();
    (env, strings(at(c, &["command"])), strings(at(c, &["args"])))
}

/// `s` with every `$(NAME)` of `env` replaced by its value, as Kubernetes expands a
/// container's command and args (`$$` is a literal `$`; an unknown name is left as written).
fn expand(s: &str, env: &BTreeMap<String, String>) -> String {
    let mut out = String::new();
    let mut rest = s;
    while let Some(i) = rest.find('$') {
        out.push_str(&rest[..i]);
        let after = &rest[i + 1..];
        if let Some(r) = after.strip_prefix('$') {
            out.push('$');
            rest = r;
        } else if let Some((name, r)) = after.strip_prefix('(').and_then(|a| a.split_once(')')) {
            match env.get(name) {
                Some(v) => out.push_str(v),
                None => out.push_str(&format!("$({name})")),
            }
            rest = r;
        } else {
            out.push('$');
            rest = after;
        }
    }
    out.push_str(rest);
    out
}

fn check(what: &str, out: &Output) {
    assert!(
        out.status.success(),
        "{what} failed ({}):\n{}\n{}",
        out.status,
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
}

/// Runs every command, all at once (as a cluster would), and checks each succeeded.
fn run_all_at_once(what: &str, mut commands: Vec<Command>) {
    let children: Vec<_> = commands
        .iter_mut()
        .map(|c| {
            c.stdout(std::process::Stdio::piped())
                .stderr(std::process::Stdio::piped())
                .spawn()
                .unwrap()
        })
        .collect();
    for (i, child) in children.into_iter().enumerate() {
        check(&format!("{what} {i}"), &child.wait_with_output().unwrap());
    }
}

/// What a region's shards and merge leave in `out`: every shard's manifest, and the merged
/// tileset, CityJSONSeq, report and preview picture.
fn assert_region(out: &Path) {
    for i in 0..SHARDS {
        let m = out.join(format!("citygen-manifest.{i}-of-{SHARDS}.json"));
        assert!(m.is_file(), "no manifest {}", m.display());
    }
    for f in [
        "3dtiles/tileset.json",
        "region.city.jsonl",
        "report.json",
        "region.png",
    ] {
        let p = out.join(f);
        assert!(
            p.is_file() && std::fs::metadata(&p).unwrap().len() > 0,
            "no merged {}",
            p.display()
        );
    }
    let png = std::fs::read(out.join("region.png")).unwrap();
    assert_eq!(&png[..8], b"\x89PNG\r\n\x1a\n");
}

/// The parameters a test gives the templates: Monaco at LOD1 into `out`.
fn params(out: &Path) -> BTreeMap<String, String> {
    let s = |p: &Path| p.to_string_lossy().into_owned();
    [
        ("CITYGEN_BIN", env!("CARGO_BIN_EXE_citygen").to_string()),
        ("INPUT", s(&root().join(MONACO))),
        ("KB", s(&root().join(KB))),
        ("OUT", s(out)),
        ("SHARDS", SHARDS.to_string()),
        ("LOD", "1".to_string()),
    ]
    .into_iter()
    .map(|(k, v)| (k.to_string(), v))
    .collect()
}

fn command(program: impl AsRef<std::ffi::OsStr>) -> Command {
    let mut c = Command::new(program);
    c.current_dir(root());
    for v in INDEX_VARS {
        c.env_remove(v);
    }
    c
}

// ---- structure ----

#[test]
fn every_yaml_parses_and_the_jobs_have_what_kubernetes_needs() {
    let yamls: Vec<PathBuf> = files(&deploy())
        .into_iter()
        .filter(|p| matches!(p.extension().and_then(|e| e.to_str()), Some("yaml" | "yml")))
        .collect();
    assert!(yamls.len() >= 2, "{yamls:?}");
    for p in &yamls {
        let y = load_yaml(p);
        assert_eq!(at(&y, &["apiVersion"]).as_str(), Some("batch/v1"), "{p:?}");
        assert_eq!(at(&y, &["kind"]).as_str(), Some("Job"), "{p:?}");
        // Every mounted volume is declared; restartPolicy Never (podFailurePolicy needs it).
        let spec = at(&y, &["spec", "template", "spec"]);
        assert_eq!(
            at(spec, &["restartPolicy"]).as_str(),
            Some("Never"),
            "{p:?}"
        );
        let volumes: Vec<&str> = at(spec, &["volumes"])
            .as_vec()
            .unwrap()
            .iter()
            .map(|v| v["name"].as_str().unwrap())
            .collect();
        for c in at(spec, &["containers"]).as_vec().unwrap() {
            for m in c["volumeMounts"].as_vec().into_iter().flatten() {
                let name = m["name"].as_str().unwrap();
                assert!(volumes.contains(&name), "{p:?}: volume {name} not declared");
            }
            let cpu = &c["resources"]["requests"]["cpu"];
            assert_eq!(cpu.as_str(), Some("2"), "{p:?}: 2 CPUs");
        }
    }

    let shards = load_yaml(&deploy().join("kubernetes/shards-job.yaml"));
    let spec = at(&shards, &["spec"]);
    assert_eq!(at(spec, &["completionMode"]).as_str(), Some("Indexed"));
    let n = at(spec, &["completions"]).as_i64().unwrap();
    assert!(n >= 1);
    assert_eq!(at(spec, &["parallelism"]).as_i64(), Some(n));
    assert!(at(spec, &["backoffLimitPerIndex"]).as_i64().unwrap() >= 0);
    assert!(at(spec, &["maxFailedIndexes"]).as_i64().is_some());
    let (env, cmd, args) = container(&shards);
    assert_eq!(cmd, ["citygen"]);
    assert!(
        args.windows(2).any(|w| w == ["--shard", "auto"]),
        "{args:?}"
    );
    // The shard count the container is told is the Job's.
    assert!(
        args.windows(2).any(|w| w == ["--shards", "$(SHARDS)"]),
        "{args:?}"
    );
    assert_eq!(env.get("SHARDS"), Some(&n.to_string()));
    // Every reference is to a variable of the container.
    for a in &args {
        let e = expand(a, &env);
        assert!(!e.contains("$("), "unknown variable in {a}");
    }

    let merge = load_yaml(&deploy().join("kubernetes/merge-job.yaml"));
    let (env, cmd, args) = container(&merge);
    assert_eq!(cmd, ["citygen"]);
    assert_eq!(args.first().map(String::as_str), Some("merge"));
    assert!(at(&merge, &["spec"])["completionMode"].is_badvalue());
    for a in &args {
        assert!(!expand(a, &env).contains("$("), "unknown variable in {a}");
    }
}

#[test]
fn every_shell_script_parses() {
    let scripts: Vec<PathBuf> = files(&deploy())
        .into_iter()
        .filter(|p| {
            matches!(
                p.extension().and_then(|e| e.to_str()),
                Some("sh" | "sbatch")
            )
        })
        .collect();
    assert!(scripts.len() >= 4, "{scripts:?}");
    for p in &scripts {
        let out = Command::new("bash").arg("-n").arg(p).output().unwrap();
        check(&format!("bash -n {}", p.display()), &out);
        let text = std::fs::read_to_string(p).unwrap();
        assert!(text.starts_with("#!/usr/bin/env bash\n"), "{p:?}: shebang");
        assert!(
            text.contains("set -euo pipefail"),
            "{p:?}: set -euo pipefail"
        );
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt;
            let mode = std::fs::metadata(p).unwrap().permissions().mode();
            assert!(mode & 0o111 != 0, "{p:?} is not executable");
        }
    }
}

// ---- the templates run ----

#[test]
fn kubernetes_jobs_run_the_region_with_local_processes() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    std::fs::create_dir_all(&out).unwrap();
    let p = params(&out);

    // The shard Job: its container's env, with the test's parameters for the placeholders.
    let (mut env, cmd, args) = container(&load_yaml(&deploy().join("kubernetes/shards-job.yaml")));
    for k in ["INPUT", "KB", "OUT", "SHARDS", "LOD"] {
        env.insert(k.into(), p[k].clone());
    }
    assert_eq!(cmd, ["citygen"]);
    let args: Vec<String> = args.iter().map(|a| expand(a, &env)).collect();
    let pods = (0..SHARDS)
        .map(|i| {
            let mut c = command(&p["CITYGEN_BIN"]);
            c.args(&args)
                .envs(&env)
                .env("JOB_COMPLETION_INDEX", i.to_string());
            c
        })
        .collect();
    run_all_at_once("kubernetes shard", pods);

    let (mut env, cmd, args) = container(&load_yaml(&deploy().join("kubernetes/merge-job.yaml")));
    env.insert("OUT".into(), p["OUT"].clone());
    assert_eq!(cmd, ["citygen"]);
    let args: Vec<String> = args.iter().map(|a| expand(a, &env)).collect();
    let merged = command(&p["CITYGEN_BIN"])
        .args(&args)
        .envs(&env)
        .output()
        .unwrap();
    check("kubernetes merge", &merged);
    assert_region(&out);
}

/// A folder with stand-ins for Slurm's `srun` (runs its arguments) and `sbatch` (logs its
/// arguments to `$SBATCH_LOG` and answers job ids 4242, 4243, ... as `--parsable` does).
fn slurm_stand_ins(dir: &Path) -> PathBuf {
    let bin = dir.join("bin");
    std::fs::create_dir_all(&bin).unwrap();
    let write = |name: &str, text: &str| {
        let p = bin.join(name);
        std::fs::write(&p, text).unwrap();
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt;
            std::fs::set_permissions(&p, std::fs::Permissions::from_mode(0o755)).unwrap();
        }
    };
    write("srun", "#!/bin/sh\nexec \"$@\"\n");
    write(
        "sbatch",
        "#!/bin/sh\necho \"$*\" >> \"$SBATCH_LOG\"\nn=$(wc -l < \"$SBATCH_LOG\")\necho \"$((4241 + n));cluster\"\n",
    );
    bin
}

fn path_with(bin: &Path) -> std::ffi::OsString {
    let mut paths = vec![bin.to_path_buf()];
    paths.extend(std::env::split_paths(
        &std::env::var_os("PATH").unwrap_or_default(),
    ));
    std::env::join_paths(paths).unwrap()
}

#[test]
fn slurm_scripts_run_the_region_with_local_processes() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let p = params(&out);
    let path = path_with(&slurm_stand_ins(dir.path()));

    // The array's tasks: the index and the count from Slurm's variables (SHARDS unset).
    let tasks = (0..SHARDS)
        .map(|i| {
            let mut c = command("bash");
            c.arg(deploy().join("slurm/shards.sbatch"))
                .env("PATH", &path)
                .env("SLURM_ARRAY_TASK_ID", i.to_string())
                .env("SLURM_ARRAY_TASK_COUNT", SHARDS.to_string())
                .env_remove("SHARDS");
            for k in ["CITYGEN_BIN", "INPUT", "KB", "OUT", "LOD"] {
                c.env(k, &p[k]);
            }
            c
        })
        .collect();
    run_all_at_once("slurm array task", tasks);

    let merged = command("bash")
        .arg(deploy().join("slurm/merge.sbatch"))
        .env("PATH", &path)
        .env("CITYGEN_BIN", &p["CITYGEN_BIN"])
        .env("OUT", &p["OUT"])
        .output()
        .unwrap();
    check("slurm merge", &merged);
    assert_region(&out);

    // submit.sh: the array over 0..N-1, then the merge after it succeeded.
    let log = dir.path().join("sbatch.log");
    let mut submit = command("bash");
    submit
        .arg(deploy().join("slurm/submit.sh"))
        .arg("--partition=test")
        .env("PATH", &path)
        .env("SBATCH_LOG", &log);
    for k in ["INPUT", "KB", "OUT", "SHARDS"] {
        submit.env(k, &p[k]);
    }
    check("slurm submit", &submit.output().unwrap());
    let calls: Vec<String> = std::fs::read_to_string(&log)
        .unwrap()
        .lines()
        .map(String::from)
        .collect();
    assert_eq!(calls.len(), 2, "{calls:?}");
    assert!(
        calls[0].contains(&format!("--array=0-{}", SHARDS - 1))
            && calls[0].contains("--partition=test")
            && calls[0].ends_with("shards.sbatch"),
        "{calls:?}"
    );
    assert!(
        calls[1].contains("--dependency=afterok:4242")
            && calls[1].contains("--partition=test")
            && calls[1].ends_with("merge.sbatch"),
        "{calls:?}"
    );
}

#[test]
fn local_script_runs_the_region_and_fails_when_a_shard_fails() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let p = params(&out);
    let script = deploy().join("local/run-shards.sh");
    let run = |out: &Path, input: &Path| {
        let mut c = command("bash");
        c.arg(&script).env("PARALLEL", "2").env("THREADS", "1");
        for k in ["CITYGEN_BIN", "KB", "SHARDS", "LOD"] {
            c.env(k, &p[k]);
        }
        c.env("OUT", out).env("INPUT", input).output().unwrap()
    };
    check("run-shards.sh", &run(&out, &root().join(MONACO)));
    assert_region(&out);

    // A shard that fails (here every shard: the input is missing) fails the script, and no
    // merge runs.
    let out2 = dir.path().join("out2");
    let failed = run(&out2, &dir.path().join("missing.osm.pbf"));
    assert!(!failed.status.success());
    assert!(
        String::from_utf8_lossy(&failed.stderr).contains("a shard failed"),
        "{}",
        String::from_utf8_lossy(&failed.stderr)
    );
    assert!(!out2.join("region.png").exists() && !out2.join("report.json").exists());
}
