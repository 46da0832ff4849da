//! What the three passes keep of each block: relations with their members, ways with their
//! node references, and the compact index of the needed nodes.

use super::*;

// ---------------------------------------------------------------------------------------------
// Pass results

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum RelKind {
    Building,
    Part,
    /// A multipolygon without tags of its own: an old-style multipolygon whose outer way may
    /// carry `building=*`.
    Untagged,
    /// An administrative boundary (`type=boundary` or `multipolygon`, `boundary=administrative`,
    /// `admin_level` 2..=10); its tags are only those of [`BOUNDARY_KEYS`].
    Boundary,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Role {
    Outer,
    Inner,
    Unknown,
}

#[derive(Clone, Debug)]
pub(super) struct Member {
    pub(super) way: i64,
    pub(super) role: Role,
}

#[derive(Clone, Debug)]
pub(super) struct RelRec {
    pub(super) id: i64,
    pub(super) kind: RelKind,
    pub(super) tags: Tags,
    pub(super) members: Vec<Member>,
    /// Node and relation members: not geometry of a multipolygon, reported and left out.
    pub(super) other_members: usize,
}

#[derive(Clone, Debug)]
pub(super) struct WayRec {
    pub(super) id: i64,
    /// Its node ids: `refs[start..end]` of its block (see [`Ways`]); `block` is set when the
    /// blocks are merged.
    pub(super) block: u32,
    pub(super) start: u32,
    pub(super) end: u32,
    /// `Some` for a building or part way.
    pub(super) kind: Option<FootprintKind>,
    /// Parsed tags of building/part ways only, parsed in the parallel pass; taken (moved into
    /// the footprint) during assembly, so the raw strings are never all held at once.
    pub(super) tags: Option<SharedTags>,
    /// The street's kind when the way is a street (see [`STREET_KINDS`]).
    pub(super) street: Option<StreetKind>,
    /// A street's `name`, a building or part way's `addr:street` (issue 45: the street its
    /// door faces).
    pub(super) name: Option<Arc<str>>,
}

/// The ways one block keeps, their node ids in one list (no allocation per way).
#[derive(Default)]
pub(super) struct WayBlock {
    pub(super) ways: Vec<WayRec>,
    pub(super) refs: Vec<i64>,
    /// Closed ways tagged as an admin boundary themselves, with their [`BOUNDARY_KEYS`] tags
    /// (few: most boundaries are relations).
    pub(super) boundaries: Vec<(i64, Tags)>,
}

impl WayBlock {
    /// Adds a way whose node ids were just pushed onto `refs` from `start` on.
    pub(super) fn push(&mut self, mut w: WayRec, start: usize) {
        // A block is at most `MAX_BLOB` bytes, at least one byte a node id: far below u32::MAX.
        w.start = start as u32;
        w.end = self.refs.len() as u32;
        self.ways.push(w);
    }

    /// The node ids of the block's ways, sorted, without duplicates. The ids of a block mostly
    /// come ascending (way after way, but for each closed way's last node, its first again):
    /// they are taken in one run, and only the few that step back are sorted and merged in.
    pub(super) fn needed(&self) -> Vec<i64> {
        let mut run = Vec::with_capacity(self.refs.len());
        let mut back = Vec::new();
        for w in &self.ways {
            let refs = &self.refs[w.start as usize..w.end as usize];
            for (i, &r) in refs.iter().enumerate() {
                match run.last() {
                    Some(&l) if r <= l => {
                        if r != l && (i == 0 || r != refs[0]) {
                            back.push(r);
                        }
                    }
                    _ => run.push(r),
                }
            }
        }
        if back.is_empty() {
            return run;
        }
        back.sort_unstable();
        back.dedup();
        let mut out = Vec::with_capacity(run.len() + back.len());
        merge_into(&mut out, &run, &back);
        out
    }

    /// The node ids of `w`, a way of this block.
    #[cfg(test)]
    pub(super) fn refs_of(&self, w: &WayRec) -> &[i64] {
        &self.refs[w.start as usize..w.end as usize]
    }
}

/// The ways of all blocks, sorted by id; their node ids stay in their blocks' lists.
pub(super) struct Ways {
    pub(super) recs: Vec<WayRec>,
    refs: Vec<Vec<i64>>,
    /// The blocks' closed boundary ways ([`WayBlock::boundaries`]), sorted by id.
    pub(super) boundaries: Vec<(i64, Tags)>,
}

impl Ways {
    /// Merges the blocks' ways in file order, then sorts them by id (stable: the first of
    /// duplicates stays first).
    pub(super) fn from_blocks(blocks: Vec<WayBlock>) -> Ways {
        let mut recs = Vec::with_capacity(blocks.iter().map(|b| b.ways.len()).sum());
        let mut refs = Vec::with_capacity(blocks.len());
        let mut boundaries = Vec::new();
        for (i, b) in blocks.into_iter().enumerate() {
            recs.extend(b.ways.into_iter().map(|mut w| {
                w.block = i as u32;
                w
            }));
            refs.push(b.refs);
            boundaries.extend(b.boundaries);
        }
        recs.sort_by_key(|w| w.id);
        boundaries.sort_by_key(|b| b.0);
        Ways {
            recs,
            refs,
            boundaries,
        }
    }

    /// Adds the ways of one more block (their ids not among `recs`), keeping `recs` sorted by
    /// id.
    pub(super) fn add_block(&mut self, b: WayBlock) {
        let block = self.refs.len() as u32;
        self.recs.extend(b.ways.into_iter().map(|mut w| {
            w.block = block;
            w
        }));
        self.refs.push(b.refs);
        // Two sorted runs: the stable sort merges them in linear time.
        self.recs.sort_by_key(|w| w.id);
        self.boundaries.extend(b.boundaries);
        self.boundaries.sort_by_key(|b| b.0);
    }

    /// The node ids of `w`, one of `recs`.
    pub(super) fn refs(&self, w: &WayRec) -> &[i64] {
        &self.refs[w.block as usize][w.start as usize..w.end as usize]
    }

    /// The way with id `id`.
    pub(super) fn find(&self, id: i64) -> Option<&WayRec> {
        let i = self.recs.binary_search_by_key(&id, |w| w.id).ok()?;
        Some(&self.recs[i])
    }
}

/// Coordinates of the needed nodes: `coords[i]` belongs to `ids[i]`.
///
/// Compact (16 bytes a node with its id): a coordinate is kept as its 1e-7 degree integer
/// (the PBF default granularity), from which the reader's f64 is rebuilt bit for bit; the
/// rare coordinate that is not a whole number of 1e-7 degrees goes to `exact`.
pub(super) struct Nodes {
    pub(super) ids: Vec<i64>,
    /// `ids[k * FENCE]` for every k: a small table that stays in cache and narrows each lookup
    /// to one run of `FENCE` ids.
    pub(super) fences: Vec<i64>,
    /// (lon, lat) in 1e-7 degrees; [`MISSING`] when not in the file, [`EXACT`] when in `exact`.
    pub(super) coords: Vec<[i32; 2]>,
    /// (index, lon, lat) of the coordinates `coords` cannot hold, sorted by index.
    pub(super) exact: Vec<(usize, f64, f64)>,
}

pub(super) const FENCE: usize = 128;
/// How far [`Nodes::index_near`] looks around its hint before searching the whole index.
const GALLOP: usize = 32;
pub(super) const MISSING: i32 = i32::MIN;
pub(super) const EXACT: i32 = i32::MAX;

impl Nodes {
    pub(super) fn new(ids: Vec<i64>) -> Nodes {
        // Written in parallel: the first touch of the pages is most of the cost.
        let mut coords = Vec::new();
        (0..ids.len())
            .into_par_iter()
            .map(|_| [MISSING; 2])
            .collect_into_vec(&mut coords);
        Nodes {
            fences: ids.iter().step_by(FENCE).copied().collect(),
            ids,
            coords,
            exact: Vec::new(),
        }
    }

    /// Sets the nodes the blocks found, as setting them one by one in file order would (the
    /// last coordinate of a node found twice stays), in parallel over ranges of indices. Each
    /// block's nodes are sorted by index, stably ([`Found::sort`]); the blocks are in file
    /// order.
    pub(super) fn fill(&mut self, found: &[Found]) {
        const CHUNK: usize = 1 << 16;
        let exact: Vec<Vec<(usize, f64, f64)>> = self
            .coords
            .par_chunks_mut(CHUNK)
            .enumerate()
            .map(|(c, coords)| {
                let base = c * CHUNK;
                let end = base + coords.len();
                let mut exact = Vec::new();
                for b in found {
                    match b {
                        Found::Small(v) => {
                            let lo = v.partition_point(|e| (e.0 as usize) < base);
                            for &(i, c) in v[lo..].iter().take_while(|e| (e.0 as usize) < end) {
                                coords[i as usize - base] = c;
                            }
                        }
                        Found::Wide(v) => {
                            let lo = v.partition_point(|e| e.0 < base);
                            for &(i, lon, lat) in v[lo..].iter().take_while(|e| e.0 < end) {
                                match (small(lon), small(lat)) {
                                    (Some(x), Some(y)) => coords[i - base] = [x, y],
                                    _ => {
                                        coords[i - base] = [EXACT; 2];
                                        exact.push((i, degrees(lon), degrees(lat)));
                                    }
                                }
                            }
                        }
                    }
                }
                exact
            })
            .collect();
        self.exact.extend(exact.into_iter().flatten());
    }

    /// Sets node `i` to exact degrees.
    #[cfg(test)]
    pub(super) fn set_exact(&mut self, i: usize, lon: f64, lat: f64) {
        self.coords[i] = [EXACT; 2];
        self.exact.push((i, lon, lat));
    }

    /// Sets node `i` to (`lon`, `lat`) degrees (`None`: deleted, as if not in the file), after
    /// the pass: compact when the degrees are a whole number of 1e-7 degrees read as the
    /// PBF reader reads them, else exact.
    pub(super) fn set(&mut self, i: usize, pos: Option<(f64, f64)>) {
        let Some(c) = self.coords.get_mut(i) else {
            return;
        };
        let Some((lon, lat)) = pos else {
            *c = [MISSING; 2];
            return;
        };
        let compact = |deg: f64| {
            let nano = (deg * 1e9).round();
            if nano.is_nan() || nano.abs() >= 9e18 {
                return None;
            }
            let nano = nano as i64;
            (degrees(nano).to_bits() == deg.to_bits())
                .then(|| small(nano))
                .flatten()
        };
        match (compact(lon), compact(lat)) {
            (Some(x), Some(y)) => *c = [x, y],
            _ => {
                *c = [EXACT; 2];
                self.exact.push((i, lon, lat));
            }
        }
    }

    /// The index of node `id` among the needed ones.
    pub(super) fn index_of(&self, id: i64) -> Option<usize> {
        self.index(id)
    }

    /// Sorts the exact table, keeping the last entry set for an index; call once all nodes are
    /// set.
    pub(super) fn finish(&mut self) {
        // Reversed, then sorted stably: of one index's entries the last set comes first.
        self.exact.reverse();
        self.exact.sort_by_key(|e| e.0);
        self.exact.dedup_by_key(|e| e.0);
    }

    pub(super) fn get(&self, id: i64) -> Option<(f64, f64)> {
        self.coord(self.index(id)?)
    }

    /// The index of `id` in `ids`.
    fn index(&self, id: i64) -> Option<usize> {
        let k = self.fences.partition_point(|&f| f <= id).checked_sub(1)?;
        let run = &self.ids[k * FENCE..self.ids.len().min((k + 1) * FENCE)];
        Some(k * FENCE + run.binary_search(&id).ok()?)
    }

    /// The index of `id` in `ids`, searched from `hint` outwards first: the nodes of a way
    /// mostly have nearby ids, so the next one is a few places from the last.
    fn index_near(&self, id: i64, hint: usize) -> Option<usize> {
        let ids = &self.ids;
        let Some(&at) = ids.get(hint) else {
            return self.index(id);
        };
        if at == id {
            return Some(hint);
        }
        // Bracket `id` by steps doubling away from `hint` (at most `GALLOP` places), then
        // search the bracket.
        let (mut near, mut step) = (hint, 1usize);
        while step <= GALLOP {
            if at < id {
                let far = hint + step;
                match ids.get(far) {
                    Some(&x) if x < id => near = far,
                    Some(_) => {
                        return ids[near + 1..=far]
                            .binary_search(&id)
                            .ok()
                            .map(|i| near + 1 + i)
                    }
                    None => break,
                }
            } else {
                let Some(far) = hint.checked_sub(step) else {
                    break;
                };
                if ids[far] > id {
                    near = far;
                } else {
                    return ids[far..near].binary_search(&id).ok().map(|i| far + i);
                }
            }
            step *= 2;
        }
        self.index(id)
    }

    fn coord(&self, i: usize) -> Option<(f64, f64)> {
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

/// A node with an `addr:street` (issue 45: an address or entrance node inside or on a
/// footprint names the street its door faces): nanodegrees of longitude and latitude, and the
/// street's name, trimmed.
pub(super) type AddrNode = (i64, i64, Arc<str>);

/// What the nodes pass takes from one block: the needed nodes and the address nodes, each in
/// file order.
pub(super) type NodeBlock = (Found, Vec<AddrNode>);

/// The needed nodes one block holds, in file order: (index in the needed ids, lon, lat).
/// Compact (12 bytes a node) while every index fits a u32 and every coordinate is a whole
/// number of 1e-7 degrees, as [`Nodes`] keeps it; else as found (nanodegrees).
#[derive(Debug, PartialEq)]
pub(super) enum Found {
    Small(Vec<(u32, [i32; 2])>),
    Wide(Vec<(usize, i64, i64)>),
}

impl Default for Found {
    fn default() -> Self {
        Found::Small(Vec::new())
    }
}

impl Found {
    /// Adds node `j` of the needed ids at nanodegrees (as osmpbf gives them).
    #[inline]
    pub(super) fn push(&mut self, j: usize, nano_lon: i64, nano_lat: i64) {
        if let Found::Small(v) = self {
            if let (Ok(i), Some(x), Some(y)) = (u32::try_from(j), small(nano_lon), small(nano_lat))
            {
                v.push((i, [x, y]));
                return;
            }
            let wide = v
                .iter()
                .map(|&(i, [x, y])| (i as usize, i64::from(x) * 100, i64::from(y) * 100))
                .collect();
            *self = Found::Wide(wide);
        }
        if let Found::Wide(v) = self {
            v.push((j, nano_lon, nano_lat));
        }
    }

    pub(super) fn reserve(&mut self, n: usize) {
        match self {
            Found::Small(v) => v.reserve(n),
            Found::Wide(v) => v.reserve(n),
        }
    }

    /// Sorts the nodes by index, stably (a node found twice keeps its file order), and frees
    /// the room reserved for nodes not found: every block's result is held until the last
    /// block is decoded, and in an extract most nodes are not a building's (issue 46: 12 bytes
    /// a node of the file otherwise).
    pub(super) fn sort(&mut self) {
        match self {
            Found::Small(v) => {
                v.sort_by_key(|e| e.0);
                v.shrink_to_fit();
            }
            Found::Wide(v) => {
                v.sort_by_key(|e| e.0);
                v.shrink_to_fit();
            }
        }
    }
}

/// A coordinate in nanodegrees as the 1e-7 degree integer [`Nodes`] keeps, if it is one.
fn small(n: i64) -> Option<i32> {
    (n % 100 == 0)
        .then_some(n / 100)
        .and_then(|d| i32::try_from(d).ok())
        .filter(|d| *d != MISSING && *d != EXACT)
}

/// Degrees from nanodegrees, computed as osmpbf's `lat()`/`lon()` do.
pub(super) fn degrees(nano: i64) -> f64 {
    1e-9 * nano as f64
}

/// The footprint kind a tag set asks for: `building:part=*` other than `no` makes a part, even
/// with `building=*` as well (Simple 3D Buildings: a way tagged both, such as a church's dome
/// `building=church` + `building:part=yes`, is a part of the outline around it; one that lies
/// in no outline becomes a building holding itself and the parts inside it); else `building=*`
/// other than `no` an outline.
pub(super) fn kind_of<'a>(tags: impl Iterator<Item = (&'a str, &'a str)>) -> Option<FootprintKind> {
    let mut building = false;
    let mut part = false;
    for (k, v) in tags {
        match k {
            "building" if v.trim() != "no" => building = true,
            "building:part" if v.trim() != "no" => part = true,
            _ => {}
        }
    }
    if part {
        Some(FootprintKind::Part)
    } else if building {
        Some(FootprintKind::Building)
    } else {
        None
    }
}

/// Keys that do not make a multipolygon "tagged": with only these, the tags live on the ways.
pub(super) fn is_metadata_key(k: &str) -> bool {
    k == "type"
        || k == "created_by"
        || k.starts_with("source")
        || k.starts_with("note")
        || k.eq_ignore_ascii_case("fixme")
}

pub(super) fn relations_of_block(block: &PrimitiveBlock) -> Vec<RelRec> {
    let mut out = Vec::new();
    for group in block.groups() {
        for rel in group.relations() {
            let members = rel.members().map(|m| {
                (
                    m.member_type == RelMemberType::Way,
                    m.member_id,
                    m.role().ok(),
                )
            });
            out.extend(relation_rec(rel.id(), || rel.tags(), members));
        }
    }
    out
}

/// The tags an admin boundary keeps: its level and what names it.
pub(super) const BOUNDARY_KEYS: &[&str] = &[
    "admin_level",
    "name",
    "name:en",
    "int_name",
    "ISO3166-1",
    "ISO3166-1:alpha2",
    "ISO3166-2",
];

/// The [`BOUNDARY_KEYS`] tags when `tags` (given afresh at each call) make an admin boundary: `boundary=administrative`
/// and an `admin_level` in [`crate::input::ADMIN_LEVELS`].
pub(super) fn admin_boundary<'a, T: Iterator<Item = (&'a str, &'a str)>>(
    tags: impl Fn() -> T,
) -> Option<Tags> {
    // Nothing allocated for the ways and relations that are no boundary (nearly all).
    if !tags().any(|(k, v)| k == "boundary" && v.trim() == "administrative") {
        return None;
    }
    let kept: Tags = tags()
        .filter(|(k, _)| BOUNDARY_KEYS.contains(k))
        .map(|(k, v)| (k.to_string(), v.trim().to_string()))
        .collect();
    let level = kept
        .iter()
        .find(|(k, _)| k == "admin_level")
        .and_then(|(_, v)| v.parse::<u8>().ok());
    level
        .is_some_and(|l| crate::input::ADMIN_LEVELS.contains(&l))
        .then_some(kept)
}

/// What pass 1 keeps of a relation: `Some` for a `type=multipolygon` relation tagged
/// `building`/`building:part`, or with only metadata tags, and for an admin boundary
/// ([`admin_boundary`], `type=boundary` or `multipolygon`). `tags` gives the tags afresh at
/// each call; `members` are (is a way, id, role).
pub(super) fn relation_rec<'a, T: Iterator<Item = (&'a str, &'a str)>>(
    id: i64,
    tags: impl Fn() -> T,
    members: impl Iterator<Item = (bool, i64, Option<&'a str>)>,
) -> Option<RelRec> {
    let is_type = |t: &str| tags().any(|(k, v)| k == "type" && v.trim() == t);
    let (kind, kept) = if is_type("multipolygon") {
        match kind_of(tags()) {
            Some(FootprintKind::Building) => (RelKind::Building, owned(tags())),
            Some(FootprintKind::Part) => (RelKind::Part, owned(tags())),
            None if tags().all(|(k, _)| is_metadata_key(k)) => (RelKind::Untagged, owned(tags())),
            None => (RelKind::Boundary, admin_boundary(&tags)?),
        }
    } else if is_type("boundary") {
        (RelKind::Boundary, admin_boundary(&tags)?)
    } else {
        return None;
    };
    let mut way_members = Vec::new();
    let mut other_members = 0;
    for (is_way, way, role) in members {
        if is_way {
            let role = match role.map(str::trim) {
                Some("outer") => Role::Outer,
                Some("inner") => Role::Inner,
                _ => Role::Unknown,
            };
            way_members.push(Member { way, role });
        } else {
            other_members += 1;
        }
    }
    Some(RelRec {
        id,
        kind,
        tags: kept,
        members: way_members,
        other_members,
    })
}

pub(super) fn owned<'a>(tags: impl Iterator<Item = (&'a str, &'a str)>) -> Tags {
    tags.map(|(k, v)| (k.to_string(), v.to_string())).collect()
}

pub(super) fn ways_of_block(
    block: &PrimitiveBlock,
    member_ways: &[i64],
    interner: &TagInterner,
) -> WayBlock {
    let mut out = WayBlock::default();
    for group in block.groups() {
        for way in group.ways() {
            out.keep_way(way.id(), || way.tags(), way.refs(), member_ways, interner);
        }
    }
    out
}

impl WayBlock {
    /// Adds the way when the ways pass keeps it: a building or part way, a member of a kept
    /// relation (`member_ways`, sorted), a street or a closed admin boundary way
    /// ([`admin_boundary`]). `tags` gives the tags afresh at each call.
    pub(super) fn keep_way<'a, T: Iterator<Item = (&'a str, &'a str)>>(
        &mut self,
        id: i64,
        tags: impl Fn() -> T,
        refs: impl Iterator<Item = i64>,
        member_ways: &[i64],
        interner: &TagInterner,
    ) {
        let kind = kind_of(tags());
        let member = member_ways.binary_search(&id).is_ok();
        let street = street_of(tags());
        let boundary = admin_boundary(&tags);
        if kind.is_none() && !member && street.is_none() && boundary.is_none() {
            return;
        }
        let start = self.refs.len();
        self.refs.extend(refs);
        if !self.keep_boundary(id, boundary, start) && kind.is_none() && !member && street.is_none()
        {
            self.refs.truncate(start);
            return;
        }
        self.push(
            WayRec {
                id,
                block: 0,
                start: 0,
                end: 0,
                kind,
                tags: kind.map(|_| interner.intern(BuildingTags::from_pairs(tags()))),
                name: match (&street, kind) {
                    (Some((_, n)), _) => n.clone(),
                    (None, Some(_)) => addr_street_of(tags()),
                    (None, None) => None,
                },
                street: street.map(|s| s.0),
            },
            start,
        );
    }
}

impl WayBlock {
    /// Records way `id`, whose node ids were just pushed from `start` on, as a boundary way
    /// when it has `boundary` tags and is closed; whether it was.
    pub(super) fn keep_boundary(&mut self, id: i64, boundary: Option<Tags>, start: usize) -> bool {
        let refs = &self.refs[start..];
        match boundary {
            Some(tags) if refs.len() >= 4 && refs.first() == refs.last() => {
                self.boundaries.push((id, tags));
                true
            }
            _ => false,
        }
    }
}

/// Finds a block's node ids in the sorted list of needed ids. Node ids in a block are usually
/// ascending, so the index is found by walking forward (binary search only for the first node
/// and after a step back).
pub(super) struct NeededCursor<'a> {
    needed: &'a [i64],
    j: usize,
    last: i64,
}

impl<'a> NeededCursor<'a> {
    pub(super) fn new(needed: &'a [i64]) -> Self {
        NeededCursor {
            needed,
            j: 0,
            last: i64::MAX,
        }
    }

    /// The index of `id` in the needed list, if it is needed.
    #[inline]
    pub(super) fn find(&mut self, id: i64) -> Option<usize> {
        let needed = self.needed;
        if id < self.last {
            self.j = needed.partition_point(|&x| x < id);
        } else {
            while self.j < needed.len() && needed[self.j] < id {
                self.j += 1;
            }
        }
        self.last = id;
        (needed.get(self.j) == Some(&id)).then_some(self.j)
    }
}

/// The needed nodes of a block.
pub(super) fn nodes_of_block(block: &PrimitiveBlock, needed: &[i64]) -> NodeBlock {
    let mut out = Found::default();
    let mut addresses = Vec::new();
    let mut cursor = NeededCursor::new(needed);
    let mut visit = |id: i64, lon: i64, lat: i64| {
        if let Some(j) = cursor.find(id) {
            out.push(j, lon, lat);
        }
    };
    for g in block.groups() {
        for n in g.dense_nodes() {
            visit(n.id(), n.nano_lon(), n.nano_lat());
            if let Some(a) = addr_street_of(n.tags()) {
                addresses.push((n.nano_lon(), n.nano_lat(), a));
            }
        }
        for n in g.nodes() {
            visit(n.id(), n.nano_lon(), n.nano_lat());
            if let Some(a) = addr_street_of(n.tags()) {
                addresses.push((n.nano_lon(), n.nano_lat(), a));
            }
        }
    }
    (out, addresses)
}

// ---------------------------------------------------------------------------------------------
// Assembly

/// A way's node list resolved to coordinates, or how many nodes are missing.
pub(super) fn resolve(refs: &[i64], nodes: &Nodes) -> Result<Ring, usize> {
    let mut pts = Vec::with_capacity(refs.len());
    let mut missing = 0;
    let mut hint = None;
    for &r in refs {
        let found = match hint {
            Some(h) => nodes.index_near(r, h),
            None => nodes.index(r),
        };
        match found {
            Some(i) => {
                hint = Some(i);
                match nodes.coord(i) {
                    Some(p) => pts.push(p),
                    None => missing += 1,
                }
            }
            None => missing += 1,
        }
    }
    if missing > 0 {
        Err(missing)
    } else {
        Ok(pts)
    }
}

pub(super) fn list_ids(ids: &[i64], prefix: &str) -> String {
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
