//! `citygen split`: an OSM PBF cut into the parts the shards of a tiled run read
//! ([`crate::pipeline::split`]).

use std::path::PathBuf;

use clap::Args;

use super::args::{parse_crs, parse_infer, parse_output_crs, InferArg};
use super::{AppError, Outcome};
use crate::crs::Crs;
use crate::grammar::Caps;
use crate::pipeline::{Options, Source};

/// `citygen split`.
#[derive(Args, Debug)]
pub(crate) struct SplitArgs {
    /// The OSM PBF to split.
    #[arg(long, value_name = "FILE.pbf")]
    osm: PathBuf,
    /// The run's knowledge base (its zones decide what is inferred, which the split computes).
    #[arg(long, value_name = "KB.xml")]
    kb: Option<PathBuf>,
    /// The run's ruleset, if it uses one instead of the knowledge base's rules.
    #[arg(long, value_name = "FILE")]
    rules: Option<PathBuf>,
    /// The run's tile size (metres): the grid whose tiles are shared out.
    #[arg(long, value_name = "METRES", value_parser = clap::value_parser!(u32).range(10..))]
    tile: u32,
    /// How many shards the run has (at most 64).
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(1..=64))]
    shards: u32,
    /// Write `part-I-of-N.osm.pbf` and `part-I-of-N.split.json` for every shard here.
    #[arg(long, value_name = "DIR")]
    out: PathBuf,
    /// How far around its tiles a shard's part reaches (metres): the neighbours, streets and
    /// rows its buildings take something from.
    #[arg(long, value_name = "METRES", default_value_t = crate::pipeline::split::DEFAULT_HALO_M)]
    halo: f64,
    /// The run's output CRS (--crs), if it passes one.
    #[arg(long, value_name = "EPSG:n", value_parser = parse_output_crs)]
    crs: Option<Crs>,
    /// The run's --src-crs, if it passes one.
    #[arg(long, value_name = "EPSG:n", value_parser = parse_crs)]
    src_crs: Option<Crs>,
    /// The run's --infer.
    #[arg(long, value_name = "WHAT", default_value = "kb", value_parser = parse_infer)]
    infer: InferArg,
    /// The run's --source-name, if it passes one.
    #[arg(long, value_name = "NAME")]
    source_name: Option<String>,
    /// No summary.
    #[arg(long, short)]
    quiet: bool,
}

/// `citygen split`.
pub(crate) fn run(args: SplitArgs) -> Result<Outcome, AppError> {
    let opts = Options {
        source: Source::Osm(args.osm.clone()),
        kb: args.kb.clone(),
        rules: args.rules.clone(),
        lod: crate::model::Lod::Lod2,
        ifc: None,
        ifc_schema: Default::default(),
        ifc_max_bytes: None,
        citygml: None,
        gltf: None,
        cityjson: None,
        cityjsonseq: None,
        report: None,
        preview: None,
        tiles3d: None,
        seed: 0,
        crs: args.crs,
        src_crs: args.src_crs,
        caps: Caps::default(),
        bbox: None,
        tile: Some(args.tile),
        dry_run: true,
        textures: false,
        force_extension: false,
        allow_empty: true,
        infer: args.infer.0,
        shard: None,
        previous: None,
        link_previous: false,
        osc: None,
        source_name: args.source_name.clone(),
        dem: Vec::new(),
        ground_height: None,
        terrain_tolerance: crate::pipeline::terrain::DEFAULT_TOLERANCE,
        no_terrain: true,
        ground_fn: None,
        split_part: None,
    };
    let s = crate::pipeline::split::split(&opts, args.shards as usize, args.halo, &args.out)?;
    if !args.quiet {
        eprintln!(
            "citygen split: {} buildings into {} parts (halo {} m) in {:.2} s",
            s.lots,
            s.parts.len(),
            args.halo,
            s.elapsed.as_secs_f64()
        );
        for (i, (own, halo, bytes)) in s.parts.iter().enumerate() {
            eprintln!(
                "  part {i}: {own} buildings of its tiles, {halo} of its halo, {bytes} bytes"
            );
        }
    }
    Ok(Outcome::Done)
}
