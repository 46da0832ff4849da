//! The IFC writer's caches of shared entities, and the views through which buildings rendered
//! in parallel use them.
//!
//! A building is rendered against a [`View`] of each cache as it was when its batch started,
//! its own insertions kept aside. The view logs every lookup with what it found; before the
//! building is appended, [`Log::holds`] replays the log against the cache as the buildings
//! before it left it: if every lookup finds the same, the rendering is exactly what a
//! sequential writer would have written, and [`Log::commit`] applies the insertions.
//! Otherwise the building is rendered again against the current caches.

use std::collections::BTreeMap;

use crate::export::step::Id;

/// A value held in a cache: entity ids, which may be local to the building that made them.
pub(super) trait Relocate: Copy + PartialEq {
    /// The value with its local ids given their file numbers ([`Id::relocate`]).
    fn relocate(self, start: u64) -> Self;
}

impl Relocate for Id {
    fn relocate(self, start: u64) -> Self {
        Id::relocate(self, start)
    }
}

impl Relocate for (Id, Id) {
    fn relocate(self, start: u64) -> Self {
        (self.0.relocate(start), self.1.relocate(start))
    }
}

/// A file-wide cache of shared entities: emptied when an insertion finds it holding `limit`
/// entries (see `SHARED_CACHE_LIMIT`).
pub(super) struct Cache<K, V> {
    pub(super) map: BTreeMap<K, V>,
    limit: usize,
    /// Insertions so far: a log made against the same version needs no replay.
    version: u64,
}

impl<K: Ord + Copy, V: Relocate> Cache<K, V> {
    pub(super) fn new(limit: usize) -> Cache<K, V> {
        Cache {
            map: BTreeMap::new(),
            limit,
            version: 0,
        }
    }

    pub(super) fn set_limit(&mut self, limit: usize) {
        self.limit = limit;
    }

    /// A view for rendering one building, logging into `log`'s storage (a log of a building
    /// appended before, reused).
    pub(super) fn view(&self, log: Log<K, V>) -> View<'_, K, V> {
        let mut log = log.ops;
        log.clear();
        View {
            base: self,
            over: BTreeMap::new(),
            cleared: false,
            log,
        }
    }

    fn insert(&mut self, k: K, v: V) {
        if self.map.len() >= self.limit {
            self.map.clear();
        }
        self.map.insert(k, v);
        self.version += 1;
    }
}

/// One operation of a view, with what a lookup found.
enum Op<K, V> {
    Get(K, Option<V>),
    Put(K, V),
}

/// A cache as one building sees it: the cache as it was, plus the building's own insertions.
pub(super) struct View<'a, K, V> {
    base: &'a Cache<K, V>,
    over: BTreeMap<K, V>,
    /// Whether an insertion of the building emptied the cache (then `base` is not seen).
    cleared: bool,
    log: Vec<Op<K, V>>,
}

impl<K: Ord + Copy, V: Relocate> View<'_, K, V> {
    pub(super) fn get(&mut self, k: &K) -> Option<V> {
        let found = lookup(&self.over, self.cleared, &self.base.map, k);
        self.log.push(Op::Get(*k, found));
        found
    }

    pub(super) fn insert(&mut self, k: K, v: V) {
        put(
            &mut self.over,
            &mut self.cleared,
            &self.base.map,
            self.base.limit,
            k,
            v,
        );
        self.log.push(Op::Put(k, v));
    }

    /// The log, detached from the cache.
    pub(super) fn into_log(self) -> Log<K, V> {
        Log {
            version: self.base.version,
            ops: self.log,
        }
    }
}

fn lookup<K: Ord, V: Copy>(
    over: &BTreeMap<K, V>,
    cleared: bool,
    base: &BTreeMap<K, V>,
    k: &K,
) -> Option<V> {
    match over.get(k) {
        Some(v) => Some(*v),
        None if !cleared => base.get(k).copied(),
        None => None,
    }
}

fn put<K: Ord, V>(
    over: &mut BTreeMap<K, V>,
    cleared: &mut bool,
    base: &BTreeMap<K, V>,
    limit: usize,
    k: K,
    v: V,
) {
    let len = over.len() + if *cleared { 0 } else { base.len() };
    if len >= limit {
        *cleared = true;
        over.clear();
    }
    over.insert(k, v);
}

/// What a building did with one cache ([`View::into_log`]).
pub(super) struct Log<K, V> {
    version: u64,
    ops: Vec<Op<K, V>>,
}

impl<K, V> Default for Log<K, V> {
    fn default() -> Self {
        Log {
            version: 0,
            ops: Vec::new(),
        }
    }
}

impl<K: Ord + Copy, V: Relocate> Log<K, V> {
    /// Whether every lookup of the log finds the same in `cache` as it did in the view.
    pub(super) fn holds(&self, cache: &Cache<K, V>) -> bool {
        if self.version == cache.version {
            return true;
        }
        let mut over = BTreeMap::new();
        let mut cleared = false;
        for op in &self.ops {
            match op {
                Op::Get(k, found) => {
                    if lookup(&over, cleared, &cache.map, k) != *found {
                        return false;
                    }
                }
                Op::Put(k, v) => put(&mut over, &mut cleared, &cache.map, cache.limit, *k, *v),
            }
        }
        true
    }

    /// Applies the log's insertions to `cache`, the building's local ids numbered from `start`.
    pub(super) fn commit(&self, cache: &mut Cache<K, V>, start: u64) {
        for op in &self.ops {
            if let Op::Put(k, v) = op {
                cache.insert(*k, v.relocate(start));
            }
        }
    }
}
