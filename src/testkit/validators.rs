//! The reference validators, found the way `../shared/tools/validate-outputs` finds them, for
//! the tests that run them: the wrapper (`$CITYGEN_VALIDATE_OUTPUTS`, else
//! `shared/tools/validate-outputs` beside the checkout) and its installed environment
//! (`$CITYGEN_VALIDATE_HOME`, default `~/.cache/citygen-validate`: the Python venv and the
//! Khronos glTF validator). Where they are missing a test says so and skips, except under CI
//! (`CI` set and not `false`), where it fails: a green CI must mean the validators ran.

use std::path::{Path, PathBuf};

/// Where the validators' environment is installed.
pub(crate) fn validate_home() -> Option<PathBuf> {
    std::env::var_os("CITYGEN_VALIDATE_HOME")
        .map(PathBuf::from)
        .or_else(|| std::env::var_os("HOME").map(|h| Path::new(&h).join(".cache/citygen-validate")))
}

/// The `validate-outputs` wrapper, if it exists.
fn wrapper() -> Option<PathBuf> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    std::env::var_os("CITYGEN_VALIDATE_OUTPUTS")
        .map(PathBuf::from)
        .into_iter()
        .chain([
            root.join("../shared/tools/validate-outputs"),
            root.join("../../shared/tools/validate-outputs"),
        ])
        .find(|p| p.exists())
}

/// Whether this run is CI's (`CI` set to anything but `false` or `0`).
pub(crate) fn under_ci() -> bool {
    std::env::var("CI").is_ok_and(|v| !v.is_empty() && v != "false" && v != "0")
}

/// The wrapper to run for the test `what`, when it and its environment are installed (running
/// it then installs nothing). Otherwise `None` with a note on stderr, or, under CI, a panic
/// naming what is missing.
pub fn validate_outputs(what: &str) -> Option<PathBuf> {
    let tool = wrapper();
    let home = validate_home();
    let installed = home.as_ref().is_some_and(|h| {
        h.join("venv/bin/python").exists() && h.join("node/node_modules/gltf-validator").is_dir()
    });
    match (tool, installed) {
        (Some(tool), true) => {
            eprintln!(
                "{what}: validating with {} (validators in {})",
                tool.display(),
                home.unwrap_or_default().display()
            );
            Some(tool)
        }
        (tool, _) => {
            let missing =
                format!(
                "{what}: the reference validators are not installed (wrapper {}, environment {}); \
                 run ../shared/tools/validate-outputs once to install them",
                tool.map_or("not found beside the checkout".into(), |t| t.display().to_string()),
                home.map_or("unknown: no HOME".into(), |h| h.display().to_string())
            );
            assert!(
                !under_ci(),
                "{missing} (CI is set, so this test may not skip)"
            );
            eprintln!("{missing}: skipped");
            None
        }
    }
}
