//! A "day 2" of a tiled benchmark input with a known edit list, to test and time incremental
//! runs (`citygen --previous`, issue 25). [`make_day2`] writes into one folder:
//!
//! - `day1.osm.pbf`: the tiled input of `n` buildings, the bytes of [`super::tiled::make_tiled`];
//! - `day2.osm.pbf`: day 1 with the edits applied (day 1's elements in day 1's order, the new
//!   nodes and ways after them);
//! - `changes.osc.gz`: the gzipped osmChange (`<osmChange version="0.6" generator="citygen
//!   bench">` with one `<create>`, `<modify>` and `<delete>` block) that turns day 1 into day 2;
//! - `edits.json`: `{"added": [...], "removed": [...], "changed": [...]}`, citygen's source ids
//!   (`way/123`) sorted by number: exactly the buildings whose footprint citygen reads as added,
//!   removed or changed.
//!
//! Edits, all drawn from the seed: round(1 %) of `n` buildings changed, round(0.5 %) added and
//! round(0.5 %) removed. Only closed building ways that citygen reads as buildings are edited,
//! and only those that share no node with another way, belong to no relation and whose bounding
//! box (grown by [`PART_MARGIN_M`]) meets no `building:part`'s: a part is attached to its outline
//! by containment, so editing such an outline would change another lot. Half of the changed
//! buildings get a tag change (`building:levels` or `roof:shape`, always to a value citygen
//! parses differently), the other half a tag change and a new ring: new nodes moved 0.3 to 0.9 m
//! (a translation of 0.6 m and a uniform scale about the centroid of at most 3 % and at most
//! 0.3 m at the farthest vertex, so the ring stays simple), the old nodes deleted. A removed
//! building loses its way and its nodes. An added building is a copy of a small existing
//! footprint (4 to 6 vertices, at most 30 m across) tagged `building=yes` (every other one with
//! `building:levels`), placed at a random point of the whole area where its bounding box grown
//! by [`ADDED_CLEARANCE_M`] meets no other way's box. New node and way ids follow day 1's
//! largest.
//!
//! Edits fall anywhere ([`Spread::Uniform`]) or, as a day of OSM changesets does, in clusters
//! ([`Spread::Clustered`]: groups of [`CLUSTER_EDITS`] within [`CLUSTER_RADIUS_M`] of a centre).
//!
//! [`verify_day2`] reads both days with citygen's reader and checks the edit list against them.

use std::collections::{BTreeMap, BTreeSet, HashMap};
use std::fmt::Write as _;
use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

use anyhow::{anyhow, bail, Context, Result};
use flate2::write::GzEncoder;
use flate2::Compression;
use osmpbf::{Element, ElementReader, RelMemberType};
use serde::{Deserialize, Serialize};

use super::pbf_write::{MemberKind, PbfWriter};
use super::tiled::{make_tiled, Tiled};
use crate::input::{read_osm, BuildingTags, Footprint, FootprintKind, SourceId};
use crate::report::Report;

/// Clearance around an added building: its bounding box grown by this many metres meets no
/// other way's bounding box.
pub const ADDED_CLEARANCE_M: f64 = 3.0;

/// An edited building's bounding box grown by this many metres meets no `building:part`'s.
pub const PART_MARGIN_M: f64 = 2.0;

/// Metres per degree of latitude (the same figure as the tiled input's jitter).
const METRE_PER_DEG: f64 = 111_320.0;

/// Cell size of the bounding-box grid index, in metres.
const GRID_CELL_M: f64 = 50.0;

/// Tries to place one added building before giving up.
const PLACE_ATTEMPTS: usize = 10_000;

/// File names written by [`make_day2`].
pub(crate) const DAY1: &str = "day1.osm.pbf";
/// Day 2's PBF.
pub(crate) const DAY2: &str = "day2.osm.pbf";
/// The osmChange from day 1 to day 2.
pub(crate) const CHANGES: &str = "changes.osc.gz";
/// The edit list.
pub(crate) const EDITS: &str = "edits.json";

/// The edit list of `edits.json`: citygen source ids (`way/123`), each list sorted by number.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct EditList {
    /// Buildings of day 2 that day 1 lacks.
    pub added: Vec<String>,
    /// Buildings of day 1 that day 2 lacks.
    pub removed: Vec<String>,
    /// Buildings of both days whose tags or ring differ.
    pub changed: Vec<String>,
}

/// What [`make_day2`] wrote.
#[derive(Clone, Debug)]
pub struct Day2 {
    /// Day 1 as [`make_tiled`] made it.
    pub tiled: Tiled,
    /// Way ids of the added buildings, ascending.
    pub added: Vec<i64>,
    /// Way ids of the removed buildings, ascending.
    pub removed: Vec<i64>,
    /// Way ids of the changed buildings, ascending.
    pub changed: Vec<i64>,
    /// The changed buildings that also got a new ring, ascending.
    pub moved: Vec<i64>,
    /// Nodes created (new rings and added buildings).
    pub created_nodes: usize,
    /// Nodes deleted (of removed buildings and old rings).
    pub deleted_nodes: usize,
}

impl Day2 {
    /// Elements of the osmChange's `<create>`, `<modify>` and `<delete>` blocks.
    pub fn osc_counts(&self) -> (usize, usize, usize) {
        (
            self.created_nodes + self.added.len(),
            self.changed.len(),
            self.removed.len() + self.deleted_nodes,
        )
    }
}

/// Where the day's edits fall.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Spread {
    /// Each edit anywhere: removed and changed buildings drawn from every editable one, added
    /// buildings at random points of the whole area.
    #[default]
    Uniform,
    /// As a day of OSM changesets: edits in groups of [`CLUSTER_EDITS`], each group the
    /// editable buildings nearest to a centre (an editable building drawn at random; no
    /// farther than [`CLUSTER_RADIUS_M`]) and added buildings within that radius of a centre.
    Clustered,
}

/// Edits in one cluster of [`Spread::Clustered`] (a mapper's changeset on one street block).
pub const CLUSTER_EDITS: usize = 25;

/// Radius of one cluster of [`Spread::Clustered`], in metres.
pub const CLUSTER_RADIUS_M: f64 = 250.0;

/// Writes day 1 (`n` tiled buildings), day 2, the osmChange and the edit list into `dir` (see
/// the module documentation), with edits spread uniformly. The same `n` and `seed` give the
/// same bytes.
pub fn make_day2(n: usize, dir: &Path, seed: u64) -> Result<Day2> {
    make_day2_spread(n, dir, seed, Spread::Uniform)
}

/// [`make_day2`] with the edits spread as `spread` says.
pub fn make_day2_spread(n: usize, dir: &Path, seed: u64, spread: Spread) -> Result<Day2> {
    std::fs::create_dir_all(dir).with_context(|| format!("{}", dir.display()))?;
    let day1 = dir.join(DAY1);
    let tiled = make_tiled(n, &day1)?;
    let osm = Osm::read(&day1)?;
    let plan = plan_edits(&osm, &day1, n, seed, spread)?;
    write_day2(&osm, &plan, &dir.join(DAY2))?;
    write_osc(&osm, &plan, &dir.join(CHANGES))?;
    let edits = plan.edit_list();
    let json = serde_json::to_string_pretty(&edits)?;
    let path = dir.join(EDITS);
    std::fs::write(&path, json + "\n").with_context(|| format!("{}", path.display()))?;
    let sorted = |v: &mut Vec<i64>| {
        v.sort_unstable();
        std::mem::take(v)
    };
    let mut changed: Vec<i64> = plan.changed.keys().copied().collect();
    let mut moved: Vec<i64> = plan
        .changed
        .iter()
        .filter(|(_, c)| c.ring.is_some())
        .map(|(&id, _)| id)
        .collect();
    let mut added: Vec<i64> = plan.added.iter().map(|a| a.id).collect();
    let mut removed: Vec<i64> = plan.removed.iter().copied().collect();
    Ok(Day2 {
        tiled,
        added: sorted(&mut added),
        removed: sorted(&mut removed),
        changed: sorted(&mut changed),
        moved: sorted(&mut moved),
        created_nodes: plan.new_nodes.len(),
        deleted_nodes: plan.deleted_nodes.len(),
    })
}

/// What [`verify_day2`] found.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Verified {
    /// Footprints (buildings and parts) citygen reads from day 1.
    pub day1_footprints: usize,
    /// Footprints citygen reads from day 2.
    pub day2_footprints: usize,
    /// Changed buildings whose tags differ.
    pub tags_changed: usize,
    /// Changed buildings whose rings differ.
    pub rings_changed: usize,
}

/// Reads `day1.osm.pbf` and `day2.osm.pbf` of `dir` with citygen's reader and checks
/// `edits.json` against them: day 2's footprint ids are day 1's minus `removed` plus `added`
/// (all of them buildings), every `changed` footprint differs in tags or rings, and every other
/// footprint is the same bit for bit (kind, tags, rings).
pub fn verify_day2(dir: &Path) -> Result<Verified> {
    let path = dir.join(EDITS);
    let text = std::fs::read_to_string(&path).with_context(|| format!("{}", path.display()))?;
    let edits: EditList =
        serde_json::from_str(&text).with_context(|| format!("{}", path.display()))?;
    let ids = |list: &[String], name: &str| -> Result<BTreeSet<SourceId>> {
        list.iter()
            .map(|s| {
                SourceId::parse(s)
                    .ok_or_else(|| anyhow!("{}: {name}: bad source id {s:?}", path.display()))
            })
            .collect()
    };
    let (added, removed, changed) = (
        ids(&edits.added, "added")?,
        ids(&edits.removed, "removed")?,
        ids(&edits.changed, "changed")?,
    );
    let read = |name: &str| -> Result<BTreeMap<SourceId, Footprint>> {
        let p = dir.join(name);
        let r = read_osm(&p, &mut Report::default())?;
        let mut map = BTreeMap::new();
        for f in r.footprints {
            let id = f.id;
            if map.insert(id, f).is_some() {
                bail!("{}: footprint {id} read twice", p.display());
            }
        }
        Ok(map)
    };
    let (d1, d2) = (read(DAY1)?, read(DAY2)?);
    let building = |m: &BTreeMap<SourceId, Footprint>, id: &SourceId| {
        m.get(id).is_some_and(|f| f.kind == FootprintKind::Building)
    };
    for id in &removed {
        if !building(&d1, id) || d2.contains_key(id) {
            bail!("removed {id}: not a day-1 building, or still in day 2");
        }
    }
    for id in &added {
        if d1.contains_key(id) || !building(&d2, id) {
            bail!("added {id}: in day 1, or not a day-2 building");
        }
    }
    let (mut tags_changed, mut rings_changed) = (0, 0);
    for (id, f1) in &d1 {
        if removed.contains(id) {
            continue;
        }
        let Some(f2) = d2.get(id) else {
            bail!("{id}: in day 1, not removed, but missing from day 2");
        };
        let same_tags = f1.tags.same_bits(&f2.tags);
        let same_rings = same_polygons(f1, f2);
        if changed.contains(id) {
            if !building(&d1, id) {
                bail!("changed {id}: not a building");
            }
            tags_changed += usize::from(!same_tags);
            rings_changed += usize::from(!same_rings);
            if same_tags && same_rings {
                bail!("changed {id}: the same tags and rings on both days");
            }
        } else if f1.kind != f2.kind || !same_tags || !same_rings {
            bail!("{id}: not in the edit list, but its footprint differs on day 2");
        }
    }
    for id in &changed {
        if !d1.contains_key(id) || removed.contains(id) {
            bail!("changed {id}: not a day-1 footprint, or removed");
        }
    }
    let expected = (d1.len() + added.len()).saturating_sub(removed.len());
    if d2.len() != expected {
        bail!(
            "day 2 has {} footprints, day 1 minus removed plus added is {expected}",
            d2.len()
        );
    }
    Ok(Verified {
        day1_footprints: d1.len(),
        day2_footprints: d2.len(),
        tags_changed,
        rings_changed,
    })
}

/// The same polygons, bit for bit.
fn same_polygons(a: &Footprint, b: &Footprint) -> bool {
    let ring = |r: &[(f64, f64)], s: &[(f64, f64)]| {
        r.len() == s.len()
            && r.iter()
                .zip(s)
                .all(|(p, q)| p.0.to_bits() == q.0.to_bits() && p.1.to_bits() == q.1.to_bits())
    };
    a.polygons.len() == b.polygons.len()
        && a.polygons.iter().zip(&b.polygons).all(|(p, q)| {
            ring(&p.outer, &q.outer)
                && p.holes.len() == q.holes.len()
                && p.holes.iter().zip(&q.holes).all(|(h, k)| ring(h, k))
        })
}

// ---- day 1 in memory ----

type Tags = Vec<(String, String)>;

/// A way of day 1.
struct Way {
    id: i64,
    refs: Vec<i64>,
    tags: Tags,
}

/// A relation of day 1: (member kind, id, role).
struct Relation {
    id: i64,
    members: Vec<(MemberKind, i64, String)>,
    tags: Tags,
}

/// Every element of a PBF, in file order; node coordinates in 1e-7 degrees (lon, lat).
struct Osm {
    nodes: Vec<(i64, i32, i32)>,
    node_index: HashMap<i64, usize>,
    ways: Vec<Way>,
    relations: Vec<Relation>,
}

impl Osm {
    fn read(path: &Path) -> Result<Osm> {
        let mut osm = Osm {
            nodes: Vec::new(),
            node_index: HashMap::new(),
            ways: Vec::new(),
            relations: Vec::new(),
        };
        let tags_of = |it: &mut dyn Iterator<Item = (&str, &str)>| -> Tags {
            it.map(|(k, v)| (k.to_string(), v.to_string())).collect()
        };
        ElementReader::from_path(path)
            .and_then(|r| {
                r.for_each(|e| match e {
                    Element::Node(n) => {
                        osm.nodes
                            .push((n.id(), n.decimicro_lon(), n.decimicro_lat()))
                    }
                    Element::DenseNode(n) => {
                        osm.nodes
                            .push((n.id(), n.decimicro_lon(), n.decimicro_lat()))
                    }
                    Element::Way(w) => osm.ways.push(Way {
                        id: w.id(),
                        refs: w.refs().collect(),
                        tags: tags_of(&mut w.tags()),
                    }),
                    Element::Relation(r) => osm.relations.push(Relation {
                        id: r.id(),
                        members: r
                            .members()
                            .map(|m| {
                                let kind = match m.member_type {
                                    RelMemberType::Node => MemberKind::Node,
                                    RelMemberType::Way => MemberKind::Way,
                                    RelMemberType::Relation => MemberKind::Relation,
                                };
                                (kind, m.member_id, m.role().unwrap_or("").to_string())
                            })
                            .collect(),
                        tags: tags_of(&mut r.tags()),
                    }),
                })
            })
            .with_context(|| format!("{}: reading", path.display()))?;
        osm.node_index = osm
            .nodes
            .iter()
            .enumerate()
            .map(|(i, n)| (n.0, i))
            .collect();
        Ok(osm)
    }

    /// The (lon, lat) in 1e-7 degrees of node `id`.
    fn node(&self, id: i64) -> Option<(i32, i32)> {
        let &i = self.node_index.get(&id)?;
        self.nodes.get(i).map(|n| (n.1, n.2))
    }
}

fn tag<'a>(tags: &'a Tags, key: &str) -> Option<&'a str> {
    tags.iter().find(|(k, _)| k == key).map(|(_, v)| v.as_str())
}

fn tagged(tags: &Tags, key: &str) -> bool {
    tag(tags, key).is_some_and(|v| v.trim() != "no")
}

// ---- metres, boxes, the grid index ----

/// Local metres: x east, y north, from 1e-7 degrees, with the cosine of one latitude.
#[derive(Clone, Copy)]
struct Frame {
    kx: f64,
}

impl Frame {
    fn metres(self, (lon, lat): (i32, i32)) -> (f64, f64) {
        (
            lon as f64 * 1e-7 * METRE_PER_DEG * self.kx,
            lat as f64 * 1e-7 * METRE_PER_DEG,
        )
    }

    /// Back to 1e-7 degrees, rounded (the PBF's granularity).
    fn e7(self, (x, y): (f64, f64)) -> (i32, i32) {
        (
            (x / (METRE_PER_DEG * self.kx) * 1e7).round() as i32,
            (y / METRE_PER_DEG * 1e7).round() as i32,
        )
    }
}

/// (min x, min y, max x, max y) in metres.
type BBox = [f64; 4];

fn bbox(pts: impl IntoIterator<Item = (f64, f64)>) -> BBox {
    pts.into_iter().fold(
        [
            f64::INFINITY,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::NEG_INFINITY,
        ],
        |b, (x, y)| [b[0].min(x), b[1].min(y), b[2].max(x), b[3].max(y)],
    )
}

fn grow(b: BBox, m: f64) -> BBox {
    [b[0] - m, b[1] - m, b[2] + m, b[3] + m]
}

fn meets(a: &BBox, b: &BBox) -> bool {
    a[0] <= b[2] && b[0] <= a[2] && a[1] <= b[3] && b[1] <= a[3]
}

/// Boxes in a uniform grid of [`GRID_CELL_M`] cells; boxes covering very many cells are kept
/// aside and tested every time.
#[derive(Default)]
struct Grid {
    cells: HashMap<(i64, i64), Vec<u32>>,
    big: Vec<u32>,
    boxes: Vec<BBox>,
}

impl Grid {
    fn cell_range(b: &BBox) -> Option<(i64, i64, i64, i64)> {
        if !b.iter().all(|v| v.is_finite()) {
            return None;
        }
        let c = |v: f64| (v / GRID_CELL_M).floor() as i64;
        Some((c(b[0]), c(b[1]), c(b[2]), c(b[3])))
    }

    fn insert(&mut self, b: BBox) {
        let i = self.boxes.len() as u32;
        self.boxes.push(b);
        match Grid::cell_range(&b) {
            Some((x0, y0, x1, y1)) if (x1 - x0 + 1) * (y1 - y0 + 1) <= 4096 => {
                for cx in x0..=x1 {
                    for cy in y0..=y1 {
                        self.cells.entry((cx, cy)).or_default().push(i);
                    }
                }
            }
            _ => self.big.push(i),
        }
    }

    /// Whether a stored box meets `b` (true for a box that is not finite).
    fn hits(&self, b: &BBox) -> bool {
        let check = |i: &u32| self.boxes.get(*i as usize).is_some_and(|o| meets(o, b));
        if self.big.iter().any(check) {
            return true;
        }
        let Some((x0, y0, x1, y1)) = Grid::cell_range(b) else {
            return true;
        };
        (x0..=x1).any(|cx| {
            (y0..=y1).any(|cy| {
                self.cells
                    .get(&(cx, cy))
                    .is_some_and(|v| v.iter().any(check))
            })
        })
    }
}

// ---- the plan ----

/// A seeded splitmix64.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// In [0, 1).
    fn unit(&mut self) -> f64 {
        (self.next() >> 11) as f64 / (1u64 << 53) as f64
    }

    /// In 0..n (0 when n is 0).
    fn below(&mut self, n: usize) -> usize {
        ((self.unit() * n as f64) as usize).min(n.saturating_sub(1))
    }
}

/// A changed building: its new tags, and its new ring (node ids, closed) when it moved.
struct Change {
    tags: Tags,
    ring: Option<Vec<i64>>,
}

/// An added building.
struct Added {
    id: i64,
    refs: Vec<i64>,
    tags: Tags,
}

/// Every edit, by id.
struct Plan {
    removed: BTreeSet<i64>,
    changed: BTreeMap<i64, Change>,
    added: Vec<Added>,
    /// New nodes in id order: (id, lon, lat) in 1e-7 degrees.
    new_nodes: Vec<(i64, i32, i32)>,
    deleted_nodes: BTreeSet<i64>,
}

impl Plan {
    fn edit_list(&self) -> EditList {
        let ways = |ids: &mut dyn Iterator<Item = i64>| -> Vec<String> {
            let mut v: Vec<i64> = ids.collect();
            v.sort_unstable();
            v.into_iter()
                .map(|i| SourceId::Way(i).to_string())
                .collect()
        };
        EditList {
            added: ways(&mut self.added.iter().map(|a| a.id)),
            removed: ways(&mut self.removed.iter().copied()),
            changed: ways(&mut self.changed.keys().copied()),
        }
    }
}

/// Edit counts of `n` buildings: (changed, added, removed), 1 %, 0.5 %, 0.5 % rounded.
pub(crate) fn edit_counts(n: usize) -> (usize, usize, usize) {
    let pct = |p: f64| (n as f64 * p / 100.0).round() as usize;
    (pct(1.0), pct(0.5), pct(0.5))
}

fn plan_edits(osm: &Osm, day1: &Path, n: usize, seed: u64, spread: Spread) -> Result<Plan> {
    let (n_changed, n_added, n_removed) = edit_counts(n);
    let mut rng = Rng(seed ^ 0x6461_7932_6564_6974);
    if osm.nodes.is_empty() {
        bail!("{}: no nodes", day1.display());
    }
    // What citygen reads as a building on day 1.
    let read = read_osm(day1, &mut Report::default())?;
    let buildings: BTreeSet<i64> = read
        .footprints
        .iter()
        .filter(|f| f.kind == FootprintKind::Building)
        .filter_map(|f| match f.id {
            SourceId::Way(i) => Some(i),
            _ => None,
        })
        .collect();
    drop(read);
    let (lat0, lat1) = osm
        .nodes
        .iter()
        .fold((i32::MAX, i32::MIN), |b, n| (b.0.min(n.2), b.1.max(n.2)));
    let mid_lat = (lat0 as f64 + lat1 as f64) / 2.0 * 1e-7;
    let frame = Frame {
        kx: mid_lat.to_radians().cos(),
    };
    // Ways using each node, relation members, part boxes, every way's box.
    let mut users: HashMap<i64, u32> = HashMap::new();
    for w in &osm.ways {
        let distinct: BTreeSet<i64> = w.refs.iter().copied().collect();
        for r in distinct {
            *users.entry(r).or_default() += 1;
        }
    }
    let members: BTreeSet<i64> = osm
        .relations
        .iter()
        .flat_map(|r| r.members.iter())
        .filter(|m| m.0 == MemberKind::Way)
        .map(|m| m.1)
        .collect();
    let part_members: BTreeSet<i64> = osm
        .relations
        .iter()
        .filter(|r| tagged(&r.tags, "building:part"))
        .flat_map(|r| r.members.iter())
        .filter(|m| m.0 == MemberKind::Way)
        .map(|m| m.1)
        .collect();
    let way_box = |w: &Way| {
        bbox(
            w.refs
                .iter()
                .filter_map(|&r| osm.node(r))
                .map(|p| frame.metres(p)),
        )
    };
    let mut parts = Grid::default();
    let mut all = Grid::default();
    for w in &osm.ways {
        let b = way_box(w);
        if tagged(&w.tags, "building:part") || part_members.contains(&w.id) {
            parts.insert(b);
        }
        all.insert(b);
    }
    // Editable buildings, in id order.
    let editable: Vec<usize> = osm
        .ways
        .iter()
        .enumerate()
        .filter(|(_, w)| {
            w.refs.len() >= 4
                && w.refs.first() == w.refs.last()
                && tagged(&w.tags, "building")
                && !tagged(&w.tags, "building:part")
                && buildings.contains(&w.id)
                && !members.contains(&w.id)
                && w.refs
                    .iter()
                    .all(|r| users.get(r) == Some(&1) && osm.node(*r).is_some())
                && !parts.hits(&grow(way_box(w), PART_MARGIN_M))
        })
        .map(|(i, _)| i)
        .collect();
    if editable.len() < n_changed + n_removed {
        bail!(
            "{}: {} editable buildings, {} changes and removals asked",
            day1.display(),
            editable.len(),
            n_changed + n_removed
        );
    }
    // Shuffle (Fisher-Yates) and take the removed, then the changed ones.
    let mut order = editable.clone();
    for i in (1..order.len()).rev() {
        order.swap(i, rng.below(i + 1));
    }
    let n_clusters = (n_changed + n_removed + n_added).div_ceil(CLUSTER_EDITS);
    // Clustered: the centres are the first of the shuffled buildings; each takes its nearest
    // not yet taken (within the radius), in turns, until the removals and changes are drawn.
    let mut centres: Vec<(f64, f64)> = Vec::new();
    if spread == Spread::Clustered && n_clusters > 0 {
        let centre_of = |i: usize| {
            let b = osm.ways.get(i).map_or([0.0; 4], way_box);
            ((b[0] + b[2]) / 2.0, (b[1] + b[3]) / 2.0)
        };
        let at: Vec<(f64, f64)> = order.iter().map(|&i| centre_of(i)).collect();
        centres = at.iter().take(n_clusters).copied().collect();
        let mut near: Vec<std::vec::IntoIter<usize>> = centres
            .iter()
            .map(|c| {
                let mut by: Vec<(f64, usize)> = at
                    .iter()
                    .enumerate()
                    .map(|(k, p)| ((p.0 - c.0).hypot(p.1 - c.1), k))
                    .filter(|(d, _)| *d <= CLUSTER_RADIUS_M)
                    .collect();
                by.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
                by.into_iter()
                    .map(|(_, k)| k)
                    .collect::<Vec<_>>()
                    .into_iter()
            })
            .collect();
        let mut taken = vec![false; order.len()];
        let mut picked: Vec<usize> = Vec::new();
        let want = n_changed + n_removed;
        while picked.len() < want {
            let before = picked.len();
            for it in near.iter_mut() {
                if picked.len() == want {
                    break;
                }
                if let Some(k) = it.by_ref().find(|&k| !taken[k]) {
                    taken[k] = true;
                    picked.push(k);
                }
            }
            if picked.len() == before {
                // Every cluster is exhausted: the rest from anywhere, in shuffled order.
                picked.extend((0..order.len()).filter(|&k| !taken[k]).take(want - before));
                break;
            }
        }
        // Removals and changes mixed within each cluster: shuffle the picked ones.
        for i in (1..picked.len()).rev() {
            picked.swap(i, rng.below(i + 1));
        }
        let mut taken = vec![false; order.len()];
        for &k in &picked {
            taken[k] = true;
        }
        let rest = (0..order.len()).filter(|&k| !taken[k]).map(|k| order[k]);
        order = picked.iter().map(|&k| order[k]).chain(rest).collect();
    }
    let mut next_node = osm.nodes.iter().map(|n| n.0).max().unwrap_or(0) + 1;
    let mut next_way = osm.ways.iter().map(|w| w.id).max().unwrap_or(0) + 1;
    let mut plan = Plan {
        removed: BTreeSet::new(),
        changed: BTreeMap::new(),
        added: Vec::new(),
        new_nodes: Vec::new(),
        deleted_nodes: BTreeSet::new(),
    };
    let ring_of = |w: &Way| -> Vec<(f64, f64)> {
        let open = w.refs.get(..w.refs.len().saturating_sub(1)).unwrap_or(&[]);
        open.iter()
            .filter_map(|&r| osm.node(r))
            .map(|p| frame.metres(p))
            .collect()
    };
    for &i in order.iter().take(n_removed) {
        let Some(w) = osm.ways.get(i) else { continue };
        plan.removed.insert(w.id);
        plan.deleted_nodes.extend(w.refs.iter().copied());
    }
    for (k, &i) in order.iter().skip(n_removed).take(n_changed).enumerate() {
        let Some(w) = osm.ways.get(i) else { continue };
        let tags = new_tags(&w.tags, k / 2 % 2 == 0, &mut rng)
            .ok_or_else(|| anyhow!("{}: way/{}: no tag change found", day1.display(), w.id))?;
        let ring = if k % 2 == 1 {
            let moved = move_ring(&ring_of(w), &mut rng);
            let first = next_node;
            for p in moved {
                let (lon, lat) = frame.e7(p);
                plan.new_nodes.push((next_node, lon, lat));
                next_node += 1;
            }
            let mut refs: Vec<i64> = (first..next_node).collect();
            refs.push(first);
            plan.deleted_nodes.extend(w.refs.iter().copied());
            Some(refs)
        } else {
            None
        };
        plan.changed.insert(w.id, Change { tags, ring });
    }
    // Added buildings: copies of small editable footprints, placed at random points of the
    // whole area where they stand clear of every way.
    let shapes: Vec<Vec<(f64, f64)>> = editable
        .iter()
        .filter_map(|&i| osm.ways.get(i))
        .filter(|w| (5..=7).contains(&w.refs.len()))
        .map(|w| {
            let pts = ring_of(w);
            let b = bbox(pts.iter().copied());
            let (cx, cy) = ((b[0] + b[2]) / 2.0, (b[1] + b[3]) / 2.0);
            pts.iter()
                .map(|&(x, y)| (x - cx, y - cy))
                .collect::<Vec<_>>()
        })
        .filter(|pts: &Vec<(f64, f64)>| {
            let b = bbox(pts.iter().copied());
            b[2] - b[0] <= 30.0 && b[3] - b[1] <= 30.0
        })
        .collect();
    if shapes.is_empty() && n_added > 0 {
        bail!("{}: no small footprint to copy", day1.display());
    }
    let area = bbox(osm.nodes.iter().map(|n| frame.metres((n.1, n.2))));
    for k in 0..n_added {
        let mut placed = None;
        for _ in 0..PLACE_ATTEMPTS {
            let Some(shape) = shapes.get(rng.below(shapes.len())) else {
                break;
            };
            let centre = match spread {
                Spread::Clustered => centres.get(rng.below(centres.len())),
                Spread::Uniform => None,
            };
            let (px, py) = match centre {
                // Uniform in the cluster's disc.
                Some(c) => {
                    let r = CLUSTER_RADIUS_M * rng.unit().sqrt();
                    let a = rng.unit() * std::f64::consts::TAU;
                    (c.0 + r * a.cos(), c.1 + r * a.sin())
                }
                _ => (
                    area[0] + rng.unit() * (area[2] - area[0]),
                    area[1] + rng.unit() * (area[3] - area[1]),
                ),
            };
            let pts: Vec<(f64, f64)> = shape.iter().map(|&(x, y)| (x + px, y + py)).collect();
            let b = bbox(pts.iter().copied());
            if !all.hits(&grow(b, ADDED_CLEARANCE_M)) {
                placed = Some((pts, b));
                break;
            }
        }
        let Some((pts, b)) = placed else {
            bail!(
                "{}: no free place for added building {} after {PLACE_ATTEMPTS} tries",
                day1.display(),
                k + 1
            );
        };
        all.insert(b);
        let first = next_node;
        for p in pts {
            let (lon, lat) = frame.e7(p);
            plan.new_nodes.push((next_node, lon, lat));
            next_node += 1;
        }
        let mut refs: Vec<i64> = (first..next_node).collect();
        refs.push(first);
        let mut tags = vec![("building".to_string(), "yes".to_string())];
        if k % 2 == 0 {
            tags.push((
                "building:levels".to_string(),
                (1 + rng.below(6)).to_string(),
            ));
        }
        plan.added.push(Added {
            id: next_way,
            refs,
            tags,
        });
        next_way += 1;
    }
    Ok(plan)
}

/// `tags` with `building:levels` (`levels`) or `roof:shape` changed to a value citygen parses
/// differently; the other key when no value of the first one does.
fn new_tags(tags: &Tags, levels: bool, rng: &mut Rng) -> Option<Tags> {
    let parsed =
        |t: &Tags| BuildingTags::from_pairs(t.iter().map(|(k, v)| (k.as_str(), v.as_str())));
    let old = parsed(tags);
    let with = |key: &str, value: String| -> Tags {
        let mut t = tags.clone();
        match t.iter_mut().find(|(k, _)| k == key) {
            Some(kv) => kv.1 = value,
            None => t.push((key.to_string(), value)),
        }
        t
    };
    let base = old
        .levels
        .map_or(1 + rng.below(6) as i64, |l| l.floor() as i64 + 1);
    const SHAPES: [&str; 5] = ["flat", "gabled", "hipped", "skillion", "pyramidal"];
    let start = rng.below(SHAPES.len());
    let by_levels = (0..3).map(|i| with("building:levels", (base + i).max(1).to_string()));
    let by_shape = (0..SHAPES.len()).filter_map(|i| {
        SHAPES
            .get((start + i) % SHAPES.len())
            .map(|s| with("roof:shape", s.to_string()))
    });
    let candidates: Vec<Tags> = if levels {
        by_levels.chain(by_shape).collect()
    } else {
        by_shape.chain(by_levels).collect()
    };
    candidates.into_iter().find(|t| !parsed(t).same_bits(&old))
}

/// The ring translated by 0.6 m in a random direction and scaled about its centroid by a
/// random factor within 3 % whose largest vertex shift is 0.3 m: every vertex moves 0.3 to
/// 0.9 m, the order and shape (up to scale) are kept.
fn move_ring(pts: &[(f64, f64)], rng: &mut Rng) -> Vec<(f64, f64)> {
    let n = pts.len().max(1) as f64;
    let (cx, cy) = pts
        .iter()
        .fold((0.0, 0.0), |(a, b), &(x, y)| (a + x / n, b + y / n));
    let r = pts
        .iter()
        .map(|&(x, y)| (x - cx).hypot(y - cy))
        .fold(0.0f64, f64::max);
    let sign = if rng.unit() < 0.5 { -1.0 } else { 1.0 };
    let d = sign * 0.03f64.min(0.3 / r.max(1e-9)) * (0.5 + 0.5 * rng.unit());
    let angle = rng.unit() * std::f64::consts::TAU;
    let (tx, ty) = (0.6 * angle.cos(), 0.6 * angle.sin());
    pts.iter()
        .map(|&(x, y)| (x + tx + d * (x - cx), y + ty + d * (y - cy)))
        .collect()
}

// ---- writers ----

fn as_str(t: &[(String, String)]) -> Vec<(&str, &str)> {
    t.iter().map(|(k, v)| (k.as_str(), v.as_str())).collect()
}

fn write_day2(osm: &Osm, plan: &Plan, out: &Path) -> Result<()> {
    let ctx = || format!("{}: writing", out.display());
    let file = File::create(out).with_context(ctx)?;
    let mut w = PbfWriter::new(BufWriter::with_capacity(1 << 20, file)).with_context(ctx)?;
    let deg = |v: i32| v as f64 / 1e7;
    for &(id, lon, lat) in osm.nodes.iter().chain(&plan.new_nodes) {
        if !plan.deleted_nodes.contains(&id) {
            w.node(id, deg(lon), deg(lat), &[]).with_context(ctx)?;
        }
    }
    for way in &osm.ways {
        if plan.removed.contains(&way.id) {
            continue;
        }
        match plan.changed.get(&way.id) {
            Some(c) => {
                let refs = c.ring.as_ref().unwrap_or(&way.refs);
                w.way(way.id, refs, &as_str(&c.tags)).with_context(ctx)?;
            }
            None => w
                .way(way.id, &way.refs, &as_str(&way.tags))
                .with_context(ctx)?,
        }
    }
    for a in &plan.added {
        w.way(a.id, &a.refs, &as_str(&a.tags)).with_context(ctx)?;
    }
    for r in &osm.relations {
        let m: Vec<(MemberKind, i64, &str)> = r
            .members
            .iter()
            .map(|(k, id, role)| (*k, *id, role.as_str()))
            .collect();
        w.relation(r.id, &m, &as_str(&r.tags)).with_context(ctx)?;
    }
    w.finish().with_context(ctx)?.flush().with_context(ctx)?;
    Ok(())
}

/// `v` 1e-7 degrees as a decimal with 7 digits.
fn e7_text(v: i32) -> String {
    let a = (v as i64).abs();
    let sign = if v < 0 { "-" } else { "" };
    format!("{sign}{}.{:07}", a / 10_000_000, a % 10_000_000)
}

/// XML-escaped attribute text.
fn escape(s: &str) -> String {
    let mut o = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '&' => o.push_str("&amp;"),
            '<' => o.push_str("&lt;"),
            '>' => o.push_str("&gt;"),
            '"' => o.push_str("&quot;"),
            '\'' => o.push_str("&apos;"),
            '\n' => o.push_str("&#10;"),
            '\r' => o.push_str("&#13;"),
            '\t' => o.push_str("&#9;"),
            c => o.push(c),
        }
    }
    o
}

fn osc_way(o: &mut String, id: i64, version: u32, refs: &[i64], tags: &Tags) {
    let _ = writeln!(o, "    <way id=\"{id}\" version=\"{version}\">");
    for r in refs {
        let _ = writeln!(o, "      <nd ref=\"{r}\"/>");
    }
    for (k, v) in tags {
        let _ = writeln!(o, "      <tag k=\"{}\" v=\"{}\"/>", escape(k), escape(v));
    }
    o.push_str("    </way>\n");
}

fn write_osc(osm: &Osm, plan: &Plan, out: &Path) -> Result<()> {
    let mut o = String::new();
    o.push_str("<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n");
    o.push_str("<osmChange version=\"0.6\" generator=\"citygen bench\">\n  <create>\n");
    for &(id, lon, lat) in &plan.new_nodes {
        let _ = writeln!(
            o,
            "    <node id=\"{id}\" version=\"1\" lat=\"{}\" lon=\"{}\"/>",
            e7_text(lat),
            e7_text(lon)
        );
    }
    for a in &plan.added {
        osc_way(&mut o, a.id, 1, &a.refs, &a.tags);
    }
    o.push_str("  </create>\n  <modify>\n");
    for w in &osm.ways {
        if let Some(c) = plan.changed.get(&w.id) {
            osc_way(&mut o, w.id, 2, c.ring.as_ref().unwrap_or(&w.refs), &c.tags);
        }
    }
    o.push_str("  </modify>\n  <delete>\n");
    for id in &plan.removed {
        let _ = writeln!(o, "    <way id=\"{id}\" version=\"1\"/>");
    }
    for id in &plan.deleted_nodes {
        let _ = writeln!(o, "    <node id=\"{id}\" version=\"1\"/>");
    }
    o.push_str("  </delete>\n</osmChange>\n");
    let ctx = || format!("{}: writing", out.display());
    let file = File::create(out).with_context(ctx)?;
    let mut gz = GzEncoder::new(BufWriter::new(file), Compression::default());
    gz.write_all(o.as_bytes()).with_context(ctx)?;
    gz.finish().with_context(ctx)?.flush().with_context(ctx)?;
    Ok(())
}

/// The four files of `dir` written by [`make_day2`]: day 1, day 2, the osmChange, the edits.
pub fn day2_files(dir: &Path) -> [PathBuf; 4] {
    [DAY1, DAY2, CHANGES, EDITS].map(|f| dir.join(f))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn e7_text_has_seven_decimals_and_a_sign() {
        assert_eq!(e7_text(437_353_272), "43.7353272");
        assert_eq!(e7_text(-5), "-0.0000005");
        assert_eq!(e7_text(0), "0.0000000");
        assert_eq!(e7_text(i32::MIN), "-214.7483648");
    }

    #[test]
    fn escape_covers_markup_and_quotes() {
        assert_eq!(escape("a<b>&\"c'\n"), "a&lt;b&gt;&amp;&quot;c&apos;&#10;");
    }

    #[test]
    fn moved_ring_vertices_shift_between_30_and_90_cm() {
        let mut rng = Rng(3);
        for size in [2.0, 10.0, 40.0, 300.0] {
            let ring = [(0.0, 0.0), (size, 0.0), (size, size / 2.0), (0.0, size)];
            let moved = move_ring(&ring, &mut rng);
            for (p, q) in ring.iter().zip(&moved) {
                let d = (p.0 - q.0).hypot(p.1 - q.1);
                assert!((0.3 - 1e-9..=0.9 + 1e-9).contains(&d), "{size} m: {d}");
            }
        }
    }

    #[test]
    fn new_tags_always_parse_differently() {
        let mut rng = Rng(9);
        let t = |pairs: &[(&str, &str)]| -> Tags {
            pairs
                .iter()
                .map(|(k, v)| (k.to_string(), v.to_string()))
                .collect()
        };
        for tags in [
            t(&[("building", "yes")]),
            t(&[("building", "yes"), ("building:levels", "3")]),
            t(&[("building", "yes"), ("building:levels", "junk")]),
            t(&[("building", "yes"), ("roof:shape", "pitched")]),
        ] {
            for levels in [true, false] {
                let new = new_tags(&tags, levels, &mut rng).unwrap();
                let p = |t: &Tags| {
                    BuildingTags::from_pairs(t.iter().map(|(k, v)| (k.as_str(), v.as_str())))
                };
                assert!(!p(&new).same_bits(&p(&tags)), "{tags:?} -> {new:?}");
            }
        }
    }
}
