//! Nightly, incremental runs: content keys per building, and `--previous DIR`.
//!
//! Every tiled run records in its manifest, for each tile, its lots in file order with two
//! keys (128-bit, SHA-256 truncated, hex):
//!
//! - **own** (`own_keys`): the lot as read and prepared, before anything from other lots is
//!   lent to it: its id, its outline polygons (every coordinate bit for bit, in the run's local
//!   frame), the drawn part of the outline, its `building:part`s (ids, polygons, tags) and its
//!   parsed tags. Two runs give a building different own keys exactly when it was edited.
//! - **key** (`full_keys`): what decides the lot's bytes in the outputs: the run's context
//!   (`context_key`: citygen's version and `OUTPUT_FORMAT`, the input's name, the SHA-256
//!   of the knowledge base, of the rulesets and SELEX programs it names and of `--rules`,
//!   seed, LOD, output CRS and origin, tile size, the options (`--ground-height` among them),
//!   the SHA-256 of the `--dem` files, and the model and 3D Tiles
//!   outputs: not the report's or the preview's path, which decide no tile's bytes), the own
//!   key, the tags as derived (after `--infer` lent it its neighbours' values), its front (from the nearest street), the zone an admin boundary of the input
//!   gave it (where one did: `kb::BoundaryZones`), and at LOD3 and LOD4 the keys of the lots
//!   within `NEIGHBOUR_MARGIN_M` of it (party walls and what stands in front of a bay are
//!   read from them). A building's random stream is seeded from the run's seed and its own id
//!   alone ([`crate::derive::Generator`]), never from its place in the file or its neighbours.
//!
//! With `--previous DIR` (yesterday's tiled output, its manifests in DIR: one run's, or the
//! shards' of a merged run), a tile whose lots and keys are those of a tile of DIR, in the same
//! order, has the same bytes: its files are copied from DIR (each opened only where it is a
//! regular file inside DIR, `open_previous_file`, and checked against the size and SHA-256
//! the manifest recorded; a file that fails is a tile derived again, the report's
//! `tiles_not_reused` saying why), its report
//! entries and manifest record taken over, and it is not derived. Every other tile is derived
//! and written as usual (with `--link-previous`, [`Previous::link`], a reused file is
//! hard-linked after its check instead of copied). [`changes`] compares the two runs' lots: added, removed, changed (own
//! key), affected (same own key, another key), with the tiles reused, rewritten and gone.

use std::collections::{BTreeMap, BTreeSet, HashMap};
use std::io::{Read, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};

use rayon::prelude::*;
use sha2::{Digest, Sha256};

use crate::geometry::Polygon;
use crate::model::{Lod, SourceId};
use crate::prepare::Lot;
use crate::report::Changes;

use super::shard::{self, LotKey, Manifest, TileRecord};

/// The version of what citygen writes for a given lot and context: raised whenever a change to
/// citygen changes output bytes without changing its version number, so that a `--previous`
/// run of another build reuses nothing (2: every building carries its provenance, issue 42).
pub(crate) const OUTPUT_FORMAT: u32 = 2;

/// How far (metres, in plan) a lot's neighbours may stand and still be read by its derivation
/// at LOD3 and LOD4 (the surroundings of the run are derived for the lots within this of a
/// written one).
pub(crate) const NEIGHBOUR_MARGIN_M: f64 = 1.0;

/// A content key: SHA-256 truncated to 128 bits.
pub type Key = [u8; 16];

fn finish(h: Sha256) -> Key {
    let d = h.finalize();
    let mut k = [0u8; 16];
    k.copy_from_slice(&d[..16]);
    k
}

fn put_str(h: &mut Sha256, s: &str) {
    h.update((s.len() as u64).to_le_bytes());
    h.update(s.as_bytes());
}

fn put_polygon(h: &mut Sha256, p: &Polygon) {
    h.update((p.holes.len() as u64 + 1).to_le_bytes());
    for ring in std::iter::once(&p.outer).chain(&p.holes) {
        h.update((ring.len() as u64).to_le_bytes());
        for q in ring {
            h.update(q.x.to_bits().to_le_bytes());
            h.update(q.y.to_bits().to_le_bytes());
        }
    }
}

fn put_polygons(h: &mut Sha256, ps: &[Polygon]) {
    h.update((ps.len() as u64).to_le_bytes());
    for p in ps {
        put_polygon(h, p);
    }
}

/// The own key of one lot (see the module documentation).
pub(crate) fn own_key(lot: &Lot) -> Key {
    let mut h = Sha256::new();
    put_str(&mut h, "citygen-lot/1");
    put_str(&mut h, &lot.id.to_string());
    // Debug of the parsed tags: every field, floats exactly (Rust prints the shortest string
    // that reads back to the same f64), in declaration order.
    put_str(&mut h, &format!("{:?}", lot.tags));
    put_polygons(&mut h, &lot.polygons);
    put_polygons(&mut h, lot.drawn_outline());
    h.update((lot.parts.len() as u64).to_le_bytes());
    for part in &lot.parts {
        put_str(&mut h, &part.id.to_string());
        put_str(&mut h, &format!("{:?}", part.tags));
        put_polygons(&mut h, &part.polygons);
    }
    // The tags an outline's rest is drawn with (only lots with parts have them: every other
    // key is as before).
    if let Some(t) = &lot.rest_tags {
        put_str(&mut h, &format!("rest {t:?}"));
    }
    h.update(lot.lonlat.0.to_bits().to_le_bytes());
    h.update(lot.lonlat.1.to_bits().to_le_bytes());
    finish(h)
}

/// The own keys of `lots` by id, computed in parallel.
pub(crate) fn own_keys(lots: &[Lot]) -> HashMap<SourceId, Key> {
    lots.par_iter().map(|l| (l.id, own_key(l))).collect()
}

/// The run's context key from what its manifest records, the input's name (it is written into
/// the files) and the output paths relative to the manifest's folder (file names are written
/// into some files, and a tile's files are reused only where they land at the same place).
pub(crate) fn context_key(run: &shard::RunKey, source_name: &str, outputs: &[String]) -> Key {
    let mut h = Sha256::new();
    put_str(&mut h, "citygen-context/1");
    put_str(&mut h, env!("CARGO_PKG_VERSION"));
    h.update(OUTPUT_FORMAT.to_le_bytes());
    put_str(&mut h, source_name);
    for f in [&run.kb, &run.rules] {
        put_str(&mut h, f.as_ref().map_or("-", |k| k.sha256.as_str()));
    }
    h.update((run.kb_files.len() as u64).to_le_bytes());
    for f in &run.kb_files {
        put_str(&mut h, &f.name);
        put_str(&mut h, &f.sha256);
    }
    h.update(run.seed.to_le_bytes());
    h.update([run.lod]);
    put_str(&mut h, &run.crs);
    h.update(run.origin[0].to_bits().to_le_bytes());
    h.update(run.origin[1].to_bits().to_le_bytes());
    h.update(run.tile_size.to_le_bytes());
    put_str(&mut h, &run.options);
    for o in run.outputs.iter().chain(outputs) {
        put_str(&mut h, o);
    }
    // The DEMs decide every building's height (nothing hashed without: the keys of runs
    // without terrain are those of before).
    if !run.dems.is_empty() {
        put_str(&mut h, "dems");
        h.update((run.dems.len() as u64).to_le_bytes());
        for f in &run.dems {
            put_str(&mut h, &f.name);
            put_str(&mut h, &f.sha256);
        }
    }
    finish(h)
}

/// Every lot's own key and its key without the run's context ([`with_context`] adds it), by
/// id. `own` are [`own_keys`] taken before `--infer` (a lot missing there, which cannot happen,
/// gets its own key now); `lots` are the lots as they will be derived, every lot of the run
/// (neighbours outside `--bbox` too).
pub(crate) fn full_keys(
    lots: &[Lot],
    own: &HashMap<SourceId, Key>,
    lod: Lod,
    boundary_zone: impl Fn(&Lot) -> Option<String> + Sync,
) -> HashMap<SourceId, (Key, Key)> {
    // What a lot is as derived at LOD2: its own key, the tags as derived, its front, and the
    // zone an input boundary gave it (nothing added where none did: such keys stay as they
    // were before boundaries counted).
    let base: Vec<(Key, Key)> = lots
        .par_iter()
        .map(|l| {
            let o = own.get(&l.id).copied().unwrap_or_else(|| own_key(l));
            let mut h = Sha256::new();
            h.update(o);
            put_str(&mut h, &format!("{:?}", l.tags));
            match l.front {
                Some(f) => {
                    h.update([1]);
                    h.update(f.x.to_bits().to_le_bytes());
                    h.update(f.y.to_bits().to_le_bytes());
                }
                None => h.update([0]),
            }
            if let Some(zone) = boundary_zone(l) {
                put_str(&mut h, "boundary-zone");
                put_str(&mut h, &zone);
            }
            (o, finish(h))
        })
        .collect();
    let near: Vec<Vec<usize>> = if lod >= Lod::Lod3 {
        neighbours(lots, NEIGHBOUR_MARGIN_M)
    } else {
        vec![Vec::new(); lots.len()]
    };
    lots.par_iter()
        .enumerate()
        .map(|(i, l)| {
            let mut h = Sha256::new();
            h.update(base[i].1);
            // Neighbours by id, so their order in the file does not count.
            let mut ns: Vec<(String, Key)> = near[i]
                .iter()
                .map(|&j| (lots[j].id.to_string(), base[j].1))
                .collect();
            ns.sort();
            h.update((ns.len() as u64).to_le_bytes());
            for (id, k) in ns {
                put_str(&mut h, &id);
                h.update(k);
            }
            (l.id, (base[i].0, finish(h)))
        })
        .collect()
}

/// The lots' [`LotKey`]s: the keys of [`full_keys`] with the run's `context` folded in.
pub(crate) fn with_context(
    context: &Key,
    keys: HashMap<SourceId, (Key, Key)>,
) -> HashMap<SourceId, LotKey> {
    keys.into_par_iter()
        .map(|(id, (own, partial))| {
            let mut h = Sha256::new();
            h.update(context);
            h.update(partial);
            let key = finish(h);
            (
                id,
                LotKey {
                    id: id.to_string(),
                    own: key_hex(&own),
                    key: key_hex(&key),
                },
            )
        })
        .collect()
}

/// For each lot, the other lots whose bounds (outline and parts) come within `margin` of its
/// own, in index order.
fn neighbours(lots: &[Lot], margin: f64) -> Vec<Vec<usize>> {
    use rstar::{primitives::GeomWithData, primitives::Rectangle, RTree, AABB};
    let bounds = |l: &Lot| -> Option<([f64; 2], [f64; 2])> {
        let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
        for p in l
            .polygons
            .iter()
            .chain(l.parts.iter().flat_map(|p| &p.polygons))
        {
            let (a, b) = p.bounds();
            lo = [lo[0].min(a.x), lo[1].min(a.y)];
            hi = [hi[0].max(b.x), hi[1].max(b.y)];
        }
        (lo.iter().chain(&hi).all(|v| v.is_finite())).then_some((lo, hi))
    };
    let boxes: Vec<Option<([f64; 2], [f64; 2])>> = lots.iter().map(bounds).collect();
    let tree = RTree::bulk_load(
        boxes
            .iter()
            .enumerate()
            .filter_map(|(i, b)| {
                b.map(|(lo, hi)| GeomWithData::new(Rectangle::from_corners(lo, hi), i))
            })
            .collect(),
    );
    boxes
        .par_iter()
        .enumerate()
        .map(|(i, b)| {
            let Some((lo, hi)) = b else {
                return Vec::new();
            };
            let env = AABB::from_corners(
                [lo[0] - margin, lo[1] - margin],
                [hi[0] + margin, hi[1] + margin],
            );
            let mut found: Vec<usize> = tree
                .locate_in_envelope_intersecting(env)
                .map(|g| g.data)
                .filter(|&j| j != i)
                .collect();
            found.sort_unstable();
            found
        })
        .collect()
}

/// Lower-case hex of a key.
pub(crate) fn key_hex(k: &Key) -> String {
    crate::fsio::hex(k)
}

/// Yesterday's run, read from its manifests.
#[derive(Debug, Default)]
pub struct Previous {
    /// The folder given.
    pub dir: PathBuf,
    /// Its tiles by suffix, each with the folder of its manifest (the files' paths are
    /// relative to it).
    pub tiles: BTreeMap<String, (PathBuf, TileRecord)>,
    /// Reused files are hard-linked rather than copied (`--link-previous`), where the two
    /// folders are on one file system.
    pub link: bool,
    /// The manifests read, in name order.
    pub(crate) manifests: Vec<PreviousManifest>,
}

/// What a previous manifest says of its run: enough to say why its tiles are not reused.
#[derive(Debug)]
pub(crate) struct PreviousManifest {
    /// The manifest's path (in the `--previous` folder as given).
    pub(crate) path: PathBuf,
    /// Its run's context key, hex (empty in manifests older than context keys).
    pub(crate) context: String,
    /// Its run's key.
    pub(crate) run: shard::RunKey,
    /// The citygen that wrote it.
    pub(crate) citygen: String,
}

/// Why the previous run's manifests cannot be used, or a file of it cannot be reused.
#[derive(Debug, thiserror::Error)]
pub(crate) enum PreviousError {
    /// The `--previous` folder cannot be listed.
    #[error(
        "--previous {}: {source} (give the folder of a tiled run: its manifests and tiles)",
        .dir.display()
    )]
    Folder {
        /// The folder.
        dir: PathBuf,
        /// The system's error.
        source: std::io::Error,
    },
    /// The folder has no manifest.
    #[error(
        "--previous {}: no citygen-manifest.*.json there (a tiled run, --tile with an output, \
         writes one beside its first output)",
        .dir.display()
    )]
    NoManifest {
        /// The folder.
        dir: PathBuf,
    },
    /// A file cannot be read or written.
    #[error("{}: {source}", .path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// The system's error.
        source: std::io::Error,
    },
    /// A manifest does not parse.
    #[error("{}: not a citygen manifest: {source}", .path.display())]
    NotAManifest {
        /// The manifest.
        path: PathBuf,
        /// serde_json's error.
        source: serde_json::Error,
    },
    /// A manifest of another format.
    #[error(
        "{}: manifest format {found:?}, this citygen reads {:?}",
        .path.display(),
        shard::MANIFEST_FORMAT
    )]
    Format {
        /// The manifest.
        path: PathBuf,
        /// Its format.
        found: String,
    },
    /// A tile listed by two manifests of one folder.
    #[error(
        "--previous {}: tile {tile} is in two manifests (shards of two runs in one \
         folder?)",
        .dir.display()
    )]
    TileTwice {
        /// The `--previous` folder.
        dir: PathBuf,
        /// The tile's suffix.
        tile: String,
    },
    /// A file of the previous run that is not a regular file: never opened, never followed.
    #[error("{}: not a regular file ({kind}): citygen reads only regular files inside --previous", .path.display())]
    NotRegular {
        /// The file.
        path: PathBuf,
        /// What it is (a symbolic link, a named pipe...).
        kind: &'static str,
    },
    /// A path a manifest lists that would leave the `--previous` folder.
    #[error("{}: outside the --previous folder ({why})", .path.display())]
    Outside {
        /// The path.
        path: PathBuf,
        /// Why (`..`, absolute, a symbolic link on the way).
        why: &'static str,
    },
    /// A file the manifest lists that is not there.
    #[error("{}: tile file missing", .path.display())]
    Missing {
        /// The file.
        path: PathBuf,
    },
    /// A file that is not the one its manifest lists (its SHA-256s are shown by their first 12
    /// digits).
    #[error(
        "{} is not the file its manifest lists ({bytes} bytes, SHA-256 {}…; listed {listed_bytes} bytes, {}…)",
        .path.display(),
        .sha256.chars().take(12).collect::<String>(),
        .listed_sha256.chars().take(12).collect::<String>()
    )]
    Mismatch {
        /// The file.
        path: PathBuf,
        /// Its size.
        bytes: u64,
        /// Its SHA-256, hex.
        sha256: String,
        /// The size listed.
        listed_bytes: u64,
        /// The SHA-256 listed, hex.
        listed_sha256: String,
    },
}

/// Reads the manifests `citygen-manifest.*.json` of `dir`. Errors name the folder or file:
/// no manifest, one that does not parse or is of another format, or a tile in two of them.
pub(crate) fn load_previous(dir: &Path) -> Result<Previous, PreviousError> {
    let entries = std::fs::read_dir(dir).map_err(|source| PreviousError::Folder {
        dir: dir.to_path_buf(),
        source,
    })?;
    let mut names: Vec<PathBuf> = entries
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| {
            p.file_name()
                .and_then(|n| n.to_str())
                .is_some_and(|n| n.starts_with("citygen-manifest.") && n.ends_with(".json"))
        })
        .collect();
    names.sort();
    if names.is_empty() {
        return Err(PreviousError::NoManifest {
            dir: dir.to_path_buf(),
        });
    }
    let mut prev = Previous {
        dir: dir.to_path_buf(),
        ..Default::default()
    };
    for p in names {
        let name = p.file_name().map(|n| n.to_string_lossy().into_owned());
        let (mut file, _) = open_previous_file(dir, name.as_deref().unwrap_or_default())?;
        let mut text = String::new();
        file.read_to_string(&mut text).map_err(io(&p))?;
        let m: Manifest =
            serde_json::from_str(&text).map_err(|source| PreviousError::NotAManifest {
                path: p.clone(),
                source,
            })?;
        if m.format != shard::MANIFEST_FORMAT {
            return Err(PreviousError::Format {
                path: p,
                found: m.format,
            });
        }
        let folder = p
            .parent()
            .filter(|d| !d.as_os_str().is_empty())
            .unwrap_or(Path::new("."))
            .to_path_buf();
        prev.manifests.push(PreviousManifest {
            path: p.clone(),
            context: m.context.clone(),
            run: m.run.clone(),
            citygen: m.citygen.clone(),
        });
        for t in m.tiles {
            if let Some((other, _)) = prev.tiles.get(&t.suffix) {
                if other == &folder {
                    return Err(PreviousError::TileTwice {
                        dir: dir.to_path_buf(),
                        tile: t.suffix,
                    });
                }
            }
            prev.tiles.insert(t.suffix.clone(), (folder.clone(), t));
        }
    }
    Ok(prev)
}

/// Whether `path` (relative, `/`-separated) names a PNG directly in one of the folders
/// `dirs` (relative too): a tile's picture ([`Previous::reusable`]).
pub(crate) fn is_picture(path: &str, dirs: &[String]) -> bool {
    dirs.iter().any(|d| {
        path.strip_prefix(d.as_str())
            .and_then(|rest| rest.strip_prefix('/'))
            .is_some_and(|name| {
                name.ends_with(".png") && !name.contains('/') && !name.starts_with('.')
            })
    })
}

impl Previous {
    /// The previous record of tile `suffix` when its lots and keys are `lots`, in order, and it
    /// wrote the files `files` (paths relative to the manifest's folder) and, besides them,
    /// only pictures directly in the folders `pictures` (relative too: `--textures`, whose
    /// files a tile knows once derived), with the folder its paths are relative to; else why
    /// not (`context_changed`: the run's context differs from the previous run's,
    /// [`Previous::context_change`]).
    pub(crate) fn reusable(
        &self,
        suffix: &str,
        lots: &[LotKey],
        (files, pictures): (&BTreeSet<String>, &[String]),
        context_changed: bool,
    ) -> Result<&(PathBuf, TileRecord), String> {
        let Some(found) = self.tiles.get(suffix) else {
            return Err("a new tile (not in the previous run)".into());
        };
        let t = &found.1;
        if lots.is_empty() {
            return Err("no building".into());
        }
        if t.lots != lots {
            return Err(lots_differ(&t.lots, lots, context_changed));
        }
        let listed = t.files.iter().filter(|f| files.contains(&f.path)).count();
        let same_files = listed == files.len()
            && t.files
                .iter()
                .all(|f| files.contains(&f.path) || is_picture(&f.path, pictures));
        if !same_files {
            return Err("the previous run wrote other files for it (other outputs)".into());
        }
        Ok(found)
    }

    /// The files the run reads from the previous folder, with the flag `--previous`: its
    /// manifests and the files they list (for [`super::outputs::check`]: no output may be
    /// one of them).
    pub(crate) fn read_files(&self) -> Vec<(&'static str, PathBuf)> {
        let manifests = self.manifests.iter().map(|m| m.path.clone());
        let files = self
            .tiles
            .values()
            .flat_map(|(folder, t)| t.files.iter().map(|f| folder.join(&f.path)));
        manifests.chain(files).map(|p| ("--previous", p)).collect()
    }

    /// Why the run's `context` key (hex) and `run` key are not those of the previous run,
    /// naming what differs (`None` when every manifest has this context).
    pub(crate) fn context_change(&self, context: &str, run: &shard::RunKey) -> Option<String> {
        let m = self.manifests.iter().find(|m| m.context != context)?;
        if m.context.is_empty() {
            return Some(format!(
                "{}: the previous run records no context key (an older citygen)",
                m.path.display()
            ));
        }
        let sha = |f: &Option<shard::FileKey>| f.as_ref().map(|k| k.sha256.clone());
        let mut why: Vec<String> = Vec::new();
        if m.citygen != env!("CARGO_PKG_VERSION") {
            why.push(format!(
                "citygen {} then, {} now",
                m.citygen,
                env!("CARGO_PKG_VERSION")
            ));
        }
        let (a, b) = (&m.run, run);
        let dems = |k: &shard::RunKey| -> Vec<(String, String)> {
            k.dems
                .iter()
                .map(|f| (f.name.clone(), f.sha256.clone()))
                .collect()
        };
        let checks: [(bool, &str); 8] = [
            (dems(a) != dems(b), "the --dem files differ"),
            (
                sha(&a.kb) != sha(&b.kb),
                "the knowledge base's SHA-256 differs",
            ),
            (
                a.kb_files != b.kb_files,
                "a ruleset or SELEX program the knowledge base names differs",
            ),
            (sha(&a.rules) != sha(&b.rules), "--rules' SHA-256 differs"),
            (a.seed != b.seed, "another --seed"),
            (a.lod != b.lod, "another --lod"),
            (
                a.crs != b.crs || a.origin != b.origin,
                "another output CRS or local origin",
            ),
            (a.tile_size != b.tile_size, "another --tile size"),
        ];
        why.extend(checks.iter().filter(|c| c.0).map(|c| c.1.to_string()));
        if a.options != b.options {
            why.push(format!(
                "other options ({} then, {} now)",
                a.options, b.options
            ));
        }
        if a.outputs != b.outputs {
            why.push(format!(
                "other outputs ({} then, {} now)",
                a.outputs.join(" "),
                b.outputs.join(" ")
            ));
        }
        if why.is_empty() {
            why.push(
                "citygen's output format, the input's name, the output files' names, or how \
                 the citygen that wrote the previous run keyed it"
                    .into(),
            );
        }
        Some(format!("context changed: {}", why.join("; ")))
    }

    /// Every lot of the previous run: id to (own, key).
    fn lots(&self) -> BTreeMap<&str, (&str, &str)> {
        self.tiles
            .values()
            .flat_map(|(_, t)| &t.lots)
            .map(|l| (l.id.as_str(), (l.own.as_str(), l.key.as_str())))
            .collect()
    }
}

/// The lots added, removed, changed and affected between `prev` and this run's `lots` (every
/// lot of the run, all shards'). The tile lists are filled as the tiles are written.
pub fn changes(prev: &Previous, lots: &BTreeMap<String, (String, String)>) -> Changes {
    let before = prev.lots();
    let mut c = Changes {
        previous: prev.dir.display().to_string(),
        ..Default::default()
    };
    for (id, (own, key)) in lots {
        match before.get(id.as_str()) {
            None => c.added.push(id.clone()),
            Some((o, _)) if *o != own => c.changed.push(id.clone()),
            Some((_, k)) if *k != key => c.affected.push(id.clone()),
            Some(_) => {}
        }
    }
    c.removed = before
        .keys()
        .filter(|id| !lots.contains_key(**id))
        .map(|s| s.to_string())
        .collect();
    // Ids sort as strings (`way/10` before `way/9`) in both lists' maps: kept so.
    c
}

/// Why a tile whose lots were `before` is not reused now that they are `now`: the buildings
/// added, removed, edited and affected, counted.
fn lots_differ(before: &[LotKey], now: &[LotKey], context_changed: bool) -> String {
    let old: HashMap<&str, &LotKey> = before.iter().map(|l| (l.id.as_str(), l)).collect();
    let ids: BTreeSet<&str> = now.iter().map(|l| l.id.as_str()).collect();
    let (mut added, mut edited, mut affected) = (0, 0, 0);
    for l in now {
        match old.get(l.id.as_str()) {
            None => added += 1,
            Some(o) if o.own != l.own => edited += 1,
            Some(o) if o.key != l.key => affected += 1,
            Some(_) => {}
        }
    }
    let removed = before
        .iter()
        .filter(|l| !ids.contains(l.id.as_str()))
        .count();
    let mut parts: Vec<String> = [(added, "added"), (removed, "removed"), (edited, "edited")]
        .iter()
        .filter(|(n, _)| *n > 0)
        .map(|(n, what)| format!("{n} building(s) {what}"))
        .collect();
    if affected > 0 {
        parts.push(if context_changed {
            format!("{affected} building(s) affected: the run's context changed (see not_reused)")
        } else {
            format!(
                "{affected} building(s) affected (a neighbour, a street, an inferred value or a \
                 boundary's zone changed)"
            )
        });
    }
    if parts.is_empty() {
        parts.push("its buildings are in another order".into());
    }
    parts.join(", ")
}

/// What a file that is not a regular one is, in words.
fn kind_of(ft: std::fs::FileType) -> &'static str {
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        if ft.is_fifo() {
            return "a named pipe";
        }
        if ft.is_socket() {
            return "a socket";
        }
        if ft.is_block_device() || ft.is_char_device() {
            return "a device";
        }
    }
    if ft.is_symlink() {
        "a symbolic link"
    } else if ft.is_dir() {
        "a folder"
    } else {
        "not a regular file"
    }
}

/// Whether two metadata are of one file (device and inode; on other systems, true).
fn same_file(a: &std::fs::Metadata, b: &std::fs::Metadata) -> bool {
    #[cfg(unix)]
    {
        use std::os::unix::fs::MetadataExt;
        a.dev() == b.dev() && a.ino() == b.ino()
    }
    #[cfg(not(unix))]
    {
        let _ = (a, b);
        true
    }
}

/// Opens `path` for reading without following a symbolic link at its end and without
/// blocking on a named pipe (`O_NOFOLLOW | O_NONBLOCK` on Unix).
fn open_nofollow(path: &Path) -> std::io::Result<std::fs::File> {
    let mut o = std::fs::OpenOptions::new();
    o.read(true);
    #[cfg(unix)]
    {
        use std::os::unix::fs::OpenOptionsExt;
        o.custom_flags(libc::O_NOFOLLOW | libc::O_NONBLOCK);
    }
    o.open(path)
}

/// The path `rel` (`/`-separated, as a manifest lists it) below `folder` when it is a plain
/// relative path, each component inside the folder: no `..`, `.`, empty component or absolute
/// path; else why not.
pub(crate) fn plain_relative(rel: &str) -> Result<Vec<&str>, &'static str> {
    if rel.starts_with('/') || Path::new(rel).is_absolute() {
        return Err("an absolute path");
    }
    let parts: Vec<&str> = rel.split('/').collect();
    if parts
        .iter()
        .any(|c| c.is_empty() || *c == "." || *c == "..")
    {
        return Err("a path with `..`, `.` or an empty component");
    }
    Ok(parts)
}

/// Opens the file `rel` (a manifest's `/`-separated path) of the previous run's `folder` for
/// reading, only where it is a regular file inside the folder: a plain relative path
/// ([`plain_relative`]), no symbolic link on the way or at the end (every component's
/// `symlink_metadata`, the last opened with `O_NOFOLLOW | O_NONBLOCK`), the opened file the
/// regular file found, and its canonical path inside the folder's at the moment of use. A
/// named pipe or a device is never opened, so it cannot hang the run. The nightly's own
/// containment check (merge has its own; to be unified).
pub(crate) fn open_previous_file(
    folder: &Path,
    rel: &str,
) -> Result<(std::fs::File, std::fs::Metadata), PreviousError> {
    let path = folder.join(rel);
    let parts = plain_relative(rel).map_err(|why| PreviousError::Outside {
        path: path.clone(),
        why,
    })?;
    let mut cur = folder.to_path_buf();
    let mut found = None;
    for (i, c) in parts.iter().enumerate() {
        cur.push(c);
        let meta = match std::fs::symlink_metadata(&cur) {
            Ok(m) => m,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
                return Err(PreviousError::Missing { path })
            }
            Err(source) => return Err(PreviousError::Io { path: cur, source }),
        };
        let (ft, last) = (meta.file_type(), i + 1 == parts.len());
        if !last && ft.is_symlink() {
            return Err(PreviousError::Outside {
                path,
                why: "a symbolic link on the way",
            });
        }
        if (!last && !ft.is_dir()) || (last && !ft.is_file()) {
            return Err(PreviousError::NotRegular {
                path: if last { path } else { cur },
                kind: kind_of(ft),
            });
        }
        found = Some(meta);
    }
    let file = open_nofollow(&path).map_err(|source| match source.raw_os_error() {
        #[cfg(unix)]
        Some(libc::ELOOP) => PreviousError::NotRegular {
            path: path.clone(),
            kind: "a symbolic link",
        },
        _ => PreviousError::Io {
            path: path.clone(),
            source,
        },
    })?;
    let meta = file.metadata().map_err(io(&path))?;
    if !meta.is_file() || !found.is_some_and(|f| same_file(&f, &meta)) {
        return Err(PreviousError::NotRegular {
            path,
            kind: "replaced while it was opened",
        });
    }
    let inside = match (std::fs::canonicalize(&path), std::fs::canonicalize(folder)) {
        (Ok(p), Ok(f)) => p.starts_with(f),
        _ => false,
    };
    if !inside {
        return Err(PreviousError::Outside {
            path,
            why: "its canonical path leaves the folder",
        });
    }
    Ok((file, meta))
}

/// The size and SHA-256 (hex) of what is left to read of `f`, read in 1 MiB blocks, each
/// also handed to `each` (to copy it).
fn hash_reader(
    f: &mut std::fs::File,
    mut each: impl FnMut(&[u8]) -> std::io::Result<()>,
) -> std::io::Result<(u64, String)> {
    let mut h = Sha256::new();
    let mut n = 0u64;
    let mut buf = vec![0u8; 1 << 20];
    loop {
        let k = f.read(&mut buf)?;
        if k == 0 {
            break;
        }
        h.update(&buf[..k]);
        n += k as u64;
        each(&buf[..k])?;
    }
    Ok((n, crate::fsio::hex(&h.finalize())))
}

/// Whether the file `rel` of the previous run's `folder` is still what its manifest lists
/// (`bytes`, `sha256`): a regular file inside the folder ([`open_previous_file`]) with that
/// size and SHA-256. An update in place removes only such files, never one put there since.
pub(crate) fn still_listed(folder: &Path, rel: &str, bytes: u64, sha256: &str) -> bool {
    let Ok((mut f, meta)) = open_previous_file(folder, rel) else {
        return false;
    };
    meta.len() == bytes
        && hash_reader(&mut f, |_| Ok(())).is_ok_and(|(n, got)| n == bytes && got == sha256)
}

/// `Err` unless `n` bytes of SHA-256 `got` (read from `src`) are the `bytes` and `sha256` its
/// manifest lists.
fn matches(src: &Path, n: u64, got: &str, bytes: u64, sha256: &str) -> Result<(), PreviousError> {
    if n == bytes && got == sha256 {
        return Ok(());
    }
    Err(PreviousError::Mismatch {
        path: src.to_path_buf(),
        bytes: n,
        sha256: got.to_string(),
        listed_bytes: bytes,
        listed_sha256: sha256.to_string(),
    })
}

/// The [`PreviousError::Io`] of `path`.
fn io(path: &Path) -> impl FnOnce(std::io::Error) -> PreviousError + '_ {
    move |source| PreviousError::Io {
        path: path.to_path_buf(),
        source,
    }
}

/// Checks the file `rel` of the previous run's `folder` (opened only where it is a regular file
/// inside it, [`open_previous_file`]) against its manifest's `bytes` and `sha256` and brings it
/// to `dst`: copied to a temporary beside `dst` (returned closed, to be renamed over `dst` with
/// the run's other files), or with `link` hard-linked there (copied when it cannot be: another
/// file system, or a system without links). `Ok(None)` when `dst` is that file itself (a run
/// updating its own folder) and it checks out. `Err` says why it is not reused.
pub(crate) fn copy_checked(
    folder: &Path,
    rel: &str,
    dst: &Path,
    (bytes, sha256): (u64, &str),
    link: bool,
) -> Result<Option<crate::fsio::PendingFile>, PreviousError> {
    let src = folder.join(rel);
    let (mut input, meta) = open_previous_file(folder, rel)?;
    let same = std::fs::symlink_metadata(dst).is_ok_and(|d| same_file(&d, &meta));
    if same || link {
        let (n, got) = hash_reader(&mut input, |_| Ok(())).map_err(io(&src))?;
        matches(&src, n, &got, bytes, sha256)?;
        if same {
            return Ok(None);
        }
        if let Ok(p) = crate::fsio::PendingFile::link(&src, dst) {
            // The link is of the file checked (not of what a swapped path names now).
            let linked = std::fs::symlink_metadata(p.temporary())
                .is_ok_and(|m| m.is_file() && same_file(&m, &meta));
            if linked {
                return Ok(Some(p));
            }
        }
        input.seek(SeekFrom::Start(0)).map_err(io(&src))?;
    }
    let out = crate::fsio::AtomicFile::create(dst).map_err(io(dst))?;
    let mut w = out.writer().map_err(io(dst))?;
    let mut failed_write = None;
    let read = hash_reader(&mut input, |b| {
        w.write_all(b)
            .inspect_err(|e| failed_write = Some(e.kind()))
    });
    let (n, got) = match (read, failed_write) {
        (Ok(r), _) => r,
        (Err(e), Some(_)) => return Err(io(dst)(e)),
        (Err(e), None) => return Err(io(&src)(e)),
    };
    matches(&src, n, &got, bytes, sha256)?;
    w.flush().map_err(io(dst))?;
    drop(w);
    out.close().map(Some).map_err(io(dst))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_regular_files_inside_the_folder_are_opened() {
        let tmp = tempfile::tempdir().unwrap();
        let (dir, out) = (tmp.path().join("prev"), tmp.path().join("outside"));
        std::fs::create_dir_all(dir.join("3d/content")).unwrap();
        std::fs::create_dir_all(&out).unwrap();
        std::fs::write(dir.join("3d/content/a.glb"), b"tile").unwrap();
        std::fs::write(out.join("b.glb"), b"secret").unwrap();
        std::os::unix::fs::symlink(out.join("b.glb"), dir.join("link.glb")).unwrap();
        std::os::unix::fs::symlink(&out, dir.join("3d/away")).unwrap();
        let fifo = std::process::Command::new("mkfifo")
            .arg(dir.join("pipe.glb"))
            .status()
            .unwrap();
        assert!(fifo.success());
        let (mut f, meta) = open_previous_file(&dir, "3d/content/a.glb").unwrap();
        assert_eq!(meta.len(), 4);
        assert_eq!(hash_reader(&mut f, |_| Ok(())).unwrap().0, 4);
        let err = |rel: &str| open_previous_file(&dir, rel).unwrap_err().to_string();
        assert!(
            err("link.glb").contains("symbolic link"),
            "{}",
            err("link.glb")
        );
        assert!(err("3d/away/b.glb").contains("symbolic link on the way"));
        assert!(err("pipe.glb").contains("named pipe"));
        assert!(err("3d/content").contains("a folder"));
        assert!(err("../outside/b.glb").contains("outside the --previous folder"));
        assert!(err("3d/./content/a.glb").contains("outside"));
        assert!(err(&out.join("b.glb").display().to_string()).contains("absolute"));
        assert!(err("gone.glb").contains("tile file missing"));
        // The error names the path as the folder was given.
        assert!(err("pipe.glb").starts_with(&dir.join("pipe.glb").display().to_string()));
    }
}
