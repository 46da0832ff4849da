//! `citygen merge`: its arguments and summary.

use std::path::PathBuf;

use clap::Args;

use super::{AppError, Outcome};

/// `citygen merge`.
#[derive(Args, Debug)]
pub(crate) struct MergeArgs {
    /// Folders holding the shards' outputs and `citygen-manifest.I-of-N.json` files.
    #[arg(required = true, value_name = "OUT_DIR")]
    dirs: Vec<PathBuf>,
    /// Write the merged run report here.
    #[arg(long, value_name = "OUT.json")]
    report: Option<PathBuf>,
    /// Write the region's CityJSONSeq here: one header, then every tile's buildings in grid
    /// order (the shards must have written --cityjsonseq).
    #[arg(long, value_name = "OUT.city.jsonl")]
    cityjsonseq: Option<PathBuf>,
    /// Write the region's OGC 3D Tiles tileset.json into this folder, over the shards' contents
    /// (the shards must have written --tiles3d; URIs relative to the folder).
    #[arg(long, value_name = "DIR")]
    tiles3d: Option<PathBuf>,
    /// Write an overview picture of the region (PNG, rendered in citygen from the 3D Tiles
    /// contents).
    #[arg(long, value_name = "OUT.png")]
    preview: Option<PathBuf>,
    /// Check the files' sizes only, not their SHA-256 (faster on a slow shared disk).
    #[arg(long)]
    no_verify: bool,
    /// No summary.
    #[arg(long, short)]
    quiet: bool,
}

/// `citygen merge`.
pub(crate) fn run(args: MergeArgs) -> Result<Outcome, AppError> {
    let opts = crate::pipeline::merge::MergeOptions {
        dirs: args.dirs,
        report: args.report,
        cityjsonseq: args.cityjsonseq,
        tiles3d: args.tiles3d,
        preview: args.preview,
        verify: !args.no_verify,
    };
    match crate::pipeline::merge::merge(&opts) {
        Ok(s) => {
            if !args.quiet {
                eprintln!(
                    "citygen merge: {} shards, {} tiles, {} buildings ({} skipped), {} files of {} bytes checked{} in {:.2} s",
                    s.shards,
                    s.tiles,
                    s.buildings,
                    s.skipped,
                    s.files,
                    s.bytes,
                    if opts.verify { " (SHA-256)" } else { " (sizes)" },
                    s.elapsed.as_secs_f64()
                );
                for p in &s.outputs {
                    eprintln!("  wrote {}", p.display());
                }
            }
            Ok(Outcome::Done)
        }
        Err(e) => Err(e.into()),
    }
}
