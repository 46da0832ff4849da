//! `--ifc-max-mb N`: an IFC output split into complete files of at most N MB (10^6 bytes, as
//! the buildingSMART validation service counts its 256 MB).
//!
//! [`SplitIfc`] writes the buildings in lot order (the order every writer gets them) to a
//! capped [`IfcWriter`] (`IfcWriter::write_fitting`): when the next building would take the
//! finished file past the cap, the file is finished and the next one begun, with its own
//! header, project, site, units and map conversion, in the same schema. Which building goes
//! to which file depends only on the bytes written, which depend only on the inputs and the
//! seed: the same at any thread count. A building larger than the cap alone gets a file of
//! its own (a report note names it); the file set's terrain goes in the first file.
//!
//! Names: `out.ifc` when everything fits in one file, else `out-001.ifc`, `out-002.ifc`, ...
//! (`part_path`; with `--tile`, each tile's file is split on its own: `out_E_N-001.ifc`). The
//! first file is written under `out.ifc`'s temporary and renamed to `out-001.ifc` if a
//! second is needed; its header's FILE_NAME keeps the name `out.ifc`. Once the run has
//! published every file, the other names of the set that a previous run left (`out.ifc`
//! beside parts, parts beside `out.ifc`, parts numbered past the last) are removed
//! (`stale_parts`), so the folder holds exactly this run's files; a failed run publishes and
//! removes nothing.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};

use crate::export::ifc::{IfcSchema, IfcWriter};
use crate::export::{BuildingWriter, Checked, ExportError, OutputContext};
use crate::model::{Building, SourceId};

use super::file_name;

/// One finished file of a split IFC output: where its bytes went (`S`, the pipeline's
/// temporary file, counter and hash).
pub(super) struct Part<S> {
    pub(super) file: S,
    /// Buildings written to it.
    pub(super) buildings: usize,
    /// Its first building (the only one when `buildings` is 1).
    pub(super) first: Option<SourceId>,
}

/// The finished files of a [`SplitIfc`], in order, for the pipeline to publish.
pub(super) type Parts<S> = Arc<Mutex<Vec<Part<S>>>>;

/// Opens the file of a path: the writer of its bytes and where they go.
pub(super) type Opener<W, S> = Box<dyn FnMut(&Path) -> Result<(W, S), ExportError> + Send>;

/// The file being written.
struct Current<W: Write + Send, S> {
    writer: IfcWriter<W>,
    file: S,
    buildings: usize,
    first: Option<SourceId>,
}

/// An IFC output split into files under a cap (see the module docs).
pub(super) struct SplitIfc<W: Write + Send, S> {
    path: PathBuf,
    schema: IfcSchema,
    cap: u64,
    open: Opener<W, S>,
    ctx: Option<OutputContext>,
    current: Option<Current<W, S>>,
    parts: Parts<S>,
}

impl<W: Write + Send, S> SplitIfc<W, S> {
    /// A split output for `path`, files of at most `cap` bytes, each opened by `open`; its
    /// finished files go to the returned [`Parts`].
    pub(super) fn new(
        path: &Path,
        schema: IfcSchema,
        cap: u64,
        open: Opener<W, S>,
    ) -> (SplitIfc<W, S>, Parts<S>) {
        let parts: Parts<S> = Arc::default();
        (
            SplitIfc {
                path: path.to_path_buf(),
                schema,
                cap,
                open,
                ctx: None,
                current: None,
                parts: Arc::clone(&parts),
            },
            parts,
        )
    }

    /// Begins the next file.
    fn open(&mut self) -> Result<(), ExportError> {
        let Some(ctx) = &self.ctx else {
            return Err(ExportError::Invalid(
                "IFC writer: write called before begin".into(),
            ));
        };
        let k = lock(&self.parts).len() + 1;
        // The first file under the output's own name (renamed if a second one comes).
        let (path, ctx) = if k == 1 {
            (self.path.clone(), ctx.clone())
        } else {
            // The terrain is the first file's.
            let mut later = ctx.clone();
            later.terrain = None;
            (part_path(&self.path, k), later)
        };
        let (w, file) = (self.open)(&path)?;
        let mut writer = IfcWriter::new(w)
            .with_file_name(&file_name(&path))
            .with_schema(self.schema)
            .with_max_bytes(self.cap);
        writer.begin(&ctx)?;
        self.current = Some(Current {
            writer,
            file,
            buildings: 0,
            first: None,
        });
        Ok(())
    }

    /// Finishes the current file and hands it to the parts.
    fn close(&mut self) -> Result<(), ExportError> {
        let Some(mut c) = self.current.take() else {
            return Ok(());
        };
        c.writer.finish()?;
        drop(c.writer);
        lock(&self.parts).push(Part {
            file: c.file,
            buildings: c.buildings,
            first: c.first,
        });
        Ok(())
    }
}

fn lock<S>(parts: &Parts<S>) -> std::sync::MutexGuard<'_, Vec<Part<S>>> {
    parts.lock().unwrap_or_else(|p| p.into_inner())
}

impl<W: Write + Send, S: Send> BuildingWriter for SplitIfc<W, S> {
    fn begin(&mut self, ctx: &OutputContext) -> Result<(), ExportError> {
        self.ctx = Some(ctx.clone());
        self.open()
    }

    fn write(&mut self, building: &Building) -> Result<(), ExportError> {
        self.write_all(std::slice::from_ref(building))
    }

    fn write_all(&mut self, buildings: &[Building]) -> Result<(), ExportError> {
        self.write_checked(&Checked::check(buildings))
    }

    fn write_checked(&mut self, checked: &Checked<'_>) -> Result<(), ExportError> {
        let mut rest = checked.finite();
        while !rest.is_empty() {
            let Some(c) = self.current.as_mut() else {
                return Err(ExportError::Invalid(
                    "IFC writer: write called outside begin..finish".into(),
                ));
            };
            let n = c.writer.write_fitting(rest)?;
            if n > 0 {
                c.first.get_or_insert(rest[0].id);
                c.buildings += n;
            }
            rest = &rest[n..];
            if !rest.is_empty() {
                self.close()?;
                self.open()?;
            }
        }
        checked.refused("IFC writer")
    }

    fn finish(&mut self) -> Result<(), ExportError> {
        self.close()
    }
}

/// The name of file `k` (from 1) of the split output `path`: `out.ifc` -> `out-00k.ifc` (at
/// least three digits).
pub(super) fn part_path(path: &Path, k: usize) -> PathBuf {
    let name = file_name(path);
    let (stem, ext) = match name.rfind('.') {
        Some(i) if i > 0 => (&name[..i], &name[i..]),
        _ => (name.as_str(), ""),
    };
    path.with_file_name(format!("{stem}-{k:03}{ext}"))
}

/// The files beside `path` that belong to its split set but are not among the `written`
/// names: `path` itself and the `out-NNN.ifc` names (any number of digits from three).
pub(super) fn stale_parts(path: &Path, written: &[PathBuf]) -> Vec<PathBuf> {
    let name = file_name(path);
    let (stem, ext) = match name.rfind('.') {
        Some(i) if i > 0 => (name[..i].to_string(), name[i..].to_string()),
        _ => (name.clone(), String::new()),
    };
    let dir = path
        .parent()
        .filter(|d| !d.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    let mut stale = Vec::new();
    let keep = |p: &Path| written.iter().any(|w| w.as_path() == p);
    if !keep(path) && path.is_file() {
        stale.push(path.to_path_buf());
    }
    let Ok(entries) = std::fs::read_dir(dir) else {
        return stale;
    };
    let mut found: Vec<PathBuf> = entries
        .filter_map(|e| e.ok())
        .filter(|e| e.file_type().is_ok_and(|t| t.is_file()))
        .filter_map(|e| {
            let n = e.file_name().into_string().ok()?;
            let digits = n
                .strip_prefix(&stem)?
                .strip_prefix('-')?
                .strip_suffix(&ext)?;
            (digits.len() >= 3 && digits.bytes().all(|b| b.is_ascii_digit()))
                .then(|| path.with_file_name(&n))
        })
        .filter(|p| !keep(p))
        .collect();
    found.sort();
    stale.extend(found);
    stale
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn part_names_number_from_one_with_three_digits() {
        assert_eq!(
            part_path(Path::new("out/city.ifc"), 1),
            PathBuf::from("out/city-001.ifc")
        );
        assert_eq!(
            part_path(Path::new("city.ifc"), 1234),
            PathBuf::from("city-1234.ifc")
        );
        assert_eq!(part_path(Path::new("city"), 2), PathBuf::from("city-002"));
    }

    #[test]
    fn stale_parts_are_the_set_names_not_written() {
        let d = tempfile::tempdir().unwrap();
        let base = d.path().join("c.ifc");
        for n in [
            "c.ifc",
            "c-001.ifc",
            "c-002.ifc",
            "c-003.ifc",
            "c-1000.ifc",
            "c-01.ifc",
            "c-abc.ifc",
            "cc-004.ifc",
            "c-004.gml",
        ] {
            std::fs::write(d.path().join(n), "x").unwrap();
        }
        let written = vec![part_path(&base, 1), part_path(&base, 2)];
        let stale: Vec<String> = stale_parts(&base, &written)
            .iter()
            .map(|p| file_name(p))
            .collect();
        assert_eq!(stale, ["c.ifc", "c-003.ifc", "c-1000.ifc"]);
        let stale: Vec<String> = stale_parts(&base, std::slice::from_ref(&base))
            .iter()
            .map(|p| file_name(p))
            .collect();
        assert_eq!(stale, ["c-001.ifc", "c-002.ifc", "c-003.ifc", "c-1000.ifc"]);
    }
}
