//! Multipolygon assembly: member ways joined into closed rings, rings grouped into polygons
//! with holes, every problem named by way and node ids.

use super::*;

/// One open or closed piece of a multipolygon ring: node ids and their coordinates.
pub(super) struct Segment {
    pub(super) way: i64,
    pub(super) role: Role,
    pub(super) ids: Vec<i64>,
    pub(super) pts: Ring,
}

/// A ring joined from segments, with the ways it came from and the role they declared.
pub(super) struct JoinedRing {
    pub(super) ways: Vec<i64>,
    pub(super) claim: Option<bool>,
    pub(super) pts: Ring,
}

/// Joins segments end to end into closed rings (by node id, reversing segments as needed).
/// Returns the closed rings and the ways of the pieces that could not be closed.
///
/// Rings start from the earliest member left; at each open end the earliest member left that
/// meets it is taken, one of the same role as the ring's first if there is one. The members
/// are found by an index of their end nodes, so a relation of many members costs
/// O(n log n), not a scan of the pool at every end.
pub(super) fn join_segments(pool: Vec<Segment>) -> (Vec<JoinedRing>, Vec<Vec<i64>>) {
    use std::collections::{BTreeSet, HashMap};
    let mut rings = Vec::new();
    let mut open = Vec::new();
    // End node -> the members (by place) that start or end there and are not used yet.
    let mut ends: HashMap<i64, BTreeSet<usize>> = HashMap::new();
    for (k, s) in pool.iter().enumerate() {
        for id in [s.ids.first(), s.ids.last()].into_iter().flatten() {
            ends.entry(*id).or_default().insert(k);
        }
    }
    let roles: Vec<Role> = pool.iter().map(|s| s.role).collect();
    let mut pool: Vec<Option<Segment>> = pool.into_iter().map(Some).collect();
    let mut take = |k: usize, ends: &mut HashMap<i64, BTreeSet<usize>>| {
        let s = pool.get_mut(k).and_then(Option::take)?;
        for id in [s.ids.first(), s.ids.last()].into_iter().flatten() {
            if let Some(set) = ends.get_mut(id) {
                set.remove(&k);
            }
        }
        Some(s)
    };
    for first in 0..roles.len() {
        let Some(first) = take(first, &mut ends) else {
            continue;
        };
        let mut ids = first.ids;
        let mut pts = first.pts;
        let mut ways = vec![first.way];
        let mut ring_roles = vec![first.role];
        while let (Some(&start), Some(&end)) = (ids.first(), ids.last()) {
            if start == end && ids.len() > 1 {
                break;
            }
            // Prefer a segment with the same role, then any; the earliest member first.
            let at = ends.get(&end);
            let pick = |same_role: bool| {
                at.and_then(|set| {
                    set.iter()
                        .copied()
                        .find(|&k| !same_role || roles[k] == ring_roles[0])
                })
            };
            let Some(k) = pick(true).or_else(|| pick(false)) else {
                break;
            };
            let Some(mut s) = take(k, &mut ends) else {
                break;
            };
            if s.ids.first() != Some(&end) {
                s.ids.reverse();
                s.pts.reverse();
            }
            ids.extend_from_slice(&s.ids[1..]);
            pts.extend_from_slice(&s.pts[1..]);
            ways.push(s.way);
            ring_roles.push(s.role);
        }
        if ids.len() > 1 && ids.first() == ids.last() {
            let claim = if ring_roles.iter().all(|r| *r == Role::Outer) {
                Some(true)
            } else if ring_roles.iter().all(|r| *r == Role::Inner) {
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
pub(super) struct Assembled {
    /// (outer ring, holes, ways of the outer ring)
    pub(super) polygons: Vec<(Ring, Vec<Ring>, Vec<i64>)>,
    /// Problems met on the way, for the report.
    pub(super) problems: Vec<String>,
    /// Whether every member way was there with all its nodes and every ring closed and was
    /// usable: nothing of the relation was left out.
    pub(super) whole: bool,
    /// Whether an `inner` member was left out (missing, or in a ring that did not close).
    pub(super) inner_lost: bool,
}

pub(super) fn assemble_relation(rel: &RelRec, ways: &Ways, nodes: &Nodes) -> Assembled {
    let mut problems = Vec::new();
    let mut missing_ways = Vec::new();
    let mut missing_nodes = Vec::new();
    let mut duplicate_members = 0;
    let mut seen: std::collections::HashSet<i64> = std::collections::HashSet::new();
    let mut pool = Vec::new();
    // Outer members the file lacks (way or nodes): an inner ring must then not be promoted to
    // an outer one, or a courtyard would be built as a building.
    let mut missing_outer = 0usize;
    let mut inner_lost = false;
    for m in &rel.members {
        if !seen.insert(m.way) {
            duplicate_members += 1;
            continue;
        }
        let Some(w) = ways.find(m.way) else {
            missing_ways.push(m.way);
            if m.role == Role::Outer {
                missing_outer += 1;
            }
            inner_lost |= m.role == Role::Inner;
            continue;
        };
        let refs = ways.refs(w);
        match resolve(refs, nodes) {
            Ok(pts) => {
                // Drop consecutive duplicate nodes, keeping ids and points in step.
                let mut ids = Vec::with_capacity(refs.len());
                let mut clean = Vec::with_capacity(pts.len());
                for (id, p) in refs.iter().zip(pts) {
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
                missing_nodes.push((w.id, n, refs.len()));
                if m.role == Role::Outer {
                    missing_outer += 1;
                }
                inner_lost |= m.role == Role::Inner;
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
    let inner_ways: std::collections::HashSet<i64> = pool
        .iter()
        .filter(|s| s.role == Role::Inner)
        .map(|s| s.way)
        .collect();
    let (joined, open) = join_segments(pool);
    let mut whole = missing_ways.is_empty() && missing_nodes.is_empty() && open.is_empty();
    inner_lost |= open.iter().flatten().any(|w| inner_ways.contains(w));
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
        if let Some(why) = ring_problem(&r.pts)
            .map(str::to_string)
            .or_else(|| lonlat_problem(&r.pts))
        {
            problems.push(format!(
                "ring of {} dropped: {why}",
                list_ids(&r.ways, "way")
            ));
            whole = false;
            inner_lost |= r.claim != Some(true);
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
            whole: false,
            inner_lost,
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
    Assembled {
        polygons,
        problems,
        whole,
        inner_lost,
    }
}
