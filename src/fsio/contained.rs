//! Files read on behalf of a manifest (a shard's, a previous run's) or a KB: a path the file
//! gives, relative to its folder, opened only when it stays inside that folder
//! ([`open_contained`]): no `..`, no absolute path, no URI scheme, no symlink as the file, no
//! symlinked folder leading out, and a regular file only (a FIFO, a device or a folder is
//! refused without blocking). The checks are made on the file as opened (`O_NOFOLLOW`, the
//! opened descriptor's metadata and, on Linux, its real path), at the moment of use.

use std::fs::File;
use std::io;
use std::path::{Component, Path, PathBuf};

/// Why a path given by a file was not opened.
#[derive(Debug, thiserror::Error)]
pub(crate) enum ContainedError {
    /// The path is empty, absolute, a URI or goes up with `..`.
    #[error("{rel:?} {why}: only paths inside the folder are read")]
    Escapes {
        /// The path as the file gives it.
        rel: String,
        /// What is wrong with it.
        why: &'static str,
    },
    /// The file is a symlink, or its real path lies outside the folder.
    #[error("{} {why}: only files inside the folder are read", .path.display())]
    Outside {
        /// The path opened (the folder joined with the given path).
        path: PathBuf,
        /// What was found.
        why: String,
    },
    /// The file is not a regular file.
    #[error("{} is {kind}, not a regular file", .path.display())]
    NotAFile {
        /// The path opened.
        path: PathBuf,
        /// What it is.
        kind: &'static str,
    },
    /// The system's error opening or inspecting the file.
    #[error("{}: {source}", .path.display())]
    Io {
        /// The path opened.
        path: PathBuf,
        /// The system's error.
        source: io::Error,
    },
}

/// `rel` as a relative path made only of names (and `.`): refused when empty, absolute, a URI
/// (`file:`, `http:`, any `scheme:`), with a `\`, or going up with `..`. A lexical check; the
/// file itself is checked by [`open_contained`].
pub(crate) fn relative_inside(rel: &str) -> Result<&Path, ContainedError> {
    let escapes = |why| {
        Err(ContainedError::Escapes {
            rel: rel.to_string(),
            why,
        })
    };
    if rel.is_empty() {
        return escapes("is empty");
    }
    if has_scheme(rel) {
        return escapes("is a URI with a scheme");
    }
    if rel.contains('\\') {
        return escapes("holds a backslash");
    }
    let path = Path::new(rel);
    for c in path.components() {
        match c {
            Component::Normal(_) | Component::CurDir => {}
            Component::ParentDir => return escapes("goes up with `..`"),
            Component::RootDir | Component::Prefix(_) => return escapes("is absolute"),
        }
    }
    Ok(path)
}

/// Whether `s` starts with a URI scheme (`letter (letter | digit | + - .)* :`).
fn has_scheme(s: &str) -> bool {
    let Some((scheme, _)) = s.split_once(':') else {
        return false;
    };
    let mut chars = scheme.chars();
    chars.next().is_some_and(|c| c.is_ascii_alphabetic())
        && chars.all(|c| c.is_ascii_alphanumeric() || "+-.".contains(c))
}

/// Opens `rel` (a path a manifest or KB in folder `dir` gives) for reading when it is a regular
/// file inside `dir`: [`relative_inside`], then opened without following a symlink as the file
/// and without blocking on a FIFO, then checked as opened: a regular file whose real path lies
/// inside `dir`'s (so no symlinked folder on the way leads out). Returns the file and its path.
pub(crate) fn open_contained(dir: &Path, rel: &str) -> Result<(File, PathBuf), ContainedError> {
    let path = dir.join(relative_inside(rel)?);
    let io_err = |source| ContainedError::Io {
        path: path.clone(),
        source,
    };
    let file = open_nofollow(&path).map_err(|e| {
        if is_symlink(&path) {
            ContainedError::Outside {
                path: path.clone(),
                why: "is a symlink".into(),
            }
        } else {
            io_err(e)
        }
    })?;
    let meta = file.metadata().map_err(io_err)?;
    if !meta.is_file() {
        return Err(ContainedError::NotAFile {
            path: path.clone(),
            kind: kind_of(&meta),
        });
    }
    let root = std::fs::canonicalize(dir).map_err(|source| ContainedError::Io {
        path: dir.to_path_buf(),
        source,
    })?;
    let real = real_path(&file, &path).map_err(io_err)?;
    if !real.starts_with(&root) {
        return Err(ContainedError::Outside {
            path,
            why: format!("leads to {} through a symlinked folder", real.display()),
        });
    }
    Ok((file, path))
}

/// Whether `p` itself is a symlink.
fn is_symlink(p: &Path) -> bool {
    std::fs::symlink_metadata(p).is_ok_and(|m| m.file_type().is_symlink())
}

/// Opens `p` read-only; on Unix with `O_NOFOLLOW` (a symlink is not opened) and `O_NONBLOCK` (a
/// FIFO without a writer does not block the open; reads of a regular file are not affected).
fn open_nofollow(p: &Path) -> io::Result<File> {
    let mut o = File::options();
    o.read(true);
    #[cfg(unix)]
    {
        use std::os::unix::fs::OpenOptionsExt;
        o.custom_flags(libc::O_NOFOLLOW | libc::O_NONBLOCK);
    }
    o.open(p)
}

/// The real path of the opened `file`: on Linux the kernel's (`/proc/self/fd`), so that the
/// check is on the file opened; elsewhere `path` canonicalised.
fn real_path(file: &File, path: &Path) -> io::Result<PathBuf> {
    #[cfg(target_os = "linux")]
    {
        use std::os::fd::AsRawFd;
        if let Ok(p) = std::fs::read_link(format!("/proc/self/fd/{}", file.as_raw_fd())) {
            return Ok(p);
        }
    }
    let _ = file;
    std::fs::canonicalize(path)
}

/// What a file that is not a regular file is, in words.
fn kind_of(meta: &std::fs::Metadata) -> &'static str {
    let t = meta.file_type();
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        if t.is_fifo() {
            return "a named pipe (FIFO)";
        }
        if t.is_block_device() || t.is_char_device() {
            return "a device";
        }
        if t.is_socket() {
            return "a socket";
        }
    }
    if t.is_dir() {
        "a folder"
    } else {
        "not a file"
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Read;

    #[test]
    fn paths_leaving_the_folder_are_refused_by_their_spelling() {
        for bad in [
            "",
            "../x",
            "a/../../x",
            "/etc/passwd",
            "file:///etc/passwd",
            "http://example.org/x.glb",
            "c:x",
            "a\\..\\x",
        ] {
            assert!(relative_inside(bad).is_err(), "{bad:?} accepted");
        }
        for good in ["x.glb", "3d/content/t_1_2.glb", "./a/b.json", "a/b:c.json"] {
            assert!(relative_inside(good).is_ok(), "{good:?} refused");
        }
        let e = relative_inside("../x.glb").unwrap_err().to_string();
        assert!(e.contains("\"../x.glb\"") && e.contains(".."), "{e}");
    }

    #[test]
    fn only_regular_files_inside_the_folder_open() {
        let tmp = tempfile::tempdir().unwrap();
        let dir = tmp.path().join("shard");
        std::fs::create_dir_all(dir.join("sub")).unwrap();
        std::fs::write(dir.join("sub/a.txt"), "inside").unwrap();
        std::fs::write(tmp.path().join("secret.txt"), "outside").unwrap();
        let (mut f, p) = open_contained(&dir, "sub/a.txt").unwrap();
        let mut s = String::new();
        f.read_to_string(&mut s).unwrap();
        assert_eq!((s.as_str(), p), ("inside", dir.join("sub/a.txt")));

        std::os::unix::fs::symlink(tmp.path().join("secret.txt"), dir.join("link.txt")).unwrap();
        let e = open_contained(&dir, "link.txt").unwrap_err().to_string();
        assert!(e.contains("link.txt") && e.contains("symlink"), "{e}");
        // A symlink inside pointing inside is refused too: the file must be the file.
        std::os::unix::fs::symlink(dir.join("sub/a.txt"), dir.join("in.txt")).unwrap();
        assert!(open_contained(&dir, "in.txt").is_err());
        // A symlinked folder leading out.
        std::fs::create_dir(tmp.path().join("elsewhere")).unwrap();
        std::fs::write(tmp.path().join("elsewhere/b.txt"), "outside").unwrap();
        std::os::unix::fs::symlink(tmp.path().join("elsewhere"), dir.join("out")).unwrap();
        let e = open_contained(&dir, "out/b.txt").unwrap_err().to_string();
        assert!(
            e.contains("out/b.txt") && e.contains("symlinked folder"),
            "{e}"
        );
        // A folder, and a FIFO (refused without blocking).
        let e = open_contained(&dir, "sub").unwrap_err().to_string();
        assert!(e.contains("a folder"), "{e}");
        let fifo = dir.join("pipe");
        assert!(std::process::Command::new("mkfifo")
            .arg(&fifo)
            .status()
            .unwrap()
            .success());
        let e = open_contained(&dir, "pipe").unwrap_err().to_string();
        assert!(e.contains("named pipe"), "{e}");
        // The shard folder itself may be reached through a symlink.
        std::os::unix::fs::symlink(&dir, tmp.path().join("alias")).unwrap();
        assert!(open_contained(&tmp.path().join("alias"), "sub/a.txt").is_ok());
    }
}
