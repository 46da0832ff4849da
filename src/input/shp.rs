//! (being written)
use super::{InputError, ReadResult};
use crate::report::Report;
use std::path::Path;
/// Shapefile reader options.
#[derive(Clone, Debug, Default)]
pub struct ShpOptions {
    pub height_field: Option<String>,
    pub levels_field: Option<String>,
    pub src_crs: Option<crate::crs::Crs>,
}
/// Reads a shapefile.
pub fn read_shp(
    path: &Path,
    opts: &ShpOptions,
    report: &mut Report,
) -> Result<ReadResult, InputError> {
    let _ = (path, opts, report);
    Ok(ReadResult::default())
}
