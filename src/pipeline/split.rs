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
//!   street (by its segments) within `halo` metres of what the shard needs (their nodes, ways
//!   and relations with their members), every node carrying `addr:street` there (address and
//!   entrance nodes name a building's street), and every admin boundary of the input. What a
//!   shard needs is its tiles, each as far as its own buildings reach, and the buildings of
//!   other shards whose *final* estimate one of its buildings takes: those within
//!   `NEIGHBOUR_MARGIN_M` of it (party walls, what a LOD3 facade looks at) and every member
//!   of a row (touching lots, followed to the row's ends) one of those is in. The halo
//!   ([`DEFAULT_HALO_M`]) is how far another building decides something of a building's
//!   estimate: its tagged neighbours within 500 m vote with their residuals, which their own
//!   density windows (up to 707 m around them) decide; colours (300 m), fronts (50 m) and
//!   the zones' boundaries lie within it. A run has no whole-input statistic past these: the
//!   estimator fits no model of its own in a run (only `citygen eval --fit` does), and the
//!   report's whole-input lines travel in the head.
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
use crate::prepare::full_bounds;
use crate::report::Report;

/// The head's `format` value.
pub(crate) const SPLIT_FORMAT: &str = "citygen-split/1";

/// The most shards one split writes (a part's membership is a 64-bit mask).
pub const MAX_SPLIT_SHARDS: usize = 64;

/// The default halo (metres): as far as another building decides something of a building's
/// estimate (its tagged neighbours within 500 m, whose residuals are taken after their local
/// form, like lots within 100 m of them, whose own density windows look up to 707 m around
/// them: 1,307 m, `estimate::REACH_M`), rounded up to 1,350 m. Colours (300 m), fronts
/// (50 m) and touching neighbours lie within it; rows are followed to their ends whatever
/// their length (module docs).
pub const DEFAULT_HALO_M: f64 = 1350.0;
const _: () = assert!(DEFAULT_HALO_M >= crate::prepare::estimate::REACH_M);
const _: () = assert!(DEFAULT_HALO_M >= crate::prepare::FRONT_MAX_DISTANCE);

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

    // Each lot's shards: its tile's, and every shard one of whose *needs* lies within the
    // halo (`Needs`): its tiles (as far as their own buildings reach), and the buildings of
    // other shards whose estimates it takes (touching neighbours, rows).
    let own: Vec<usize> = site
        .lots
        .iter()
        .map(|l| grid.shard_of(site.crs, l))
        .collect();
    let boxes: Vec<Option<(DVec2, DVec2)>> = site
        .lots
        .iter()
        .map(|l| {
            // With the point that places the lot in its tile (its ring's mean, which a repair
            // may leave outside the outline).
            let (x, y) = site.crs.from_lonlat(l.lonlat.0, l.lonlat.1);
            let p = DVec2::new(x, y);
            let (lo, hi) = full_bounds(l)?;
            let (lo, hi) = (lo + site.origin, hi + site.origin);
            Some(if p.is_finite() {
                (lo.min(p), hi.max(p))
            } else {
                (lo, hi)
            })
        })
        .collect();
    let mut needs = Needs::new(f64::from(size), halo_m);
    for (cell, &s) in &grid.cells() {
        let lo = DVec2::new(cell.0 as f64, cell.1 as f64) * f64::from(size);
        needs.add(*cell, lo, lo + DVec2::splat(f64::from(size)), 1 << s);
    }
    for ((lot, b), &s) in site.lots.iter().zip(&boxes).zip(&own) {
        if let Some((lo, hi)) = b {
            let cell = crate::prepare::tile_cell(site.crs, lot, size);
            needs.add(cell, *lo, *hi, 1 << s);
        }
    }
    // The buildings whose final estimate a shard takes: its own, their neighbours within
    // `NEIGHBOUR_MARGIN_M` (party walls, what a LOD3 facade looks at), and every member of
    // a row one of those is in (rows share one estimate). Each, where it is another shard's,
    // needs its own reach in the part too.
    let mut finals: Vec<u64> = own.iter().map(|&s| 1u64 << s).collect();
    {
        use rstar::primitives::{GeomWithData, Rectangle};
        use rstar::{RTree, AABB};
        let margin = super::incremental::NEIGHBOUR_MARGIN_M;
        let tree = RTree::bulk_load(
            boxes
                .iter()
                .enumerate()
                .filter_map(|(i, b)| {
                    b.map(|(lo, hi)| {
                        GeomWithData::new(Rectangle::from_corners(lo.to_array(), hi.to_array()), i)
                    })
                })
                .collect(),
        );
        // Two lots of different shards within the margin: one of them comes within the margin
        // of its own tile's edge (else both lie inside one tile), so only those look.
        let sz = f64::from(size);
        for (i, (lot, b)) in site.lots.iter().zip(&boxes).enumerate() {
            let Some((lo, hi)) = b else {
                continue;
            };
            let cell = crate::prepare::tile_cell(site.crs, lot, size);
            let corner = DVec2::new(cell.0 as f64, cell.1 as f64) * sz;
            let (a, z) = (*lo - DVec2::splat(margin), *hi + DVec2::splat(margin));
            if a.cmpgt(corner).all() && z.cmplt(corner + DVec2::splat(sz)).all() {
                continue;
            }
            for g in
                tree.locate_in_envelope_intersecting(AABB::from_corners(a.to_array(), z.to_array()))
            {
                let j = g.data;
                if own[j] != own[i] {
                    finals[j] |= 1 << own[i];
                    finals[i] |= 1 << own[j];
                }
            }
        }
    }
    let touching = std::mem::take(&mut run.touching);
    let mut parent: Vec<usize> = (0..site.lots.len()).collect();
    let find = |p: &mut Vec<usize>, mut i: usize| {
        while p[i] != i {
            p[i] = p[p[i]];
            i = p[i];
        }
        i
    };
    for &(a, b, _) in &touching {
        let (ra, rb) = (find(&mut parent, a as usize), find(&mut parent, b as usize));
        if ra != rb {
            parent[ra.max(rb)] = ra.min(rb);
        }
    }
    drop(touching);
    let roots: Vec<usize> = (0..site.lots.len()).map(|i| find(&mut parent, i)).collect();
    let mut row_mask = vec![0u64; site.lots.len()];
    for (i, &r) in roots.iter().enumerate() {
        row_mask[r] |= finals[i];
    }
    for (i, &r) in roots.iter().enumerate() {
        finals[i] |= row_mask[r];
    }
    drop((parent, roots, row_mask));
    for (i, b) in boxes.iter().enumerate() {
        let extra = finals[i] & !(1u64 << own[i]);
        if let (Some((lo, hi)), true) = (b, extra != 0) {
            needs.add(needs.cell(*lo), *lo, *hi, extra);
        }
    }
    drop(finals);
    needs.finish();
    // Elements by (kind, id): 0 node, 1 way, 2 relation.
    let mut want: HashMap<(u8, i64), u64> = HashMap::new();
    let key = |id: SourceId| match id {
        SourceId::Way(w) => Some((1u8, w)),
        SourceId::Relation(r) => Some((2u8, r)),
        _ => None,
    };
    let mut counts = vec![(0usize, 0usize, 0u64); shards];
    for ((lot, &o), b) in site.lots.iter().zip(&own).zip(&boxes) {
        let Some((lo, hi)) = b else {
            continue;
        };
        let m = needs.mask(*lo, *hi) | 1 << o;
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
    drop(boxes);
    // Street nodes are placed by the node's own position.
    let node_mask = |lon: f64, lat: f64| -> u64 {
        let (x, y) = site.crs.from_lonlat(lon, lat);
        if !(x.is_finite() && y.is_finite()) {
            return 0;
        }
        let p = DVec2::new(x, y);
        needs.mask(p, p)
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
    let mut node_at: Vec<Option<DVec2>> = vec![None; street_nodes.len()];
    osmpbf::ElementReader::from_path(input)
        .map_err(pbf_err)?
        .for_each(|e| {
            let (id, lon, lat) = match e {
                osmpbf::Element::DenseNode(n) => (n.id(), n.lon(), n.lat()),
                osmpbf::Element::Node(n) => (n.id(), n.lon(), n.lat()),
                _ => return,
            };
            if let Ok(i) = street_nodes.binary_search(&id) {
                let (x, y) = site.crs.from_lonlat(lon, lat);
                node_at[i] = (x.is_finite() && y.is_finite()).then(|| DVec2::new(x, y));
            }
        })
        .map_err(pbf_err)?;
    // Each street to every shard that needs one of its segments (a straight road's nodes
    // may lie far apart, on either side of a shard's tiles).
    for (id, refs) in &streets {
        let at: Vec<DVec2> = refs
            .iter()
            .filter_map(|r| street_nodes.binary_search(r).ok())
            .filter_map(|i| node_at[i])
            .collect();
        let m = match at.as_slice() {
            [p] => needs.mask(*p, *p),
            _ => at
                .windows(2)
                .fold(0, |m, w| m | needs.mask(w[0].min(w[1]), w[0].max(w[1]))),
        };
        if m != 0 {
            *want.entry((1, *id)).or_default() |= m;
        }
    }
    drop((streets, street_nodes, node_at));
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

    // The heads: each shard's share of the report, as a shard of the whole input makes it
    // (the run's entries, then a note for every lot its neighbours changed, in lot order;
    // each kept by the shard owning its building, with its place in that list), the list
    // made and cut once for all shards.
    let owner: std::collections::BTreeMap<String, usize> = site
        .lots
        .iter()
        .zip(&own)
        .map(|(l, &s)| (l.id.to_string(), s))
        .collect();
    let notes = site.lots.iter().filter_map(|lot| {
        run.inferred_notes
            .get(&lot.id)
            .map(|n| crate::report::Entry {
                id: lot.id.to_string(),
                outcome: crate::report::Outcome::Note,
                reason: n.clone(),
            })
    });
    let mut entries: Vec<Vec<(usize, crate::report::Entry)>> = vec![Vec::new(); shards];
    for (k, e) in std::mem::take(&mut run.report.entries)
        .into_iter()
        .chain(notes)
        .enumerate()
    {
        let o = shard::owner_of(&e, &owner);
        if let Some(list) = entries.get_mut(o) {
            list.push((k, e));
        }
    }
    drop(owner);
    let mut heads = Vec::new();
    for (i, c) in counts.iter().enumerate() {
        let s = shard::Shard {
            index: i,
            count: shards,
        };
        grid.set_index(i);
        let mut report = run.report.clone();
        super::count_boundary_zones(&run.generator, &site.lots, |k| own[k] == i, &mut report);
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
        // No entries: `manifest_head` cuts none, and the shard's are set below.
        let mut head = grid.manifest_head(rk, &(s, String::new()), site, &mut report)?;
        head.report.prepared = std::mem::take(&mut entries[i]);
        report.entries = head
            .report
            .prepared
            .iter()
            .map(|(_, e)| e.clone())
            .collect();
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

/// A box (lower-left, upper-right corner) and the shards that need what lies within the halo
/// of it.
type NeedBox = (DVec2, DVec2, u64);

/// What the shards need around them (output CRS metres): boxes, each with the shards that
/// need everything within the halo of it, kept per grid cell of the run's tile size; boxes
/// of one cell and the same shards are merged into their union (a superset: the halo of a
/// union holds the halo of each).
struct Needs {
    size: f64,
    halo: f64,
    merged: HashMap<((i64, i64), u64), (DVec2, DVec2)>,
    cells: HashMap<(i64, i64), Vec<NeedBox>>,
    /// How far a box reaches below its cell's corner, and above it.
    below: f64,
    above: f64,
}

impl Needs {
    fn new(size: f64, halo: f64) -> Needs {
        Needs {
            size,
            halo,
            merged: HashMap::new(),
            cells: HashMap::new(),
            below: 0.0,
            above: 0.0,
        }
    }

    fn cell(&self, p: DVec2) -> (i64, i64) {
        (
            (p.x / self.size).floor() as i64,
            (p.y / self.size).floor() as i64,
        )
    }

    /// Shards `bits` need what lies within the halo of the box (`lo`, `hi`), kept in `cell`.
    fn add(&mut self, cell: (i64, i64), lo: DVec2, hi: DVec2, bits: u64) {
        let e = self.merged.entry((cell, bits)).or_insert((lo, hi));
        e.0 = e.0.min(lo);
        e.1 = e.1.max(hi);
    }

    /// Done adding.
    fn finish(&mut self) {
        for ((cell, bits), (lo, hi)) in std::mem::take(&mut self.merged) {
            let corner = DVec2::new(cell.0 as f64, cell.1 as f64) * self.size;
            self.below = self.below.max((corner - lo).max_element());
            self.above = self.above.max((hi - corner).max_element());
            self.cells.entry(cell).or_default().push((lo, hi, bits));
        }
    }

    /// The shards that need the box (`lo`, `hi`): those with a box within the halo of it.
    fn mask(&self, lo: DVec2, hi: DVec2) -> u64 {
        let c0 = self.cell(lo - DVec2::splat(self.halo + self.above));
        let c1 = self.cell(hi + DVec2::splat(self.halo + self.below));
        let mut m = 0u64;
        for cx in c0.0..=c1.0 {
            for cy in c0.1..=c1.1 {
                for (a, b, bits) in self.cells.get(&(cx, cy)).into_iter().flatten() {
                    if m & bits == *bits {
                        continue;
                    }
                    let d = (*a - hi).max(lo - *b).max(DVec2::ZERO);
                    if d.length() <= self.halo {
                        m |= bits;
                    }
                }
            }
        }
        m
    }
}
