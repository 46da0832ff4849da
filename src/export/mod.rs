//! Writers: IFC4 (STEP), CityGML 2.0, CityJSON 2.0 (and CityJSONSeq), glTF 2.0 binary, OGC 3D
//! Tiles 1.1 (GLB contents and the tileset), and a PNG preview picture.
//! Each consumes [`crate::model::Building`] values one at a time (streaming) and nothing else.

pub mod citygml;
pub mod cityjson;
#[cfg(target_os = "linux")]
mod direct;
#[cfg(test)]
pub(crate) mod fixtures;
mod format;
pub mod gltf;
pub mod ifc;
pub mod lod3geom;
pub mod lod4geom;
pub mod preview;
pub mod step;
pub mod tiles3d;

use std::fs::File;
use std::io::{self, BufWriter};
use std::path::{Path, PathBuf};

use glam::DVec3;
use thiserror::Error;

use crate::crs::Crs;
use crate::model::{Building, Lod};

/// What every writer needs to know about the run, given once before the first building.
#[derive(Clone, Debug)]
pub struct OutputContext {
    /// The output CRS (projected).
    pub crs: Crs,
    /// Coordinates, in `crs`, of the local frame's origin: a model point p is at `origin + p`.
    pub origin: DVec3,
    /// The origin as WGS84 (lon, lat) degrees.
    pub origin_lonlat: (f64, f64),
    /// The run's level of detail (`--lod`): the buildings are already cut at it.
    pub lod: Lod,
    /// Name of the input file (for headers and descriptions).
    pub source_name: String,
    /// The run's `--seed`: written in the files' descriptions, and part of the namespace of
    /// the IFC GlobalIds.
    pub seed: u64,
}

/// Why a writer could not write.
#[derive(Debug, Error)]
pub enum ExportError {
    /// The output (or a scratch file) could not be written.
    #[error("write failed: {0}")]
    Io(#[from] io::Error),
    /// What the writer was given cannot be written as a valid file: a non-finite coordinate,
    /// a call out of order, a file over a format limit. The message says which.
    #[error("{0}")]
    Invalid(String),
}

/// [`Building::check_finite`] as the [`ExportError::Invalid`] of `writer` (e.g. `"IFC writer"`):
/// every writer calls it before writing anything of a building, unless given the buildings
/// [`Checked`].
pub(crate) fn check_finite(writer: &str, b: &Building) -> Result<(), ExportError> {
    b.check_finite()
        .map_err(|e| ExportError::Invalid(format!("{writer}: {e}")))
}

/// Buildings checked once for every writer ([`Building::check_finite`]): those before the
/// first that is refused, and why that one is. It borrows the buildings, so they cannot
/// change while it is held: a writer given one ([`BuildingWriter::write_checked`]) need not
/// check again.
pub struct Checked<'a> {
    buildings: &'a [Building],
    /// How many buildings are finite before the first refused one.
    ok: usize,
    refused: Option<crate::model::NotFinite>,
}

impl<'a> Checked<'a> {
    /// Checks `buildings` (in parallel).
    pub fn check(buildings: &'a [Building]) -> Checked<'a> {
        use rayon::prelude::*;
        let first_bad = if buildings.len() > 1 {
            buildings
                .par_iter()
                .position_first(|b| b.check_finite().is_err())
        } else {
            buildings.iter().position(|b| b.check_finite().is_err())
        };
        match first_bad {
            Some(i) => Checked {
                buildings,
                ok: i,
                refused: buildings[i].check_finite().err(),
            },
            None => Checked {
                buildings,
                ok: buildings.len(),
                refused: None,
            },
        }
    }

    /// The buildings before the first refused one (all of them if none is).
    pub fn finite(&self) -> &'a [Building] {
        &self.buildings[..self.ok]
    }

    /// The [`ExportError::Invalid`] of `writer` for the first refused building, if any.
    pub fn refused(&self, writer: &str) -> Result<(), ExportError> {
        match &self.refused {
            Some(e) => Err(ExportError::Invalid(format!("{writer}: {e}"))),
            None => Ok(()),
        }
    }
}

/// Buildings a writer's `write_all` renders in parallel at a time: enough to keep the cores
/// busy, few enough that their rendered bytes (a few MB a LOD4 building) stay small.
pub const PARALLEL_BATCH: usize = 16;

/// A streaming writer of one output format.
///
/// Call order: `begin` once, `write` per building in output order, `finish` once. Output is a
/// pure function of the context and the buildings in order (no clock, no randomness), so equal
/// inputs give byte-identical files.
pub trait BuildingWriter: Send {
    /// Starts the file: header, project and site, or their equivalents, from the run's context.
    fn begin(&mut self, ctx: &OutputContext) -> Result<(), ExportError>;
    /// Writes one building (after [`BuildingWriter::begin`], in output order).
    fn write(&mut self, building: &Building) -> Result<(), ExportError>;
    /// Writes `buildings` in order: the same bytes as `write` on each, and the same first error.
    /// A writer may do its per-building work in parallel here (rayon) and append the results
    /// in order.
    fn write_all(&mut self, buildings: &[Building]) -> Result<(), ExportError> {
        buildings.iter().try_for_each(|b| self.write(b))
    }
    /// `write_all` of buildings already checked ([`Checked`]), so that a run checks them once
    /// for all its writers: the same bytes and first error. A writer that checks in its
    /// `write_all` anyway keeps this default.
    fn write_checked(&mut self, checked: &Checked<'_>) -> Result<(), ExportError> {
        // The refused building is given too, for the writer's own error.
        let n = checked.ok + usize::from(checked.refused.is_some());
        self.write_all(&checked.buildings[..n])
    }
    /// Flushes and completes the file. The writer is unusable afterwards.
    fn finish(&mut self) -> Result<(), ExportError>;
}

/// A scratch file beside `target` (in its folder, so on the output's disk rather than a possibly
/// small temporary file system), named `.{file name}.{pid}.{tag}.tmp`, open for reading and
/// writing. It is unlinked at once where the system allows (Unix: only the handle keeps it);
/// otherwise its path is returned, for the caller to remove when done.
pub(crate) fn scratch_beside(target: &Path, tag: &str) -> io::Result<(File, Option<PathBuf>)> {
    let dir = target
        .parent()
        .filter(|d| !d.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    let name = target
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let path = dir.join(format!(".{name}.{}.{tag}.tmp", std::process::id()));
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
        let tmp = temporary_of(target)?;
        let file = File::create(&tmp)?;
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
    /// from a background thread (`O_DIRECT`, see `export::direct`), elsewhere it is the file
    /// itself. Write through a `BufWriter` or in large pieces. Drop the writer, then call
    /// [`StreamSink::finish`] before [`AtomicFile::close`]: only then are the bytes complete.
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
    pub fn finish(self) -> io::Result<()> {
        #[cfg(target_os = "linux")]
        if let Some(s) = self.0 {
            return s.finish();
        }
        Ok(())
    }
}

/// The temporary `.{name}.{pid}.tmp` beside `target` ([`AtomicFile`], [`PendingFile::link`]),
/// its folder created if needed and dead runs' temporaries of that name removed.
fn temporary_of(target: &Path) -> io::Result<PathBuf> {
    let dir = target
        .parent()
        .filter(|d| !d.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    std::fs::create_dir_all(dir)?;
    let name = target
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    remove_stale_temporaries(dir, &name);
    Ok(dir.join(format!(".{name}.{}.tmp", std::process::id())))
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
    pub fn link(src: &Path, target: &Path) -> io::Result<PendingFile> {
        let tmp = temporary_of(target)?;
        // A temporary of ours left by an earlier attempt in this process.
        let _ = std::fs::remove_file(&tmp);
        std::fs::hard_link(src, &tmp)?;
        Ok(PendingFile {
            target: target.to_path_buf(),
            tmp,
            committed: false,
        })
    }

    /// Renames the temporary over the target.
    pub fn commit(mut self) -> io::Result<()> {
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

    /// Several batches of buildings, LOD4 and LOD3 alike, for the `write_all` checks.
    fn many_buildings() -> Vec<Building> {
        let all = fixtures::lod4_all();
        (0..3 * PARALLEL_BATCH + 5)
            .map(|i| {
                let mut b = all[i % all.len()].clone();
                b.id = crate::model::SourceId::Way(1000 + i as i64);
                b
            })
            .collect()
    }

    fn ctx() -> OutputContext {
        OutputContext {
            crs: Crs::Lambert93,
            origin: DVec3::new(574_000.25, 6_279_000.5, 140.0),
            origin_lonlat: (1.44, 43.6),
            lod: Lod::Lod4,
            source_name: "batches.osm.pbf".into(),
            seed: 3,
        }
    }

    /// What one writer leaves in its sink: one `write` per building, or one `write_all`.
    fn both_ways<W: BuildingWriter>(
        make: impl Fn() -> W,
        sink: impl Fn(W) -> Vec<u8>,
        buildings: &[Building],
    ) -> [(Vec<u8>, Option<String>); 2] {
        let run = |all: bool| {
            let mut w = make();
            w.begin(&ctx()).unwrap();
            let r = if all {
                w.write_all(buildings)
            } else {
                buildings.iter().try_for_each(|b| w.write(b))
            };
            let err = match r {
                Ok(()) => {
                    w.finish().unwrap();
                    None
                }
                Err(e) => Some(e.to_string()),
            };
            (sink(w), err)
        };
        [run(false), run(true)]
    }

    #[test]
    fn write_all_writes_the_bytes_and_the_first_error_of_one_write_per_building() {
        use crate::export::citygml::CityGmlWriter;
        use crate::export::gltf::GltfWriter;
        let mut buildings = many_buildings();
        let gml = |b: &[Building]| {
            both_ways(
                || CityGmlWriter::new(Vec::new()),
                CityGmlWriter::into_inner,
                b,
            )
        };
        let glb = |b: &[Building]| {
            both_ways(
                || GltfWriter::new(Vec::new(), tempfile::tempfile().unwrap()),
                |w| w.into_inner(),
                b,
            )
        };
        let [one, all] = gml(&buildings);
        assert!(one.1.is_none() && one.0.len() > 100_000);
        assert!(one == all, "CityGML: write_all differs from write");
        let [one, all] = glb(&buildings);
        assert!(one.1.is_none() && one.0.len() > 100_000);
        assert!(one == all, "glTF: write_all differs from write");

        // A dry run's glTF writer keeps nothing but writes a GLB of the same length.
        let dry = both_ways(
            || GltfWriter::discarding(Vec::new()),
            |w| w.into_inner(),
            &buildings,
        );
        for (d, real) in dry.iter().zip([&one, &all]) {
            assert_eq!(d.0.len(), real.0.len(), "dry glTF length");
            assert_eq!(d.0[..12], real.0[..12], "GLB header");
        }

        // A building the CityGML writer refuses, in the middle of a batch: the buildings before
        // it are written, the error is the same, nothing after it is written.
        buildings[PARALLEL_BATCH + 3].measured_height = f64::NAN;
        let [one, all] = gml(&buildings);
        let err = one.1.clone().expect("the NaN height is refused");
        assert!(err.contains("not finite"), "{err}");
        assert!(
            one == all,
            "CityGML: write_all differs from write on an error"
        );
    }
}
