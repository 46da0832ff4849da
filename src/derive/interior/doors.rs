//! Shared walls, doors grown from the entrance or the stair, the merge of rooms no door
//! reaches, and the entrance on the front (step 7 of the algorithm in [`super`]).

use super::*;

/// A segment (start, end).
pub(super) type Seg = (DVec2, DVec2);
/// Two rooms (i < j) and the segments they share.
pub(super) type Adjacency = (usize, usize, Vec<Seg>);

/// Adjacency: for each pair of rooms that share boundary, the shared segments.
pub(super) struct Graph {
    /// (i, j, segments) with i < j.
    pub(super) pairs: Vec<Adjacency>,
}

pub(super) fn graph(protos: &[Proto]) -> Graph {
    let bounds: Vec<(DVec2, DVec2)> = protos.iter().map(|p| ring_bounds(&p.poly.outer)).collect();
    let mut pairs = Vec::new();
    for i in 0..protos.len() {
        for j in (i + 1)..protos.len() {
            let (a, b) = (bounds[i], bounds[j]);
            let e = geom::EPS;
            if a.0.x > b.1.x + e || b.0.x > a.1.x + e || a.0.y > b.1.y + e || b.0.y > a.1.y + e {
                continue;
            }
            let segs = geom::shared_segments(&protos[i].poly.outer, &protos[j].poly.outer);
            if !segs.is_empty() {
                pairs.push((i, j, segs));
            }
        }
    }
    Graph { pairs }
}

/// The rooms sharing boundary with room `r`, with the shared length.
pub(super) fn neighbours(protos: &[Proto], r: usize) -> Vec<(f64, usize)> {
    let a = ring_bounds(&protos[r].poly.outer);
    let e = geom::EPS;
    (0..protos.len())
        .filter(|&j| j != r)
        .filter_map(|j| {
            let b = ring_bounds(&protos[j].poly.outer);
            if a.0.x > b.1.x + e || b.0.x > a.1.x + e || a.0.y > b.1.y + e || b.0.y > a.1.y + e {
                return None;
            }
            let l: f64 = geom::shared_segments(&protos[r].poly.outer, &protos[j].poly.outer)
                .iter()
                .map(seg_len)
                .sum();
            (l > 0.0).then_some((l, j))
        })
        .collect()
}

pub(super) fn seg_len(s: &(DVec2, DVec2)) -> f64 {
    s.0.distance(s.1)
}

pub(super) fn longest(segs: &[(DVec2, DVec2)]) -> Option<(DVec2, DVec2)> {
    segs.iter()
        .copied()
        .max_by(|a, b| seg_len(a).total_cmp(&seg_len(b)))
}

/// A door of up to `width` centred on `s`, keeping `margin` to each end.
pub(super) fn door_on(s: (DVec2, DVec2), width: f64, margin: f64) -> ((DVec2, DVec2), f64) {
    let l = seg_len(&s);
    let w = width.min(l - 2.0 * margin).max(0.0);
    let mid = 0.5 * (s.0 + s.1);
    let dir = if l > 0.0 { (s.1 - s.0) / l } else { DVec2::X };
    ((mid - dir * 0.5 * w, mid + dir * 0.5 * w), w)
}

/// Merges room `r` into room `into` when their union is one simple polygon; returns whether it
/// did.
pub(super) fn merge(protos: &mut Vec<Proto>, r: usize, into: usize) -> bool {
    let u = geom::to_geo(&protos[r].poly).union(&geom::to_geo(&protos[into].poly));
    if u.0.len() != 1 {
        return false;
    }
    let p = geom::from_geo(&u.0[0]);
    if !p.holes.is_empty() || p.outer.len() < 3 || !geom::is_valid(&geom::to_geo(&p)) {
        return false;
    }
    // A union that touches itself (two rooms meeting at a corner and along a seam) is not one
    // room a writer can build.
    let (mut outers, pinched) = geom::simple_parts(&p.outer);
    if outers.len() != 1 || !pinched.is_empty() {
        return false;
    }
    protos[into].poly = Polygon::new(outers.remove(0), Vec::new());
    protos.remove(r);
    true
}

/// Merges slivers, grows the doors, merges unreachable rooms and builds the storey plan.
pub(super) fn finish(usable: &Polygon, mut protos: Vec<Proto>, ground: bool) -> Option<StoreyPlan> {
    // 1. Slivers into the neighbour with the longest shared boundary.
    let is_sliver = |p: &Proto| {
        let a = p.poly.area();
        p.kind != RoomKind::Stair
            && (a < SLIVER_AREA || 2.0 * a / perimeter(&p.poly.outer) < SLIVER_WIDTH)
    };
    let mut kept = vec![false; protos.len()];
    for _ in 0..500 {
        let bad = (0..protos.len())
            .filter(|&i| !kept[i] && is_sliver(&protos[i]))
            .min_by(|a, b| protos[*a].poly.area().total_cmp(&protos[*b].poly.area()));
        let Some(r) = bad else { break };
        let mut nbrs: Vec<(f64, usize)> = neighbours(&protos, r)
            .into_iter()
            .filter(|(_, o)| protos[*o].kind != RoomKind::Stair)
            .collect();
        nbrs.sort_by(|a, b| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1)));
        let mut merged = false;
        for (_, o) in nbrs {
            if merge(&mut protos, r, o) {
                kept.remove(r);
                merged = true;
                break;
            }
        }
        if !merged {
            if protos[r].poly.area() < 1e-3 {
                protos.remove(r);
                kept.remove(r);
            } else {
                // Nothing takes it: it stays a small room.
                kept[r] = true;
            }
        }
    }
    // 2. Doors, merging rooms that no door reaches.
    for _ in 0..100 {
        let g = graph(&protos);
        let entrance = if ground {
            entrance_for(usable, &protos)
        } else {
            None
        };
        let start = if ground {
            entrance.as_ref().map(|d| d.a)
        } else {
            protos.iter().position(|p| p.kind == RoomKind::Stair)
        };
        let start = start.or(if protos.is_empty() { None } else { Some(0) })?;
        let (doors, reached) = grow_doors(&protos, &g, start);
        let unreached: Vec<usize> = (0..protos.len()).filter(|i| !reached[*i]).collect();
        if unreached.is_empty() && (!ground || entrance.is_some()) {
            let (rooms, stair_room) = to_rooms(protos);
            let walls = g
                .pairs
                .iter()
                .flat_map(|(i, j, segs)| {
                    segs.iter().map(move |s| Wall {
                        a: *i,
                        b: *j,
                        segment: *s,
                    })
                })
                .collect();
            return Some(StoreyPlan {
                rooms,
                walls,
                doors,
                entrance,
                stair_room,
            });
        }
        if unreached.is_empty() {
            return None;
        }
        // Merge the smallest unreachable room into its best neighbour, reached ones first.
        let r = *unreached
            .iter()
            .filter(|i| protos[**i].kind != RoomKind::Stair)
            .min_by(|a, b| protos[**a].poly.area().total_cmp(&protos[**b].poly.area()))?;
        let mut nbrs: Vec<(bool, f64, usize)> = g
            .pairs
            .iter()
            .filter(|(i, j, _)| *i == r || *j == r)
            .map(|(i, j, s)| {
                let o = if *i == r { *j } else { *i };
                (!reached[o], s.iter().map(seg_len).sum::<f64>(), o)
            })
            .filter(|(_, _, o)| protos[*o].kind != RoomKind::Stair)
            .collect();
        nbrs.sort_by(|a, b| a.0.cmp(&b.0).then(b.1.total_cmp(&a.1)).then(a.2.cmp(&b.2)));
        if !nbrs.iter().any(|(_, _, o)| merge(&mut protos, r, *o)) {
            return None;
        }
    }
    None
}

pub(super) fn to_rooms(protos: Vec<Proto>) -> (Vec<Room>, Option<usize>) {
    let stair_room = protos.iter().position(|p| p.kind == RoomKind::Stair);
    let rooms = protos
        .into_iter()
        .map(|p| Room {
            polygon: p.poly,
            kind: p.kind,
            name: p.name,
            unit: p.unit,
            min_area: p.min_area,
        })
        .collect();
    (rooms, stair_room)
}

/// Prim-style spanning tree of doors from `start` (see the module documentation).
pub(super) fn grow_doors(protos: &[Proto], g: &Graph, start: usize) -> (Vec<Door>, Vec<bool>) {
    let n = protos.len();
    let mut reached = vec![false; n];
    let mut doors = Vec::new();
    if start >= n {
        return (doors, reached);
    }
    reached[start] = true;
    let edges: Vec<(usize, usize, (DVec2, DVec2))> = g
        .pairs
        .iter()
        .filter_map(|(i, j, s)| longest(s).map(|l| (*i, *j, l)))
        .filter(|(_, _, l)| seg_len(l) >= MIN_DOOR_WALL)
        .collect();
    let level = |s: usize, t: usize| -> u32 {
        let (a, b) = (&protos[s], &protos[t]);
        match (a.unit, b.unit) {
            (x, y) if x == y => 0,
            (None, Some(_)) if b.kind == RoomKind::Hall => 0,
            (Some(_), None) if a.kind == RoomKind::Hall => 0,
            (None, _) | (_, None) => 1,
            _ => 2,
        }
    };
    let mut adj: Vec<Vec<(usize, (DVec2, DVec2))>> = vec![Vec::new(); n];
    for &(i, j, seg) in &edges {
        adj[i].push((j, seg));
        adj[j].push((i, seg));
    }
    // Min-heap of candidate doors from reached rooms; the key orders by short wall, dwelling
    // crossing, passage rank of the source, then the longest wall (millimetres), then indices
    // so that ties break the same way everywhere.
    type Key = (u32, u32, u32, i64, usize, usize);
    let mut heap: std::collections::BinaryHeap<std::cmp::Reverse<Key>> =
        std::collections::BinaryHeap::new();
    let push = |heap: &mut std::collections::BinaryHeap<std::cmp::Reverse<Key>>,
                s: usize,
                adj: &[Vec<(usize, (DVec2, DVec2))>],
                reached: &[bool]| {
        for (t, seg) in &adj[s] {
            if reached[*t] {
                continue;
            }
            let l = seg_len(seg);
            heap.push(std::cmp::Reverse((
                u32::from(l < DOOR_WALL),
                level(s, *t),
                protos[s].kind.passage_rank(),
                -((l * 1000.0).round() as i64),
                s,
                *t,
            )));
        }
    };
    push(&mut heap, start, &adj, &reached);
    while let Some(std::cmp::Reverse((_, _, _, _, s, t))) = heap.pop() {
        if reached[t] {
            continue;
        }
        let Some(seg) = adj[s].iter().find(|(o, _)| *o == t).map(|x| x.1) else {
            continue;
        };
        reached[t] = true;
        let (segment, width) = door_on(seg, DOOR_WIDTH, 0.1);
        doors.push(Door {
            a: s,
            b: Some(t),
            segment,
            width,
        });
        push(&mut heap, t, &adj, &reached);
    }
    (doors, reached)
}

/// The entrance: on the outer ring of the usable polygon, front-facing first, then the best
/// circulation room, then the longest wall.
pub(super) fn entrance_for(usable: &Polygon, protos: &[Proto]) -> Option<Door> {
    let mut best: Option<((u32, u32, f64), usize, Seg)> = None;
    for (k, p) in protos.iter().enumerate() {
        if p.kind == RoomKind::Stair {
            continue;
        }
        for s in geom::shared_segments(&p.poly.outer, &usable.outer) {
            let l = seg_len(&s);
            if l < MIN_ENTRANCE_WALL {
                continue;
            }
            // Room rings are CCW: the outward normal is the edge turned clockwise; the front
            // is -y in the plan frame.
            let d = (s.1 - s.0) / l;
            let facing = DVec2::new(d.y, -d.x).dot(DVec2::new(0.0, -1.0));
            // Common circulation (a corridor, an entrance hall) before any dwelling's hall.
            let key = (
                u32::from(l < ENTRANCE_WIDTH + 0.3) * 4
                    + u32::from(facing < 0.5) * 2
                    + u32::from(p.unit.is_some()),
                p.kind.passage_rank(),
                -l,
            );
            let better = best.as_ref().is_none_or(|b| {
                (key.0, key.1)
                    .cmp(&(b.0 .0, b.0 .1))
                    .then(key.2.total_cmp(&b.0 .2))
                    .is_lt()
            });
            if better {
                best = Some((key, k, s));
            }
        }
    }
    best.map(|(_, k, s)| {
        let (segment, width) = door_on(s, ENTRANCE_WIDTH, 0.05);
        Door {
            a: k,
            b: None,
            segment,
            width,
        }
    })
}
