//! Output paths checked before any work (issue 18): every output has the extension of its
//! format, lies in a folder that is one (or can be made one), is no input of the run and is no
//! other output of the run, the same file reached through `..` or a symlink counting as the
//! same. A refusal is a [`RunError::Usage`] naming the flag and the path (an output that is an
//! existing folder is a [`RunError::Output`], as it would be at the end of the run); nothing
//! has been read or written then.

use std::ffi::OsString;
use std::path::{Component, Path, PathBuf};

use super::RunError;

/// The extensions each output flag accepts (lower case, compared case-insensitively).
fn extensions(flag: &str) -> &'static [&'static str] {
    match flag {
        "--ifc" => &["ifc"],
        "--citygml" => &["gml", "xml"],
        "--gltf" => &["glb"],
        "--cityjson" => &["json", "cityjson"],
        "--cityjsonseq" => &["jsonl"],
        "--report" => &["json"],
        "--preview" => &["png"],
        "--tiles3d" => &["json"],
        _ => &[],
    }
}

/// `p` as an absolute path with `.` and `..` resolved: the deepest ancestor that exists is
/// canonicalised (symlinks followed) and the rest appended, so that two spellings of one file,
/// existing or not yet, compare equal.
pub(crate) fn resolve(p: &Path) -> PathBuf {
    if let Ok(c) = std::fs::canonicalize(p) {
        return c;
    }
    let abs = std::path::absolute(p).unwrap_or_else(|_| p.to_path_buf());
    let mut lexical = PathBuf::new();
    for c in abs.components() {
        match c {
            Component::CurDir => {}
            Component::ParentDir => {
                lexical.pop();
            }
            other => lexical.push(other),
        }
    }
    let mut rest: Vec<OsString> = Vec::new();
    let mut cur = lexical.as_path();
    loop {
        if let Ok(mut base) = std::fs::canonicalize(cur) {
            for name in rest.iter().rev() {
                base.push(name);
            }
            return base;
        }
        match (cur.parent(), cur.file_name()) {
            (Some(parent), Some(name)) => {
                rest.push(name.to_os_string());
                cur = parent;
            }
            _ => return lexical,
        }
    }
}

/// The deepest ancestor of `p`'s folder that exists, when it is not a folder (a file where the
/// output's folder would be made).
fn blocked_folder(p: &Path) -> Option<PathBuf> {
    let mut dir = p.parent()?;
    loop {
        if dir.as_os_str().is_empty() {
            return None;
        }
        if let Ok(meta) = std::fs::metadata(dir) {
            return (!meta.is_dir()).then(|| dir.to_path_buf());
        }
        dir = dir.parent()?;
    }
}

/// The files a shapefile input is read from: the `.shp` and its `.shx`, `.dbf`, `.prj` and
/// `.cpg` beside it (either case of the extension).
pub(crate) fn shapefile_parts(shp: &Path) -> Vec<PathBuf> {
    let mut out = vec![shp.to_path_buf()];
    for ext in ["shx", "dbf", "prj", "cpg"] {
        out.push(shp.with_extension(ext));
        out.push(shp.with_extension(ext.to_ascii_uppercase()));
    }
    out
}

/// Checks the run's outputs (`(flag, path)`) against its inputs (`(flag, path)`): see the
/// module documentation. `force_extension` accepts any extension.
pub(crate) fn check(
    outputs: &[(&'static str, PathBuf)],
    inputs: &[(&'static str, PathBuf)],
    force_extension: bool,
) -> Result<(), RunError> {
    let usage = |m: String| Err(RunError::Usage(m));
    for (flag, path) in outputs.iter().map(|(f, p)| (*f, p.as_path())) {
        let ext = path
            .extension()
            .map(|e| e.to_string_lossy().to_ascii_lowercase());
        let wanted = extensions(flag);
        if !force_extension
            && !wanted.is_empty()
            && !ext.as_deref().is_some_and(|e| wanted.contains(&e))
        {
            let list: Vec<String> = wanted.iter().map(|e| format!(".{e}")).collect();
            return usage(format!(
                "{flag} {}: the file name must end in {} for this format (or pass --force-extension)",
                path.display(),
                list.join(" or ")
            ));
        }
        if path.is_dir() {
            return Err(RunError::Output {
                path: path.to_path_buf(),
                source: crate::export::ExportError::Io(std::io::Error::other(format!(
                    "{flag} names a folder, not a file"
                ))),
            });
        }
        if let Some(file) = blocked_folder(path) {
            return usage(format!(
                "{flag} {}: {} is a file, not a folder",
                path.display(),
                file.display()
            ));
        }
    }
    let resolved: Vec<PathBuf> = outputs.iter().map(|(_, p)| resolve(p)).collect();
    let read: Vec<(&str, &PathBuf, PathBuf)> = inputs
        .iter()
        .filter(|(_, p)| p.exists())
        .map(|(flag, p)| (*flag, p, resolve(p)))
        .collect();
    for (i, &(flag, ref path)) in outputs.iter().enumerate() {
        for &(in_flag, input, ref at) in &read {
            if *at == resolved[i] {
                return usage(format!(
                    "{flag} {} is the file {in_flag} reads ({}): refusing to overwrite an input",
                    path.display(),
                    input.display()
                ));
            }
        }
        for (j, &(other, ref other_path)) in outputs.iter().enumerate().skip(i + 1) {
            if resolved[i] == resolved[j] {
                return usage(format!(
                    "{flag} {} and {other} {} are the same file ({}): give each output its own path",
                    path.display(),
                    other_path.display(),
                    resolved[i].display()
                ));
            }
        }
    }
    Ok(())
}

/// Refuses an output that a tiled run writes at its own path (`outputs`: the report, the
/// picture, the tileset; the model outputs get a tile's suffix) when it is the `manifest` the
/// run writes beside its outputs: one would replace the other. Named like the other clashes,
/// before anything is read or written.
pub(crate) fn check_manifest(
    outputs: &[(&'static str, PathBuf)],
    manifest: &Path,
) -> Result<(), RunError> {
    let at = resolve(manifest);
    match outputs.iter().find(|(_, p)| resolve(p) == at) {
        Some((flag, path)) => Err(RunError::Usage(format!(
            "{flag} {} is the manifest this tiled run writes beside its outputs ({}): give the \
             {} another name",
            path.display(),
            manifest.display(),
            flag.trim_start_matches("--")
        ))),
        None => Ok(()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// [`super::check`] on borrowed paths.
    fn check(
        outs: &[(&'static str, &Path)],
        ins: &[(&'static str, PathBuf)],
        force_extension: bool,
    ) -> Result<(), RunError> {
        let owned: Vec<(&'static str, PathBuf)> =
            outs.iter().map(|(f, p)| (*f, p.to_path_buf())).collect();
        super::check(&owned, ins, force_extension)
    }

    #[test]
    fn spellings_of_one_file_resolve_alike_existing_or_not() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        std::fs::create_dir(d.join("a")).unwrap();
        assert_eq!(resolve(&d.join("a/../x.ifc")), resolve(&d.join("x.ifc")));
        assert_eq!(
            resolve(&d.join("a/./b/../y.gml")),
            resolve(&d.join("a/y.gml"))
        );
        std::fs::write(d.join("real.json"), "{}").unwrap();
        std::os::unix::fs::symlink(d.join("real.json"), d.join("link.json")).unwrap();
        assert_eq!(resolve(&d.join("link.json")), resolve(&d.join("real.json")));
    }

    #[test]
    fn each_refusal_names_the_flag_and_the_path() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        let msg = |outs: &[(&'static str, &Path)], ins: &[(&'static str, PathBuf)]| match check(
            outs, ins, false,
        ) {
            Err(RunError::Usage(m)) => m,
            other => panic!("{other:?}"),
        };
        let x = d.join("x.ifc");
        let j = d.join("x.json");
        let m = msg(&[("--ifc", &x), ("--report", &d.join("sub/../x.ifc"))], &[]);
        assert!(
            m.contains("--report") && m.contains("must end in .json"),
            "{m}"
        );
        let m = msg(&[("--ifc", &x), ("--citygml", &d.join("x.ifc"))], &[]);
        assert!(m.contains("--citygml") && m.contains(".gml or .xml"), "{m}");
        let m = msg(&[("--report", &j), ("--report", &d.join("./x.json"))], &[]);
        assert!(m.contains("are the same file"), "{m}");
        std::fs::write(d.join("README.md"), "x").unwrap();
        let m = msg(&[("--ifc", &d.join("README.md/x.ifc"))], &[]);
        assert!(m.contains("is a file, not a folder"), "{m}");
        let kb = d.join("kb.json");
        std::fs::write(&kb, "x").unwrap();
        let m = msg(
            &[("--report", &d.join("sub/../kb.json"))],
            &[("--kb", kb.clone())],
        );
        assert!(
            m.contains("the file --kb reads") && m.contains("refusing to overwrite"),
            "{m}"
        );
        assert!(check(
            &[
                ("--ifc", &x),
                ("--citygml", &d.join("x.gml")),
                ("--report", &j)
            ],
            &[("--kb", kb)],
            false
        )
        .is_ok());
        assert!(check(&[("--ifc", &d.join("x.step"))], &[], true).is_ok());
        // CityJSON: .city.json (or .cityjson), CityJSONSeq: .city.jsonl; the report's .json
        // is another file.
        assert!(check(
            &[
                ("--cityjson", &d.join("x.city.json")),
                ("--cityjsonseq", &d.join("x.city.jsonl")),
                ("--report", &j)
            ],
            &[],
            false
        )
        .is_ok());
        let m = msg(&[("--cityjsonseq", &d.join("x.city.json"))], &[]);
        assert!(m.contains("--cityjsonseq") && m.contains(".jsonl"), "{m}");
        let m = msg(
            &[("--cityjson", &j), ("--report", &d.join("./x.json"))],
            &[],
        );
        assert!(m.contains("are the same file"), "{m}");
    }
}
