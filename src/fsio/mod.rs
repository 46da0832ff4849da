//! Files, on the ground floor: the one atomic write ([`AtomicFile`], [`PendingFile`],
//! `write_atomic`), scratch files beside an output, the SHA-256 of a file and the one hex
//! encoder, and the files a manifest or KB names opened only inside their folder
//! (`contained::open_contained` for a name relative to a folder, `open_inside` for a path
//! already resolved). It imports nothing of ours.
//!
//! Every file citygen publishes goes through a temporary `.{name}.{pid}.tmp` beside its target,
//! renamed over it once complete: a failed or killed run never leaves a half-written file, and
//! the next run removes the temporaries that dead runs left.

pub(crate) mod contained;
#[cfg(target_os = "linux")]
mod direct;
mod inside;

pub(crate) use inside::open_inside;
pub use inside::InsideError;

use std::fs::File;
use std::io::{self, BufWriter, Read, Write};
use std::path::{Path, PathBuf};

use sha2::{Digest, Sha256};

/// The folder of `target`: its parent, or `.` for a bare file name.
fn folder_of(target: &Path) -> &Path {
    target
        .parent()
        .filter(|d| !d.as_os_str().is_empty())
        .unwrap_or(Path::new("."))
}

/// The file name of `target`, lossily as text (empty without one).
fn name_of(target: &Path) -> String {
    target
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default()
}

/// The temporary beside `target`: `.{name}.{pid}.tmp`, or `.{name}.{pid}.{tag}.tmp`.
fn temporary_path(target: &Path, tag: Option<&str>) -> PathBuf {
    let name = name_of(target);
    let pid = std::process::id();
    folder_of(target).join(match tag {
        None => format!(".{name}.{pid}.tmp"),
        Some(tag) => format!(".{name}.{pid}.{tag}.tmp"),
    })
}

/// A scratch file beside `target` (in its folder, so on the output's disk rather than a possibly
/// small temporary file system), named `.{file name}.{pid}.{tag}.tmp`, open for reading and
/// writing. It is unlinked at once where the system allows (Unix: only the handle keeps it);
/// otherwise its path is returned, for the caller to remove when done.
pub(crate) fn scratch_beside(target: &Path, tag: &str) -> io::Result<(File, Option<PathBuf>)> {
    let path = temporary_path(target, Some(tag));
    let file = File::options()
        .read(true)
        .write(true)
        .create(true)
        .truncate(true)
        .open(&path)?;
    let left = std::fs::remove_file(&path).is_err().then_some(path);
    Ok((file, left))
}

/// A file written atomically: bytes go to a temporary file beside the target, which is renamed
/// over the target by [`AtomicFile::commit`]. Dropped without commit, the temporary is removed and
/// the target is untouched, so a failed or killed run never leaves a half-written output.
pub struct AtomicFile {
    target: PathBuf,
    tmp: PathBuf,
    file: File,
    committed: bool,
}

impl AtomicFile {
    /// Creates the temporary file in the target's folder, creating the folder if needed.
    pub fn create(target: &Path) -> io::Result<AtomicFile> {
        AtomicFile::open(target, None)
    }

    /// [`AtomicFile::create`] with the temporary named `.{name}.{pid}.{tag}.tmp`.
    fn open(target: &Path, tag: Option<&str>) -> io::Result<AtomicFile> {
        let tmp = temporary_of(target, tag)?;
        // A new file, never one planted at the temporary's name (a symlink there is replaced,
        // not followed).
        let _ = std::fs::remove_file(&tmp);
        let file = File::options().write(true).create_new(true).open(&tmp)?;
        Ok(AtomicFile {
            target: target.to_path_buf(),
            tmp,
            file,
            committed: false,
        })
    }

    /// The temporary file itself (another handle on it), unbuffered.
    pub fn file(&self) -> io::Result<File> {
        self.file.try_clone()
    }

    /// A writer of the temporary file for a large output: on Linux it writes past the page cache
    /// from a background thread (`O_DIRECT`, see `fsio::direct`), elsewhere it is the file
    /// itself. Write through a `BufWriter` or in large pieces. Drop the writer, then call
    /// `StreamSink::finish` before [`AtomicFile::close`]: only then are the bytes complete.
    pub fn stream(&self) -> io::Result<(Box<dyn io::Write + Send>, StreamSink)> {
        #[cfg(target_os = "linux")]
        {
            let (w, sink) = direct::open(&self.tmp)?;
            Ok((Box::new(w), StreamSink(Some(sink))))
        }
        #[cfg(not(target_os = "linux"))]
        {
            Ok((Box::new(self.file()?), StreamSink(None)))
        }
    }

    /// A buffered writer on the temporary file. Flush it before [`AtomicFile::commit`].
    pub fn writer(&self) -> io::Result<BufWriter<File>> {
        Ok(BufWriter::with_capacity(1 << 20, self.file.try_clone()?))
    }

    /// Syncs the temporary file and renames it over the target.
    pub fn commit(self) -> io::Result<()> {
        self.close()?.commit()
    }

    /// Syncs and closes the temporary file without renaming it yet, so that a run writing many
    /// files (tiles) can publish them all at the end without holding a descriptor per file.
    pub fn close(mut self) -> io::Result<PendingFile> {
        self.file.sync_all()?;
        // Hand the temporary over: this AtomicFile must not delete it when dropped.
        self.committed = true;
        Ok(PendingFile {
            target: std::mem::take(&mut self.target),
            tmp: std::mem::take(&mut self.tmp),
            committed: false,
        })
    }
}

/// The completion of an [`AtomicFile::stream`] writer.
pub struct StreamSink(
    #[cfg(target_os = "linux")] Option<direct::DirectSink>,
    #[cfg(not(target_os = "linux"))] Option<()>,
);

impl StreamSink {
    /// Waits until every byte given to the (dropped) writer is in the file; returns the first
    /// error of any write.
    pub(crate) fn finish(self) -> io::Result<()> {
        #[cfg(target_os = "linux")]
        if let Some(s) = self.0 {
            return s.finish();
        }
        Ok(())
    }
}

/// The temporary beside `target` ([`temporary_path`]: [`AtomicFile`], [`PendingFile::link`]),
/// its folder created if needed and dead runs' temporaries `.{name}.{pid}.tmp` removed.
fn temporary_of(target: &Path, tag: Option<&str>) -> io::Result<PathBuf> {
    let dir = folder_of(target);
    std::fs::create_dir_all(dir)?;
    remove_stale_temporaries(dir, &name_of(target));
    Ok(temporary_path(target, tag))
}

/// Removes the temporaries `.{name}.{pid}.tmp` that killed runs left beside a target: those
/// whose process is gone (on Linux, no `/proc/{pid}`). Elsewhere, where liveness cannot be
/// told, nothing is removed. Best effort: errors are ignored.
///
/// Each folder is listed once per process (a tiled run creates thousands of files in one
/// folder: listing it for each was quadratic), and what it held of dead runs is kept by name
/// until a file of that name is created.
fn remove_stale_temporaries(dir: &Path, name: &str) {
    use std::collections::HashMap;
    use std::sync::{Mutex, OnceLock};
    type Stale = HashMap<String, Vec<PathBuf>>;
    static SEEN: OnceLock<Mutex<HashMap<PathBuf, Stale>>> = OnceLock::new();
    if !Path::new("/proc/self").exists() {
        return;
    }
    let key = std::fs::canonicalize(dir).unwrap_or_else(|_| dir.to_path_buf());
    let stale = {
        let mut seen = SEEN
            .get_or_init(Default::default)
            .lock()
            .unwrap_or_else(|e| e.into_inner());
        seen.entry(key)
            .or_insert_with(|| stale_temporaries(dir))
            .remove(name)
    };
    for p in stale.into_iter().flatten() {
        let _ = std::fs::remove_file(p);
    }
}

/// The temporaries `.{name}.{pid}.tmp` in `dir` of processes that are gone, by name.
fn stale_temporaries(dir: &Path) -> std::collections::HashMap<String, Vec<PathBuf>> {
    let mut out: std::collections::HashMap<String, Vec<PathBuf>> = Default::default();
    let Ok(entries) = std::fs::read_dir(dir) else {
        return out;
    };
    for e in entries.flatten() {
        let file = e.file_name();
        let Some((name, pid)) = file
            .to_str()
            .and_then(|f| f.strip_prefix('.'))
            .and_then(|f| f.strip_suffix(".tmp"))
            .and_then(|f| f.rsplit_once('.'))
            .and_then(|(n, p)| Some((n, p.parse::<u32>().ok()?)))
        else {
            continue;
        };
        if pid != std::process::id() && !Path::new(&format!("/proc/{pid}")).exists() {
            out.entry(name.to_string()).or_default().push(e.path());
        }
    }
    out
}

/// A complete, closed temporary file waiting to be renamed over its target
/// ([`AtomicFile::close`]). Dropped without commit, the temporary is removed.
pub struct PendingFile {
    target: PathBuf,
    tmp: PathBuf,
    committed: bool,
}

impl PendingFile {
    /// A hard link to `src` as the temporary of `target` (in its folder, created if needed):
    /// renamed over `target` on commit, it publishes `src`'s bytes without copying them.
    /// Fails where `src` and `target` are on two file systems or links are not supported.
    pub(crate) fn link(src: &Path, target: &Path) -> io::Result<PendingFile> {
        let tmp = temporary_of(target, None)?;
        // A temporary of ours left by an earlier attempt in this process.
        let _ = std::fs::remove_file(&tmp);
        std::fs::hard_link(src, &tmp)?;
        Ok(PendingFile {
            target: target.to_path_buf(),
            tmp,
            committed: false,
        })
    }

    /// The same file, to be renamed over `target` instead (in the same folder).
    pub(crate) fn retarget(mut self, target: &Path) -> PendingFile {
        self.target = target.to_path_buf();
        self
    }

    /// The temporary file's path (complete: it can be read, e.g. checked, before the commit).
    pub(crate) fn temporary(&self) -> &Path {
        &self.tmp
    }

    /// Renames the temporary over the target.
    pub(crate) fn commit(mut self) -> io::Result<()> {
        std::fs::rename(&self.tmp, &self.target)?;
        self.committed = true;
        Ok(())
    }
}

impl Drop for PendingFile {
    fn drop(&mut self) {
        if !self.committed {
            let _ = std::fs::remove_file(&self.tmp);
        }
    }
}

impl Drop for AtomicFile {
    fn drop(&mut self) {
        if !self.committed {
            let _ = std::fs::remove_file(&self.tmp);
        }
    }
}

/// Why `write_atomic` or `write_pending` failed: the path that could not be written (the
/// target's folder, the temporary or the target) and the system's error. Shown as
/// `{path}: {error}`.
#[derive(Debug)]
pub struct WriteError {
    /// The folder, temporary file or target that failed.
    pub path: PathBuf,
    /// The system's error.
    pub error: io::Error,
}

impl std::fmt::Display for WriteError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}: {}", self.path.display(), self.error)
    }
}

impl std::error::Error for WriteError {}

/// `bytes` written to a complete, closed temporary beside `target` (`.{name}.{pid}.tmp`, or
/// `.{name}.{pid}.{tag}.tmp` with a `tag`), the folder created if needed: the [`PendingFile`]
/// to check and commit. Dropped, the temporary is removed.
pub(crate) fn write_pending(
    target: &Path,
    tag: Option<&str>,
    bytes: &[u8],
) -> Result<PendingFile, WriteError> {
    let dir = folder_of(target);
    std::fs::create_dir_all(dir).map_err(|error| WriteError {
        path: dir.to_path_buf(),
        error,
    })?;
    let at_temporary = |error| WriteError {
        path: temporary_path(target, tag),
        error,
    };
    let f = AtomicFile::open(target, tag).map_err(at_temporary)?;
    (&f.file).write_all(bytes).map_err(at_temporary)?;
    f.close().map_err(at_temporary)
}

/// Writes `bytes` to `target` atomically ([`write_pending`], then the rename over `target`).
pub(crate) fn write_atomic(target: &Path, bytes: &[u8]) -> Result<(), WriteError> {
    write_pending(target, None, bytes)?
        .commit()
        .map_err(|error| WriteError {
            path: target.to_path_buf(),
            error,
        })
}

/// Lower-case hex of bytes (a digest, a token).
pub fn hex(bytes: &[u8]) -> String {
    use std::fmt::Write;
    let mut s = String::with_capacity(bytes.len() * 2);
    for b in bytes {
        let _ = write!(s, "{b:02x}");
    }
    s
}

/// The size of the file at `path` and its SHA-256 ([`hex`]), read in 1 MiB blocks.
pub(crate) fn file_sha256(path: &Path) -> io::Result<(u64, String)> {
    read_sha256(&mut File::open(path)?)
}

/// The bytes read from `f` to its end and their SHA-256 ([`hex`]), in 1 MiB blocks.
pub(crate) fn read_sha256(f: &mut impl Read) -> io::Result<(u64, String)> {
    let mut h = Sha256::new();
    let mut buf = vec![0u8; 1 << 20];
    let mut bytes = 0u64;
    loop {
        let n = f.read(&mut buf)?;
        if n == 0 {
            break;
        }
        h.update(&buf[..n]);
        bytes += n as u64;
    }
    Ok((bytes, hex(&h.finalize())))
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Write;

    #[test]
    fn temporaries_of_dead_runs_are_removed_and_others_kept() {
        let dir = tempfile::tempdir().unwrap();
        let target = dir.path().join("out.gml");
        // Above Linux's largest pid (2^22), so never a live process.
        let dead = dir.path().join(".out.gml.4194305.tmp");
        let alive = dir
            .path()
            .join(format!(".out.gml.{}.tmp.keep", std::process::id()));
        let other = dir.path().join(".other.gml.4194305.tmp");
        for p in [&dead, &alive, &other] {
            std::fs::write(p, b"x").unwrap();
        }
        let f = AtomicFile::create(&target).unwrap();
        f.commit().unwrap();
        assert!(!dead.exists() || !Path::new("/proc/self").exists());
        assert!(alive.exists() && other.exists());
    }

    #[test]
    fn closed_file_is_published_only_on_commit_and_removed_when_dropped() {
        let dir = tempfile::tempdir().unwrap();
        let target = dir.path().join("tile.gml");
        std::fs::write(&target, b"old").unwrap();
        let write = |bytes: &[u8]| {
            let f = AtomicFile::create(&target).unwrap();
            let mut w = f.writer().unwrap();
            w.write_all(bytes).unwrap();
            w.flush().unwrap();
            drop(w);
            f.close().unwrap()
        };
        drop(write(b"abandoned"));
        assert_eq!(std::fs::read(&target).unwrap(), b"old");
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
        let pending = write(b"new");
        assert_eq!(std::fs::read(&target).unwrap(), b"old", "not before commit");
        pending.commit().unwrap();
        assert_eq!(std::fs::read(&target).unwrap(), b"new");
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
    }

    #[test]
    fn atomic_file_replaces_only_on_commit() {
        let dir = tempfile::tempdir().unwrap();
        let target = dir.path().join("out.txt");
        std::fs::write(&target, b"old").unwrap();
        {
            let f = AtomicFile::create(&target).unwrap();
            let mut w = f.writer().unwrap();
            w.write_all(b"half").unwrap();
            w.flush().unwrap();
            // dropped without commit
        }
        assert_eq!(std::fs::read(&target).unwrap(), b"old");
        assert_eq!(
            std::fs::read_dir(dir.path()).unwrap().count(),
            1,
            "temporary left behind"
        );
        let f = AtomicFile::create(&target).unwrap();
        let mut w = f.writer().unwrap();
        w.write_all(b"new").unwrap();
        w.flush().unwrap();
        f.commit().unwrap();
        assert_eq!(std::fs::read(&target).unwrap(), b"new");
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
    }

    #[test]
    fn write_atomic_names_the_path_that_failed() {
        let dir = tempfile::tempdir().unwrap();
        let target = dir.path().join("sub").join("out.json");
        write_atomic(&target, b"one").unwrap();
        write_atomic(&target, b"two").unwrap();
        assert_eq!(std::fs::read(&target).unwrap(), b"two");
        assert_eq!(
            std::fs::read_dir(target.parent().unwrap()).unwrap().count(),
            1
        );
        // A folder in the way of the target: the rename fails, naming the target, and the
        // temporary is gone.
        let blocked = dir.path().join("blocked");
        std::fs::create_dir_all(blocked.join("x")).unwrap();
        let e = write_atomic(&blocked, b"three").unwrap_err();
        assert_eq!(e.path, blocked);
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 2);
        // A file in the way of the folder: creating the folder fails, naming it.
        let file = dir.path().join("file");
        std::fs::write(&file, b"x").unwrap();
        let e = write_atomic(&file.join("out.json"), b"four").unwrap_err();
        assert_eq!(e.path, file);
    }

    #[test]
    fn a_pending_write_with_a_tag_is_readable_before_its_commit() {
        let dir = tempfile::tempdir().unwrap();
        let target = dir.path().join("kb.xml");
        std::fs::write(&target, b"old").unwrap();
        let p = write_pending(&target, Some("evolve"), b"new").unwrap();
        let name = p.temporary().file_name().unwrap().to_string_lossy();
        assert_eq!(name, format!(".kb.xml.{}.evolve.tmp", std::process::id()));
        assert_eq!(std::fs::read(p.temporary()).unwrap(), b"new");
        assert_eq!(std::fs::read(&target).unwrap(), b"old");
        drop(p);
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
        write_pending(&target, Some("evolve"), b"new")
            .unwrap()
            .commit()
            .unwrap();
        assert_eq!(std::fs::read(&target).unwrap(), b"new");
    }

    #[test]
    fn hex_and_file_sha256() {
        assert_eq!(hex(&[0, 1, 0xab, 0xff]), "0001abff");
        assert_eq!(hex(&[]), "");
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("abc");
        std::fs::write(&path, b"abc").unwrap();
        assert_eq!(
            file_sha256(&path).unwrap(),
            (
                3,
                "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad".to_string()
            )
        );
    }
}
