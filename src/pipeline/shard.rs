//! Shards: N processes share one tiled run with no coordinator (`--shard I/N`, `--shard auto`).
//!
//! Every shard reads the whole input and prepares it exactly as a single run would (the same
//! lots, the same output CRS and origin), computes the same tile grid, and the same assignment
//! of tiles to shards (`assign`: the tiles by building count, largest first, each to the
//! least-loaded shard, ties to the lower tile and shard; it depends on the input and N alone,
//! not on which machine runs which shard). It then derives and writes only its own tiles — each
//! tile's files the same bytes the single run writes, since a building's derivation depends
//! only on the input, the seed and its neighbours, which every shard derives alike — and a
//! `Manifest`: what was run (version, input, KB and rules hashes, seed, LOD, options), the
//! whole grid with each tile's shard and lot count, and for each of its tiles the buildings
//! with a per-building digest ([`crate::model::Building::digest`]), the lots skipped, the
//! report entries, and every file with its size and SHA-256. `citygen merge` reads the
//! manifests back ([`crate::pipeline::merge`]).
//!
//! Report entries of the read and prepare stages are the same in every shard; each goes to the
//! shard owning the lot it names, and those naming no lot of the run (a footprint skipped
//! while reading, a part, the run itself) to shard 0, each with its place in the single run's
//! order, so that the merged report holds every entry once.

use std::collections::BTreeMap;
use std::path::Path;

use serde::{Deserialize, Serialize};

pub use crate::fsio::hex;
use crate::report::Entry;

/// The manifest's `format` value; a merge refuses any other.
pub(crate) const MANIFEST_FORMAT: &str = "citygen-manifest/1";

/// The most shards a run may be split into.
pub(crate) const MAX_SHARDS: usize = 100_000;

/// Shard `index` (0-based) of `count`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Shard {
    /// 0-based: shard 0 is the first.
    pub index: usize,
    /// How many shards share the run (at least 1).
    pub count: usize,
}

impl Shard {
    /// The whole run as one shard (a tiled run without `--shard`).
    pub(crate) const ONE: Shard = Shard { index: 0, count: 1 };

    /// `citygen-manifest.{index}-of-{count}.json`: the manifest's file name.
    pub(crate) fn manifest_name(&self) -> String {
        format!("citygen-manifest.{}-of-{}.json", self.index, self.count)
    }
}

impl std::fmt::Display for Shard {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}/{}", self.index, self.count)
    }
}

/// What `--shard` says: a fixed shard, or `auto` (from the job's environment).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum ShardArg {
    /// `--shard I/N`.
    Fixed(Shard),
    /// `--shard auto`.
    Auto,
}

/// Why `--shard` or its environment gives no shard.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub(crate) enum ShardError {
    /// Neither `I/N` nor `auto`.
    #[error("{text:?} is not I/N (e.g. 0/4, shards counted from 0) or auto")]
    NotIN {
        /// The value given.
        text: String,
    },
    /// The index or the count of `I/N` is not a whole number.
    #[error("{text:?}: {what} {word:?} is not a whole number")]
    NotWhole {
        /// The value given.
        text: String,
        /// "the index" or "the count".
        what: &'static str,
        /// The word that is not a number.
        word: String,
    },
    /// A count of 0 or over [`MAX_SHARDS`].
    #[error("shard count {count} is not between 1 and {}", MAX_SHARDS)]
    Count {
        /// The count.
        count: usize,
    },
    /// An index not below the count.
    #[error(
        "shard index {index} is not below the count {count} (shards are counted from 0: \
         0/{count} to {}/{count})",
        .count - 1
    )]
    Index {
        /// The index.
        index: usize,
        /// The count.
        count: usize,
    },
    /// A variable of the job's environment that is not a whole number.
    #[error("--shard auto: {name}={value:?} is not a whole number")]
    Variable {
        /// The variable.
        name: String,
        /// Its value.
        value: String,
    },
    /// No variable gives the index.
    #[error(
        "--shard auto: neither JOB_COMPLETION_INDEX (a Kubernetes Indexed Job) nor \
         SLURM_ARRAY_TASK_ID (a Slurm array) is set; pass --shard I/N"
    )]
    NoIndex,
    /// A Slurm array that is not the whole run.
    #[error(
        "--shard auto: the Slurm array is not 0-{} (SLURM_ARRAY_TASK_MIN={},                  SLURM_ARRAY_TASK_MAX={}): a partial array (a re-submission) does not tell the                  run's shard count; pass --shards N",
        .count.saturating_sub(1),
        .min.map_or("unset".into(), |v| v.to_string()),
        .max.map_or("unset".into(), |v| v.to_string()),
    )]
    PartialArray {
        /// `SLURM_ARRAY_TASK_COUNT`.
        count: usize,
        /// `SLURM_ARRAY_TASK_MIN`.
        min: Option<usize>,
        /// `SLURM_ARRAY_TASK_MAX`.
        max: Option<usize>,
    },
    /// The index is found, the count is not.
    #[error(
        "--shard auto: {from} gives the index but nothing gives the count; pass \
         --shards N (the Job's completions)"
    )]
    NoCount {
        /// Where the index came from (`NAME=VALUE`).
        from: String,
    },
    /// The shard found in the environment is not valid.
    #[error("--shard auto: {0}")]
    Auto(Box<ShardError>),
}

/// Parses `--shard`'s value: `I/N` (0 <= I < N <= [`MAX_SHARDS`]) or `auto`.
pub(crate) fn parse_shard(s: &str) -> Result<ShardArg, ShardError> {
    let s = s.trim();
    if s.eq_ignore_ascii_case("auto") {
        return Ok(ShardArg::Auto);
    }
    let (i, n) = s.split_once('/').ok_or_else(|| ShardError::NotIN {
        text: s.to_string(),
    })?;
    let num = |t: &str, what: &'static str| {
        t.trim().parse::<usize>().map_err(|_| ShardError::NotWhole {
            text: s.to_string(),
            what,
            word: t.to_string(),
        })
    };
    let shard = Shard {
        index: num(i, "the index")?,
        count: num(n, "the count")?,
    };
    check(shard).map(ShardArg::Fixed)
}

fn check(s: Shard) -> Result<Shard, ShardError> {
    if s.count == 0 || s.count > MAX_SHARDS {
        return Err(ShardError::Count { count: s.count });
    }
    if s.index >= s.count {
        return Err(ShardError::Index {
            index: s.index,
            count: s.count,
        });
    }
    Ok(s)
}

/// The shard of `--shard auto` from the job's environment (`env` looks a variable up):
/// `JOB_COMPLETION_INDEX` (a Kubernetes Indexed Job), else `SLURM_ARRAY_TASK_ID` (a Slurm
/// array, `--array=0-(N-1)`: the task id is the index as it is, so that re-submitting the
/// failed tasks alone, `--array=3,5`, runs shards 3 and 5). The count is `shards` (`--shards
/// N`), else `SLURM_ARRAY_TASK_COUNT` where the array is the whole run (`SLURM_ARRAY_TASK_MIN`
/// 0 and `SLURM_ARRAY_TASK_MAX` one less than the count; a partial array must pass
/// `--shards`); Kubernetes does not tell a pod the job's completions, so an Indexed Job passes
/// `--shards`. Returns the shard and a sentence saying where it came from.
pub(crate) fn from_env(
    shards: Option<usize>,
    env: &dyn Fn(&str) -> Option<String>,
) -> Result<(Shard, String), ShardError> {
    let var = |name: &str| -> Result<Option<usize>, ShardError> {
        match env(name) {
            None => Ok(None),
            Some(v) if v.trim().is_empty() => Ok(None),
            Some(v) => v
                .trim()
                .parse::<usize>()
                .map(Some)
                .map_err(|_| ShardError::Variable {
                    name: name.to_string(),
                    value: v,
                }),
        }
    };
    let (index, source) = if let Some(i) = var("JOB_COMPLETION_INDEX")? {
        (i, format!("JOB_COMPLETION_INDEX={i}"))
    } else if let Some(id) = var("SLURM_ARRAY_TASK_ID")? {
        (id, format!("SLURM_ARRAY_TASK_ID={id}"))
    } else {
        return Err(ShardError::NoIndex);
    };
    let slurm = (
        var("SLURM_ARRAY_TASK_COUNT")?,
        var("SLURM_ARRAY_TASK_MIN")?,
        var("SLURM_ARRAY_TASK_MAX")?,
    );
    let (count, how) = match (shards, slurm) {
        (Some(n), _) => (n, "--shards".to_string()),
        (None, (Some(n), Some(0), Some(max))) if n > 0 && max == n - 1 => {
            (n, format!("SLURM_ARRAY_TASK_COUNT={n}"))
        }
        (None, (Some(n), min, max)) => return Err(ShardError::PartialArray { count: n, min, max }),
        (None, _) => return Err(ShardError::NoCount { from: source }),
    };
    let shard = check(Shard { index, count }).map_err(|e| ShardError::Auto(Box::new(e)))?;
    Ok((
        shard,
        format!("shard {shard} (index from {source}, count from {how})"),
    ))
}

/// The shard of each tile: the tiles (`cells`, their grid cells; `counts`, their building
/// counts) in the order of a Hilbert curve over the grid, cut into `n` runs of consecutive
/// tiles whose largest building count is the least possible (the optimal contiguous
/// partition, found by bisection on that maximum and a greedy cut), shard 0 first. A shard
/// so holds one compact block of the region, not tiles scattered over it: what a shard reads
/// beyond its tiles (`citygen split`'s halo) costs only its block's perimeter. Its load is at
/// most the ideal (total / `n`) plus the largest tile. Depends on `cells`, `counts` and `n`
/// alone.
pub(crate) fn assign(cells: &[(i64, i64)], counts: &[usize], n: usize) -> Vec<usize> {
    let n = n.max(1);
    let len = cells.len().min(counts.len());
    if len == 0 {
        return Vec::new();
    }
    let (x0, y0) = cells[..len]
        .iter()
        .fold((i64::MAX, i64::MAX), |(x, y), c| (x.min(c.0), y.min(c.1)));
    let span = cells[..len]
        .iter()
        .map(|c| (c.0.abs_diff(x0)).max(c.1.abs_diff(y0)))
        .max()
        .unwrap_or(0);
    let mut side: u64 = 1;
    while side <= span && side < (1 << 31) {
        side <<= 1;
    }
    let mut order: Vec<usize> = (0..len).collect();
    order.sort_by_key(|&t| {
        let key = hilbert_index(
            side,
            cells[t].0.abs_diff(x0).min(side - 1),
            cells[t].1.abs_diff(y0).min(side - 1),
        );
        (key, t)
    });
    let loads: Vec<usize> = order.iter().map(|&t| counts[t]).collect();
    // The least maximum run load with at most `n` runs: between the largest tile and the sum.
    let runs_needed = |cap: usize| {
        let (mut runs, mut acc) = (1, 0usize);
        for &l in &loads {
            if acc + l > cap && acc > 0 {
                runs += 1;
                acc = 0;
            }
            acc += l;
        }
        runs
    };
    let (mut lo, mut hi) = (
        loads.iter().copied().max().unwrap_or(0),
        loads.iter().sum::<usize>(),
    );
    while lo < hi {
        let mid = lo + (hi - lo) / 2;
        if runs_needed(mid) <= n {
            hi = mid;
        } else {
            lo = mid + 1;
        }
    }
    let mut shard = vec![0; counts.len()];
    let (mut s, mut acc) = (0usize, 0usize);
    for (i, &t) in order.iter().enumerate() {
        let l = loads[i];
        // A new run when this tile would pass the cap, or when exactly as many tiles remain
        // as shards still empty (so that every shard gets a tile when there are enough).
        let left = len - i;
        let empty = n - 1 - s;
        if s + 1 < n && acc > 0 && (acc + l > lo || left <= empty) {
            s += 1;
            acc = 0;
        }
        shard[t] = s;
        acc += l;
    }
    shard
}

/// The position of cell (`x`, `y`) along the Hilbert curve filling a `side` × `side` grid
/// (`side` a power of two).
fn hilbert_index(side: u64, mut x: u64, mut y: u64) -> u64 {
    let mut d = 0;
    let mut s = side / 2;
    while s > 0 {
        let rx = u64::from(x & s > 0);
        let ry = u64::from(y & s > 0);
        d += s * s * ((3 * rx) ^ ry);
        // Rotate the quadrant so that the curve's pieces join.
        if ry == 0 {
            if rx == 1 {
                x = side - 1 - x;
                y = side - 1 - y;
            }
            std::mem::swap(&mut x, &mut y);
        }
        s /= 2;
    }
    d
}

/// A shard's manifest (`citygen-manifest.{I}-of-{N}.json`, beside its outputs).
#[derive(Clone, Debug, Serialize, Deserialize)]
pub(crate) struct Manifest {
    /// [`MANIFEST_FORMAT`].
    pub format: String,
    /// citygen's version (`CARGO_PKG_VERSION`).
    pub citygen: String,
    /// Which shard wrote it.
    pub shard: Shard,
    /// Where the shard index came from (`--shard 2/7`, `JOB_COMPLETION_INDEX=2`, ...).
    pub shard_from: String,
    /// What decides the outputs: shards of one run have equal keys.
    pub run: RunKey,
    /// The whole grid, the same in every shard of the run.
    pub grid: Grid,
    /// The tiles this shard wrote, in grid order.
    pub tiles: Vec<TileRecord>,
    /// The shard's share of the run's report: the counts and the entries of the read and
    /// prepare stages it owns (those of its tiles are in `tiles`).
    pub report: ShardReport,
    /// The run's context key ([`crate::pipeline::incremental::context_key`]): every lot key
    /// of the run includes it.
    #[serde(default)]
    pub context: String,
    /// What changed since `--previous` (the whole region's buildings; every shard lists the
    /// same).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub changes: Option<crate::report::Changes>,
}

/// What decides a run's outputs, and so must be equal in the manifests of one merge.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub(crate) struct RunKey {
    /// The input files (an OSM PBF, or a shapefile's parts).
    pub inputs: Vec<FileKey>,
    /// The knowledge base, if any.
    pub kb: Option<FileKey>,
    /// The files the knowledge base names (appearances' rulesets and SELEX programs, those
    /// that exist), named as the KB writes them, sorted: they decide outputs as the KB does.
    #[serde(default)]
    pub kb_files: Vec<FileKey>,
    /// The ruleset, if any.
    pub rules: Option<FileKey>,
    /// `--seed`.
    pub seed: u64,
    /// `--lod` (1 to 4).
    pub lod: u8,
    /// The output CRS, e.g. `EPSG:32632`.
    pub crs: String,
    /// The local origin in the output CRS (metres).
    pub origin: [f64; 2],
    /// `--tile` (metres).
    pub tile_size: u32,
    /// The other options that change outputs, as one string (`--bbox`, caps, `--infer`, ...).
    pub options: String,
    /// The outputs each shard writes per tile, by kind (`ifc`, `citygml`, `gltf`, `cityjson`,
    /// `cityjsonseq`, `tiles3d`), and whether the run is a dry run.
    pub outputs: Vec<String>,
    /// The `--dem` files in the order given (absent without: older manifests' bytes kept).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub dems: Vec<FileKey>,
}

/// An input file: its name (not its folder: machines mount inputs at different places), its
/// size and SHA-256.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub(crate) struct FileKey {
    /// File name only.
    pub name: String,
    /// Size in bytes.
    pub bytes: u64,
    /// Lower-case hex SHA-256 of the whole file.
    pub sha256: String,
}

/// The run's tile grid: every tile holding a building, its lots and its shard.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Grid {
    /// Lots the run writes (after `--bbox`), over all tiles.
    pub lots: usize,
    /// Every tile of the run, in grid order (easting, then northing, of the lower-left corner).
    pub tiles: Vec<GridTile>,
}

/// One tile of the grid.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct GridTile {
    /// `{easting}_{northing}` of the lower-left corner: the files' suffix.
    pub suffix: String,
    /// The lower-left corner in the output CRS, whole metres.
    pub corner: [i64; 2],
    /// Lots in the tile.
    pub lots: usize,
    /// The shard writing it.
    pub shard: usize,
}

/// What a shard wrote for one tile.
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
pub struct TileRecord {
    /// The tile's suffix ([`GridTile::suffix`]).
    pub suffix: String,
    /// The buildings written, in file order.
    pub buildings: Vec<BuildingRecord>,
    /// The tile's lots that could not be generated (their reasons are in `entries`).
    pub skipped: Vec<String>,
    /// The report entries of deriving the tile, in order.
    pub entries: Vec<Entry>,
    /// The files written, paths relative to the manifest's folder, `/`-separated.
    pub files: Vec<FileRecord>,
    /// The 3D Tiles contents' facts, for the tileset.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tiles3d: Option<serde_json::Value>,
    /// Every lot of the tile, in file order, with its content keys: a later run
    /// (`--previous`) reuses the tile's files when its lots and keys are the same
    /// ([`crate::pipeline::incremental`]).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub lots: Vec<LotKey>,
    /// The facade counts of the tile's buildings (a reused tile adds them to the report).
    #[serde(default)]
    pub facades: crate::model::FacadeCounts,
    /// The provenance counts of the tile's buildings (a reused tile adds them to the report).
    #[serde(default)]
    pub provenance: crate::report::ProvenanceCounts,
    /// The polygons of the tile's buildings (for the run's summary).
    #[serde(default)]
    pub polygons: usize,
    /// The XML elements of the tile's CityGML file, if any (for the warning of files over the
    /// schema validator's cap).
    #[serde(default)]
    pub citygml_elements: u64,
}

/// One lot's content keys ([`crate::pipeline::incremental`]).
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct LotKey {
    /// Source id (`way/123`).
    pub id: String,
    /// The lot as read: geometry, parts and tags (hex, 32 digits). Differs between two runs
    /// when the building itself was edited.
    pub own: String,
    /// Everything that decides the lot's output bytes: `own`, the run's context (seed, LOD,
    /// knowledge base, CRS, outputs, citygen's output format...), what its neighbours and the
    /// streets lend it (inferred tags, the front, at LOD3 the neighbours it may touch).
    pub key: String,
}

/// One building of a tile.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct BuildingRecord {
    /// Source id (`way/123`).
    pub id: String,
    /// [`crate::model::Building::digest`] in hex (16 digits).
    pub digest: String,
}

/// One file written.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct FileRecord {
    /// Relative to the manifest's folder, `/`-separated.
    pub path: String,
    /// Size in bytes.
    pub bytes: u64,
    /// Lower-case hex SHA-256 (of the bytes rendered, for a dry run).
    pub sha256: String,
}

/// A shard's share of the report.
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
pub(crate) struct ShardReport {
    /// Footprints read (the whole input: equal in every shard).
    pub read: usize,
    /// `building:part`s read (the whole input).
    pub parts_read: usize,
    /// Buildings this shard generated.
    pub generated: usize,
    /// The facade counts of this shard's buildings.
    pub facades: crate::model::FacadeCounts,
    /// The provenance counts of this shard's buildings.
    #[serde(default)]
    pub provenance: crate::report::ProvenanceCounts,
    /// Entries of the read and prepare stages owned by this shard, each with its index in the
    /// single run's list of them.
    pub prepared: Vec<(usize, Entry)>,
    /// Notes about the shard's outputs as a whole (a CityGML tile over the validator's cap).
    pub notes: Vec<Entry>,
    /// The input's admin boundaries (equal in every shard) with the buildings of this shard
    /// each placed (absent when the input has none).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub boundaries: Option<crate::report::Boundaries>,
    /// The run's terrain (the report's `terrain`) where it has one (absent without `--dem` or
    /// `--ground-height`, so that such a run's manifest keeps its bytes).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub terrain: Option<String>,
}

/// The [`FileKey`] of a file: its name, size and SHA-256 ([`crate::fsio::file_sha256`]).
pub(crate) fn file_key(path: &Path) -> std::io::Result<FileKey> {
    let (bytes, sha256) = crate::fsio::file_sha256(path)?;
    Ok(FileKey {
        name: path
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default(),
        bytes,
        sha256,
    })
}

/// Which shard owns each entry of the read and prepare stages: the shard of the lot it names,
/// else shard 0. `owner` maps a lot's id to its shard.
pub(crate) fn owner_of(entry: &Entry, owner: &BTreeMap<String, usize>) -> usize {
    owner.get(&entry.id).copied().unwrap_or(0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shard_values_parse_or_say_what_is_wrong() {
        assert_eq!(
            parse_shard("2/7"),
            Ok(ShardArg::Fixed(Shard { index: 2, count: 7 }))
        );
        assert_eq!(parse_shard("AUTO"), Ok(ShardArg::Auto));
        for (bad, says) in [
            ("7/7", "counted from 0"),
            ("1/0", "between 1"),
            ("x/3", "index \"x\""),
            ("3", "I/N"),
            ("0/100001", "between 1"),
        ] {
            let e = parse_shard(bad).unwrap_err().to_string();
            assert!(e.contains(says), "{bad}: {e}");
        }
    }

    fn env<'a>(vars: &'a [(&'a str, &'a str)]) -> impl Fn(&str) -> Option<String> + 'a {
        move |k| {
            vars.iter()
                .find(|(n, _)| *n == k)
                .map(|(_, v)| v.to_string())
        }
    }

    #[test]
    fn auto_reads_kubernetes_then_slurm_and_says_which() {
        let (s, how) = from_env(Some(4), &env(&[("JOB_COMPLETION_INDEX", "3")])).unwrap();
        assert_eq!(s, Shard { index: 3, count: 4 });
        assert!(how.contains("JOB_COMPLETION_INDEX=3") && how.contains("--shards"));
        let e = from_env(None, &env(&[("JOB_COMPLETION_INDEX", "3")]))
            .unwrap_err()
            .to_string();
        assert!(e.contains("--shards N"), "{e}");
        let vars = [
            ("SLURM_ARRAY_TASK_ID", "5"),
            ("SLURM_ARRAY_TASK_MIN", "0"),
            ("SLURM_ARRAY_TASK_MAX", "6"),
            ("SLURM_ARRAY_TASK_COUNT", "7"),
        ];
        let (s, how) = from_env(None, &env(&vars)).unwrap();
        assert_eq!(s, Shard { index: 5, count: 7 });
        assert!(how.contains("SLURM_ARRAY_TASK_COUNT=7"), "{how}");
        // A re-submission of two failed tasks (--array=3,5): the ids are the shards, and the
        // count must come from --shards.
        let partial = [
            ("SLURM_ARRAY_TASK_ID", "5"),
            ("SLURM_ARRAY_TASK_MIN", "3"),
            ("SLURM_ARRAY_TASK_MAX", "5"),
            ("SLURM_ARRAY_TASK_COUNT", "2"),
        ];
        let e = from_env(None, &env(&partial)).unwrap_err().to_string();
        assert!(e.contains("pass --shards N"), "{e}");
        let (s, _) = from_env(Some(7), &env(&partial)).unwrap();
        assert_eq!(s, Shard { index: 5, count: 7 });
        let e = from_env(None, &env(&[])).unwrap_err().to_string();
        assert!(e.contains("JOB_COMPLETION_INDEX"), "{e}");
        let e = from_env(Some(2), &env(&[("JOB_COMPLETION_INDEX", "2")]))
            .unwrap_err()
            .to_string();
        assert!(e.contains("counted from 0"), "{e}");
        let e = from_env(Some(2), &env(&[("SLURM_ARRAY_TASK_ID", "one")]))
            .unwrap_err()
            .to_string();
        assert!(e.contains("not a whole number"), "{e}");
    }

    #[test]
    fn tiles_go_in_compact_balanced_blocks_alike_everywhere() {
        // A 4 x 4 grid away from the origin, uneven counts.
        let mut cells = Vec::new();
        let mut counts = Vec::new();
        for y in 0..4i64 {
            for x in 0..4i64 {
                cells.push((x - 7, y + 3));
                counts.push(((x * 7 + y * 3) % 5 + 1) as usize);
            }
        }
        let total: usize = counts.iter().sum();
        for n in 1..=6 {
            let a = assign(&cells, &counts, n);
            assert_eq!(a, assign(&cells, &counts, n));
            let mut load = vec![0; n];
            for (t, s) in a.iter().enumerate() {
                load[*s] += counts[t];
            }
            let max = *load.iter().max().unwrap();
            // At most the ideal plus the largest tile, and every shard holds a tile.
            assert!(max <= total.div_ceil(n) + 5, "{n}: {load:?}");
            assert!(load.iter().all(|l| *l > 0), "{n}: {load:?}");
            // Each shard's tiles are one edge-connected block of the grid.
            for s in 0..n {
                let mine: Vec<(i64, i64)> = (0..cells.len())
                    .filter(|t| a[*t] == s)
                    .map(|t| cells[t])
                    .collect();
                let mut seen = vec![mine[0]];
                let mut i = 0;
                while i < seen.len() {
                    let c = seen[i];
                    for m in &mine {
                        if !seen.contains(m) && (m.0 - c.0).abs() + (m.1 - c.1).abs() == 1 {
                            seen.push(*m);
                        }
                    }
                    i += 1;
                }
                assert_eq!(
                    seen.len(),
                    mine.len(),
                    "{n}: shard {s} is not one block: {mine:?}"
                );
            }
        }
        assert_eq!(assign(&cells, &counts, 1), vec![0; cells.len()]);
        // More shards than tiles: each tile alone, the rest empty.
        let a = assign(&[(0, 0), (1, 0)], &[5, 4], 4);
        assert_eq!(a, vec![0, 1]);
        assert!(assign(&[], &[], 3).is_empty());
    }

    #[test]
    fn the_hilbert_curve_visits_every_cell_once_by_neighbour_steps() {
        let side = 8;
        let mut at = vec![(0, 0); 64];
        for x in 0..side {
            for y in 0..side {
                at[hilbert_index(side, x, y) as usize] = (x as i64, y as i64);
            }
        }
        for w in at.windows(2) {
            assert_eq!(
                (w[0].0 - w[1].0).abs() + (w[0].1 - w[1].1).abs(),
                1,
                "{w:?}"
            );
        }
    }
}
