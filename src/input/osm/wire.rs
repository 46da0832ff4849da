//! Direct decoding of the data blocks the ways and nodes passes read, without osmpbf's
//! protobuf objects (one allocation per element and per packed array, a UTF-8 check per tag
//! read).
//!
//! The decoder is strict: it accepts only what rust-protobuf (osmpbf's parser) accepts and in
//! the layout every common writer uses (one string table, packed arrays in one piece, one
//! `dense` per group, only the kind of element the pass wants). Anything else — an encoding
//! it does not take, a block of another kind, a corrupt or unusual blob — makes it answer
//! `None`, and the block is decoded by osmpbf instead, as before. So the results, the errors
//! and the detection of mixed blocks are osmpbf's in every case. The fields the passes do not
//! use (element metadata, node tags) are checked as rust-protobuf reads them, so a block that
//! osmpbf would refuse is refused too.

use super::*;
use crate::input::tags::is_known_key;

/// Reusable state of one decoding thread: the inflater and the inflated block.
pub(super) struct Scratch {
    inflater: flate2::Decompress,
    block: Vec<u8>,
}

impl Default for Scratch {
    fn default() -> Self {
        Scratch {
            inflater: flate2::Decompress::new(true),
            block: Vec::new(),
        }
    }
}

/// A protobuf varint as rust-protobuf reads it: at most 10 bytes, the 10th at most 1.
#[inline]
fn varint(b: &[u8], pos: &mut usize) -> Option<u64> {
    let mut v = 0u64;
    for i in 0..10 {
        let byte = *b.get(*pos)?;
        *pos += 1;
        if i == 9 && byte & 0x7f > 1 {
            return None;
        }
        v |= u64::from(byte & 0x7f) << (7 * i);
        if byte < 0x80 {
            return Some(v);
        }
    }
    None
}

fn zigzag(v: u64) -> i64 {
    ((v >> 1) as i64) ^ -((v & 1) as i64)
}

/// One field of a message.
#[derive(Clone, Copy)]
enum Value<'a> {
    Varint(u64),
    Bytes(&'a [u8]),
    /// A fixed32 or fixed64 (never a field the passes read).
    Fixed,
}

/// The fields of a message in order; `Err` ends the walk at bytes rust-protobuf would refuse
/// (or this decoder does not take: groups, wire types 3 and 4).
struct Fields<'a> {
    b: &'a [u8],
    pos: usize,
}

fn fields(b: &[u8]) -> Fields<'_> {
    Fields { b, pos: 0 }
}

impl<'a> Iterator for Fields<'a> {
    type Item = Result<(u32, Value<'a>), ()>;

    fn next(&mut self) -> Option<Self::Item> {
        if self.pos >= self.b.len() {
            return None;
        }
        Some(self.field().ok_or(()))
    }
}

impl<'a> Fields<'a> {
    fn field(&mut self) -> Option<(u32, Value<'a>)> {
        let key = u32::try_from(varint(self.b, &mut self.pos)?).ok()?;
        let number = key >> 3;
        if number == 0 {
            return None;
        }
        let value = match key & 7 {
            0 => Value::Varint(varint(self.b, &mut self.pos)?),
            1 | 5 => {
                let n = if key & 7 == 1 { 8 } else { 4 };
                let end = self.pos.checked_add(n).filter(|&e| e <= self.b.len())?;
                self.pos = end;
                Value::Fixed
            }
            2 => {
                let len = u32::try_from(varint(self.b, &mut self.pos)?).ok()? as usize;
                let end = self.pos.checked_add(len).filter(|&e| e <= self.b.len())?;
                let v = &self.b[self.pos..end];
                self.pos = end;
                Value::Bytes(v)
            }
            _ => return None,
        };
        Some((number, value))
    }
}

/// How rust-protobuf reads each element of a packed array.
#[derive(Clone, Copy)]
enum Packed {
    /// int64, sint64, uint64, bool: any varint.
    Any64,
    /// uint32, sint32 (read as a uint32 first).
    U32,
    /// int32: the varint as an i64 must fit an i32.
    I32,
}

/// Whether a packed array reads without error.
fn check_packed(b: &[u8], kind: Packed) -> bool {
    let mut pos = 0;
    while pos < b.len() {
        let Some(v) = varint(b, &mut pos) else {
            return false;
        };
        let ok = match kind {
            Packed::Any64 => true,
            Packed::U32 => v <= u64::from(u32::MAX),
            Packed::I32 => i32::try_from(v as i64).is_ok(),
        };
        if !ok {
            return false;
        }
    }
    true
}

/// The next element of a packed uint32 array; `Err` when it is malformed.
#[inline]
fn next_u32(b: &[u8], pos: &mut usize) -> Result<Option<u32>, ()> {
    if *pos >= b.len() {
        return Ok(None);
    }
    let v = varint(b, pos).ok_or(())?;
    u32::try_from(v).map(Some).map_err(|_| ())
}

/// Whether an `Info` message reads without error.
fn check_info(b: &[u8]) -> bool {
    for f in fields(b) {
        match f {
            Err(()) => return false,
            // version, uid: int32.
            Ok((1 | 4, Value::Varint(v))) if i32::try_from(v as i64).is_err() => return false,
            // user_sid: uint32.
            Ok((5, Value::Varint(v))) if v > u64::from(u32::MAX) => return false,
            Ok((1..=6, Value::Varint(_))) => {}
            Ok((1..=6, _)) => return false,
            Ok(_) => {}
        }
    }
    true
}

/// Whether a `DenseInfo` message reads without error (and in one piece per array).
fn check_dense_info(b: &[u8]) -> bool {
    let mut seen = 0u32;
    for f in fields(b) {
        let (n, v) = match f {
            Ok(f) => f,
            Err(()) => return false,
        };
        if !(1..=6).contains(&n) {
            continue;
        }
        let Value::Bytes(arr) = v else {
            return false;
        };
        if seen & (1 << n) != 0 {
            return false;
        }
        seen |= 1 << n;
        let kind = match n {
            1 => Packed::I32,
            4 | 5 => Packed::U32,
            _ => Packed::Any64,
        };
        if !check_packed(arr, kind) {
            return false;
        }
    }
    true
}

/// A decoded PrimitiveBlock's parts the passes use.
pub(super) struct Block<'a> {
    /// The string table, `None` for an entry that is not UTF-8.
    strings: Vec<Option<&'a str>>,
    groups: Vec<&'a [u8]>,
    granularity: i64,
    lat_offset: i64,
    lon_offset: i64,
}

impl<'a> Block<'a> {
    fn parse(b: &'a [u8]) -> Option<Block<'a>> {
        let mut strings = None;
        let mut groups = Vec::new();
        let (mut granularity, mut lat_offset, mut lon_offset) = (100i64, 0i64, 0i64);
        for f in fields(b) {
            match f.ok()? {
                (1, Value::Bytes(t)) => {
                    if strings.is_some() {
                        return None;
                    }
                    let mut s = Vec::new();
                    for f in fields(t) {
                        match f.ok()? {
                            (1, Value::Bytes(x)) => s.push(std::str::from_utf8(x).ok()),
                            (1, _) => return None,
                            _ => {}
                        }
                    }
                    strings = Some(s);
                }
                (2, Value::Bytes(g)) => groups.push(g),
                (n @ (17 | 18), Value::Varint(v)) => {
                    let v = i32::try_from(v as i64).ok()?;
                    if n == 17 {
                        granularity = i64::from(v);
                    }
                }
                (19, Value::Varint(v)) => lat_offset = v as i64,
                (20, Value::Varint(v)) => lon_offset = v as i64,
                (1 | 2 | 17..=20, _) => return None,
                _ => {}
            }
        }
        Some(Block {
            strings: strings?,
            groups,
            granularity,
            lat_offset,
            lon_offset,
        })
    }

    /// The string at `i` as osmpbf's tag iterators give it (`None` ends the tags).
    #[inline]
    fn string(&self, i: u32) -> Option<&'a str> {
        self.strings.get(i as usize).copied().flatten()
    }
}

/// The PrimitiveBlock of a data frame (4-byte length, BlobHeader, Blob), inflated into
/// `scratch` when compressed; `None` for anything osmpbf should look at itself.
pub(super) fn inflated<'s>(frame: &'s Frame, scratch: &'s mut Scratch) -> Option<&'s [u8]> {
    if frame.index == 0 {
        return None;
    }
    let b = &frame.bytes;
    let hlen = u32::from_be_bytes(b.get(..4)?.try_into().ok()?) as usize;
    if hlen >= MAX_HEADER {
        return None;
    }
    let header = b.get(4..4 + hlen)?;
    let (mut kind, mut size) = (None, None);
    for f in fields(header) {
        match f.ok()? {
            (1, Value::Bytes(t)) => kind = Some(std::str::from_utf8(t).ok()?),
            (2, Value::Bytes(_)) => {}
            (3, Value::Varint(v)) => size = Some(i32::try_from(v as i64).ok()?),
            (1..=3, _) => return None,
            _ => {}
        }
    }
    if kind? != "OSMData" {
        return None;
    }
    let size = usize::try_from(size?).ok()?;
    let blob = b.get(4 + hlen..)?;
    if blob.len() != size {
        return None;
    }
    let (mut raw, mut zlib, mut data_fields) = (None, None, 0);
    for f in fields(blob) {
        match f.ok()? {
            (1, Value::Bytes(r)) => raw = Some(r),
            (3, Value::Bytes(z)) => zlib = Some(z),
            (2, Value::Varint(v)) => {
                i32::try_from(v as i64).ok()?;
                continue;
            }
            (1..=7, _) => return None,
            _ => continue,
        }
        data_fields += 1;
    }
    if data_fields != 1 {
        return None;
    }
    if let Some(r) = raw {
        return ((r.len() as u64) < MAX_BLOB).then_some(r);
    }
    let z = zlib?;
    let Scratch { inflater, block } = scratch;
    inflater.reset(true);
    block.clear();
    loop {
        if block.len() == block.capacity() {
            block.reserve(block.len().max(64 * 1024));
        }
        let consumed = usize::try_from(inflater.total_in()).ok()?;
        let before = block.len();
        let status = inflater
            .decompress_vec(z.get(consumed..)?, block, flate2::FlushDecompress::None)
            .ok()?;
        if block.len() as u64 > MAX_BLOB {
            return None;
        }
        if status == flate2::Status::StreamEnd {
            return Some(block.as_slice());
        }
        let stuck = block.len() == before
            && usize::try_from(inflater.total_in()).ok()? == consumed
            && block.len() < block.capacity();
        if stuck {
            return None;
        }
    }
}

/// The ways of a block of ways (see [`ways_of_block`]), or `None` for osmpbf to decode it.
pub(super) fn fast_ways(
    frame: &Frame,
    scratch: &mut Scratch,
    member_ways: &[i64],
    interner: &TagInterner,
) -> Option<WayBlock> {
    let bytes = inflated(frame, scratch)?;
    let block = Block::parse(bytes)?;
    let mut out = WayBlock::default();
    let mut tags: Vec<(&str, &str)> = Vec::new();
    let mut known: Vec<(&str, &str)> = Vec::new();
    type TagsGive = (
        Option<FootprintKind>,
        Option<StreetKind>,
        Option<Arc<str>>,
        Option<SharedTags>,
        Option<Tags>,
    );
    let mut seen: std::collections::HashMap<(&[u8], &[u8]), TagsGive> =
        std::collections::HashMap::new();
    for g in &block.groups {
        for f in fields(g) {
            let Value::Bytes(w) = (match f.ok()? {
                (3, v) => v,
                // Other elements, or changesets: osmpbf decides.
                (1..=5, _) => return None,
                _ => continue,
            }) else {
                return None;
            };
            let (mut id, mut keys, mut vals, mut refs) = (None, None, None, None);
            for f in fields(w) {
                match f.ok()? {
                    (1, Value::Varint(v)) => id = Some(v as i64),
                    (2, Value::Bytes(k)) if keys.is_none() => keys = Some(k),
                    (3, Value::Bytes(v)) if vals.is_none() => vals = Some(v),
                    (4, Value::Bytes(i)) if check_info(i) => {}
                    (8, Value::Bytes(r)) if refs.is_none() => refs = Some(r),
                    (9 | 10, Value::Bytes(l)) if check_packed(l, Packed::Any64) => {}
                    (1..=4 | 8..=10, _) => return None,
                    _ => {}
                }
            }
            let id = id?;
            let (keys, vals, refs) = (
                keys.unwrap_or_default(),
                vals.unwrap_or_default(),
                refs.unwrap_or_default(),
            );
            // What the tags give depends only on their bytes: worked out once per tag set of
            // the block (most ways of a block share a few).
            let (kind, street, name, shared, boundary) = match seen.get(&(keys, vals)) {
                Some(v) => v.clone(),
                None => {
                    if !check_packed(keys, Packed::U32) || !check_packed(vals, Packed::U32) {
                        return None;
                    }
                    // osmpbf's tag iterator: pairs until either list ends or a string is
                    // unusable.
                    tags.clear();
                    let (mut kp, mut vp) = (0, 0);
                    while let (Ok(Some(k)), Ok(Some(v))) =
                        (next_u32(keys, &mut kp), next_u32(vals, &mut vp))
                    {
                        match (block.string(k), block.string(v)) {
                            (Some(k), Some(v)) => tags.push((k, v)),
                            _ => break,
                        }
                    }
                    let kind = kind_of(tags.iter().copied());
                    let street = street_of(tags.iter().copied());
                    let name = match (&street, kind) {
                        (Some((_, n)), _) => n.clone(),
                        (None, Some(_)) => addr_street_of(tags.iter().copied()),
                        (None, None) => None,
                    };
                    let street = street.map(|s| s.0);
                    let boundary = admin_boundary(|| tags.iter().copied());
                    let shared = kind.map(|_| {
                        known.clear();
                        known.extend(tags.iter().filter(|(k, _)| is_known_key(k)));
                        interner.intern_pairs(&known)
                    });
                    let give = (kind, street, name, shared, boundary);
                    seen.insert((keys, vals), give.clone());
                    give
                }
            };
            let member = member_ways.binary_search(&id).is_ok();
            let kept = kind.is_some() || member || street.is_some();
            if !kept && boundary.is_none() {
                if !check_packed(refs, Packed::Any64) {
                    return None;
                }
                continue;
            }
            // Decoding the node ids checks them too.
            let start = out.refs.len();
            let (mut pos, mut current) = (0, 0i64);
            while pos < refs.len() {
                current = current.wrapping_add(zigzag(varint(refs, &mut pos)?));
                out.refs.push(current);
            }
            if !out.keep_boundary(id, boundary, start) && !kept {
                out.refs.truncate(start);
                continue;
            }
            let w = WayRec {
                id,
                block: 0,
                start: 0,
                end: 0,
                kind,
                tags: shared,
                street,
                name,
            };
            out.push(w, start);
        }
    }
    Some(out)
}

/// The needed nodes of a block of nodes (see [`nodes_of_block`]), or `None` for osmpbf to
/// decode it.
pub(super) fn fast_nodes(
    frame: &Frame,
    scratch: &mut Scratch,
    needed: &[i64],
) -> Option<NodeBlock> {
    let bytes = inflated(frame, scratch)?;
    let block = Block::parse(bytes)?;
    let mut out = Found::default();
    let mut addresses: Vec<AddrNode> = Vec::new();
    let (g, lat0, lon0) = (block.granularity, block.lat_offset, block.lon_offset);
    // Tags are read only in a block whose string table holds `addr:street` (issue 45).
    let addr_keys: Vec<u32> = (0..block.strings.len())
        .filter(|&i| block.strings[i] == Some("addr:street"))
        .filter_map(|i| u32::try_from(i).ok())
        .collect();
    let nano = |lon: i64, lat: i64| {
        (
            lon0.wrapping_add(g.wrapping_mul(lon)),
            lat0.wrapping_add(g.wrapping_mul(lat)),
        )
    };
    let mut cursor = NeededCursor::new(needed);
    let mut visit = |out: &mut Found, id: i64, lat: i64, lon: i64| {
        if let Some(j) = cursor.find(id) {
            let (x, y) = nano(lon, lat);
            out.push(j, x, y);
        }
    };
    // The `addr:street` among the (key, value) string indices of one node's tags, as
    // `addr_street_of` reads osmpbf's (a string that is not UTF-8 ends the tags).
    // Keys compared by their index, not their text: a block of nodes holds many tags.
    let street = |pairs: &mut dyn Iterator<Item = (u32, u32)>| -> Option<Arc<str>> {
        for (k, v) in pairs {
            let (Some(_), Some(value)) = (block.string(k), block.string(v)) else {
                return None;
            };
            if addr_keys.contains(&k) && !value.trim().is_empty() {
                return Some(Arc::from(value.trim()));
            }
        }
        None
    };
    let mut plain: Vec<&[u8]> = Vec::new();
    for grp in &block.groups {
        let mut dense = None;
        plain.clear();
        for f in fields(grp) {
            match f.ok()? {
                (1, Value::Bytes(n)) => plain.push(n),
                (2, Value::Bytes(d)) if dense.is_none() => dense = Some(d),
                (1..=5, _) => return None,
                _ => {}
            }
        }
        if let Some(d) = dense {
            let (mut ids, mut lats, mut lons, mut kvs) = (None, None, None, None);
            for f in fields(d) {
                match f.ok()? {
                    (1, Value::Bytes(a)) if ids.is_none() => ids = Some(a),
                    (8, Value::Bytes(a)) if lats.is_none() => lats = Some(a),
                    (9, Value::Bytes(a)) if lons.is_none() => lons = Some(a),
                    (5, Value::Bytes(i)) if check_dense_info(i) => {}
                    (10, Value::Bytes(kv)) if kvs.is_none() && check_packed(kv, Packed::I32) => {
                        kvs = Some(kv)
                    }
                    (1 | 5 | 8..=10, _) => return None,
                    _ => {}
                }
            }
            let (ids, lats, lons) = (
                ids.unwrap_or_default(),
                lats.unwrap_or_default(),
                lons.unwrap_or_default(),
            );
            out.reserve(ids.iter().filter(|&&b| b < 0x80).count());
            // Decoding checks the arrays as it goes; what is left of the longer ones after.
            let (mut pi, mut pa, mut po, mut pk) = (0, 0, 0, 0);
            let (mut id, mut lat, mut lon) = (0i64, 0i64, 0i64);
            while pi < ids.len() && pa < lats.len() && po < lons.len() {
                id = id.wrapping_add(zigzag(varint(ids, &mut pi)?));
                lat = lat.wrapping_add(zigzag(varint(lats, &mut pa)?));
                lon = lon.wrapping_add(zigzag(varint(lons, &mut po)?));
                visit(&mut out, id, lat, lon);
                // This node's tags: (key, value) pairs up to a 0.
                if let (Some(kv), false) = (kvs, addr_keys.is_empty()) {
                    let mut pairs = std::iter::from_fn(|| {
                        let k = u32::try_from(varint(kv, &mut pk)?).ok()?;
                        if k == 0 {
                            return None;
                        }
                        let v = u32::try_from(varint(kv, &mut pk)?).ok()?;
                        Some((k, v))
                    })
                    // Not a step past this node's 0 once it has ended.
                    .fuse();
                    let a = street(&mut pairs);
                    // What the lookup left of this node's pairs.
                    pairs.for_each(drop);
                    if let Some(a) = a {
                        let (x, y) = nano(lon, lat);
                        addresses.push((x, y, a));
                    }
                }
            }
            if !check_packed(&ids[pi..], Packed::Any64)
                || !check_packed(&lats[pa..], Packed::Any64)
                || !check_packed(&lons[po..], Packed::Any64)
            {
                return None;
            }
        }
        for n in &plain {
            let (mut id, mut lat, mut lon) = (None, None, None);
            let (mut keys, mut vals): (&[u8], &[u8]) = (&[], &[]);
            for f in fields(n) {
                match f.ok()? {
                    (1, Value::Varint(v)) => id = Some(zigzag(v)),
                    (8, Value::Varint(v)) => lat = Some(zigzag(v)),
                    (9, Value::Varint(v)) => lon = Some(zigzag(v)),
                    (2, Value::Bytes(k)) if check_packed(k, Packed::U32) => keys = k,
                    (3, Value::Bytes(k)) if check_packed(k, Packed::U32) => vals = k,
                    (4, Value::Bytes(i)) if check_info(i) => {}
                    (1..=4 | 8 | 9, _) => return None,
                    _ => {}
                }
            }
            let (id, lat, lon) = (id?, lat?, lon?);
            visit(&mut out, id, lat, lon);
            if !addr_keys.is_empty() && !keys.is_empty() {
                let (mut a, mut b) = (0, 0);
                let mut pairs = std::iter::from_fn(|| {
                    Some((next_u32(keys, &mut a).ok()??, next_u32(vals, &mut b).ok()??))
                });
                if let Some(s) = street(&mut pairs) {
                    let (x, y) = nano(lon, lat);
                    addresses.push((x, y, s));
                }
            }
        }
    }
    Some((out, addresses))
}
