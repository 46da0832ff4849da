//! Parts at the precision they are written: every vertex on the output grid (the millimetre,
//! `crate::model::GRID_STEPS_PER_M`), distinct vertices at least `MIN_GAP` apart.
//!
//! The writers round coordinates (CityGML to three decimals). Rounding a part vertex by vertex
//! can merge two vertices that were distinct, fold a ring back on itself (`x, y, x`), or leave
//! a short edge whose tilt, once rounded, turns a triangle of its face by tens of degrees; a
//! validator that snaps vertices within 1 mm (val3dity's default) merges vertices one grid step
//! apart. So the model itself is put on the grid once, as a whole part, before anything is
//! written: `polygon_on_grid` for footprints, [`finish`] for the built surfaces. What every
//! writer then rounds is already round, and the part checked in memory
//! ([`super::check_part`], [`super::written_defects`]) is the part in the files.
//!
//! [`finish`] keeps the solid closed: vertices are merged into representatives part-wide (every
//! face that shares a vertex shares its representative), rings drop the repeats and spikes
//! that merging leaves, faces that collapse are dropped, and an edge left without its twin
//! takes the vertices that lie on it (a T-junction) so that it pairs up again.

use std::collections::HashMap;

use glam::{DVec2, DVec3};

use crate::geometry::{is_simple, ring, Polygon};
use crate::model::{on_grid, Face, Wall, GRID_STEPS_PER_M};

/// Distinct vertices of a part are at least this far apart before they are put on the grid
/// ([`crate::model::MIN_VERTEX_GAP`]). A part vertex moves by at most this much (a roof node
/// merged into its neighbour) plus half a grid step.
pub(crate) const MIN_GAP: f64 = crate::model::MIN_VERTEX_GAP;

/// [`MIN_GAP`] in grid steps: two vertices of the ground and the walls closer than this are one.
const MIN_GAP_STEPS: i64 = 3;

/// A vertex on the grid, in grid steps.
type Key = (i64, i64, i64);

fn key(p: DVec3) -> Key {
    crate::model::grid_key(p)
}

fn point(k: Key) -> DVec3 {
    DVec3::new(
        k.0 as f64 / GRID_STEPS_PER_M,
        k.1 as f64 / GRID_STEPS_PER_M,
        k.2 as f64 / GRID_STEPS_PER_M,
    )
}

/// A 2D point on the grid.
pub(crate) fn point2_on_grid(p: DVec2) -> DVec2 {
    DVec2::new(on_grid(p.x), on_grid(p.y))
}

/// The place nearest `u` (metres along the line from `start` to `end`, both on the grid), moved
/// towards `u + shift` by at most `|shift|`, whose point lies within a small fraction of a grid
/// step of the line, on the grid point the writers round it to.
///
/// An opening's corners are written rounded to the millimetre; a corner rounded half a
/// millimetre off its wall's plane, against a neighbour rounded the other way, tilts the long
/// thin triangles a validator makes between an opening 2 cm from the wall's base or top and the
/// wall's far corners by tens of degrees (val3dity's 204). Grid points by an oblique line lie at
/// every multiple of `1 / |end - start|` steps from it, so within a few steps along the line
/// there is one a hundredth of a step from it, or closer: the jamb moves there. `u` comes back
/// unchanged when `start` or `end` is not on the grid, or the line has no length.
pub(crate) fn along_on_grid(start: DVec2, end: DVec2, u: f64, shift: f64) -> f64 {
    let steps = |v: f64| v * GRID_STEPS_PER_M;
    let whole = |p: DVec2| {
        let (x, y) = (steps(p.x), steps(p.y));
        ((x - x.round()).abs() < 1e-6 && (y - y.round()).abs() < 1e-6)
            .then(|| (x.round() as i64, y.round() as i64))
    };
    let (Some(s), Some(e)) = (whole(start), whole(end)) else {
        return u;
    };
    let d = (e.0 - s.0, e.1 - s.1);
    let len = ((d.0 as f64).powi(2) + (d.1 as f64).powi(2)).sqrt();
    if !(len > 0.0 && u.is_finite() && shift.is_finite()) || d.0.abs().max(d.1.abs()) > 1 << 40 {
        return u;
    }
    // Along the line's dominant axis (a), one grid point per step: the other coordinate (b)
    // rounded to the line, scored by the cross product (an integer: |cross| / len steps off).
    let swap = d.1.abs() > d.0.abs();
    let (da, db) = if swap { (d.1, d.0) } else { (d.0, d.1) };
    let per_step = len / da.abs() as f64; // along-line steps per step of a
    let target = steps(u) / per_step * da.signum() as f64; // a offset of u from start
    let toward = if shift >= 0.0 {
        da.signum()
    } else {
        -da.signum()
    };
    let (lo, hi) = (steps(u.min(u + shift)), steps(u.max(u + shift)));
    let start_a = if toward > 0 {
        target.floor() as i64
    } else {
        target.ceil() as i64
    };
    let reach = (steps(shift.abs()) / per_step).ceil() as i64 + 1;
    // Staying put is a candidate: u's own point, as the writers round it.
    let here = {
        let t = DVec2::new(steps(start.x), steps(start.y))
            + (DVec2::new(d.0 as f64, d.1 as f64) / len) * steps(u);
        let q = (t.x.round() as i64 - s.0, t.y.round() as i64 - s.1);
        let cross = (q.0 as i128 * d.1 as i128 - q.1 as i128 * d.0 as i128).unsigned_abs();
        i64::try_from(cross).unwrap_or(i64::MAX)
    };
    let mut best: (i64, Option<f64>) = (here, None); // (|cross|, along in steps; None: u)
    for k in 0..=reach.min(100_000) {
        let qa = start_a + toward * k;
        let qb = ((qa as f64) * db as f64 / da as f64).round() as i64;
        let cross = (qa as i128 * db as i128 - qb as i128 * da as i128).unsigned_abs();
        let cross = i64::try_from(cross).unwrap_or(i64::MAX);
        // A point no closer to the line than the best so far changes nothing unless it is on
        // the line (which ends the search when it is within reach): its place is not needed.
        if cross >= best.0 && cross != 0 {
            continue;
        }
        let (qx, qy) = if swap { (qb, qa) } else { (qa, qb) };
        let along = (qx as f64 * d.0 as f64 + qy as f64 * d.1 as f64) / len;
        if along < lo || along > hi {
            continue;
        }
        if cross < best.0 {
            best = (cross, Some(along));
        }
        if cross == 0 {
            break;
        }
    }
    best.1.map_or(u, |along| along / GRID_STEPS_PER_M)
}

/// The footprint on the grid: every vertex rounded to the millimetre, vertices closer than
/// [`MIN_GAP`] to the one kept before them dropped, spikes removed. `None` when a ring is left
/// with fewer than 3 vertices or no area, or when a ring crosses or touches itself once rounded
/// ([`is_simple`]): the caller keeps the polygon as it was (a footprint a millimetre from
/// touching itself; the writers round it as they can). Idempotent: a polygon on the grid whose
/// vertices are [`MIN_GAP`] apart is returned unchanged.
pub(crate) fn polygon_on_grid(p: &Polygon) -> Option<Polygon> {
    let snap_ring = |r: &Vec<DVec2>| -> Option<Vec<DVec2>> {
        let mut v: Vec<DVec2> = r.iter().map(|q| point2_on_grid(*q)).collect();
        // Within the gap (measured on the grid, with a little slack for the division).
        ring::dedup_within(&mut v, MIN_GAP - 1e-3 / GRID_STEPS_PER_M);
        ring::remove_spikes_by(&mut v, |a, b| a == b);
        if v.len() < 3
            || crate::geometry::ring_signed_area(&v).abs() < 1.0 / GRID_STEPS_PER_M
            || !is_simple(&v)
        {
            return None;
        }
        Some(v)
    };
    let outer = snap_ring(&p.outer)?;
    let holes = p.holes.iter().map(snap_ring).collect::<Option<Vec<_>>>()?;
    let out = Polygon::new(outer, holes);
    holes_inside_and_apart(&out).then_some(out)
}

/// Whether every hole of `p` lies inside its outer ring and has no vertex inside another hole.
/// A vertex inside a ring lies in the ring's bounding box, so each hole is tested only against
/// the holes whose boxes meet its own, found in an R-tree: an outline with the holes of 10,000
/// parts costs O(n log n), not O(n²).
fn holes_inside_and_apart(p: &Polygon) -> bool {
    use rstar::primitives::{GeomWithData, Rectangle};
    use rstar::{RTree, RTreeObject};
    let contains = crate::geometry::ring_contains;
    let inside_outer = |h: &Vec<DVec2>| h.iter().all(|q| contains(&p.outer, *q));
    let apart = |i: usize, j: usize| {
        let (h, g) = (&p.holes[i], &p.holes[j]);
        i == j || !h.iter().any(|q| contains(g, *q))
    };
    if !p.holes.iter().all(inside_outer) {
        return false;
    }
    if !p.holes.iter().flatten().all(|q| q.is_finite()) {
        let n = p.holes.len();
        return (0..n).all(|i| (0..n).all(|j| apart(i, j)));
    }
    let boxes: Vec<GeomWithData<Rectangle<[f64; 2]>, usize>> = p
        .holes
        .iter()
        .enumerate()
        .map(|(i, h)| {
            let (mut lo, mut hi) = (DVec2::INFINITY, DVec2::NEG_INFINITY);
            for q in h {
                lo = lo.min(*q);
                hi = hi.max(*q);
            }
            GeomWithData::new(Rectangle::from_corners(lo.to_array(), hi.to_array()), i)
        })
        .collect();
    let tree = RTree::bulk_load(boxes.clone());
    boxes.iter().all(|b| {
        tree.locate_in_envelope_intersecting(b.envelope())
            .all(|o| apart(b.data, o.data) && apart(o.data, b.data))
    })
}

/// Representatives of the part's vertices: each vertex goes to the first representative (in
/// the order vertices are offered) within [`MIN_GAP`], else becomes one. Representatives are
/// therefore pairwise at least [`MIN_GAP`] apart, and a vertex moves by less than [`MIN_GAP`].
#[derive(Default)]
struct Reps {
    reps: Vec<Key>,
    /// Representatives by cell of [`MIN_GAP`] steps (3 × 3 × 3 grid steps), once there are
    /// more than [`Reps::LINEAR`] of them (below, a scan of `reps` is cheaper than 27 probes).
    cells: HashMap<Key, Vec<u32>, crate::geometry::CellHash>,
    /// Every vertex offered so far, with its representative.
    seen: HashMap<Key, u32, crate::geometry::CellHash>,
}

impl Reps {
    /// Representatives scanned one by one, up to this many; past it the cells are used.
    const LINEAR: usize = 48;

    fn with_capacity(n: usize) -> Reps {
        Reps {
            reps: Vec::with_capacity(n),
            cells: HashMap::default(),
            seen: HashMap::with_capacity_and_hasher(n, Default::default()),
        }
    }

    fn cell(k: Key) -> Key {
        let c = MIN_GAP_STEPS;
        (k.0.div_euclid(c), k.1.div_euclid(c), k.2.div_euclid(c))
    }

    /// The representative of `k`: the first one within `gap` grid steps, else `k` itself.
    fn of(&mut self, k: Key, gap: i64) -> Key {
        if let Some(&i) = self.seen.get(&k) {
            return self.reps[i as usize];
        }
        let c = Reps::cell(k);
        let near = |r: Key| {
            let d = (r.0 - k.0, r.1 - k.1, r.2 - k.2);
            d.0 * d.0 + d.1 * d.1 + d.2 * d.2 < gap * gap
        };
        let mut found: Option<u32> = None;
        if self.reps.len() <= Reps::LINEAR {
            // The smallest index within the gap, among those in the 27 cells around `k`'s
            // (the cells hold every representative within MIN_GAP_STEPS; `gap` is never more).
            for (i, &r) in self.reps.iter().enumerate() {
                let rc = Reps::cell(r);
                if (rc.0 - c.0).abs() <= 1
                    && (rc.1 - c.1).abs() <= 1
                    && (rc.2 - c.2).abs() <= 1
                    && near(r)
                {
                    found = Some(i as u32);
                    break;
                }
            }
        } else {
            for dx in -1..=1 {
                for dy in -1..=1 {
                    for dz in -1..=1 {
                        let Some(v) = self.cells.get(&(c.0 + dx, c.1 + dy, c.2 + dz)) else {
                            continue;
                        };
                        for &i in v {
                            if near(self.reps[i as usize]) && found.is_none_or(|f| i < f) {
                                found = Some(i);
                            }
                        }
                    }
                }
            }
        }
        let i = match found {
            Some(i) => i,
            None => {
                let i = self.reps.len() as u32;
                self.reps.push(k);
                if self.reps.len() == Reps::LINEAR + 1 {
                    for (j, &r) in self.reps.iter().enumerate() {
                        self.cells.entry(Reps::cell(r)).or_default().push(j as u32);
                    }
                } else if self.reps.len() > Reps::LINEAR + 1 {
                    self.cells.entry(c).or_default().push(i);
                }
                i
            }
        };
        self.seen.insert(k, i);
        self.reps[i as usize]
    }
}

/// A ring of grid keys without consecutive repeats (the closing one included) and spikes: a
/// vertex where the ring turns straight back (`x, y, x`, or `u, v, w` with `w` back on the
/// segment `u v` or `u` on `v w`: a face running out along an edge and part of the way back,
/// which the straight skeleton leaves where a few of its nodes nearly coincide). Emptied when
/// fewer than 3 vertices are left.
fn clean(r: &mut Vec<Key>) {
    loop {
        let before = r.len();
        ring::dedup_by(r, |a, b| a == b);
        ring::remove_spikes_by(r, |a, b| a == b);
        let n = r.len();
        if n >= 3 {
            let fold = (0..n).find(|&i| {
                let (u, v, w) = (r[(i + n - 1) % n], r[i], r[(i + 1) % n]);
                let f = |k: Key| DVec3::new(k.0 as f64, k.1 as f64, k.2 as f64);
                (f(v) - f(u)).dot(f(w) - f(v)) < 0.0
                    && (on_segment(u, v, w).is_some() || on_segment(v, w, u).is_some())
            });
            if let Some(i) = fold {
                r.remove(i);
            }
        }
        if r.len() == before || r.len() < 3 {
            break;
        }
    }
    if r.len() < 3 {
        r.clear();
    }
}

/// Twice the area vector of a ring of keys (Newell), in steps².
fn newell(r: &[Key]) -> (i128, i128, i128) {
    let n = r.len();
    let (mut x, mut y, mut z) = (0i128, 0i128, 0i128);
    for i in 0..n {
        let (a, b) = (r[i], r[(i + 1) % n]);
        let (a0, a1, a2) = (i128::from(a.0), i128::from(a.1), i128::from(a.2));
        let (b0, b1, b2) = (i128::from(b.0), i128::from(b.1), i128::from(b.2));
        x += (a1 - b1) * (a2 + b2);
        y += (a2 - b2) * (a0 + b0);
        z += (a0 - b0) * (a1 + b1);
    }
    (x, y, z)
}

/// Whether `w` lies on the segment `u v` strictly between its ends, within 1.5 grid steps of
/// the line.
fn on_segment(u: Key, v: Key, w: Key) -> Option<f64> {
    if w == u || w == v {
        return None;
    }
    let f = |k: Key| DVec3::new(k.0 as f64, k.1 as f64, k.2 as f64);
    let (a, b, p) = (f(u), f(v), f(w));
    let d = b - a;
    let l2 = d.length_squared();
    if l2 <= 0.0 {
        return None;
    }
    let s = (p - a).dot(d) / l2;
    if s <= 0.0 || s >= 1.0 {
        return None;
    }
    ((a + d * s).distance_squared(p) <= 2.25).then_some(s)
}

/// Puts a built part on the grid (see the module documentation). `ground` and the walls'
/// bases must already be on it (the footprint through `polygon_on_grid`, the heights through
/// `on_grid`): they are offered first, so they keep their places and every roof vertex within
/// `MIN_GAP` of one of them joins it. A wall keeps its outline's first two vertices (its
/// base); walls have no openings yet (they are cut at LOD3, after this). Roof faces that
/// collapse are dropped.
pub fn finish(ground: &mut Face, walls: &mut [Wall], roof: &mut Vec<Face>) {
    // Roof vertices that nearly coincide made one where the faces stay flat, unless that
    // leaves the shell not 2-manifold (two thin faces folded onto one edge, a ring touching
    // itself): then the roof as built. Every vertex then joins the first within MIN_GAP.
    let collapsed = collapse_clusters(ground, walls, roof);
    let (mut faces, mut alive) = on_keys(ground, walls, collapsed.as_deref().unwrap_or(roof));
    if collapsed.is_some() && !sound(&faces, &alive) {
        (faces, alive) = on_keys(ground, walls, roof);
    }
    // Back into the faces.
    let back = |r: &Vec<Key>| -> Vec<DVec3> { r.iter().map(|k| point(*k)).collect() };
    let face = |f: &Vec<Vec<Key>>| Face {
        outer: back(&f[0]),
        holes: f[1..].iter().map(back).collect(),
    };
    let mut faces = faces.into_iter().zip(alive);
    if let Some((g, _)) = faces.next() {
        if !g.is_empty() {
            *ground = face(&g);
        }
    }
    for w in walls.iter_mut() {
        if let Some((f, _)) = faces.next() {
            if !f.is_empty() {
                w.outline.outer = back(&f[0]);
            }
        }
    }
    *roof = faces
        .filter(|(f, a)| *a && !f.is_empty())
        .map(|(f, _)| face(&f))
        .collect();
}

/// Roof vertices closer than this (metres), directly or through a chain of such neighbours,
/// form a cluster that `finish` makes one vertex where one fits (see `collapse_clusters`).
pub(crate) const ROOF_CLUSTER: f64 = 0.03;

/// Roof edges shorter than this (metres) have their ends made one by `collapse_clusters`
/// where a point fits.
pub(crate) const ROOF_SHORT_EDGE: f64 = 0.1;

/// Vertices become one only where one point lies within this (metres) of the plane of every
/// roof face they touch: a millimetre, the rounding's own size, so that faces stay as flat as
/// the grid lets them (a vertex moved further off its planes tilts the near-degenerate
/// triangles of the faces around it, the very slivers this removes).
const CLUSTER_PLANE_TOL: f64 = 0.001;

/// The roof with each cluster of nearby vertices, and the ends of each short edge, made one
/// vertex where that keeps every face flat; `None` when nothing moves.
///
/// The straight skeleton of a nearly regular outline (a bay's arc, a tower's polygon with a
/// courtyard) does not meet in single nodes: its nodes land a centimetre or two apart, joined
/// by edges of millimetres, or in a chain a few centimetres apart along a curved side, and the
/// faces between them are needles. Rounded to the millimetre, a validator triangulating such a
/// face finds triangles tilted by tens of degrees (val3dity's 204). Where the faces' planes
/// nearly meet in one point, that point replaces the vertices: the least-squares point of the
/// planes (pulled towards the vertices' centroid along any direction they leave free, a
/// ridge's), kept only when it lies within [`CLUSTER_PLANE_TOL`] of every plane and near every
/// vertex it replaces. A vertex at a wall or ground vertex (an eave corner, a gable's apex)
/// keeps that place, on the same condition. First the clusters of vertices chained within
/// [`ROOF_CLUSTER`]; then the edges shorter than [`ROOF_SHORT_EDGE`], shortest first, each
/// joining what its two ends already joined. Faces left with repeated vertices are cleaned by
/// [`on_keys`]; the caller keeps the roof as it was if the shell is then not sound.
fn collapse_clusters(ground: &Face, walls: &[Wall], roof: &[Face]) -> Option<Vec<Face>> {
    type Map<V> = HashMap<Key, V, crate::geometry::CellHash>;
    let reach = (ROOF_CLUSTER * GRID_STEPS_PER_M).round() as i64;
    let cell = |k: Key| {
        (
            k.0.div_euclid(reach),
            k.1.div_euclid(reach),
            k.2.div_euclid(reach),
        )
    };
    fn rings(f: &Face) -> impl Iterator<Item = DVec3> + '_ {
        std::iter::once(&f.outer)
            .chain(f.holes.iter())
            .flatten()
            .copied()
    }
    // The roof's distinct vertices (by grid key, in order of appearance) and their faces.
    let n_points: usize = roof.iter().map(|f| rings(f).count()).sum();
    let mut ids: Map<usize> = Map::with_capacity_and_hasher(n_points, Default::default());
    let mut verts: Vec<(Key, DVec3)> = Vec::new();
    // The id of every ring vertex, in the order of the faces' rings.
    let mut ring_ids: Vec<usize> = Vec::with_capacity(n_points);
    for f in roof {
        for p in rings(f) {
            let k = key(p);
            let id = *ids.entry(k).or_insert_with(|| {
                verts.push((k, p));
                verts.len() - 1
            });
            ring_ids.push(id);
        }
    }
    let near = |k: Key, f: &mut dyn FnMut(Key)| {
        let c = cell(k);
        for dx in -1..=1 {
            for dy in -1..=1 {
                for dz in -1..=1 {
                    f((c.0 + dx, c.1 + dy, c.2 + dz));
                }
            }
        }
    };
    // Clusters: union-find over the pairs within ROOF_CLUSTER whose cells (of ROOF_CLUSTER)
    // are neighbours. The pairs are found by a sweep in x: a pair farther apart than
    // ROOF_CLUSTER in x is farther apart than that. A component's root is its smallest index
    // whatever the order of the unions.
    let mut parent: Vec<usize> = (0..verts.len()).collect();
    fn root(parent: &mut [usize], mut i: usize) -> usize {
        while parent[i] != i {
            parent[i] = parent[parent[i]];
            i = parent[i];
        }
        i
    }
    let r2 = ROOF_CLUSTER * ROOF_CLUSTER;
    let mut any = false;
    let cells: Vec<Key> = verts.iter().map(|v| cell(v.0)).collect();
    let mut by_x: Vec<usize> = (0..verts.len()).collect();
    by_x.sort_unstable_by(|&a, &b| verts[a].1.x.total_cmp(&verts[b].1.x).then(a.cmp(&b)));
    for (n, &i) in by_x.iter().enumerate() {
        let (pi, ci) = (verts[i].1, cells[i]);
        for &j in &by_x[n + 1..] {
            let pj = verts[j].1;
            if pj.x - pi.x >= ROOF_CLUSTER {
                break;
            }
            let cj = cells[j];
            let neighbours =
                (ci.0 - cj.0).abs() <= 1 && (ci.1 - cj.1).abs() <= 1 && (ci.2 - cj.2).abs() <= 1;
            if neighbours && pi.distance_squared(pj) < r2 {
                let (a, b) = (root(&mut parent, i), root(&mut parent, j));
                if a != b {
                    parent[a.max(b)] = a.min(b);
                    any = true;
                }
            }
        }
    }
    // The roof's edges shorter than ROOF_SHORT_EDGE, shortest first.
    let mut edges: Vec<(f64, usize, usize)> = Vec::new();
    let mut at = 0;
    for f in roof {
        for r in std::iter::once(&f.outer).chain(f.holes.iter()) {
            let n = r.len();
            let rid = &ring_ids[at..at + n];
            at += n;
            for i in 0..n {
                let (a, b) = (rid[i], rid[(i + 1) % n]);
                let l = verts[a].1.distance(verts[b].1);
                if a != b && l < ROOF_SHORT_EDGE {
                    edges.push((l, a.min(b), a.max(b)));
                }
            }
        }
    }
    edges.sort_by(|x, y| x.0.total_cmp(&y.0).then(x.1.cmp(&y.1)).then(x.2.cmp(&y.2)));
    edges.dedup_by(|x, y| x.1 == y.1 && x.2 == y.2);
    if !any && edges.is_empty() {
        return None;
    }
    // The faces of each vertex (made only when something may move).
    let mut faces_of: Vec<Vec<usize>> = vec![Vec::new(); verts.len()];
    let mut at = 0;
    for (fi, f) in roof.iter().enumerate() {
        let n = rings(f).count();
        for &id in &ring_ids[at..at + n] {
            if faces_of[id].last() != Some(&fi) {
                faces_of[id].push(fi);
            }
        }
        at += n;
    }
    // Vertices of the ground and walls, by cell: they do not move.
    let mut fixed: Map<Vec<DVec3>> = Map::default();
    for p in rings(ground).chain(walls.iter().flat_map(|w| w.outline.outer.iter().copied())) {
        fixed.entry(cell(key(p))).or_default().push(p);
    }
    let mut members: Vec<Vec<usize>> = vec![Vec::new(); verts.len()];
    for i in 0..verts.len() {
        let r = root(&mut parent, i);
        members[r].push(i);
    }
    // Each face's plane: unit normal and offset.
    let planes: Vec<Option<(DVec3, f64)>> = roof
        .iter()
        .map(|f| {
            let n = crate::geometry::newell_normal(&f.outer);
            let l = n.length();
            (l.is_finite() && l > 1e-12).then(|| {
                let n = n / l;
                let c = f.outer.iter().copied().sum::<DVec3>() / f.outer.len() as f64;
                (n, n.dot(c))
            })
        })
        .collect();
    // The vertices within MIN_GAP of a wall or ground vertex, with it.
    let anchor_of: Vec<Option<DVec3>> = verts
        .iter()
        .map(|&(k, p)| {
            let mut found = None;
            near(k, &mut |c| {
                if let Some(v) = fixed.get(&c) {
                    for q in v {
                        if q.distance(p) < MIN_GAP && found.is_none() {
                            found = Some(*q);
                        }
                    }
                }
            });
            found
        })
        .collect();
    // The point for a group of vertices, if one fits (see the doc comment).
    let fit = |group: &[usize], at: &[DVec3], reach: f64| -> Option<DVec3> {
        let mut face_ids: Vec<usize> = group.iter().flat_map(|&i| faces_of[i].clone()).collect();
        face_ids.sort_unstable();
        face_ids.dedup();
        let ps = face_ids
            .iter()
            .map(|&f| planes[f])
            .collect::<Option<Vec<(DVec3, f64)>>>()?;
        let mut anchors: Vec<DVec3> = group.iter().filter_map(|&i| anchor_of[i]).collect();
        anchors.dedup();
        let centroid = group.iter().map(|&i| at[i]).sum::<DVec3>() / group.len() as f64;
        let x = match anchors.as_slice() {
            [] => {
                let lambda = 1e-4;
                let mut a = glam::DMat3::from_diagonal(DVec3::splat(lambda));
                let mut b = centroid * lambda;
                for (n, d) in &ps {
                    a += glam::DMat3::from_cols(*n * n.x, *n * n.y, *n * n.z);
                    b += *n * *d;
                }
                if a.determinant().abs() < 1e-15 {
                    return None;
                }
                a.inverse() * b
            }
            [one] => *one,
            _ => return None,
        };
        let fits = x.is_finite()
            && ps
                .iter()
                .all(|(n, d)| (n.dot(x) - d).abs() <= CLUSTER_PLANE_TOL)
            && group.iter().all(|&i| verts[i].1.distance(x) <= reach);
        fits.then_some(x)
    };
    // Stage 1: the clusters. `pos` is where each vertex goes, `merged` which are one.
    let mut pos: Vec<DVec3> = verts.iter().map(|v| v.1).collect();
    let mut merged: Vec<usize> = (0..verts.len()).collect();
    let mut groups: Vec<Vec<usize>> = (0..verts.len()).map(|i| vec![i]).collect();
    let mut changed = false;
    for group in members.iter().filter(|g| g.len() > 1) {
        if let Some(x) = fit(group, &pos, 2.0 * ROOF_CLUSTER) {
            for &i in group {
                pos[i] = x;
                merged[i] = group[0];
            }
            groups[group[0]] = group.clone();
            changed = true;
        }
    }
    // Stage 2: roof edges shorter than ROOF_SHORT_EDGE, shortest first, their two ends (and
    // what each was merged with) made one where a point fits. A chain of skeleton nodes a few
    // centimetres apart along a curved side's faces leaves corners a millimetre off straight,
    // which the rounding turns into slivers just as a cluster does.
    for (_, a, b) in edges {
        let (ra, rb) = (merged[a], merged[b]);
        if ra == rb {
            continue;
        }
        let mut group = groups[ra].clone();
        group.extend(groups[rb].iter().copied());
        if let Some(x) = fit(&group, &pos, 2.0 * ROOF_SHORT_EDGE) {
            let r = ra.min(rb);
            for &i in &group {
                pos[i] = x;
                merged[i] = r;
            }
            groups[r] = group;
            changed = true;
        }
    }
    if !changed {
        return None;
    }
    let mv = |r: &Vec<DVec3>| -> Vec<DVec3> { r.iter().map(|p| pos[ids[&key(*p)]]).collect() };
    Some(
        roof.iter()
            .map(|f| Face {
                outer: mv(&f.outer),
                holes: f.holes.iter().map(mv).collect(),
            })
            .collect(),
    )
}

/// Whether every directed edge of the live faces is used once, and its reverse once, and every
/// ring is simple in its face's plane (no vertex passed twice, no edge crossing or touching
/// another).
fn sound(faces: &[Vec<Vec<Key>>], alive: &[bool]) -> bool {
    let mut count: HashMap<(Key, Key), i32, crate::geometry::CellHash> = HashMap::default();
    for r in faces
        .iter()
        .zip(alive)
        .filter(|(_, a)| **a)
        .flat_map(|(f, _)| f.iter())
    {
        let mut seen: Vec<Key> = r.clone();
        seen.sort_unstable();
        if seen.windows(2).any(|w| w[0] == w[1]) {
            return false;
        }
        let pts: Vec<DVec3> = r.iter().map(|k| point(*k)).collect();
        let normal = crate::geometry::newell_normal(&pts);
        if normal.length().is_nan() || normal.length() <= 1e-12 {
            return false;
        }
        let (ex, ey) = crate::geometry::plane_axes(normal.normalize());
        let plan: Vec<glam::DVec2> = pts
            .iter()
            .map(|p| glam::DVec2::new((*p - pts[0]).dot(ex), (*p - pts[0]).dot(ey)))
            .collect();
        if !crate::geometry::is_simple(&plan) {
            return false;
        }
        let n = r.len();
        for i in 0..n {
            *count.entry((r[i], r[(i + 1) % n])).or_default() += 1;
        }
    }
    count
        .iter()
        .all(|(&(a, b), &c)| c == 1 && count.get(&(b, a)) == Some(&1))
}

/// The part's faces on grid keys, vertices within [`MIN_GAP`] merged, rings
/// cleaned and T-junctions closed; with each face's liveness.
fn on_keys(ground: &Face, walls: &[Wall], roof: &[Face]) -> (Vec<Vec<Vec<Key>>>, Vec<bool>) {
    let points = |f: &Face| f.outer.len() + f.holes.iter().map(Vec::len).sum::<usize>();
    let n_points = points(ground)
        + walls.iter().map(|w| w.outline.outer.len()).sum::<usize>()
        + roof.iter().map(points).sum::<usize>();
    let mut reps = Reps::with_capacity(n_points);
    let mut ring_keys = |r: &Vec<DVec3>| -> Vec<Key> {
        r.iter().map(|p| reps.of(key(*p), MIN_GAP_STEPS)).collect()
    };
    // Ground, then the walls (base first in each outline), then the roof: one list of faces,
    // each a list of rings (the outer first). A wall is its outline's outer ring.
    let mut faces: Vec<Vec<Vec<Key>>> = Vec::with_capacity(1 + walls.len() + roof.len());
    faces.push(
        std::iter::once(&ground.outer)
            .chain(ground.holes.iter())
            .map(&mut ring_keys)
            .collect(),
    );
    for w in walls {
        faces.push(vec![ring_keys(&w.outline.outer)]);
    }
    for f in roof {
        faces.push(
            std::iter::once(&f.outer)
                .chain(f.holes.iter())
                .map(&mut ring_keys)
                .collect(),
        );
    }
    let roof0 = 1 + walls.len();
    let mut alive = vec![true; faces.len()];
    let tidy = |faces: &mut Vec<Vec<Vec<Key>>>, alive: &mut Vec<bool>| {
        for (i, f) in faces.iter_mut().enumerate() {
            if f.is_empty() {
                alive[i] = false;
                continue;
            }
            for r in f.iter_mut() {
                clean(r);
            }
            // A roof face whose outer ring collapsed, or has no area left, goes: its edges pair
            // up among its neighbours once the vertices on them are inserted.
            if i >= roof0 && (f[0].is_empty() || newell(&f[0]) == (0, 0, 0)) {
                alive[i] = false;
            }
            let outer_empty = f[0].is_empty();
            f.retain(|r| !r.is_empty());
            if outer_empty {
                f.clear();
            }
        }
    };
    tidy(&mut faces, &mut alive);
    // T-junctions: an edge without its twin takes the vertices lying on it.
    for _ in 0..3 {
        let live = || {
            faces
                .iter()
                .zip(&alive)
                .filter(|(_, a)| **a)
                .flat_map(|(f, _)| f.iter())
        };
        // Every directed edge of the live faces, by its ends' representatives' indices (every
        // vertex of a face is a representative), sorted: an edge is lonely when its reverse is
        // not among them.
        let id = |k: &Key| -> u64 { u64::from(reps.seen[k]) };
        let ring_ids: Vec<Vec<u64>> = live().map(|r| r.iter().map(id).collect()).collect();
        let mut count: Vec<u64> = Vec::with_capacity(ring_ids.iter().map(Vec::len).sum());
        for r in &ring_ids {
            let n = r.len();
            for i in 0..n {
                count.push(r[i] << 32 | r[(i + 1) % n]);
            }
        }
        count.sort_unstable();
        let lonely_ids = |a: u64, b: u64| count.binary_search(&(b << 32 | a)).is_err();
        // Nothing to do (the usual case) unless some edge is lonely, a wall's base aside.
        let mut any = false;
        let mut at = 0;
        for (fi, f) in faces.iter().enumerate() {
            if !alive[fi] {
                continue;
            }
            let is_wall = (1..roof0).contains(&fi);
            for (ri, r) in ring_ids[at..at + f.len()].iter().enumerate() {
                let n = r.len();
                any |= (0..n)
                    .any(|i| !(is_wall && ri == 0 && i == 0) && lonely_ids(r[i], r[(i + 1) % n]));
            }
            at += f.len();
            if any {
                break;
            }
        }
        if !any {
            break;
        }
        let lonely = |a: Key, b: Key| lonely_ids(id(&a), id(&b));
        let mut verts: Vec<Key> = live().flat_map(|r| r.iter().copied()).collect();
        verts.sort_unstable();
        verts.dedup();
        // The vertices that may lie on the segment u v (`on_segment`: within 1.5 steps of a
        // point of it): those whose x is within 2 steps of its x range (`verts` is sorted by x
        // first).
        let near_x = |u: Key, v: Key| -> &[Key] {
            let (lo, hi) = (u.0.min(v.0) - 2, u.0.max(v.0) + 2);
            let a = verts.partition_point(|w| w.0 < lo);
            let b = verts.partition_point(|w| w.0 <= hi);
            &verts[a..b.max(a)]
        };
        let mut changed = false;
        for (fi, f) in faces.iter_mut().enumerate() {
            if !alive[fi] {
                continue;
            }
            let is_wall = (1..roof0).contains(&fi);
            for (ri, r) in f.iter_mut().enumerate() {
                let n = r.len();
                let mut out = Vec::with_capacity(n);
                for i in 0..n {
                    let (u, v) = (r[i], r[(i + 1) % n]);
                    out.push(u);
                    // A wall's base is its own: nothing stands on it but the ground's corners.
                    if (is_wall && ri == 0 && i == 0) || !lonely(u, v) {
                        continue;
                    }
                    let mut on: Vec<(f64, Key)> = near_x(u, v)
                        .iter()
                        .filter_map(|&w| on_segment(u, v, w).map(|s| (s, w)))
                        .collect();
                    if on.is_empty() {
                        continue;
                    }
                    on.sort_by(|x, y| x.0.total_cmp(&y.0).then(x.1.cmp(&y.1)));
                    out.extend(on.into_iter().map(|x| x.1));
                    changed = true;
                }
                *r = out;
            }
        }
        if !changed {
            break;
        }
        tidy(&mut faces, &mut alive);
    }
    (faces, alive)
}
