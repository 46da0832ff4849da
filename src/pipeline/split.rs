//! `citygen split`: an OSM PBF cut into the parts the shards of a tiled run read (issue 46).
//!
//! The split reads and prepares the whole input once, as every shard of the run does
//! (`super::RunState::prepare`: output CRS, origin, fronts, inference), computes the run's
//! tile grid and its assignment of tiles to shards (`super::plan::GridPlan`,
//! `super::shard::assign`), and writes per shard `part-I-of-N.osm.pbf` and its head
//! `part-I-of-N.split.json`:
//!
//! - the PBF holds, copied element for element from the input (same ids, tags, coordinates,
//!   order), every building of the shard's tiles and the **halo**: every building, part and
//!   street within `halo` metres of one of its tiles (their nodes, ways and relations with
//!   their members), every node carrying `addr:street` there (address and entrance nodes
//!   name a building's street), and every admin boundary of the input. The halo is what the shard's
//!   buildings take from outside their tile: tagged neighbours for the estimator (500 m; their
//!   own features look 250 m further), touching neighbours (party walls, rows), the nearest
//!   street for the front (50 m), the boundaries for the zones.
//! - the head ([`SplitHead`]) holds what a shard cannot know from its part: the original
//!   input's name, size and SHA-256 (its manifest names the input the run read), the CRS and
//!   origin of the whole input, the whole grid with each tile's shard, and the shard's share
//!   of the read and prepare stages' report (counts and entries, as a shard of the whole
//!   input computes them).
//!
//! A shard run given the part (`--osm part-I-of-N.osm.pbf --split-part part-I-of-N.split.json
//! --shard I/N`) takes these from the head and derives its tiles from the part: its files and
//! manifest are those of the same shard run on the whole input, byte for byte, so `merge` is
//! unchanged (`tests/it/split.rs`).

use std::collections::HashMap;
use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};
use std::time::Instant;

use glam::DVec2;
use serde::{Deserialize, Serialize};

use super::plan::GridPlan;
use super::{shard, Options, RunError, RunState, Source, Targets};
use crate::crs::Crs;
use crate::input::osm::pbf_write::{MemberKind, PbfWriter};
use crate::model::SourceId;
use crate::report::Report;

/// The head's `format` value.
pub(crate) const SPLIT_FORMAT: &str = "citygen-split/1";

/// The most shards one split writes (a part's membership is a 64-bit mask).
pub const MAX_SPLIT_SHARDS: usize = 64;

/// The default halo (metres): the estimator's neighbours (500 m) and their own surroundings
/// (250 m), with room for rows of touching buildings.
pub const DEFAULT_HALO_M: f64 = 1000.0;

/// What a shard reads beside its part ([`crate::pipeline::split`]).
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct SplitHead {
    /// `SPLIT_FORMAT`.
    pub format: String,
    /// citygen's version.
    pub citygen: String,
    /// The shard the part is for.
    pub shard: shard::Shard,
    /// The part's PBF, a file name beside the head.
    pub part: String,
    /// The input that was split: its name, size and SHA-256 (the shard's manifest names it).
    pub(crate) inputs: Vec<shard::FileKey>,
    /// The source's name written into the outputs (the input's file name, or --source-name).
    pub source_name: String,
    /// The options the split was run with that decide the grid and the preparation (KB,
    /// --infer, --crs, --src-crs); a shard run with others is refused.
    pub options: String,
    /// The output CRS's EPSG code.
    pub epsg: u32,
    /// The whole input's origin in the output CRS.
    pub origin: [f64; 2],
    /// `--tile`.
    pub tile_size: u32,
    /// The halo, metres.
    pub halo_m: f64,
    /// The whole grid, each tile with its shard.
    pub grid: shard::Grid,
    /// The buildings of the shard's tiles, and of the halo, in the part.
    pub lots_own: usize,
    /// The buildings of the halo in the part.
    pub lots_halo: usize,
    /// The shard's share of the read and prepare stages (its manifest's `report`).
    pub(crate) share: shard::ShardReport,
    /// The shard's report as it stands when the shard starts deriving.
    pub(crate) report: Report,
}

/// A node as copied: id, latitude and longitude in nanodegrees, tags.
type CopiedNode<'a> = (i64, i64, i64, Vec<(&'a str, &'a str)>);

/// What [`split`] did.
#[derive(Debug)]
pub struct SplitSummary {
    /// The heads written, one per shard.
    pub heads: Vec<PathBuf>,
    /// Per shard: buildings of its tiles, buildings of its halo, bytes of its PBF.
    pub parts: Vec<(usize, usize, u64)>,
    /// Buildings of the input (after preparation).
    pub lots: usize,
    /// Wall time.
    pub elapsed: std::time::Duration,
}

/// The options string a head records and a shard run must match.
pub(crate) fn options_key(opts: &Options) -> Result<String, RunError> {
    let kb = match &opts.kb {
        Some(p) => {
            shard::file_key(p)
                .map_err(|e| RunError::Input(format!("{}: {e}", p.display())))?
                .sha256
        }
        None => "-".into(),
    };
    let rules = match &opts.rules {
        Some(p) => {
            shard::file_key(p)
                .map_err(|e| RunError::Input(format!("{}: {e}", p.display())))?
                .sha256
        }
        None => "-".into(),
    };
    Ok(format!(
        "kb={kb} rules={rules} crs={:?} src_crs={:?} infer={:?} tile={:?}",
        opts.crs.map(|c| c.to_string()),
        opts.src_crs.map(|c| c.to_string()),
        opts.infer,
        opts.tile,
    ))
}

/// Reads a head and checks it against the run's options (the shard, the options).
pub(crate) fn load_head(path: &Path, opts: &Options) -> Result<SplitHead, RunError> {
    let text = std::fs::read_to_string(path)
        .map_err(|e| RunError::Input(format!("{}: {e}", path.display())))?;
    let head: SplitHead = serde_json::from_str(&text)
        .map_err(|e| RunError::Input(format!("{}: not a split head: {e}", path.display())))?;
    let bad = |why: String| {
        Err(RunError::Usage(format!(
            "--split-part {}: {why}",
            path.display()
        )))
    };
    if head.format != SPLIT_FORMAT || head.citygen != env!("CARGO_PKG_VERSION") {
        return bad(format!(
            "written by citygen {} ({}), this is {} ({SPLIT_FORMAT}): split again",
            head.citygen,
            head.format,
            env!("CARGO_PKG_VERSION")
        ));
    }
    match &opts.shard {
        Some((s, _)) if *s == head.shard => {}
        _ => {
            return bad(format!(
                "the part is shard {}: pass --shard {}",
                head.shard, head.shard
            ))
        }
    }
    let mine = options_key(opts)?;
    if mine != head.options {
        return bad(format!(
            "split with other options ({}) than this run's ({mine})",
            head.options
        ));
    }
    for (what, given) in [
        ("--bbox", opts.bbox.is_some()),
        ("--osc", opts.osc.is_some()),
        ("--previous", opts.previous.is_some()),
        ("--dem", !opts.dem.is_empty()),
        ("--ground-height", opts.ground_height.is_some()),
    ] {
        if given {
            return bad(format!("{what} is not supported with a split part yet"));
        }
    }
    if let Source::Osm(p) = &opts.source {
        if p.file_name().map(|n| n.to_string_lossy().into_owned()) != Some(head.part.clone()) {
            return bad(format!(
                "its PBF is {}, not {}",
                head.part,
                crate::pipeline::file_name(p)
            ));
        }
    } else {
        return bad("a split part is an --osm input".into());
    }
    Ok(head)
}

impl SplitHead {
    /// The output CRS.
    pub(crate) fn crs(&self) -> Result<Crs, RunError> {
        Crs::from_epsg_str(&format!("EPSG:{}", self.epsg))
            .map_err(|e| RunError::Input(format!("split head: {e}")))
    }
}

/// Splits `opts.source` (an OSM PBF) into `shards` parts in `out` (see the module docs).
pub fn split(
    opts: &Options,
    shards: usize,
    halo_m: f64,
    out: &Path,
) -> Result<SplitSummary, RunError> {
    let start = Instant::now();
    let Source::Osm(input) = &opts.source else {
        return Err(RunError::Usage("citygen split reads an --osm PBF".into()));
    };
    let Some(size) = opts.tile else {
        return Err(RunError::Usage("citygen split needs --tile METRES".into()));
    };
    if shards == 0 || shards > MAX_SPLIT_SHARDS {
        return Err(RunError::Usage(format!(
            "citygen split: --shards {shards} is not between 1 and {MAX_SPLIT_SHARDS}"
        )));
    }
    if !(halo_m.is_finite() && halo_m >= 0.0) {
        return Err(RunError::Usage(format!(
            "--halo {halo_m} is not a distance"
        )));
    }
    if opts.bbox.is_some() || opts.osc.is_some() {
        return Err(RunError::Usage(
            "citygen split: --bbox and --osc are not supported yet".into(),
        ));
    }
    std::fs::create_dir_all(out).map_err(|e| RunError::Input(format!("{}: {e}", out.display())))?;
    let options = options_key(opts)?;
    let input_key =
        shard::file_key(input).map_err(|e| RunError::Input(format!("{}: {e}", input.display())))?;

    // Read and prepare as every shard of the run does.
    let targets = Targets {
        ifc: None,
        ifc_schema: opts.ifc_schema,
        ifc_max_bytes: None,
        citygml: None,
        gltf: None,
        cityjson: None,
        cityjsonseq: None,
        report: None,
        preview: None,
        tiles3d: None,
        dry_run: true,
        textures: false,
        allow_empty: true,
        manifest: None,
        terrain: None,
    };
    let one = (shard::Shard::ONE, String::new());
    let mut run = RunState::prepare(opts, targets, one, Instant::now())?;
    // No terrain (refused with a part): the report says so as the shard's does.
    run.seat(None)?;
    let site = &run.site;
    let all = vec![true; site.lots.len()];
    let mut grid = GridPlan::new(
        site,
        size,
        &all,
        shard::Shard {
            index: 0,
            count: shards,
        },
    );

    // Each lot's shards: its tile's, and every shard with a tile within the halo.
    let own: Vec<usize> = site
        .lots
        .iter()
        .map(|l| grid.shard_of(site.crs, l))
        .collect();
    let tiles = grid.cells();
    let ring = (halo_m / f64::from(size)).ceil() as i64;
    let sz = f64::from(size);
    let mask_of = |lo: DVec2, hi: DVec2| -> u64 {
        let mut m = 0u64;
        let (c0, c1) = (
            ((lo.x / sz).floor() as i64, (lo.y / sz).floor() as i64),
            ((hi.x / sz).floor() as i64, (hi.y / sz).floor() as i64),
        );
        for cx in c0.0 - ring..=c1.0 + ring {
            for cy in c0.1 - ring..=c1.1 + ring {
                let Some(&s) = tiles.get(&(cx, cy)) else {
                    continue;
                };
                if m & (1 << s) != 0 {
                    continue;
                }
                // The distance between the box and the tile.
                let (tx, ty) = (cx as f64 * sz, cy as f64 * sz);
                let dx = (tx - hi.x).max(lo.x - (tx + sz)).max(0.0);
                let dy = (ty - hi.y).max(lo.y - (ty + sz)).max(0.0);
                if dx.hypot(dy) <= halo_m {
                    m |= 1 << s;
                }
            }
        }
        m
    };
    // Elements by (kind, id): 0 node, 1 way, 2 relation.
    let mut want: HashMap<(u8, i64), u64> = HashMap::new();
    let key = |id: SourceId| match id {
        SourceId::Way(w) => Some((1u8, w)),
        SourceId::Relation(r) => Some((2u8, r)),
        _ => None,
    };
    let mut counts = vec![(0usize, 0usize, 0u64); shards];
    for (lot, &o) in site.lots.iter().zip(&own) {
        let Some((lo, hi)) = lot.bounds() else {
            continue;
        };
        let m = mask_of(lo + site.origin, hi + site.origin) | 1 << o;
        counts[o].0 += 1;
        for (s, c) in counts.iter_mut().enumerate() {
            if s != o && m & (1 << s) != 0 {
                c.1 += 1;
            }
        }
        for id in std::iter::once(lot.id).chain(lot.parts.iter().map(|p| p.id)) {
            if let Some(k) = key(id) {
                *want.entry(k).or_default() |= m;
            }
        }
    }
    // Street nodes are placed by the node's own position.
    let node_mask = |lon: f64, lat: f64| -> u64 {
        let (x, y) = site.crs.from_lonlat(lon, lat);
        if !(x.is_finite() && y.is_finite()) {
            return 0;
        }
        let p = DVec2::new(x, y);
        mask_of(p, p)
    };
    let everyone = if shards == 64 {
        u64::MAX
    } else {
        (1u64 << shards) - 1
    };

    // Pass 1: relations (buildings' members, every admin boundary) and streets' nodes.
    let mut streets: Vec<(i64, Vec<i64>)> = Vec::new();
    let mut rel_members: Vec<(i64, Vec<(u8, i64)>)> = Vec::new();
    let mut boundary_rels: Vec<i64> = Vec::new();
    let mut boundary_ways: Vec<i64> = Vec::new();
    let pbf_err = |e: osmpbf::Error| RunError::Input(format!("{}: {e}", input.display()));
    osmpbf::ElementReader::from_path(input)
        .map_err(pbf_err)?
        .for_each(|e| match e {
            osmpbf::Element::Way(w) => {
                if w.tags().any(|(k, _)| k == "highway") {
                    streets.push((w.id(), w.refs().collect::<Vec<i64>>()));
                }
                if w.tags()
                    .any(|(k, v)| k == "boundary" && v == "administrative")
                {
                    boundary_ways.push(w.id());
                }
            }
            osmpbf::Element::Relation(r) => {
                let members: Vec<(u8, i64)> = r
                    .members()
                    .map(|m| {
                        let k = match m.member_type {
                            osmpbf::RelMemberType::Node => 0,
                            osmpbf::RelMemberType::Way => 1,
                            osmpbf::RelMemberType::Relation => 2,
                        };
                        (k, m.member_id)
                    })
                    .collect();
                if r.tags()
                    .any(|(k, v)| k == "boundary" && v == "administrative")
                {
                    boundary_rels.push(r.id());
                    rel_members.push((r.id(), members));
                } else if want.contains_key(&(2, r.id())) {
                    rel_members.push((r.id(), members));
                }
            }
            _ => {}
        })
        .map_err(pbf_err)?;
    for id in &boundary_rels {
        *want.entry((2, *id)).or_default() |= everyone;
    }
    for id in &boundary_ways {
        *want.entry((1, *id)).or_default() |= everyone;
    }
    for (id, members) in &rel_members {
        let m = want.get(&(2, *id)).copied().unwrap_or(0);
        for k in members {
            *want.entry(*k).or_default() |= m;
        }
    }
    drop(rel_members);
    // Street nodes: their positions (pass 2), then each street to every shard one of its nodes
    // is near.
    let mut street_nodes: Vec<i64> = streets.iter().flat_map(|s| s.1.iter().copied()).collect();
    street_nodes.sort_unstable();
    street_nodes.dedup();
    let mut node_masks: Vec<u64> = vec![0; street_nodes.len()];
    osmpbf::ElementReader::from_path(input)
        .map_err(pbf_err)?
        .for_each(|e| {
            let (id, lon, lat) = match e {
                osmpbf::Element::DenseNode(n) => (n.id(), n.lon(), n.lat()),
                osmpbf::Element::Node(n) => (n.id(), n.lon(), n.lat()),
                _ => return,
            };
            if let Ok(i) = street_nodes.binary_search(&id) {
                node_masks[i] = node_mask(lon, lat);
            }
        })
        .map_err(pbf_err)?;
    for (id, refs) in &streets {
        let m = refs
            .iter()
            .filter_map(|r| street_nodes.binary_search(r).ok())
            .fold(0, |m, i| m | node_masks[i]);
        if m != 0 {
            *want.entry((1, *id)).or_default() |= m;
        }
    }
    drop((streets, street_nodes, node_masks));
    // Pass 3: the ways' nodes.
    osmpbf::ElementReader::from_path(input)
        .map_err(pbf_err)?
        .for_each(|e| {
            if let osmpbf::Element::Way(w) = e {
                if let Some(&m) = want.get(&(1, w.id())) {
                    for r in w.refs() {
                        *want.entry((0, r)).or_default() |= m;
                    }
                }
            }
        })
        .map_err(pbf_err)?;

    // Pass 4: copy.
    let name = |i: usize, ext: &str| format!("part-{i}-of-{shards}.{ext}");
    let mut writers: Vec<PbfWriter<BufWriter<File>>> = (0..shards)
        .map(|i| {
            let p = out.join(name(i, "osm.pbf"));
            File::create(&p)
                .and_then(|f| PbfWriter::new(BufWriter::new(f)))
                .map_err(|e| RunError::Input(format!("{}: {e}", p.display())))
        })
        .collect::<Result<_, _>>()?;
    let mut failed: Option<String> = None;
    let each = |m: u64,
                writers: &mut Vec<PbfWriter<BufWriter<File>>>,
                f: &mut dyn FnMut(&mut PbfWriter<BufWriter<File>>) -> std::io::Result<()>|
     -> Option<String> {
        for (s, w) in writers.iter_mut().enumerate() {
            if m & (1 << s) != 0 {
                if let Err(e) = f(w) {
                    return Some(e.to_string());
                }
            }
        }
        None
    };
    osmpbf::ElementReader::from_path(input)
        .map_err(pbf_err)?
        .for_each(|e| {
            if failed.is_some() {
                return;
            }
            let n: Option<CopiedNode<'_>> = match &e {
                osmpbf::Element::DenseNode(n) => {
                    Some((n.id(), n.nano_lat(), n.nano_lon(), n.tags().collect()))
                }
                osmpbf::Element::Node(n) => {
                    Some((n.id(), n.nano_lat(), n.nano_lon(), n.tags().collect()))
                }
                _ => None,
            };
            if let Some((id, nlat, nlon, tags)) = n {
                let mut m = want.get(&(0, id)).copied().unwrap_or(0);
                // Address and entrance nodes name a building's street (`Streets::address_points`):
                // each goes to the shards whose tiles or halo hold it.
                if tags.iter().any(|(k, _)| *k == "addr:street") {
                    m |= node_mask(nlon as f64 * 1e-9, nlat as f64 * 1e-9);
                }
                if m == 0 {
                    return;
                }
                if nlat % 100 != 0 || nlon % 100 != 0 {
                    failed = Some(format!(
                        "node/{id}: coordinates finer than 1e-7 degrees cannot be copied exactly"
                    ));
                    return;
                }
                failed = each(m, &mut writers, &mut |w| {
                    w.node_e7(id, nlon / 100, nlat / 100, &tags)
                });
                return;
            }
            match e {
                osmpbf::Element::Way(w) => {
                    let Some(&m) = want.get(&(1, w.id())) else {
                        return;
                    };
                    let tags: Vec<(&str, &str)> = w.tags().collect();
                    let refs = w.refs().collect::<Vec<i64>>();
                    failed = each(m, &mut writers, &mut |wr| wr.way(w.id(), &refs, &tags));
                }
                osmpbf::Element::Relation(r) => {
                    let Some(&m) = want.get(&(2, r.id())) else {
                        return;
                    };
                    let tags: Vec<(&str, &str)> = r.tags().collect();
                    let members: Vec<(MemberKind, i64, String)> = r
                        .members()
                        .map(|mb| {
                            let k = match mb.member_type {
                                osmpbf::RelMemberType::Node => MemberKind::Node,
                                osmpbf::RelMemberType::Way => MemberKind::Way,
                                osmpbf::RelMemberType::Relation => MemberKind::Relation,
                            };
                            (k, mb.member_id, mb.role().unwrap_or("").to_string())
                        })
                        .collect();
                    let members: Vec<(MemberKind, i64, &str)> = members
                        .iter()
                        .map(|(k, i, r)| (*k, *i, r.as_str()))
                        .collect();
                    failed = each(m, &mut writers, &mut |wr| {
                        wr.relation(r.id(), &members, &tags)
                    });
                }
                _ => {}
            }
        })
        .map_err(pbf_err)?;
    if let Some(why) = failed {
        return Err(RunError::Input(format!("{}: {why}", input.display())));
    }
    for (i, w) in writers.into_iter().enumerate() {
        let p = out.join(name(i, "osm.pbf"));
        w.finish()
            .map_err(|e| RunError::Input(format!("{}: {e}", p.display())))?;
        counts[i].2 = std::fs::metadata(&p).map(|m| m.len()).unwrap_or(0);
    }

    // The heads: each shard's share of the report, as a shard of the whole input makes it.
    let mut heads = Vec::new();
    for (i, c) in counts.iter().enumerate() {
        let s = shard::Shard {
            index: i,
            count: shards,
        };
        grid.set_index(i);
        let mut report = run.report.clone();
        super::count_boundary_zones(&run.generator, &site.lots, |k| own[k] == i, &mut report);
        for lot in &site.lots {
            if let Some(note) = run.inferred_notes.get(&lot.id) {
                report.add(Some(lot.id), crate::report::Outcome::Note, note.clone());
            }
        }
        let rk = shard::RunKey {
            inputs: Vec::new(),
            kb: None,
            kb_files: Vec::new(),
            rules: None,
            seed: 0,
            lod: 0,
            crs: String::new(),
            origin: [0.0; 2],
            tile_size: size,
            options: String::new(),
            outputs: Vec::new(),
            dems: Vec::new(),
        };
        let head = grid.manifest_head(rk, &(s, String::new()), site, &mut report)?;
        let split = SplitHead {
            format: SPLIT_FORMAT.into(),
            citygen: env!("CARGO_PKG_VERSION").into(),
            shard: s,
            part: name(i, "osm.pbf"),
            inputs: vec![input_key.clone()],
            source_name: run.source_name.clone(),
            options: options.clone(),
            epsg: site.crs.epsg(),
            origin: [site.origin.x, site.origin.y],
            tile_size: size,
            halo_m,
            grid: head.grid,
            lots_own: c.0,
            lots_halo: c.1,
            share: head.report,
            report,
        };
        let p = out.join(name(i, "split.json"));
        let text = serde_json::to_string(&split).map_err(|e| RunError::Input(e.to_string()))?;
        crate::fsio::write_atomic(&p, text.as_bytes())
            .map_err(|e| RunError::Input(format!("{}: {e}", p.display())))?;
        heads.push(p);
    }
    Ok(SplitSummary {
        heads,
        parts: counts,
        lots: site.lots.len(),
        elapsed: start.elapsed(),
    })
}
