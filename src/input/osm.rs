//! OSM PBF reader: building ways, building multipolygon relations and `building:part`s.
//!
//! A sweep frames every blob and inflates only the start of each data blob to see the kind of
//! its first group (nodes, ways or relations). Then three passes, each decoding only the blobs
//! of its kind, so every blob is decoded once:
//! 1. relations: `type=multipolygon` relations tagged `building`/`building:part`, and untagged
//!    ones (old-style multipolygons carry their tags on the outer way); keep their member ways;
//! 2. ways: building/part ways, the member ways of pass 1 and street ways ([`STREET_KINDS`]);
//!    collect the node ids they need;
//! 3. nodes: only the needed ids, in a compact index (sorted ids, 1e-7 degree integers beside).
//!
//! A block that holds more than one kind of element (no common writer makes one) is noticed
//! when decoded; the read then starts again with every pass decoding every blob. Blocks are
//! decoded in parallel (rayon) in batches, and the per-block results are merged in file order,
//! then sorted by id, so the output does not depend on the thread count.
//!
//! Every building or part object ends as exactly one footprint or one `Skipped` report entry;
//! `report.read` / `report.parts_read` count them all, skipped ones included.

use std::fs::File;
use std::io::{BufReader, Read, Seek, SeekFrom};
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::{Path, PathBuf};

use osmpbf::{BlobDecode, BlobReader, PrimitiveBlock, RelMemberType};
use rayon::prelude::*;

use super::rings::{group_rings, oriented_polygon, ring_problem};
use super::{
    BuildingTags, Footprint, FootprintKind, InputError, ReadResult, Ring, SharedTags, SourceId,
    TagInterner,
};
use crate::geometry::ring;
use crate::report::{Outcome, Report};

/// Blobs decoded per parallel batch: enough to keep the cores busy, few enough that the
/// compressed blobs held at once stay small.
const BATCH: usize = 64;

/// At most this many ids are listed in one report reason.
const MAX_LISTED: usize = 5;

type Tags = Vec<(String, String)>;

/// Reads the building footprints of an OSM PBF file.
///
/// Returns the footprints sorted (ways by id, then relations by id), in WGS84 lon/lat
/// (`source_crs` is `None`). Record-level problems become report entries with the OSM id;
/// file-level problems (missing file, not a PBF, corrupt or truncated block) are an
/// [`InputError`] naming the file and the block. Never panics.
pub fn read_osm(path: &Path, report: &mut Report) -> Result<ReadResult, InputError> {
    let pbf = Pbf::open(path)?;
    let mut locs = pbf.sweep()?;
    if let Some(r) = read_passes(&pbf, &locs, report)? {
        return Ok(r);
    }
    // A block held more than one kind of element: every pass decodes every block.
    for l in &mut locs {
        l.kind = BlobKind::Any;
    }
    read_passes(&pbf, &locs, report)?.ok_or_else(|| pbf.corrupt(0, None, "inconsistent blocks"))
}

/// The three passes over the blobs `locs` (relations, ways, needed nodes) and the assembly;
/// `None` when a block held another kind of element than the sweep saw (nothing was reported
/// then).
fn read_passes(
    pbf: &Pbf,
    locs: &[BlobLoc],
    report: &mut Report,
) -> Result<Option<ReadResult>, InputError> {
    // Pass 1: relations.
    let (rels, mixed) = pbf.pass(locs, BlobKind::Relations, relations_of_block)?;
    if mixed {
        return Ok(None);
    }
    let mut rels: Vec<RelRec> = rels.into_iter().flatten().collect();
    rels.sort_by_key(|r| r.id);
    rels.dedup_by_key(|r| r.id);
    let mut member_ways: Vec<i64> = rels
        .iter()
        .flat_map(|r| r.members.iter().map(|m| m.way))
        .collect();
    member_ways.sort_unstable();
    member_ways.dedup();

    // Pass 2: ways. Their parsed tags are shared between ways with the same ones.
    let interner = TagInterner::default();
    let (ways, mixed) = pbf.pass(locs, BlobKind::Ways, |b| {
        ways_of_block(b, &member_ways, &interner)
    })?;
    if mixed {
        return Ok(None);
    }
    let mut ways: Vec<WayRec> = ways.into_iter().flatten().collect();
    ways.sort_by_key(|w| w.id);
    ways.dedup_by_key(|w| w.id);
    drop(member_ways);
    let mut needed: Vec<i64> = ways.iter().flat_map(|w| w.refs.iter().copied()).collect();
    needed.sort_unstable();
    needed.dedup();

    // Pass 3: nodes.
    let mut nodes = Nodes::new(needed);
    let (found, mixed) = pbf.pass(locs, BlobKind::Nodes, |b| nodes_of_block(b, &nodes.ids))?;
    if mixed {
        return Ok(None);
    }
    for (i, lon, lat) in found.into_iter().flatten() {
        nodes.set(i, lon, lat);
    }
    nodes.finish();

    let mut result = assemble(&mut ways, &rels, &nodes, &interner, report);
    result.streets = streets_of(&ways, &nodes);
    Ok(Some(result))
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
pub const STREET_KINDS: &[&str] = &[
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
fn is_street<'a>(tags: impl Iterator<Item = (&'a str, &'a str)>) -> bool {
    let mut street = false;
    for (k, v) in tags {
        let v = v.trim();
        match k {
            "highway" => street = STREET_KINDS.contains(&v),
            "tunnel" | "indoor" if v != "no" => return false,
            "service" if v == "parking_aisle" => return false,
            _ => {}
        }
    }
    street
}

/// The street ways as polylines in way-id order. A way with missing nodes keeps its runs of
/// consecutive known nodes (a street clipped by the extract's border is still a street).
fn streets_of(ways: &[WayRec], nodes: &Nodes) -> super::Streets {
    let mut streets = super::Streets::default();
    let mut run: Ring = Vec::new();
    for w in ways.iter().filter(|w| w.street) {
        run.clear();
        for &r in &w.refs {
            match nodes.get(r) {
                Some(p) => run.push(p),
                None => {
                    streets.push(&run);
                    run.clear();
                }
            }
        }
        streets.push(&run);
    }
    streets
}

// ---------------------------------------------------------------------------------------------
// File access

/// Largest BlobHeader the PBF format allows (64 KiB).
const MAX_HEADER: usize = 64 * 1024;
/// Largest Blob the PBF format allows (32 MiB).
const MAX_BLOB: u64 = 32 * 1024 * 1024;

/// Which elements a data blob holds, as far as the sweep can tell from its first group.
///
/// Writers (osmium, osmosis, ours) put one kind of element in a block, so the first group tells
/// the pass that needs the block. `Any` (the blob could not be peeked, or holds no group) is
/// decoded by every pass. A block that turns out to hold other kinds too makes the read start
/// again with every blob `Any`: exact, and as slow as three full decodes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum BlobKind {
    Nodes,
    Ways,
    Relations,
    Any,
}

/// Where a data blob lies in the file: its frame (length prefix, header, blob) and kind.
#[derive(Clone, Copy, Debug)]
struct BlobLoc {
    /// 0-based index among all blobs of the file, for messages.
    index: usize,
    start: u64,
    len: usize,
    kind: BlobKind,
}

/// One framed blob read from the file.
struct Frame {
    index: usize,
    start: u64,
    /// The whole frame: 4-byte length, BlobHeader, Blob.
    bytes: Vec<u8>,
    /// Where the Blob message starts in `bytes`.
    data: usize,
    /// The header's type: `OSMHeader`, `OSMData` or something else.
    data_blob: bool,
}

/// An opened PBF file: the path for messages and the length to detect trailing garbage.
struct Pbf {
    path: PathBuf,
    len: u64,
}

impl Pbf {
    fn open(path: &Path) -> Result<Pbf, InputError> {
        let io = |source| InputError::Io {
            path: path.to_path_buf(),
            source,
        };
        let meta = std::fs::metadata(path).map_err(io)?;
        if meta.is_dir() {
            return Err(InputError::NotPbf {
                path: path.to_path_buf(),
                reason: "it is a directory".into(),
            });
        }
        if meta.len() == 0 {
            return Err(InputError::NotPbf {
                path: path.to_path_buf(),
                reason: "the file is empty".into(),
            });
        }
        Ok(Pbf {
            path: path.to_path_buf(),
            len: meta.len(),
        })
    }

    fn corrupt(&self, block: usize, offset: Option<u64>, reason: impl Into<String>) -> InputError {
        InputError::CorruptPbf {
            path: self.path.clone(),
            block,
            offset,
            reason: reason.into(),
        }
    }

    fn file(&self) -> Result<File, InputError> {
        File::open(&self.path).map_err(|source| InputError::Io {
            path: self.path.clone(),
            source,
        })
    }

    /// An error while framing blob `index`: the first blob failing means this is not a PBF.
    fn framing_error(&self, index: usize, offset: u64, reason: &str) -> InputError {
        if index == 0 {
            InputError::NotPbf {
                path: self.path.clone(),
                reason: format!("cannot read the first block: {reason}"),
            }
        } else {
            self.corrupt(index, Some(offset), reason)
        }
    }

    /// Reads the frame of blob `index` starting at `start`, or `None` at the end of the file.
    /// Checks the sizes the format allows before allocating.
    fn read_frame(
        &self,
        r: &mut impl Read,
        index: usize,
        start: u64,
    ) -> Result<Option<Frame>, InputError> {
        let err = |reason: &str| self.framing_error(index, start, reason);
        let mut len4 = [0u8; 4];
        let got = read_full(r, &mut len4).map_err(|e| err(&e.to_string()))?;
        if got == 0 {
            return Ok(None);
        }
        if got < 4 {
            return Err(self.corrupt(
                index,
                Some(start),
                format!(
                    "{got} bytes after the last complete block: the file is truncated or has trailing garbage"
                ),
            ));
        }
        let hlen = u32::from_be_bytes(len4) as usize;
        if hlen > MAX_HEADER {
            return Err(err(&format!(
                "blob header of {hlen} bytes (at most {MAX_HEADER})"
            )));
        }
        let mut bytes = vec![0u8; 4 + hlen];
        bytes[..4].copy_from_slice(&len4);
        if read_full(r, &mut bytes[4..]).map_err(|e| err(&e.to_string()))? < hlen {
            return Err(err("the file ends inside a blob header"));
        }
        let (data_blob, size) = parse_blob_header(&bytes[4..])
            .map(|(kind, size)| (kind == b"OSMData", size))
            .ok_or_else(|| err("unreadable blob header"))?;
        if size > MAX_BLOB {
            return Err(err(&format!("blob of {size} bytes (at most {MAX_BLOB})")));
        }
        let data = bytes.len();
        bytes.resize(data + size as usize, 0);
        if read_full(r, &mut bytes[data..]).map_err(|e| err(&e.to_string()))? < size as usize {
            return Err(err("the file ends inside a blob"));
        }
        Ok(Some(Frame {
            index,
            start,
            bytes,
            data,
            data_blob,
        }))
    }

    /// Frames every blob of the file once, checks the header block, and peeks at each data
    /// blob's first group to tell its kind. Checks the framing: the first blob must be an
    /// OSMHeader, and the blobs must end exactly at the end of the file.
    fn sweep(&self) -> Result<Vec<BlobLoc>, InputError> {
        let mut r = BufReader::new(self.file()?);
        let mut locs = Vec::new();
        let mut index = 0usize;
        let mut pos = 0u64;
        loop {
            let mut batch = Vec::with_capacity(BATCH);
            while batch.len() < BATCH {
                let Some(frame) = self.read_frame(&mut r, index, pos)? else {
                    break;
                };
                pos += frame.bytes.len() as u64;
                index += 1;
                batch.push(frame);
            }
            if batch.is_empty() {
                break;
            }
            let kinds: Vec<Result<Option<BlobKind>, InputError>> = batch
                .par_iter()
                .map(|f| {
                    if f.data_blob && f.index > 0 {
                        let kind = catch_unwind(AssertUnwindSafe(|| peek_kind(&f.bytes[f.data..])));
                        return Ok(Some(kind.unwrap_or(BlobKind::Any)));
                    }
                    // The header block, a data block in its place, or an unknown type: fully
                    // decoded, as osmpbf sees them.
                    self.decode(f, |_| ()).map(|_| None)
                })
                .collect();
            for (f, k) in batch.iter().zip(kinds) {
                if let Some(kind) = k? {
                    locs.push(BlobLoc {
                        index: f.index,
                        start: f.start,
                        len: f.bytes.len(),
                        kind,
                    });
                }
            }
        }
        if index == 0 {
            return Err(InputError::NotPbf {
                path: self.path.clone(),
                reason: "no PBF blocks found".into(),
            });
        }
        if pos != self.len {
            return Err(self.corrupt(
                index,
                Some(pos),
                format!(
                    "{} bytes after the last complete block: the file is truncated or has trailing garbage",
                    self.len.saturating_sub(pos)
                ),
            ));
        }
        Ok(locs)
    }

    /// Decodes one frame with osmpbf and runs `f` on its block: `Ok(None)` for a header or
    /// unknown blob (checked like a header when it is the first). Fenced against panics: a
    /// corrupt file must never bring the process down.
    fn decode<T, F>(&self, frame: &Frame, f: F) -> Result<Option<T>, InputError>
    where
        F: Fn(&PrimitiveBlock) -> T,
    {
        let i = frame.index;
        let decoded = catch_unwind(AssertUnwindSafe(|| {
            let blob = match BlobReader::new(frame.bytes.as_slice()).next() {
                Some(Ok(b)) => b,
                Some(Err(e)) => return Err(e.to_string()),
                None => return Err("empty blob".to_string()),
            };
            match blob.decode() {
                Ok(BlobDecode::OsmHeader(h)) => {
                    let unsupported: Vec<&String> = h
                        .required_features()
                        .iter()
                        .filter(|f| !matches!(f.as_str(), "OsmSchema-V0.6" | "DenseNodes"))
                        .collect();
                    if unsupported.is_empty() {
                        Ok(None)
                    } else {
                        Err(format!("unsupported required features {unsupported:?}"))
                    }
                }
                Ok(BlobDecode::OsmData(_)) if i == 0 => {
                    Err("the first block is not an OSMHeader".to_string())
                }
                Ok(BlobDecode::OsmData(block)) => Ok(Some(f(&block))),
                Ok(BlobDecode::Unknown(t)) if i == 0 => {
                    Err(format!("the first block has unknown type {t:?}"))
                }
                Ok(BlobDecode::Unknown(_)) => Ok(None),
                Err(e) => Err(e.to_string()),
            }
        }));
        match decoded {
            Ok(Ok(v)) => Ok(v),
            Ok(Err(reason)) if i == 0 => Err(InputError::NotPbf {
                path: self.path.clone(),
                reason,
            }),
            Ok(Err(reason)) => Err(self.corrupt(i, Some(frame.start), reason)),
            Err(_) => Err(self.corrupt(i, Some(frame.start), "the block cannot be decoded")),
        }
    }

    /// Runs `f` on every data block of kind `want` (and every `Any` block), in parallel
    /// batches, and returns the results in file order, with whether a block held elements of
    /// another kind than the sweep saw (then the caller starts again with every blob `Any`).
    fn pass<T, F>(
        &self,
        locs: &[BlobLoc],
        want: BlobKind,
        f: F,
    ) -> Result<(Vec<T>, bool), InputError>
    where
        T: Send,
        F: Fn(&PrimitiveBlock) -> T + Sync,
    {
        let mut file = self.file()?;
        let mut out = Vec::new();
        let mut mixed = false;
        let wanted: Vec<&BlobLoc> = locs
            .iter()
            .filter(|l| l.kind == want || l.kind == BlobKind::Any)
            .collect();
        for chunk in wanted.chunks(BATCH) {
            let mut batch = Vec::with_capacity(chunk.len());
            for l in chunk {
                let mut bytes = vec![0u8; l.len];
                file.seek(SeekFrom::Start(l.start))
                    .and_then(|_| file.read_exact(&mut bytes))
                    .map_err(|e| self.corrupt(l.index, Some(l.start), e.to_string()))?;
                batch.push((
                    l.kind,
                    Frame {
                        index: l.index,
                        start: l.start,
                        data: 0,
                        bytes,
                        data_blob: true,
                    },
                ));
            }
            let results: Vec<Result<Option<(T, bool)>, InputError>> = batch
                .par_iter()
                .map(|(kind, frame)| {
                    self.decode(frame, |block| {
                        let foreign = *kind != BlobKind::Any && holds_other_than(block, want);
                        (f(block), foreign)
                    })
                })
                .collect();
            for r in results {
                if let Some((v, foreign)) = r? {
                    mixed |= foreign;
                    out.push(v);
                }
            }
        }
        Ok((out, mixed))
    }
}

/// Reads until `buf` is full or the end of the input; returns the bytes read.
fn read_full(r: &mut impl Read, buf: &mut [u8]) -> std::io::Result<usize> {
    let mut n = 0;
    while n < buf.len() {
        match r.read(&mut buf[n..]) {
            Ok(0) => break,
            Ok(k) => n += k,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
            Err(e) => return Err(e),
        }
    }
    Ok(n)
}

/// Whether a block holds elements of another kind than `want`.
fn holds_other_than(block: &PrimitiveBlock, want: BlobKind) -> bool {
    block.groups().any(|g| {
        let nodes = g.nodes().next().is_some() || g.dense_nodes().next().is_some();
        let ways = g.ways().next().is_some();
        let rels = g.relations().next().is_some();
        match want {
            BlobKind::Nodes => ways || rels,
            BlobKind::Ways => nodes || rels,
            BlobKind::Relations => nodes || ways,
            BlobKind::Any => false,
        }
    })
}

/// A protobuf varint at `*pos`, advancing it; `None` when the bytes end or it is too long.
fn varint(b: &[u8], pos: &mut usize) -> Option<u64> {
    let mut v = 0u64;
    for shift in (0..64).step_by(7) {
        let byte = *b.get(*pos)?;
        *pos += 1;
        v |= u64::from(byte & 0x7f) << shift;
        if byte & 0x80 == 0 {
            return Some(v);
        }
    }
    None
}

/// Skips a field of wire type `wire` at `*pos`; `None` when the bytes end or the type is
/// unknown.
fn skip_field(b: &[u8], pos: &mut usize, wire: u64) -> Option<()> {
    let end = match wire {
        0 => return varint(b, pos).map(|_| ()),
        1 => pos.checked_add(8)?,
        2 => {
            let len = usize::try_from(varint(b, pos)?).ok()?;
            pos.checked_add(len)?
        }
        5 => pos.checked_add(4)?,
        _ => return None,
    };
    (end <= b.len()).then(|| *pos = end)
}

/// A BlobHeader's type (field 1) and data size (field 3).
fn parse_blob_header(b: &[u8]) -> Option<(&[u8], u64)> {
    let (mut pos, mut kind, mut size) = (0, None, None);
    while pos < b.len() {
        let key = varint(b, &mut pos)?;
        match key {
            0x0a => {
                let len = usize::try_from(varint(b, &mut pos)?).ok()?;
                let end = pos.checked_add(len).filter(|&e| e <= b.len())?;
                kind = Some(&b[pos..end]);
                pos = end;
            }
            0x18 => size = Some(varint(b, &mut pos)?),
            _ => skip_field(b, &mut pos, key & 7)?,
        }
    }
    Some((kind?, size?))
}

/// The kind of a data blob's first group, inflating only as much of the block as it takes
/// (the string table and the first group's first field). `Any` when it cannot tell.
fn peek_kind(blob: &[u8]) -> BlobKind {
    // Blob: field 1 raw bytes, field 3 zlib_data; other compressions are left to osmpbf.
    let (mut pos, mut raw, mut zlib) = (0, None, None);
    while pos < blob.len() {
        let Some(key) = varint(blob, &mut pos) else {
            return BlobKind::Any;
        };
        if key == 0x0a || key == 0x1a {
            let Some(len) = varint(blob, &mut pos).and_then(|l| usize::try_from(l).ok()) else {
                return BlobKind::Any;
            };
            let Some(end) = pos.checked_add(len).filter(|&e| e <= blob.len()) else {
                return BlobKind::Any;
            };
            if key == 0x0a {
                raw = Some(&blob[pos..end]);
            } else {
                zlib = Some(&blob[pos..end]);
            }
            pos = end;
        } else if skip_field(blob, &mut pos, key & 7).is_none() {
            return BlobKind::Any;
        }
    }
    if let Some(r) = raw {
        return first_group_kind(r, true).unwrap_or(BlobKind::Any);
    }
    let Some(z) = zlib else {
        return BlobKind::Any;
    };
    let mut inflater = flate2::Decompress::new(true);
    let mut buf: Vec<u8> = Vec::with_capacity(16 * 1024);
    loop {
        if buf.len() == buf.capacity() {
            if buf.len() as u64 >= MAX_BLOB {
                return BlobKind::Any;
            }
            buf.reserve(buf.len());
        }
        let consumed = usize::try_from(inflater.total_in()).unwrap_or(usize::MAX);
        let Some(input) = z.get(consumed..) else {
            return BlobKind::Any;
        };
        let before = buf.len();
        let status = match inflater.decompress_vec(input, &mut buf, flate2::FlushDecompress::None) {
            Ok(s) => s,
            Err(_) => return BlobKind::Any,
        };
        let done = status == flate2::Status::StreamEnd;
        if let Some(kind) = first_group_kind(&buf, done) {
            return kind;
        }
        let stuck = buf.len() == before
            && usize::try_from(inflater.total_in()).unwrap_or(usize::MAX) == consumed;
        if done || stuck {
            return BlobKind::Any;
        }
    }
}

/// The kind of a PrimitiveBlock's first non-empty group (field 2), from its first field;
/// `None` when `b` is a prefix too short to tell (and `complete` is false).
fn first_group_kind(b: &[u8], complete: bool) -> Option<BlobKind> {
    let more = if complete { Some(BlobKind::Any) } else { None };
    let mut pos = 0;
    loop {
        if pos >= b.len() {
            return more;
        }
        let Some(key) = varint(b, &mut pos) else {
            return more;
        };
        if key == 0x12 {
            let Some(len) = varint(b, &mut pos) else {
                return more;
            };
            if len == 0 {
                continue;
            }
            let Some(inner) = varint(b, &mut pos) else {
                return more;
            };
            return Some(match inner >> 3 {
                1 | 2 => BlobKind::Nodes,
                3 => BlobKind::Ways,
                4 => BlobKind::Relations,
                _ => BlobKind::Any,
            });
        }
        if skip_field(b, &mut pos, key & 7).is_none() {
            return more;
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Pass results

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum RelKind {
    Building,
    Part,
    /// A multipolygon without tags of its own: an old-style multipolygon whose outer way may
    /// carry `building=*`.
    Untagged,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Role {
    Outer,
    Inner,
    Unknown,
}

#[derive(Clone, Debug)]
struct Member {
    way: i64,
    role: Role,
}

#[derive(Clone, Debug)]
struct RelRec {
    id: i64,
    kind: RelKind,
    tags: Tags,
    members: Vec<Member>,
    /// Node and relation members: not geometry of a multipolygon, reported and left out.
    other_members: usize,
}

#[derive(Clone, Debug)]
struct WayRec {
    id: i64,
    refs: Vec<i64>,
    /// `Some` for a building or part way.
    kind: Option<FootprintKind>,
    /// Parsed tags of building/part ways only, parsed in the parallel pass; taken (moved into
    /// the footprint) during assembly, so the raw strings are never all held at once.
    tags: Option<SharedTags>,
    /// Whether the way is a street (see [`STREET_KINDS`]).
    street: bool,
}

/// Coordinates of the needed nodes: `coords[i]` belongs to `ids[i]`.
///
/// Compact (16 bytes a node with its id): a coordinate is kept as its 1e-7 degree integer
/// (the PBF default granularity), from which the reader's f64 is rebuilt bit for bit; the
/// rare coordinate that is not a whole number of 1e-7 degrees goes to `exact`.
struct Nodes {
    ids: Vec<i64>,
    /// `ids[k * FENCE]` for every k: a small table that stays in cache and narrows each lookup
    /// to one run of `FENCE` ids.
    fences: Vec<i64>,
    /// (lon, lat) in 1e-7 degrees; [`MISSING`] when not in the file, [`EXACT`] when in `exact`.
    coords: Vec<[i32; 2]>,
    /// (index, lon, lat) of the coordinates `coords` cannot hold, sorted by index.
    exact: Vec<(usize, f64, f64)>,
}

const FENCE: usize = 128;
const MISSING: i32 = i32::MIN;
const EXACT: i32 = i32::MAX;

impl Nodes {
    fn new(ids: Vec<i64>) -> Nodes {
        let coords = vec![[MISSING; 2]; ids.len()];
        Nodes {
            fences: ids.iter().step_by(FENCE).copied().collect(),
            ids,
            coords,
            exact: Vec::new(),
        }
    }

    /// Sets node `i` from nanodegrees (as osmpbf gives them).
    fn set(&mut self, i: usize, nano_lon: i64, nano_lat: i64) {
        let small = |n: i64| {
            (n % 100 == 0)
                .then_some(n / 100)
                .and_then(|d| i32::try_from(d).ok())
                .filter(|d| *d != MISSING && *d != EXACT)
        };
        match (small(nano_lon), small(nano_lat)) {
            (Some(x), Some(y)) => self.coords[i] = [x, y],
            _ => self.set_exact(i, degrees(nano_lon), degrees(nano_lat)),
        }
    }

    /// Sets node `i` to exact degrees.
    fn set_exact(&mut self, i: usize, lon: f64, lat: f64) {
        self.coords[i] = [EXACT; 2];
        self.exact.push((i, lon, lat));
    }

    /// Sorts the exact table; call once all nodes are set.
    fn finish(&mut self) {
        self.exact.sort_by_key(|e| e.0);
        self.exact.dedup_by_key(|e| e.0);
    }

    fn get(&self, id: i64) -> Option<(f64, f64)> {
        let k = self.fences.partition_point(|&f| f <= id).checked_sub(1)?;
        let run = &self.ids[k * FENCE..self.ids.len().min((k + 1) * FENCE)];
        let i = k * FENCE + run.binary_search(&id).ok()?;
        match self.coords[i] {
            [MISSING, _] => None,
            [EXACT, _] => {
                let k = self.exact.binary_search_by_key(&i, |e| e.0).ok()?;
                Some((self.exact[k].1, self.exact[k].2))
            }
            [x, y] => Some((degrees(i64::from(x) * 100), degrees(i64::from(y) * 100))),
        }
    }
}

/// Degrees from nanodegrees, computed as osmpbf's `lat()`/`lon()` do.
fn degrees(nano: i64) -> f64 {
    1e-9 * nano as f64
}

/// The footprint kind a tag set asks for: `building=*` other than `no`, else `building:part=*`
/// other than `no`.
fn kind_of<'a>(tags: impl Iterator<Item = (&'a str, &'a str)>) -> Option<FootprintKind> {
    let mut building = false;
    let mut part = false;
    for (k, v) in tags {
        match k {
            "building" if v.trim() != "no" => building = true,
            "building:part" if v.trim() != "no" => part = true,
            _ => {}
        }
    }
    if building {
        Some(FootprintKind::Building)
    } else if part {
        Some(FootprintKind::Part)
    } else {
        None
    }
}

/// Keys that do not make a multipolygon "tagged": with only these, the tags live on the ways.
fn is_metadata_key(k: &str) -> bool {
    k == "type"
        || k == "created_by"
        || k.starts_with("source")
        || k.starts_with("note")
        || k.eq_ignore_ascii_case("fixme")
}

fn relations_of_block(block: &PrimitiveBlock) -> Vec<RelRec> {
    let mut out = Vec::new();
    for group in block.groups() {
        for rel in group.relations() {
            if !rel
                .tags()
                .any(|(k, v)| k == "type" && v.trim() == "multipolygon")
            {
                continue;
            }
            let kind = match kind_of(rel.tags()) {
                Some(FootprintKind::Building) => RelKind::Building,
                Some(FootprintKind::Part) => RelKind::Part,
                None if rel.tags().all(|(k, _)| is_metadata_key(k)) => RelKind::Untagged,
                None => continue,
            };
            let mut members = Vec::new();
            let mut other_members = 0;
            for m in rel.members() {
                if m.member_type == RelMemberType::Way {
                    let role = match m.role().map(|r| r.trim()) {
                        Ok("outer") => Role::Outer,
                        Ok("inner") => Role::Inner,
                        _ => Role::Unknown,
                    };
                    members.push(Member {
                        way: m.member_id,
                        role,
                    });
                } else {
                    other_members += 1;
                }
            }
            out.push(RelRec {
                id: rel.id(),
                kind,
                tags: owned(rel.tags()),
                members,
                other_members,
            });
        }
    }
    out
}

fn owned<'a>(tags: impl Iterator<Item = (&'a str, &'a str)>) -> Tags {
    tags.map(|(k, v)| (k.to_string(), v.to_string())).collect()
}

fn ways_of_block(
    block: &PrimitiveBlock,
    member_ways: &[i64],
    interner: &TagInterner,
) -> Vec<WayRec> {
    let mut out = Vec::new();
    for group in block.groups() {
        for way in group.ways() {
            let kind = kind_of(way.tags());
            let member = member_ways.binary_search(&way.id()).is_ok();
            let street = is_street(way.tags());
            if kind.is_none() && !member && !street {
                continue;
            }
            out.push(WayRec {
                id: way.id(),
                refs: way.refs().collect(),
                kind,
                tags: kind.map(|_| interner.intern(BuildingTags::from_pairs(way.tags()))),
                street,
            });
        }
    }
    out
}

/// The needed nodes of a block as (index in `needed`, nanodegrees lon, lat). Node ids in a
/// block are usually ascending, so the index is found by walking forward (binary search only
/// for the first node and after a step back).
fn nodes_of_block(block: &PrimitiveBlock, needed: &[i64]) -> Vec<(usize, i64, i64)> {
    let mut out = Vec::new();
    let mut j = 0usize;
    let mut last = i64::MAX;
    let mut visit = |id: i64, lon: i64, lat: i64| {
        if id < last {
            j = needed.partition_point(|&x| x < id);
        } else {
            while j < needed.len() && needed[j] < id {
                j += 1;
            }
        }
        last = id;
        if needed.get(j) == Some(&id) {
            out.push((j, lon, lat));
        }
    };
    for g in block.groups() {
        for n in g.dense_nodes() {
            visit(n.id(), n.nano_lon(), n.nano_lat());
        }
        for n in g.nodes() {
            visit(n.id(), n.nano_lon(), n.nano_lat());
        }
    }
    out
}

// ---------------------------------------------------------------------------------------------
// Assembly

/// A way's node list resolved to coordinates, or how many nodes are missing.
fn resolve(refs: &[i64], nodes: &Nodes) -> Result<Ring, usize> {
    let mut pts = Vec::with_capacity(refs.len());
    let mut missing = 0;
    for &r in refs {
        match nodes.get(r) {
            Some(p) => pts.push(p),
            None => missing += 1,
        }
    }
    if missing > 0 {
        Err(missing)
    } else {
        Ok(pts)
    }
}

fn list_ids(ids: &[i64], prefix: &str) -> String {
    let mut s: Vec<String> = ids
        .iter()
        .take(MAX_LISTED)
        .map(|i| format!("{prefix}/{i}"))
        .collect();
    if ids.len() > MAX_LISTED {
        s.push(format!("and {} more", ids.len() - MAX_LISTED));
    }
    s.join(", ")
}

/// One open or closed piece of a multipolygon ring: node ids and their coordinates.
struct Segment {
    way: i64,
    role: Role,
    ids: Vec<i64>,
    pts: Ring,
}

/// A ring joined from segments, with the ways it came from and the role they declared.
struct JoinedRing {
    ways: Vec<i64>,
    claim: Option<bool>,
    pts: Ring,
}

/// Joins segments end to end into closed rings (by node id, reversing segments as needed).
/// Returns the closed rings and the ways of the pieces that could not be closed.
fn join_segments(mut pool: Vec<Segment>) -> (Vec<JoinedRing>, Vec<Vec<i64>>) {
    let mut rings = Vec::new();
    let mut open = Vec::new();
    pool.reverse(); // pop() then takes members in relation order
    while let Some(first) = pool.pop() {
        let mut ids = first.ids;
        let mut pts = first.pts;
        let mut ways = vec![first.way];
        let mut roles = vec![first.role];
        while let (Some(&start), Some(&end)) = (ids.first(), ids.last()) {
            if start == end && ids.len() > 1 {
                break;
            }
            // Prefer a segment with the same role, then any; last in pool = earliest member.
            let pick = |same_role: bool| {
                pool.iter().rposition(|s| {
                    (!same_role || s.role == roles[0])
                        && (s.ids.first() == Some(&end) || s.ids.last() == Some(&end))
                })
            };
            let Some(k) = pick(true).or_else(|| pick(false)) else {
                break;
            };
            let mut s = pool.remove(k);
            if s.ids.first() != Some(&end) {
                s.ids.reverse();
                s.pts.reverse();
            }
            ids.extend_from_slice(&s.ids[1..]);
            pts.extend_from_slice(&s.pts[1..]);
            ways.push(s.way);
            roles.push(s.role);
        }
        if ids.len() > 1 && ids.first() == ids.last() {
            let claim = if roles.iter().all(|r| *r == Role::Outer) {
                Some(true)
            } else if roles.iter().all(|r| *r == Role::Inner) {
                Some(false)
            } else {
                None
            };
            rings.push(JoinedRing { ways, claim, pts });
        } else {
            open.push(ways);
        }
    }
    (rings, open)
}

/// What a multipolygon relation turned into.
struct Assembled {
    /// (outer ring, holes, ways of the outer ring)
    polygons: Vec<(Ring, Vec<Ring>, Vec<i64>)>,
    /// Problems met on the way, for the report.
    problems: Vec<String>,
}

fn assemble_relation(rel: &RelRec, ways: &[WayRec], nodes: &Nodes) -> Assembled {
    let mut problems = Vec::new();
    let mut missing_ways = Vec::new();
    let mut missing_nodes = Vec::new();
    let mut duplicate_members = 0;
    let mut seen: Vec<i64> = Vec::new();
    let mut pool = Vec::new();
    // Outer members the file lacks (way or nodes): an inner ring must then not be promoted to
    // an outer one, or a courtyard would be built as a building.
    let mut missing_outer = 0usize;
    for m in &rel.members {
        if seen.contains(&m.way) {
            duplicate_members += 1;
            continue;
        }
        seen.push(m.way);
        let Ok(i) = ways.binary_search_by_key(&m.way, |w| w.id) else {
            missing_ways.push(m.way);
            if m.role == Role::Outer {
                missing_outer += 1;
            }
            continue;
        };
        let w = &ways[i];
        match resolve(&w.refs, nodes) {
            Ok(pts) => {
                // Drop consecutive duplicate nodes, keeping ids and points in step.
                let mut ids = Vec::with_capacity(w.refs.len());
                let mut clean = Vec::with_capacity(pts.len());
                for (id, p) in w.refs.iter().zip(pts) {
                    if ids.last() != Some(id) {
                        ids.push(*id);
                        clean.push(p);
                    }
                }
                if ids.len() >= 2 {
                    pool.push(Segment {
                        way: w.id,
                        role: m.role,
                        ids,
                        pts: clean,
                    });
                } else {
                    problems.push(format!("member way/{} has fewer than 2 nodes", w.id));
                }
            }
            Err(n) => {
                missing_nodes.push((w.id, n, w.refs.len()));
                if m.role == Role::Outer {
                    missing_outer += 1;
                }
            }
        }
    }
    if !missing_ways.is_empty() {
        problems.push(format!(
            "{} member way(s) missing from the file ({})",
            missing_ways.len(),
            list_ids(&missing_ways, "way")
        ));
    }
    for (w, n, total) in &missing_nodes {
        problems.push(format!(
            "member way/{w} left out: {n} of {total} nodes missing from the file"
        ));
    }
    if duplicate_members > 0 {
        problems.push(format!("{duplicate_members} duplicate member(s) ignored"));
    }
    if rel.other_members > 0 {
        problems.push(format!(
            "{} node/relation member(s) ignored",
            rel.other_members
        ));
    }
    let (joined, open) = join_segments(pool);
    for ways in &open {
        problems.push(format!(
            "ring that cannot be closed dropped ({})",
            list_ids(ways, "way")
        ));
    }
    let mut rings: Vec<Ring> = Vec::new();
    let mut claims = Vec::new();
    let mut ring_ways = Vec::new();
    for mut r in joined {
        ring::dedup_by(&mut r.pts, |a, b| a == b);
        if let Some(why) = ring_problem(&r.pts) {
            problems.push(format!(
                "ring of {} dropped: {why}",
                list_ids(&r.ways, "way")
            ));
            continue;
        }
        rings.push(r.pts);
        claims.push(r.claim);
        ring_ways.push(r.ways);
    }
    let g = group_rings(&rings, &claims);
    if g.role_fixes > 0 && missing_outer > 0 {
        problems.push(format!(
            "incomplete multipolygon: {missing_outer} outer member(s) missing, so its other rings are not built as the building"
        ));
        return Assembled {
            polygons: Vec::new(),
            problems,
        };
    }
    if g.role_fixes > 0 {
        problems.push(format!(
            "{} ring role(s) corrected by containment",
            g.role_fixes
        ));
    }
    let polygons = g
        .polygons
        .iter()
        .map(|(o, hs)| {
            (
                rings[*o].clone(),
                hs.iter().map(|h| rings[*h].clone()).collect(),
                ring_ways[*o].clone(),
            )
        })
        .collect();
    Assembled { polygons, problems }
}

/// A building/part relation's footprint (`None` when skipped) and its report entries.
type RelOutcome = (Option<Footprint>, Vec<(Outcome, String)>, RelRec);

/// Turns the three passes' results into footprints and report entries.
fn assemble(
    ways: &mut [WayRec],
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
    let way_kind = |id: i64| {
        ways.binary_search_by_key(&id, |w| w.id)
            .ok()
            .and_then(|i| ways[i].kind)
    };

    for rel in rels {
        let a = assemble_relation(rel, ways, nodes);
        match rel.kind {
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

    // The rings of the building/part ways, built in parallel: the costly part (node lookups,
    // clean-up, checks); report entries are then added in way order.
    let rings: Vec<Option<Result<Ring, String>>> = ways
        .par_iter()
        .map(|w| w.kind.map(|_| way_ring(w, &built_by, nodes)))
        .collect();
    let mut result = ReadResult::default();
    for (w, ring) in ways.iter_mut().zip(rings) {
        let (Some(kind), Some(ring)) = (w.kind, ring) else {
            continue;
        };
        let id = SourceId::Way(w.id);
        count_read(report, kind);
        let outer = match ring {
            Ok(r) => r,
            Err(why) => {
                report.skipped += 1;
                report.add(Some(id), Outcome::Skipped, why);
                continue;
            }
        };
        let tags = w.tags.take().unwrap_or_default();
        let holes = match old_style.binary_search_by_key(&w.id, |(x, _, _)| *x) {
            Ok(i) => {
                let (_, r, holes) = &old_style[i];
                report.add(
                    Some(id),
                    Outcome::Note,
                    format!(
                        "{} hole(s) taken from old-style multipolygon relation/{r}",
                        holes.len()
                    ),
                );
                holes.clone()
            }
            Err(_) => Vec::new(),
        };
        for (_, note) in old_style_notes.iter().filter(|(x, _)| *x == w.id) {
            report.add(Some(id), Outcome::Note, note.clone());
        }
        note_ignored(report, id, &tags);
        result.footprints.push(Footprint {
            id,
            kind,
            polygons: vec![oriented_polygon(outer, holes)],
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

/// The cleaned outer ring of a building/part way, or why it is skipped. `built_by` is sorted.
fn way_ring(w: &WayRec, built_by: &[(i64, i64)], nodes: &Nodes) -> Result<Ring, String> {
    let first = built_by.partition_point(|(x, _)| *x < w.id);
    if let Some((_, r)) = built_by.get(first).filter(|(x, _)| *x == w.id) {
        return Err(format!(
            "outer ring of multipolygon relation/{r}, which is built instead"
        ));
    }
    if w.refs.len() < 2 || w.refs.first() != w.refs.last() {
        return Err(match (w.refs.first(), w.refs.last()) {
            (Some(a), Some(b)) if w.refs.len() >= 2 => {
                format!("unclosed way: first node node/{a}, last node node/{b}")
            }
            _ => format!("way with {} node(s)", w.refs.len()),
        });
    }
    let mut outer = resolve(&w.refs, nodes)
        .map_err(|n| format!("{n} of {} nodes missing from the file", w.refs.len()))?;
    ring::dedup_by(&mut outer, |a, b| a == b);
    if let Some(why) = ring_problem(&outer) {
        return Err(why.to_string());
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
mod tests;
