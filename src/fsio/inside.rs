//! A file opened only if it lies inside a folder at the moment it is opened: its real path
//! (symlinks resolved) under the folder's real path, the last step not a symlink
//! (`O_NOFOLLOW`, so a swap after the check fails the open), and a regular file (checked on the
//! open handle, which is opened without blocking so a FIFO cannot hang it).

use std::fs::File;
use std::io;
use std::path::{Path, PathBuf};

/// Why `open_inside` refused a file.
#[derive(Debug, thiserror::Error)]
pub enum InsideError {
    /// The file's real path (symlinks followed) lies outside the folder.
    #[error("it leads outside {} (through a symlink, to {})", .folder.display(), .real.display())]
    Outside {
        /// The folder, as given.
        folder: PathBuf,
        /// Where the path leads.
        real: PathBuf,
    },
    /// The file became a symlink between the check and the open.
    #[error("it is a symlink")]
    Symlink,
    /// Not a regular file (a folder, a FIFO, a device, ...).
    #[error("it is not a regular file")]
    NotFile,
    /// The folder or the file cannot be resolved or opened.
    #[error(transparent)]
    Io(#[from] io::Error),
}

/// Opens `path` for reading if it lies inside `folder` (see the module docs).
pub(crate) fn open_inside(folder: &Path, path: &Path) -> Result<File, InsideError> {
    let real_folder = std::fs::canonicalize(folder)?;
    let real = std::fs::canonicalize(path)?;
    if !real.starts_with(&real_folder) {
        return Err(InsideError::Outside {
            folder: folder.to_path_buf(),
            real,
        });
    }
    let file = match open_no_follow(&real) {
        Ok(f) => f,
        Err(e) if e.raw_os_error() == Some(libc::ELOOP) => return Err(InsideError::Symlink),
        Err(e) => return Err(e.into()),
    };
    if !file.metadata()?.is_file() {
        return Err(InsideError::NotFile);
    }
    Ok(file)
}

#[cfg(unix)]
fn open_no_follow(path: &Path) -> io::Result<File> {
    use std::os::unix::fs::OpenOptionsExt;
    File::options()
        .read(true)
        .custom_flags(libc::O_NOFOLLOW | libc::O_NONBLOCK)
        .open(path)
}

#[cfg(not(unix))]
fn open_no_follow(path: &Path) -> io::Result<File> {
    File::open(path)
}

#[cfg(all(test, unix))]
mod tests {
    use super::*;
    use std::io::Read;

    #[test]
    fn only_regular_files_inside_the_folder_open() {
        let dir = tempfile::tempdir().unwrap();
        let kb = dir.path().join("kb");
        std::fs::create_dir_all(kb.join("sub")).unwrap();
        std::fs::write(kb.join("sub/a.cga"), b"inside").unwrap();
        std::fs::write(dir.path().join("secret"), b"outside").unwrap();
        std::os::unix::fs::symlink("sub/a.cga", kb.join("link.cga")).unwrap();
        std::os::unix::fs::symlink("../secret", kb.join("out.cga")).unwrap();
        std::os::unix::fs::symlink("..", kb.join("up")).unwrap();
        let mut text = String::new();
        open_inside(&kb, &kb.join("link.cga"))
            .unwrap()
            .read_to_string(&mut text)
            .unwrap();
        assert_eq!(text, "inside");
        for bad in ["out.cga", "up/secret"] {
            let e = open_inside(&kb, &kb.join(bad)).unwrap_err();
            assert!(matches!(e, InsideError::Outside { .. }), "{bad}: {e}");
        }
        let e = open_inside(&kb, &kb.join("sub")).unwrap_err();
        assert!(matches!(e, InsideError::NotFile), "{e}");
        let fifo = kb.join("fifo.cga");
        let made = std::process::Command::new("mkfifo")
            .arg(&fifo)
            .status()
            .unwrap();
        assert!(made.success());
        let e = open_inside(&kb, &fifo).unwrap_err();
        assert!(matches!(e, InsideError::NotFile), "{e}");
        let e = open_inside(&kb, &kb.join("missing.cga")).unwrap_err();
        assert!(matches!(e, InsideError::Io(_)), "{e}");
    }
}
