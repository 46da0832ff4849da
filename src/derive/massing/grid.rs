//! Parts at the precision they are written: every vertex on the output grid (the millimetre,
//! [`crate::model::GRID_STEPS_PER_M`]), distinct vertices at least [`MIN_GAP`] apart.
//!
//! The writers round coordinates (CityGML to three decimals). Rounding a part vertex by vertex
//! can merge two vertices that were distinct, fold a ring back on itself (`x, y, x`), or leave
//! a short edge whose tilt, once rounded, turns a triangle of its face by tens of degrees; a
//! validator that snaps vertices within 1 mm (val3dity's default) merges vertices one grid step
//! apart. So the model itself is put on the grid once, as a whole part, before anything is
//! written: [`polygon_on_grid`] for footprints, [`finish`] for the built surfaces. What every
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
pub const MIN_GAP: f64 = crate::model::MIN_VERTEX_GAP;

/// [`MIN_GAP`] in grid steps: two vertices of the ground and the walls closer than this are one.
const MIN_GAP_STEPS: i64 = 3;

/// Roof vertices closer than this (metres) to a vertex offered before them join it. A roof
/// edge of a few millimetres (skeleton nodes that nearly coincide, on curved footprints
/// above all) is tilted by the millimetre rounding of its ends by tens of degrees, and a
/// validator triangulating the face finds a sliver there (val3dity's 204); merging it moves a
/// vertex by less than this, which a roof face's planarity (1 cm) absorbs at any pitch up to
/// 70° (8 mm × sin 70° plus the rounding).
pub const ROOF_GAP: f64 = 0.008;

/// [`ROOF_GAP`] in grid steps.
const ROOF_GAP_STEPS: i64 = 8;

/// A vertex on the grid, in grid steps.
type Key = (i64, i64, i64);

fn key(p: DVec3) -> Key {
    let s = |v: f64| (v * GRID_STEPS_PER_M).round() as i64;
    (s(p.x), s(p.y), s(p.z))
}

fn point(k: Key) -> DVec3 {
    DVec3::new(
        k.0 as f64 / GRID_STEPS_PER_M,
        k.1 as f64 / GRID_STEPS_PER_M,
        k.2 as f64 / GRID_STEPS_PER_M,
    )
}

/// A 2D point on the grid.
pub fn point2_on_grid(p: DVec2) -> DVec2 {
    DVec2::new(on_grid(p.x), on_grid(p.y))
}

/// The footprint on the grid: every vertex rounded to the millimetre, vertices closer than
/// [`MIN_GAP`] to the one kept before them dropped, spikes removed. `None` when a ring is left
/// with fewer than 3 vertices or no area, or when a ring crosses or touches itself once rounded
/// ([`is_simple`]): the caller keeps the polygon as it was (a footprint a millimetre from
/// touching itself; the writers round it as they can). Idempotent: a polygon on the grid whose
/// vertices are [`MIN_GAP`] apart is returned unchanged.
pub fn polygon_on_grid(p: &Polygon) -> Option<Polygon> {
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
    // Holes still inside the outer ring and apart from each other.
    let ok =
        out.holes.iter().enumerate().all(|(i, h)| {
            h.iter()
                .all(|q| crate::geometry::ring_contains(&out.outer, *q))
                && out.holes.iter().enumerate().all(|(j, g)| {
                    i == j || !h.iter().any(|q| crate::geometry::ring_contains(g, *q))
                })
        });
    ok.then_some(out)
}

/// Representatives of the part's vertices: each vertex goes to the first representative (in
/// the order vertices are offered) within [`MIN_GAP`], else becomes one. Representatives are
/// therefore pairwise at least [`MIN_GAP`] apart, and a vertex moves by less than [`MIN_GAP`].
#[derive(Default)]
struct Reps {
    reps: Vec<Key>,
    /// Representatives by cell of [`MIN_GAP`] steps (3 × 3 × 3 grid steps).
    cells: HashMap<Key, Vec<u32>, crate::derive::massing::CellHash>,
    /// Every vertex offered so far, with its representative.
    seen: HashMap<Key, u32, crate::derive::massing::CellHash>,
}

impl Reps {
    fn cell(k: Key) -> Key {
        let c = ROOF_GAP_STEPS;
        (k.0.div_euclid(c), k.1.div_euclid(c), k.2.div_euclid(c))
    }

    /// The representative of `k`: the first one within `gap` grid steps, else `k` itself.
    fn of(&mut self, k: Key, gap: i64) -> Key {
        if let Some(&i) = self.seen.get(&k) {
            return self.reps[i as usize];
        }
        let c = Reps::cell(k);
        let mut found: Option<u32> = None;
        for dx in -1..=1 {
            for dy in -1..=1 {
                for dz in -1..=1 {
                    let Some(v) = self.cells.get(&(c.0 + dx, c.1 + dy, c.2 + dz)) else {
                        continue;
                    };
                    for &i in v {
                        let r = self.reps[i as usize];
                        let d = (r.0 - k.0, r.1 - k.1, r.2 - k.2);
                        if d.0 * d.0 + d.1 * d.1 + d.2 * d.2 < gap * gap
                            && found.is_none_or(|f| i < f)
                        {
                            found = Some(i);
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
                self.cells.entry(c).or_default().push(i);
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
/// bases must already be on it (the footprint through [`polygon_on_grid`], the heights through
/// [`on_grid`]): they are offered first, so they keep their places and every roof vertex within
/// [`MIN_GAP`] of one of them joins it. A wall keeps its outline's first two vertices (its
/// base); walls have no openings yet (they are cut at LOD3, after this). Roof faces that
/// collapse are dropped.
pub fn finish(ground: &mut Face, walls: &mut [Wall], roof: &mut Vec<Face>) {
    // Roof vertices merged at ROOF_GAP, unless that leaves the shell not 2-manifold (two thin
    // faces folded onto one edge, a ring touching itself): then at MIN_GAP, as ground and walls.
    let (mut faces, mut alive) = on_keys(ground, walls, roof, ROOF_GAP_STEPS);
    if !sound(&faces, &alive) {
        (faces, alive) = on_keys(ground, walls, roof, MIN_GAP_STEPS);
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

/// Whether every directed edge of the live faces is used once, and its reverse once, and every
/// ring is simple in its face's plane (no vertex passed twice, no edge crossing or touching
/// another).
fn sound(faces: &[Vec<Vec<Key>>], alive: &[bool]) -> bool {
    let mut count: HashMap<(Key, Key), i32, crate::derive::massing::CellHash> = HashMap::default();
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

/// The part's faces on grid keys, vertices merged (roof ones within `roof_gap` steps), rings
/// cleaned and T-junctions closed; with each face's liveness.
fn on_keys(
    ground: &Face,
    walls: &[Wall],
    roof: &[Face],
    roof_gap: i64,
) -> (Vec<Vec<Vec<Key>>>, Vec<bool>) {
    let mut reps = Reps::default();
    let mut to_keys = |f: &Face, gap: i64| -> Vec<Vec<Key>> {
        std::iter::once(&f.outer)
            .chain(f.holes.iter())
            .map(|r| r.iter().map(|p| reps.of(key(*p), gap)).collect())
            .collect()
    };
    // Ground, then the walls (base first in each outline), then the roof: one list of faces,
    // each a list of rings (the outer first).
    let mut faces: Vec<Vec<Vec<Key>>> = vec![to_keys(ground, MIN_GAP_STEPS)];
    faces.extend(
        walls
            .iter()
            .map(|w| to_keys(&Face::new(w.outline.outer.clone()), MIN_GAP_STEPS)),
    );
    faces.extend(roof.iter().map(|f| to_keys(f, roof_gap)));
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
        let mut count: HashMap<(Key, Key), i32, crate::derive::massing::CellHash> =
            HashMap::default();
        let live = || {
            faces
                .iter()
                .zip(&alive)
                .filter(|(_, a)| **a)
                .flat_map(|(f, _)| f.iter())
        };
        for r in live() {
            let n = r.len();
            for i in 0..n {
                *count.entry((r[i], r[(i + 1) % n])).or_default() += 1;
            }
        }
        let mut verts: Vec<Key> = live().flat_map(|r| r.iter().copied()).collect();
        verts.sort_unstable();
        verts.dedup();
        let lonely = |a: Key, b: Key| count.get(&(b, a)).copied().unwrap_or(0) == 0;
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
                    let mut on: Vec<(f64, Key)> = verts
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
