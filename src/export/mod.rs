//! Writers: IFC4 (STEP), CityGML 2.0 and glTF 2.0 binary. Each consumes [`crate::model::Building`]
//! values one at a time (streaming) and nothing else.

pub mod citygml;
pub mod gltf;
pub mod ifc;
pub mod step;

use std::fs::File;
use std::io::{self, BufWriter, Write};
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
    pub lod: Lod,
    /// Name of the input file (for headers and descriptions).
    pub source_name: String,
    pub seed: u64,
}

#[derive(Debug, Error)]
pub enum ExportError {
    #[error("write failed: {0}")]
    Io(#[from] io::Error),
    #[error("{0}")]
    Invalid(String),
}

/// A streaming writer of one output format.
///
/// Call order: `begin` once, `write` per building in output order, `finish` once. Output is a
/// pure function of the context and the buildings in order (no clock, no randomness), so equal
/// inputs give byte-identical files.
pub trait BuildingWriter: Send {
    fn begin(&mut self, ctx: &OutputContext) -> Result<(), ExportError>;
    fn write(&mut self, building: &Building) -> Result<(), ExportError>;
    /// Flushes and completes the file. The writer is unusable afterwards.
    fn finish(&mut self) -> Result<(), ExportError>;
}

/// A file written atomically: bytes go to a temporary file beside the target, which is renamed
/// over the target by [`AtomicFile::commit`]. Dropped without commit, the temporary is removed and
/// the target is untouched.
pub struct AtomicFile {
    target: PathBuf,
    tmp: PathBuf,
    file: Option<BufWriter<File>>,
}

impl AtomicFile {
    /// Creates the temporary file in the target's folder (which must exist).
    pub fn create(target: &Path) -> io::Result<AtomicFile> {
        let dir = target
            .parent()
            .filter(|d| !d.as_os_str().is_empty())
            .unwrap_or(Path::new("."));
        let name = target
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        let tmp = dir.join(format!(".{name}.{}.tmp", std::process::id()));
        let file = File::create(&tmp)?;
        Ok(AtomicFile {
            target: target.to_path_buf(),
            tmp,
            file: Some(BufWriter::with_capacity(1 << 20, file)),
        })
    }

    /// Flushes, syncs and renames the temporary file over the target.
    pub fn commit(mut self) -> io::Result<()> {
        if let Some(w) = self.file.take() {
            let f = w.into_inner().map_err(|e| e.into_error())?;
            f.sync_all()?;
        }
        std::fs::rename(&self.tmp, &self.target)
    }
}

impl Write for AtomicFile {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        match self.file.as_mut() {
            Some(f) => f.write(buf),
            None => Err(io::Error::other("file already committed")),
        }
    }
    fn flush(&mut self) -> io::Result<()> {
        match self.file.as_mut() {
            Some(f) => f.flush(),
            None => Ok(()),
        }
    }
}

impl Drop for AtomicFile {
    fn drop(&mut self) {
        if self.file.take().is_some() {
            let _ = std::fs::remove_file(&self.tmp);
        }
    }
}
