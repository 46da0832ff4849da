//! OSM reader (PBF, or OSM XML through `xml`): building ways, building multipolygon relations
//! and `building:part`s.
//!
//! OSM XML (plain, gzip or bzip2, told by the first bytes) goes through the same three passes
//! and assembly as a PBF: `Passes` is what a format gives each pass; the rest of this text
//! describes the PBF's.
//!
//! The file is read as a stream, never held whole (issue 46): a sweep reads the blob headers
//! in order to frame every blob, and inflates only the start of each data blob to see the kind
//! of its first group (nodes, ways or relations). Then three passes, each reading and decoding
//! only the blobs of its kind (each thread reads its own blob from the file), so every blob is
//! decoded once and a thread holds one blob at a time:
//! 1. relations: `type=multipolygon` relations tagged `building`/`building:part`, and untagged
//!    ones (old-style multipolygons carry their tags on the outer way); keep their member ways;
//! 2. ways: building/part ways, the member ways of pass 1 and street ways (`STREET_KINDS`);
//!    collect the node ids they need;
//! 3. nodes: only the needed ids, in a compact index (sorted ids, 1e-7 degree integers beside),
//!    and the nodes with an `addr:street` (issue 45: address and entrance nodes name the street
//!    a building's door faces; a block's node tags are read only when its string table holds
//!    `addr:street`; OSM XML's too). A change file's nodes give no address nodes.
//!
//! Admin boundaries ride along (`boundaries`): pass 1 keeps `boundary=administrative`
//! relations of `admin_level` 2..=10 with only their naming tags, pass 2 their member ways and
//! the closed ways tagged as boundaries themselves; they are assembled as multipolygons after
//! the footprints. Nothing else of a relation or way that is not a building is held.
//!
//! A block that holds more than one kind of element (no common writer makes one) is noticed
//! when decoded; the read then starts again with every pass decoding every blob. Blocks are
//! decoded in parallel (rayon), and the per-block results are merged in file order,
//! then sorted by id, so the output does not depend on the thread count. The ways and nodes
//! passes decode their blocks directly (`wire`), falling back to osmpbf for any block the
//! direct decoder does not take.
//!
//! Every building or part object ends as exactly one footprint or one `Skipped` report entry;
//! `report.read` / `report.parts_read` count them all, skipped ones included.
//!
//! [`read_osm_with_changes`] also applies an OSM change file (`read_osc`, module `osc`):
//! after pass 1 the change's relations replace and add to the file's (so member ways are chosen
//! from the changed relations), after pass 2 its ways (kept by the same rules, their tags parsed
//! with the same interner; their node ids join the needed ones), after pass 3 its nodes
//! (moved, created, or deleted: missing). Each step is a lookup per kept record in the change's
//! sorted maps, nothing per element of the file; without a change the read is unchanged.

use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::{Path, PathBuf};
use std::sync::Arc;

use osmpbf::{BlobDecode, BlobReader, PrimitiveBlock, RelMemberType};
use rayon::prelude::*;

use super::rings::{group_rings, lonlat_problem, oriented_polygon, ring_problem};
use super::{
    BuildingTags, Footprint, FootprintKind, InputError, ReadResult, Ring, SharedTags, SourceId,
    SourcePolygon, StreetKind, TagInterner,
};
use crate::geometry::ring;
use crate::report::{Outcome, Report};

mod boundaries;
mod multipolygon;
mod osc;
mod pbf;
pub mod pbf_write;
mod records;
mod wire;
mod xml;

pub(crate) use osc::{read_osc, Change, MemberType};

use multipolygon::*;
use pbf::*;
use records::*;
use wire::*;

/// At most this many ids are listed in one report reason.
const MAX_LISTED: usize = 5;

type Tags = Vec<(String, String)>;

/// Reads the building footprints of an OSM PBF or OSM XML file (plain, gzip or bzip2; told by
/// its content, see `xml`).
///
/// Returns the footprints sorted (ways by id, then relations by id), in WGS84 lon/lat
/// (`source_crs` is `None`). Record-level problems become report entries with the OSM id;
/// file-level problems (missing file, not a PBF, corrupt or truncated block) are an
/// [`InputError`] naming the file and the block. Never panics.
pub fn read_osm(path: &Path, report: &mut Report) -> Result<ReadResult, InputError> {
    read_osm_with_changes(path, None, report)
}

/// Reads the building footprints of an OSM PBF or XML file with an OSM change file applied
/// (osmChange XML, plain or gzip: `read_osc`); `None` reads the PBF alone, as [`read_osm`].
///
/// The result is that of [`read_osm`] on the extract with the changes applied: the change's
/// relations, ways and nodes replace the PBF's of the same id (a deleted one is as if absent
/// from the file), the created ones are added. Relations are changed before their member ways
/// are chosen; a created or modified way's tags are parsed as the PBF's are, and its nodes are
/// taken from the change or the PBF; a moved node moves every building and street using it; a
/// way using a deleted node is a way with a missing node. Footprints stay sorted (ways by id,
/// then relations by id).
///
/// The change should cover the extract's area only (a diff between two extracts, e.g.
/// `osmium derive-changes`, or a replication diff cut to the area): applied as is, a
/// planet-wide diff adds every building created anywhere, and its modified ways outside the
/// extract, whose nodes the PBF lacks, are reported as ways with missing nodes.
///
/// The change file is read first: its errors
/// ([`InputError::OsmChange`], [`InputError::Io`]) name it. Never panics.
pub fn read_osm_with_changes(
    path: &Path,
    osc: Option<&Path>,
    report: &mut Report,
) -> Result<ReadResult, InputError> {
    let change = osc.map(read_osc).transpose()?;
    let change = change.as_ref();
    if let Some(xml) = xml::detect(path)? {
        // The XML passes never find a mixed block.
        return read_passes(&xml, change, report)?.ok_or_else(|| InputError::OsmXml {
            path: path.to_path_buf(),
            place: "the whole file".into(),
            reason: "inconsistent passes".into(),
        });
    }
    let pbf = Pbf::open(path)?;
    let mut locs = pbf.sweep()?;
    let src = PbfPasses {
        pbf: &pbf,
        locs: &locs,
    };
    if let Some(r) = read_passes(&src, change, report)? {
        return Ok(r);
    }
    // A block held more than one kind of element: every pass decodes every block.
    for l in &mut locs {
        l.kind = BlobKind::Any;
    }
    let src = PbfPasses {
        pbf: &pbf,
        locs: &locs,
    };
    read_passes(&src, change, report)?.ok_or_else(|| pbf.corrupt(0, None, "inconsistent blocks"))
}

/// One report note per id that appears more than once in `sorted_ids` (an extract merged
/// twice, a broken writer): the first record in file order is used, the others are dropped,
/// and the note says so.
fn note_duplicates(
    sorted_ids: impl Iterator<Item = i64>,
    id: fn(i64) -> SourceId,
    report: &mut Report,
) {
    let mut run: Option<(i64, usize)> = None;
    let flush = |run: Option<(i64, usize)>, report: &mut Report| {
        if let Some((i, n)) = run.filter(|r| r.1 > 1) {
            report.add(
                Some(id(i)),
                Outcome::Note,
                format!(
                    "{} appears {n} times in the file: the first is used, the others are ignored",
                    id(i)
                ),
            );
        }
    };
    for i in sorted_ids {
        match &mut run {
            Some((j, n)) if *j == i => *n += 1,
            _ => {
                flush(run.take(), report);
                run = Some((i, 1));
            }
        }
    }
    flush(run, report);
}

/// A block's kept ways with the node ids they need (sorted, deduplicated).
type WaysOfBlock = (WayBlock, Vec<i64>);

/// Where the three passes take their elements from: a PBF's blocks ([`PbfPasses`]) or the
/// elements of an OSM XML file ([`xml::XmlPasses`]). Each pass gives its results per block (a
/// run of elements) in file order; `None` when a block held another kind of element than the
/// sweep saw (PBF only: the read starts again with every block decoded by every pass).
trait Passes {
    /// Pass 1: the relations kept ([`relation_rec`]).
    fn relations(&self) -> Result<Option<Vec<Vec<RelRec>>>, InputError>;
    /// Pass 2: the ways kept ([`WayBlock::keep_way`]) with each block's needed node ids
    /// ([`WayBlock::needed`]).
    fn ways(
        &self,
        member_ways: &[i64],
        interner: &TagInterner,
    ) -> Result<Option<Vec<WaysOfBlock>>, InputError>;
    /// Pass 3: the nodes of `needed` (sorted) found, each block's sorted by index
    /// ([`Found::sort`]), and the nodes with an `addr:street` ([`AddrNode`]).
    fn nodes(&self, needed: &[i64]) -> Result<Option<Vec<NodeBlock>>, InputError>;
}

/// The PBF's blobs `locs`, read from the file and decoded in parallel by each pass.
struct PbfPasses<'a> {
    pbf: &'a Pbf,
    locs: &'a [BlobLoc],
}

impl Passes for PbfPasses<'_> {
    fn relations(&self) -> Result<Option<Vec<Vec<RelRec>>>, InputError> {
        let (rels, mixed) = self.pbf.pass(
            self.locs,
            BlobKind::Relations,
            |_, _| None,
            relations_of_block,
        )?;
        Ok((!mixed).then_some(rels))
    }

    fn ways(
        &self,
        member_ways: &[i64],
        interner: &TagInterner,
    ) -> Result<Option<Vec<WaysOfBlock>>, InputError> {
        // Each block's ways come with the node ids they need, sorted and deduplicated in the
        // parallel pass; the file's list is then a merge of sorted runs.
        let with_needed = |b: WayBlock| {
            let needed = b.needed();
            (b, needed)
        };
        let (blocks, mixed) = self.pbf.pass(
            self.locs,
            BlobKind::Ways,
            |f, s| fast_ways(f, s, member_ways, interner).map(with_needed),
            |b| with_needed(ways_of_block(b, member_ways, interner)),
        )?;
        Ok((!mixed).then_some(blocks))
    }

    fn nodes(&self, needed: &[i64]) -> Result<Option<Vec<NodeBlock>>, InputError> {
        // Each block's found nodes sorted by index in the parallel pass, for `Nodes::fill`.
        let by_index = |(mut found, addresses): NodeBlock| {
            found.sort();
            (found, addresses)
        };
        let (found, mixed) = self.pbf.pass(
            self.locs,
            BlobKind::Nodes,
            |f, s| fast_nodes(f, s, needed).map(by_index),
            |b| by_index(nodes_of_block(b, needed)),
        )?;
        Ok((!mixed).then_some(found))
    }
}

/// The three passes of `src` (relations, ways, needed nodes) and the assembly, with `change`
/// applied after each pass; `None` when a block held another kind of element than the sweep
/// saw (nothing was reported then).
fn read_passes(
    src: &impl Passes,
    change: Option<&Change>,
    report: &mut Report,
) -> Result<Option<ReadResult>, InputError> {
    // What the passes note is taken back when a later pass finds a mixed block (the caller
    // reads the file again, and would note it twice).
    let mark = report.entries.len();
    // Pass 1: relations.
    let Some(rels) = src.relations()? else {
        report.entries.truncate(mark);
        return Ok(None);
    };
    let mut rels: Vec<RelRec> = rels.into_iter().flatten().collect();
    if let Some(c) = change {
        // The change's relations replace the file's (a duplicate in the file included).
        rels.retain(|r| !c.relations.contains_key(&r.id));
    }
    rels.sort_by_key(|r| r.id);
    note_duplicates(rels.iter().map(|r| r.id), SourceId::Relation, report);
    rels.dedup_by_key(|r| r.id);
    if let Some(c) = change {
        rels.extend(changed_relations(c));
        rels.sort_by_key(|r| r.id);
    }
    let mut member_ways: Vec<i64> = rels
        .iter()
        .flat_map(|r| r.members.iter().map(|m| m.way))
        .collect();
    member_ways.sort_unstable();
    member_ways.dedup();

    // Pass 2: ways. Their parsed tags are shared between ways with the same ones.
    let interner = TagInterner::default();
    let Some(blocks) = src.ways(&member_ways, &interner)? else {
        report.entries.truncate(mark);
        return Ok(None);
    };
    let (blocks, needed): (Vec<WayBlock>, Vec<Vec<i64>>) = blocks.into_iter().unzip();
    let mut ways = Ways::from_blocks(blocks);
    if let Some(c) = change {
        ways.recs.retain(|w| !c.ways.contains_key(&w.id));
    }
    note_duplicates(
        ways.recs.iter().filter(|w| w.kind.is_some()).map(|w| w.id),
        SourceId::Way,
        report,
    );
    ways.recs.dedup_by_key(|w| w.id);
    // The ids of ways dropped as duplicates or replaced by the change may stay: an id too many
    // in the index changes no lookup.
    let mut needed = merge_runs(needed);
    if let Some(c) = change {
        let mut block = WayBlock::default();
        for (&id, w) in &c.ways {
            if let Some((refs, tags)) = w {
                let tags = || tags.iter().map(|(k, v)| (k.as_str(), v.as_str()));
                block.keep_way(id, tags, refs.iter().copied(), &member_ways, &interner);
            }
        }
        let extra = block.needed();
        if !extra.is_empty() {
            let mut all = Vec::with_capacity(needed.len() + extra.len());
            merge_into(&mut all, &needed, &extra);
            needed = all;
        }
        ways.add_block(block);
    }
    drop(member_ways);

    // Pass 3: nodes.
    let mut nodes = Nodes::new(needed);
    let Some(found) = src.nodes(&nodes.ids)? else {
        report.entries.truncate(mark);
        return Ok(None);
    };
    let (found, addresses): (Vec<Found>, Vec<Vec<AddrNode>>) = found.into_iter().unzip();
    nodes.fill(&found);
    drop(found);
    if let Some(c) = change {
        for (&id, &pos) in &c.nodes {
            if let Some(i) = nodes.index_of(id) {
                nodes.set(i, pos);
            }
        }
    }
    nodes.finish();

    let mut result = assemble(&mut ways, &rels, &nodes, &interner, report);
    result.streets = streets_of(&ways, &rels, &nodes);
    add_address_nodes(&mut result.streets, addresses.into_iter().flatten());
    result.boundaries = boundaries::admin_boundaries(&ways, &rels, &nodes, report);
    // Freeing the large lists is a fair share of the read: both at once.
    rayon::join(move || drop(ways), move || drop(nodes));
    Ok(Some(result))
}

/// The change's created and modified relations that pass 1 keeps (see [`relation_rec`]).
fn changed_relations(c: &Change) -> impl Iterator<Item = RelRec> + '_ {
    c.relations.iter().filter_map(|(&id, r)| {
        let (members, tags) = r.as_ref()?;
        relation_rec(
            id,
            || tags.iter().map(|(k, v)| (k.as_str(), v.as_str())),
            members
                .iter()
                .map(|(t, id, role)| (*t == MemberType::Way, *id, Some(role.as_str()))),
        )
    })
}

/// The union of sorted, deduplicated runs, sorted and deduplicated. The blocks of a sorted file
/// give runs that mostly follow each other (each one's ids above the last one's, but for a few
/// shared nodes): each run is appended, merging only its first ids that are not above the ids
/// so far into the tail they overlap. When that merging grows beyond the ids' count (an
/// unsorted file), everything is sorted instead.
fn merge_runs(runs: Vec<Vec<i64>>) -> Vec<i64> {
    let total = runs.iter().map(Vec::len).sum();
    let mut out: Vec<i64> = Vec::with_capacity(total);
    let mut work = 0usize;
    for (n, r) in runs.iter().enumerate() {
        let Some(&last) = out.last() else {
            out.extend_from_slice(r);
            continue;
        };
        let k = r.partition_point(|&x| x <= last);
        if k > 0 {
            let p = out.partition_point(|&x| x < r[0]);
            work += out.len() - p + k;
            if work > total {
                for r in &runs[n..] {
                    out.extend_from_slice(r);
                }
                out.par_sort_unstable();
                out.dedup();
                return out;
            }
            let tail = out.split_off(p);
            merge_into(&mut out, &tail, &r[..k]);
        }
        out.extend_from_slice(&r[k..]);
    }
    out
}

/// Appends the sorted union of sorted `a` and `b` to `out`, without duplicates (nor the last of
/// `out` again).
pub(super) fn merge_into(out: &mut Vec<i64>, a: &[i64], b: &[i64]) {
    let (mut i, mut j) = (0, 0);
    while i < a.len() || j < b.len() {
        let x = if j >= b.len() || (i < a.len() && a[i] <= b[j]) {
            i += 1;
            a[i - 1]
        } else {
            j += 1;
            b[j - 1]
        };
        if out.last() != Some(&x) {
            out.push(x);
        }
    }
}

/// The `highway=*` values read as streets a front door can face, with their `_link` roads.
///
/// Roads with frontage (trunk down to residential, service, living streets) and the ways people
/// walk to doors on: `pedestrian`, `footway` (which includes mapped sidewalks, parallel to the
/// street and right in front of the facades) and `steps` — in old towns such as Monaco-Ville
/// many houses open only onto stepped lanes. Left out: motorways (no frontage), `track`,
/// `path`, `cycleway`, `bridleway` (rarely what a house faces), `corridor` (indoor),
/// `proposed`/`construction`, and any way in a tunnel (Monaco runs roads under whole
/// districts), indoors or a parking aisle (a car park lane, not an address street).
pub(crate) const STREET_KINDS: &[&str] = &[
    "trunk",
    "trunk_link",
    "primary",
    "primary_link",
    "secondary",
    "secondary_link",
    "tertiary",
    "tertiary_link",
    "unclassified",
    "residential",
    "living_street",
    "service",
    "pedestrian",
    "footway",
    "steps",
];

/// Whether a way's tags make it a street (see [`STREET_KINDS`]).
#[cfg(test)]
fn is_street<'a>(tags: impl Iterator<Item = (&'a str, &'a str)>) -> bool {
    street_of(tags).is_some()
}

/// The street a way's tags make (see [`STREET_KINDS`]): its kind and its `name`.
fn street_of<'a>(
    tags: impl Iterator<Item = (&'a str, &'a str)>,
) -> Option<(StreetKind, Option<Arc<str>>)> {
    let (mut kind, mut name, mut lane) = (None, None, false);
    for (k, v) in tags {
        let v = v.trim();
        match k {
            "highway" => {
                kind = STREET_KINDS.contains(&v).then_some(match v {
                    "service" => StreetKind::Service,
                    "footway" | "steps" => StreetKind::Foot,
                    _ => StreetKind::Road,
                })
            }
            "tunnel" | "indoor" if v != "no" => return None,
            "service" if v == "parking_aisle" => return None,
            "service" => lane = v == "alley" || v == "driveway",
            "name" if !v.is_empty() => name = Some(Arc::from(v)),
            _ => {}
        }
    }
    match kind? {
        StreetKind::Service if lane => Some((StreetKind::Lane, name)),
        k => Some((k, name)),
    }
}

/// A building's `addr:street`, trimmed (a blank value is none).
fn addr_street_of<'a>(mut tags: impl Iterator<Item = (&'a str, &'a str)>) -> Option<Arc<str>> {
    tags.find(|(k, v)| *k == "addr:street" && !v.trim().is_empty())
        .map(|(_, v)| Arc::from(v.trim()))
}

/// The street ways as polylines in way-id order, with their kinds and names, and the
/// `addr:street` of the building ways and relations. A way with missing nodes keeps its runs
/// of consecutive known nodes (a street clipped by the extract's border is still a street).
fn streets_of(ways: &Ways, rels: &[RelRec], nodes: &Nodes) -> super::Streets {
    let mut streets = super::Streets::default();
    let mut index = std::collections::HashMap::new();
    let mut run: Ring = Vec::new();
    for w in &ways.recs {
        let Some(kind) = w.street else {
            if let (Some(_), Some(a)) = (w.kind, &w.name) {
                let n = streets.name_index(a, &mut index);
                streets.addresses.push((SourceId::Way(w.id), n));
            }
            continue;
        };
        let name = match &w.name {
            Some(n) => streets.name_index(n, &mut index),
            None => super::Streets::NO_NAME,
        };
        run.clear();
        for &r in ways.refs(w) {
            match nodes.get(r) {
                Some(p) => run.push(p),
                None => {
                    streets.push_street(&run, kind, name);
                    run.clear();
                }
            }
        }
        streets.push_street(&run, kind, name);
    }
    for r in rels
        .iter()
        .filter(|r| matches!(r.kind, RelKind::Building | RelKind::Part))
    {
        if let Some(a) = addr_street_of(r.tags.iter().map(|(k, v)| (k.as_str(), v.as_str()))) {
            let n = streets.name_index(&a, &mut index);
            streets.addresses.push((SourceId::Relation(r.id), n));
        }
    }
    streets.addresses.sort_by_key(|a| a.0);
    streets.addresses.dedup_by_key(|a| a.0);
    streets
}

/// Adds the address nodes (issue 45: `addr:street` on a node; an entrance or address node
/// inside or on a building's outline names its street) to `streets`, in degrees, in file
/// order. A change file's nodes are not read for their tags.
fn add_address_nodes(streets: &mut super::Streets, nodes: impl Iterator<Item = AddrNode>) {
    let mut index: std::collections::HashMap<String, u32> = streets
        .names
        .iter()
        .enumerate()
        .map(|(i, n)| (n.clone(), i as u32))
        .collect();
    for (lon, lat, name) in nodes {
        let n = streets.name_index(&name, &mut index);
        if n != super::Streets::NO_NAME {
            streets
                .address_points
                .push((lon as f64 * 1e-9, lat as f64 * 1e-9, n));
        }
    }
}

/// A building/part relation's footprint (`None` when skipped) and its report entries.
type RelOutcome = (Option<Footprint>, Vec<(Outcome, String)>, RelRec);

/// Turns the three passes' results into footprints and report entries.
fn assemble(
    ways: &mut Ways,
    rels: &[RelRec],
    nodes: &Nodes,
    interner: &TagInterner,
    report: &mut Report,
) -> ReadResult {
    // Relations first: they decide which ways are built by a relation instead of alone, and
    // which ways get holes from an old-style multipolygon. Their entries are emitted after the
    // ways' so that the report follows the footprint order.
    let mut rel_out: Vec<RelOutcome> = Vec::new();
    // (way id, relation id) of ways built as part of a relation of the same kind.
    let mut built_by: Vec<(i64, i64)> = Vec::new();
    // (way id, relation id, holes) from old-style multipolygons.
    let mut old_style: Vec<(i64, i64, Vec<Ring>)> = Vec::new();
    // (way id, note) for building ways whose old-style relation could not be assembled.
    let mut old_style_notes: Vec<(i64, String)> = Vec::new();
    let way_kind = |id: i64| ways.find(id).and_then(|w| w.kind);

    for rel in rels.iter().filter(|r| r.kind != RelKind::Boundary) {
        let a = assemble_relation(rel, ways, nodes);
        match rel.kind {
            // Left out by the filter: `boundaries::admin_boundaries` builds them.
            RelKind::Boundary => {}
            RelKind::Untagged => {
                let mut used = false;
                for (_, holes, outer_ways) in &a.polygons {
                    if let [w] = outer_ways.as_slice() {
                        if way_kind(*w).is_some()
                            && !holes.is_empty()
                            && !old_style.iter().any(|(o, _, _)| o == w)
                        {
                            old_style.push((*w, rel.id, holes.clone()));
                            used = true;
                        }
                    }
                }
                if !used {
                    // Not a building relation; only worth a word when an outer member is a
                    // building that would have received holes.
                    for m in rel.members.iter().filter(|m| m.role == Role::Outer) {
                        if way_kind(m.way).is_some() && !a.problems.is_empty() {
                            old_style_notes.push((
                                m.way,
                                format!(
                                    "old-style multipolygon relation/{} could not be assembled, built without its holes: {}",
                                    rel.id,
                                    a.problems.join("; ")
                                ),
                            ));
                        }
                    }
                }
            }
            RelKind::Building | RelKind::Part => {
                let kind = if rel.kind == RelKind::Building {
                    FootprintKind::Building
                } else {
                    FootprintKind::Part
                };
                let id = SourceId::Relation(rel.id);
                let mut entries = Vec::new();
                if a.polygons.is_empty() {
                    let why = if a.problems.is_empty() {
                        "multipolygon without any closed ring".to_string()
                    } else {
                        format!(
                            "multipolygon without a usable outer ring: {}",
                            a.problems.join("; ")
                        )
                    };
                    entries.push((Outcome::Skipped, why));
                    rel_out.push((None, entries, rel.clone()));
                    continue;
                }
                if !a.problems.is_empty() {
                    entries.push((Outcome::Repaired, a.problems.join("; ")));
                }
                for (_, _, outer_ways) in &a.polygons {
                    for w in outer_ways {
                        if way_kind(*w) == Some(kind) {
                            built_by.push((*w, rel.id));
                        }
                    }
                }
                let tags = BuildingTags::from_pairs(
                    rel.tags.iter().map(|(k, v)| (k.as_str(), v.as_str())),
                );
                let polygons = a
                    .polygons
                    .into_iter()
                    .map(|(o, h, _)| oriented_polygon(o, h))
                    .collect();
                rel_out.push((
                    Some(Footprint {
                        id,
                        kind,
                        polygons,
                        tags: interner.intern(tags),
                    }),
                    entries,
                    rel.clone(),
                ));
            }
        }
    }
    built_by.sort_unstable();
    old_style.sort_by_key(|(w, _, _)| *w);
    old_style_notes.sort_by_key(|(w, _)| *w);

    // The polygons of the building/part ways, built in parallel: the costly part (node
    // lookups, clean-up, checks, orientation); report entries are then added in way order.
    let old_style_at = |w: i64| old_style.binary_search_by_key(&w, |(x, _, _)| *x).ok();
    let polygons: Vec<Option<Result<Vec<SourcePolygon>, WayError>>> = ways
        .recs
        .par_iter()
        .map(|w| {
            w.kind.map(|_| {
                way_ring(w, ways.refs(w), &built_by, nodes).map(|outer| {
                    let holes =
                        old_style_at(w.id).map_or_else(Vec::new, |i| old_style[i].2.clone());
                    vec![oriented_polygon(outer, holes)]
                })
            })
        })
        .collect();
    let mut result = ReadResult::default();
    result
        .footprints
        .reserve(polygons.iter().flatten().count() + rel_out.len());
    for (w, polygons) in ways.recs.iter_mut().zip(polygons) {
        let (Some(kind), Some(polygons)) = (w.kind, polygons) else {
            continue;
        };
        let id = SourceId::Way(w.id);
        count_read(report, kind);
        let polygons = match polygons {
            Ok(p) => p,
            Err(why) => {
                report.skipped += 1;
                report.add(Some(id), Outcome::Skipped, why.to_string());
                continue;
            }
        };
        let tags = w.tags.take().unwrap_or_default();
        if let Some(i) = old_style_at(w.id) {
            let (_, r, holes) = &old_style[i];
            report.add(
                Some(id),
                Outcome::Note,
                format!(
                    "{} hole(s) taken from old-style multipolygon relation/{r}",
                    holes.len()
                ),
            );
        }
        let first = old_style_notes.partition_point(|(x, _)| *x < w.id);
        for (_, note) in old_style_notes[first..]
            .iter()
            .take_while(|(x, _)| *x == w.id)
        {
            report.add(Some(id), Outcome::Note, note.clone());
        }
        note_ignored(report, id, &tags);
        result.footprints.push(Footprint {
            id,
            kind,
            polygons,
            tags,
        });
    }

    for (fp, entries, rel) in rel_out {
        let id = SourceId::Relation(rel.id);
        count_read(
            report,
            if rel.kind == RelKind::Part {
                FootprintKind::Part
            } else {
                FootprintKind::Building
            },
        );
        for (outcome, why) in entries {
            match outcome {
                Outcome::Skipped => report.skipped += 1,
                Outcome::Repaired => report.repaired += 1,
                Outcome::Note => {}
            }
            report.add(Some(id), outcome, why);
        }
        if let Some(fp) = fp {
            note_ignored(report, id, &fp.tags);
            result.footprints.push(fp);
        }
    }
    result
}

/// Why a building/part way is skipped (the reason its report entry gives).
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
enum WayError {
    /// It is the outer ring of a multipolygon relation built instead.
    #[error("outer ring of multipolygon relation/{relation}, which is built instead")]
    BuiltByRelation { relation: i64 },
    /// Its first and last nodes differ.
    #[error("unclosed way: first node node/{first}, last node node/{last}")]
    Unclosed { first: i64, last: i64 },
    /// Fewer than 2 nodes.
    #[error("way with {nodes} node(s)")]
    FewNodes { nodes: usize },
    /// Nodes it names are not in the file.
    #[error("{missing} of {nodes} nodes missing from the file")]
    MissingNodes { missing: usize, nodes: usize },
    /// The cleaned ring cannot be used ([`ring_problem`]).
    #[error("{0}")]
    BadRing(&'static str),
    /// A point is not on the Earth ([`lonlat_problem`]'s message).
    #[error("{0}")]
    OutsideEarth(String),
}

/// The cleaned outer ring of a building/part way, or why it is skipped. `built_by` is sorted;
/// `refs` are the way's node ids.
fn way_ring(
    w: &WayRec,
    refs: &[i64],
    built_by: &[(i64, i64)],
    nodes: &Nodes,
) -> Result<Ring, WayError> {
    let first = built_by.partition_point(|(x, _)| *x < w.id);
    if let Some((_, r)) = built_by.get(first).filter(|(x, _)| *x == w.id) {
        return Err(WayError::BuiltByRelation { relation: *r });
    }
    if refs.len() < 2 || refs.first() != refs.last() {
        return Err(match (refs.first(), refs.last()) {
            (Some(a), Some(b)) if refs.len() >= 2 => WayError::Unclosed {
                first: *a,
                last: *b,
            },
            _ => WayError::FewNodes { nodes: refs.len() },
        });
    }
    let mut outer = resolve(refs, nodes).map_err(|missing| WayError::MissingNodes {
        missing,
        nodes: refs.len(),
    })?;
    ring::dedup_by(&mut outer, |a, b| a == b);
    if let Some(why) = ring_problem(&outer) {
        return Err(WayError::BadRing(why));
    }
    if let Some(why) = lonlat_problem(&outer) {
        return Err(WayError::OutsideEarth(why));
    }
    Ok(outer)
}

fn count_read(report: &mut Report, kind: FootprintKind) {
    match kind {
        FootprintKind::Building => report.read += 1,
        FootprintKind::Part => report.parts_read += 1,
    }
}

/// One `Note` entry per tag value that could not be used.
pub(crate) fn note_ignored(report: &mut Report, id: SourceId, tags: &BuildingTags) {
    for (k, v, why) in &tags.ignored {
        report.add(
            Some(id),
            Outcome::Note,
            format!("tag {k}={v} ignored: {why}"),
        );
    }
}

#[cfg(test)]
mod osc_tests;
#[cfg(test)]
mod tests;
#[cfg(test)]
mod xml_tests;
