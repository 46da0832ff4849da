//! Triangulation of planar polygons with holes (ear clipping, via the `earcut` crate), in 2D and
//! for planar 3D faces.
//!
//! Contract: output triangles keep the polygon's orientation. In 2D every triangle is
//! counter-clockwise (positive area); for a 3D face every triangle is counter-clockwise seen from
//! the side the face's Newell normal points to, so a face that is CCW seen from outside yields
//! outward-facing triangles. Degenerate input (fewer than 3 points, zero area, non-finite
//! coordinates) gives no triangles, never NaN and never a panic.
//!
//! ```
//! use glam::DVec2;
//! use citygen::geometry::triangulate::triangulate_2d;
//! let square = [DVec2::new(0.0, 0.0), DVec2::new(1.0, 0.0), DVec2::new(1.0, 1.0), DVec2::new(0.0, 1.0)];
//! assert_eq!(triangulate_2d(&square, &[]).len(), 2);
//! ```

use glam::{DVec2, DVec3};

/// Triangles of one planar 3D face.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct FaceTriangles {
    /// Unit normal of the face (Newell normal of its outer ring).
    pub normal: DVec3,
    /// The face's vertices that some triangle uses, in ring order (outer ring, then holes).
    pub vertices: Vec<DVec3>,
    /// Triangles as indices into `vertices`, counter-clockwise seen from the `normal` side.
    pub triangles: Vec<[u32; 3]>,
}

/// Relative size under which an area counts as zero: far below any real building detail, far
/// above f64 rounding noise on coordinates of a few kilometres.
const REL_EPS: f64 = 1e-12;

/// Triangulates a 2D polygon with holes.
///
/// Vertices are numbered over the concatenation `outer ++ holes[0] ++ holes[1] ...` and every
/// returned triangle is counter-clockwise (positive signed area), whatever the input rings'
/// orientations. Rings with fewer than 3 points are ignored (a hole) or give no triangles (the
/// outer ring); so do non-finite coordinates. Triangles of (near) zero area are dropped.
/// For a simple polygon whose holes lie inside it without touching, the triangles cover it
/// exactly: their areas add up to the polygon's area.
pub fn triangulate_2d(outer: &[DVec2], holes: &[Vec<DVec2>]) -> Vec<[u32; 3]> {
    let mut t = Triangulator::default();
    t.flat.clear();
    t.flat.extend_from_slice(outer);
    t.ring_ends.clear();
    t.ring_ends.push(outer.len());
    for h in holes {
        t.flat.extend_from_slice(h);
        t.ring_ends.push(t.flat.len());
    }
    t.cut_flat();
    std::mem::take(&mut t.tris)
}

/// Triangulates a planar 3D polygon with holes (a model face).
///
/// The face is projected onto its own plane, whose orientation is given by the Newell normal of
/// the outer ring, so triangles come out counter-clockwise seen from the normal's side. Returns
/// `None` for a degenerate face: fewer than 3 points, non-finite coordinates, zero area, or no
/// triangle left. Only vertices used by a triangle are returned.
pub(crate) fn triangulate_face(outer: &[DVec3], holes: &[Vec<DVec3>]) -> Option<FaceTriangles> {
    let mut t = Triangulator::default();
    let f = t.face(outer, holes)?;
    Some(FaceTriangles {
        normal: f.normal,
        vertices: f.vertices.to_vec(),
        triangles: f.triangles.to_vec(),
    })
}

/// [`triangulate_face`]'s result, borrowed from the [`Triangulator`] that made it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct FaceTrianglesRef<'a> {
    /// Unit normal of the face (Newell normal of its outer ring).
    pub normal: DVec3,
    /// The face's vertices that some triangle uses, in ring order (outer ring, then holes).
    pub vertices: &'a [DVec3],
    /// Triangles as indices into `vertices`, counter-clockwise seen from the `normal` side.
    pub triangles: &'a [[u32; 3]],
}

/// Reusable working memory for [`triangulate_face`] and [`triangulate_2d`]: one per thread
/// triangulates any number of faces without allocating per face, with the same results.
///
/// Rings without holes of at most [`SMALL_RING`] points (nearly every face: quads, panes,
/// reveals, slabs) are cut by a replica of earcut's ear-slicing pass on a plain index ring,
/// which gives exactly the triangles, in the same order, that earcut gives; whenever that
/// pass would hand over to earcut's later passes (no ear found in a whole loop), earcut itself
/// cuts the ring from the start.
#[derive(Default)]
pub(crate) struct Triangulator {
    /// The rings' 3D points relative to the outer ring's first one (outer ring only).
    rel: Vec<DVec3>,
    /// All rings' points, flat (2D: projected), and where each ring ends in it.
    flat: Vec<DVec2>,
    ring_ends: Vec<usize>,
    /// What earcut is given: points relative to the first, skipping short holes.
    data: Vec<[f64; 2]>,
    index_map: Vec<u32>,
    hole_starts: Vec<u32>,
    raw: Vec<u32>,
    /// Kept triangles, numbered over `flat`.
    tris: Vec<[u32; 3]>,
    /// The face's used vertices and its triangles renumbered to them.
    new_index: Vec<u32>,
    vertices: Vec<DVec3>,
    face_tris: Vec<[u32; 3]>,
    /// The ear-slicing pass's ring: vertex, next and previous node per node.
    ring: Vec<(u32, u32, u32)>,
    earcut: earcut::Earcut<f64>,
}

/// The most points of a hole-free ring that [`Triangulator`] cuts itself: earcut switches to
/// its z-order hashed search above 80 points.
pub(crate) const SMALL_RING: usize = 80;

impl Triangulator {
    /// [`triangulate_face`] into this triangulator's buffers.
    pub(crate) fn face(
        &mut self,
        outer: &[DVec3],
        holes: &[Vec<DVec3>],
    ) -> Option<FaceTrianglesRef<'_>> {
        if outer.len() < 3 {
            return None;
        }
        let all_finite =
            outer.iter().all(|p| p.is_finite()) && holes.iter().flatten().all(|p| p.is_finite());
        if !all_finite {
            return None;
        }
        let origin = outer[0];
        self.rel.clear();
        self.rel.extend(outer.iter().map(|p| *p - origin));
        let newell = super::newell_normal(&self.rel);
        let extent = self
            .rel
            .iter()
            .fold(0.0f64, |m, p| m.max(p.abs().max_element()));
        // The Newell vector's length is twice the area.
        if newell.length() <= 2.0 * REL_EPS * extent * extent {
            return None;
        }
        let normal = newell.normalize();
        if !normal.is_finite() {
            return None;
        }
        // Right-handed basis (u, v, normal): CCW around the normal in 3D is CCW in (u, v).
        let u = normal.any_orthonormal_vector();
        let v = normal.cross(u);
        let project = |p: &DVec3| {
            let q = *p - origin;
            DVec2::new(q.dot(u), q.dot(v))
        };
        self.flat.clear();
        self.ring_ends.clear();
        self.flat.extend(outer.iter().map(project));
        self.ring_ends.push(self.flat.len());
        for h in holes {
            self.flat.extend(h.iter().map(project));
            self.ring_ends.push(self.flat.len());
        }
        self.cut_flat();
        if self.tris.is_empty() {
            return None;
        }

        // Keep only used vertices, numbered in ring order (deterministic).
        let total = self.flat.len();
        self.new_index.clear();
        self.new_index.resize(total, u32::MAX);
        for t in &self.tris {
            for &i in t {
                self.new_index[i as usize] = 0;
            }
        }
        self.vertices.clear();
        let all = std::iter::once(outer).chain(holes.iter().map(Vec::as_slice));
        for (i, p) in all.flatten().enumerate() {
            let slot = &mut self.new_index[i];
            if *slot == 0 {
                *slot = self.vertices.len() as u32;
                self.vertices.push(*p);
            }
        }
        self.face_tris.clear();
        let new_index = &self.new_index;
        self.face_tris.extend(self.tris.iter().map(|t| {
            [
                new_index[t[0] as usize],
                new_index[t[1] as usize],
                new_index[t[2] as usize],
            ]
        }));
        Some(FaceTrianglesRef {
            normal,
            vertices: &self.vertices,
            triangles: &self.face_tris,
        })
    }

    /// [`triangulate_2d`] of the rings in `flat` / `ring_ends` (outer first) into `tris`.
    fn cut_flat(&mut self) {
        self.tris.clear();
        let outer_len = self.ring_ends[0];
        if outer_len < 3 {
            return;
        }
        if !self.flat.iter().all(|p| p.is_finite()) {
            return;
        }
        let total = self.flat.len();
        if u32::try_from(total).is_err() {
            return;
        }

        // Earcut's vertex numbering skips ignored holes; `index_map` takes it back to ours.
        // Coordinates are taken relative to the first vertex so that large offsets do not eat
        // the precision.
        let origin = self.flat[0];
        self.data.clear();
        self.index_map.clear();
        self.hole_starts.clear();
        let mut first = 0;
        for (ri, &end) in self.ring_ends.iter().enumerate() {
            let ring = &self.flat[first..end];
            if ri == 0 || ring.len() >= 3 {
                if ri > 0 {
                    self.hole_starts.push(self.data.len() as u32);
                }
                for (k, p) in ring.iter().enumerate() {
                    let q = *p - origin;
                    self.data.push([q.x, q.y]);
                    self.index_map.push((first + k) as u32);
                }
            }
            first = end;
        }

        let (lo, hi) = self.data.iter().fold(
            (DVec2::splat(f64::INFINITY), DVec2::splat(f64::NEG_INFINITY)),
            |(lo, hi), p| (lo.min(DVec2::from(*p)), hi.max(DVec2::from(*p))),
        );
        let extent = (hi - lo).max_element();
        // `extent` is finite here (all points are); zero means all points coincide.
        if extent <= 0.0 {
            return;
        }
        let min_area = REL_EPS * extent * extent;

        let small = self.hole_starts.is_empty() && self.data.len() <= SMALL_RING;
        let many = self.hole_starts.len() > MANY_HOLES;
        if many && cdt_cut(&self.data, &self.hole_starts, &mut self.raw) {
            // Cut by the constrained Delaunay triangulation.
        } else if !(small && ear_slice(&self.data, &mut self.ring, &mut self.raw)) {
            self.earcut
                .earcut(self.data.iter().copied(), &self.hole_starts, &mut self.raw);
        }

        for t in self.raw.chunks_exact(3) {
            let (a, b, c) = (t[0] as usize, t[1] as usize, t[2] as usize);
            let (Some(pa), Some(pb), Some(pc)) =
                (self.data.get(a), self.data.get(b), self.data.get(c))
            else {
                continue;
            };
            let (pa, pb, pc) = (DVec2::from(*pa), DVec2::from(*pb), DVec2::from(*pc));
            let twice_area = (pb - pa).perp_dot(pc - pa);
            if twice_area.abs() <= 2.0 * min_area {
                continue;
            }
            let (ia, ib, ic) = (self.index_map[a], self.index_map[b], self.index_map[c]);
            if twice_area > 0.0 {
                self.tris.push([ia, ib, ic]);
            } else {
                self.tris.push([ia, ic, ib]);
            }
        }
    }
}

/// The most holes a face may have for earcut: past them [`cdt_cut`] triangulates it. Earcut
/// bridges every hole to the outer ring by walking the ring, which grows with each bridged
/// hole: O(holes × points), 10 s for the 10,000 holes the rest of an outline with 10,000
/// parts has (issue 43). Ordinary faces (a few courtyards) keep earcut's triangles.
pub(crate) const MANY_HOLES: usize = 64;

/// The constrained Delaunay triangulation (`spade`) of the rings in `data` (outer ring, then
/// holes from each of `hole_starts`), its triangles inside the polygon as indices into `data`
/// in `out` (orientation fixed by the caller), O(n log n). The inside is found by flooding
/// from the convex hull, crossing a ring's edge flipping in and out. Points at the same place
/// are one vertex (the first one's index); an edge that would cross one already added is left
/// out (rings that touch or cross: the flood may then misjudge a region). Returns `false`
/// when the triangulation cannot be built, for the caller to use earcut.
fn cdt_cut(data: &[[f64; 2]], hole_starts: &[u32], out: &mut Vec<u32>) -> bool {
    use spade::handles::FixedFaceHandle;
    use spade::{ConstrainedDelaunayTriangulation, Point2, Triangulation};
    use std::collections::{HashMap, VecDeque};
    out.clear();
    // One vertex per place (spade would drop the later ones and shift the indices).
    let mut first_at: HashMap<(u64, u64), u32> = HashMap::with_capacity(data.len());
    let mut vertex_of = Vec::with_capacity(data.len());
    let mut points = Vec::with_capacity(data.len());
    let mut index_of = Vec::with_capacity(data.len());
    for (i, p) in data.iter().enumerate() {
        let key = (p[0].to_bits(), p[1].to_bits());
        let v = *first_at.entry(key).or_insert_with(|| {
            points.push(Point2::new(p[0], p[1]));
            index_of.push(i as u32);
            (points.len() - 1) as u32
        });
        vertex_of.push(v as usize);
    }
    let mut edges = Vec::with_capacity(data.len());
    let starts: Vec<usize> = std::iter::once(0)
        .chain(hole_starts.iter().map(|&s| s as usize))
        .chain(std::iter::once(data.len()))
        .collect();
    for w in starts.windows(2) {
        let (a, b) = (w[0], w[1]);
        for k in a..b {
            let next = if k + 1 == b { a } else { k + 1 };
            let (u, v) = (vertex_of[k], vertex_of[next]);
            if u != v {
                edges.push([u, v]);
            }
        }
    }
    let Ok(cdt) =
        ConstrainedDelaunayTriangulation::<Point2<f64>>::try_bulk_load_cdt(points, edges, |_| {})
    else {
        return false;
    };
    // Flood from the outer face: a face's depth is the fewest ring edges crossed to reach it.
    let mut depth: Vec<Option<u32>> = vec![None; cdt.num_all_faces()];
    let mut queue: VecDeque<(FixedFaceHandle<spade::handles::PossiblyOuterTag>, u32)> =
        VecDeque::new();
    queue.push_back((cdt.outer_face().fix(), 0));
    while let Some((f, d)) = queue.pop_front() {
        let slot = &mut depth[f.index()];
        if slot.is_some_and(|old| old <= d) {
            continue;
        }
        *slot = Some(d);
        let face = cdt.face(f);
        let edges: Vec<_> = match face.as_inner() {
            Some(inner) => inner.adjacent_edges().to_vec(),
            // The hull's edges turned to have the outer face on their left.
            None => cdt
                .convex_hull()
                .map(|e| if e.face().is_outer() { e } else { e.rev() })
                .collect(),
        };
        for e in edges {
            let across = e.rev().face().fix();
            if depth[across.index()].is_some() {
                continue;
            }
            if cdt.is_constraint_edge(e.as_undirected().fix()) {
                queue.push_back((across, d + 1));
            } else {
                queue.push_front((across, d));
            }
        }
    }
    for f in cdt.inner_faces() {
        if depth[f.fix().index()].is_some_and(|d| d % 2 == 1) {
            for v in f.vertices() {
                out.push(index_of[v.fix().index()]);
            }
        }
    }
    true
}

/// Earcut's first pass on one ring without holes of at most [`SMALL_RING`] points (earcut
/// 0.4's `linked_list` then `earcut_linked` at pass 0 without z-order hashing), with its
/// arithmetic, so that it cuts the same triangles in the same order into `out`. Returns false,
/// with `out` undefined, where earcut would go on to its later passes (no ear in a whole loop
/// round the remaining ring): the caller then runs earcut itself.
fn ear_slice(data: &[[f64; 2]], ring: &mut Vec<(u32, u32, u32)>, out: &mut Vec<u32>) -> bool {
    out.clear();
    let n = data.len();
    if n < 3 {
        return true;
    }
    // linked_list(clockwise = true): the points in order when their signed area (earcut's sum)
    // is positive, else reversed; node k is the k-th inserted.
    let mut sum = 0.0;
    let [mut bx, mut by] = data[n - 1];
    for &[ax, ay] in data {
        sum += (bx - ax) * (ay + by);
        (bx, by) = (ax, ay);
    }
    let forward = sum > 0.0;
    ring.clear();
    ring.extend((0..n).map(|k| {
        let v = if forward { k } else { n - 1 - k };
        (v as u32, ((k + 1) % n) as u32, ((k + n - 1) % n) as u32)
    }));
    let xy = |node: u32, ring: &[(u32, u32, u32)]| data[ring[node as usize].0 as usize];
    let remove = |node: u32, ring: &mut [(u32, u32, u32)]| {
        let (_, next, prev) = ring[node as usize];
        ring[prev as usize].1 = next;
        ring[next as usize].2 = prev;
    };
    // The last node inserted, dropped if it equals its next (the first).
    let mut ear = (n - 1) as u32;
    if xy(ear, ring) == xy(ring[ear as usize].1, ring) {
        let next = ring[ear as usize].1;
        remove(ear, ring);
        ear = next;
    }
    if ring[ear as usize].1 == ring[ear as usize].2 {
        return true;
    }
    let mut stop = ear;
    loop {
        let (_, next, prev) = ring[ear as usize];
        if prev == next {
            return true;
        }
        if is_ear(data, ring, ear) {
            out.extend([
                ring[prev as usize].0,
                ring[ear as usize].0,
                ring[next as usize].0,
            ]);
            remove(ear, ring);
            // Skipping the next vertex leads to fewer sliver triangles.
            ear = ring[next as usize].1;
            stop = ear;
            continue;
        }
        ear = next;
        if ear == stop {
            return false;
        }
    }
}

/// Earcut's signed area of triangle `p q r` (negative: counter-clockwise, a convex corner).
fn ear_area(p: [f64; 2], q: [f64; 2], r: [f64; 2]) -> f64 {
    (q[1] - p[1]) * (r[0] - q[0]) - (q[0] - p[0]) * (r[1] - q[1])
}

/// Earcut's `is_ear`: node `b` is a convex corner and no reflex point of the ring lies in the
/// triangle it cuts off.
fn is_ear(data: &[[f64; 2]], ring: &[(u32, u32, u32)], b: u32) -> bool {
    let (bv, cn, an) = ring[b as usize];
    let (av, cv) = (ring[an as usize].0, ring[cn as usize].0);
    let (a, bp, c) = (data[av as usize], data[bv as usize], data[cv as usize]);
    if ear_area(a, bp, c) >= 0.0 {
        return false;
    }
    let x0 = a[0].min(bp[0].min(c[0]));
    let y0 = a[1].min(bp[1].min(c[1]));
    let x1 = a[0].max(bp[0].max(c[0]));
    let y1 = a[1].max(bp[1].max(c[1]));
    let mut p = ring[cn as usize].1;
    let mut p_prev = ring[p as usize].2;
    while p != an {
        let p_next = ring[p as usize].1;
        let pp = data[ring[p as usize].0 as usize];
        if (pp[0] >= x0 && pp[0] <= x1 && pp[1] >= y0 && pp[1] <= y1)
            && !(a[0] == pp[0] && a[1] == pp[1])
            && point_in_triangle(a, bp, c, pp)
            && ear_area(
                data[ring[p_prev as usize].0 as usize],
                pp,
                data[ring[p_next as usize].0 as usize],
            ) >= 0.0
        {
            return false;
        }
        (p_prev, p) = (p, p_next);
    }
    true
}

/// Earcut's `point_in_triangle` (boundary included).
fn point_in_triangle(a: [f64; 2], b: [f64; 2], c: [f64; 2], p: [f64; 2]) -> bool {
    ((c[0] - p[0]) * (a[1] - p[1]) >= (a[0] - p[0]) * (c[1] - p[1]))
        && ((a[0] - p[0]) * (b[1] - p[1]) >= (b[0] - p[0]) * (a[1] - p[1]))
        && ((b[0] - p[0]) * (c[1] - p[1]) >= (c[0] - p[0]) * (b[1] - p[1]))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::ring_signed_area;
    use proptest::prelude::*;

    fn v2(x: f64, y: f64) -> DVec2 {
        DVec2::new(x, y)
    }

    fn area_2d(pts: &[DVec2], tris: &[[u32; 3]]) -> f64 {
        tris.iter()
            .map(|t| {
                let (a, b, c) = (pts[t[0] as usize], pts[t[1] as usize], pts[t[2] as usize]);
                0.5 * (b - a).perp_dot(c - a)
            })
            .sum()
    }

    fn area_3d(f: &FaceTriangles) -> f64 {
        f.triangles
            .iter()
            .map(|t| {
                let (a, b, c) = (
                    f.vertices[t[0] as usize],
                    f.vertices[t[1] as usize],
                    f.vertices[t[2] as usize],
                );
                0.5 * (b - a).cross(c - a).length()
            })
            .sum()
    }

    #[test]
    fn square_with_hole_covers_its_area_ccw() {
        let outer = vec![v2(0.0, 0.0), v2(10.0, 0.0), v2(10.0, 10.0), v2(0.0, 10.0)];
        let hole = vec![v2(3.0, 3.0), v2(3.0, 7.0), v2(7.0, 7.0), v2(7.0, 3.0)];
        let tris = triangulate_2d(&outer, std::slice::from_ref(&hole));
        let all: Vec<DVec2> = outer.iter().chain(hole.iter()).copied().collect();
        assert!((area_2d(&all, &tris) - 84.0).abs() < 1e-9);
        assert_eq!(tris.len(), 8);
        for t in &tris {
            let (a, b, c) = (all[t[0] as usize], all[t[1] as usize], all[t[2] as usize]);
            assert!((b - a).perp_dot(c - a) > 0.0);
        }
    }

    #[test]
    fn clockwise_input_still_gives_ccw_triangles() {
        let outer = vec![v2(0.0, 0.0), v2(0.0, 4.0), v2(4.0, 4.0), v2(4.0, 0.0)];
        let tris = triangulate_2d(&outer, &[]);
        assert!((area_2d(&outer, &tris) - 16.0).abs() < 1e-9);
    }

    #[test]
    fn short_holes_are_ignored_but_keep_numbering() {
        let outer = vec![v2(0.0, 0.0), v2(10.0, 0.0), v2(10.0, 10.0), v2(0.0, 10.0)];
        let bad = vec![v2(1.0, 1.0), v2(2.0, 2.0)];
        let hole = vec![v2(3.0, 3.0), v2(3.0, 7.0), v2(7.0, 7.0), v2(7.0, 3.0)];
        let tris = triangulate_2d(&outer, &[bad.clone(), hole.clone()]);
        let all: Vec<DVec2> = outer
            .iter()
            .chain(bad.iter())
            .chain(hole.iter())
            .copied()
            .collect();
        assert!(tris.iter().flatten().all(|&i| i != 4 && i != 5));
        assert!((area_2d(&all, &tris) - 84.0).abs() < 1e-9);
    }

    #[test]
    fn degenerate_faces_give_nothing() {
        let line = [DVec3::ZERO, DVec3::X, DVec3::X * 2.0, DVec3::X * 3.0];
        assert_eq!(triangulate_face(&line, &[]), None);
        assert_eq!(triangulate_face(&[DVec3::ZERO, DVec3::X], &[]), None);
        let nan = [DVec3::ZERO, DVec3::X, DVec3::new(f64::NAN, 1.0, 0.0)];
        assert_eq!(triangulate_face(&nan, &[]), None);
        let same = [DVec3::ONE, DVec3::ONE, DVec3::ONE];
        assert_eq!(triangulate_face(&same, &[]), None);
        assert!(
            triangulate_2d(&[v2(0.0, 0.0), v2(f64::INFINITY, 0.0), v2(0.0, 1.0)], &[]).is_empty()
        );
    }

    #[test]
    fn vertical_wall_faces_outward() {
        // South wall of a box, CCW seen from the south (outside): normal -Y.
        let wall = [
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(10.0, 0.0, 0.0),
            DVec3::new(10.0, 0.0, 3.0),
            DVec3::new(0.0, 0.0, 3.0),
        ];
        let f = triangulate_face(&wall, &[]).unwrap();
        assert!((f.normal - DVec3::NEG_Y).length() < 1e-12);
        assert!((area_3d(&f) - 30.0).abs() < 1e-9);
        for t in &f.triangles {
            let (a, b, c) = (
                f.vertices[t[0] as usize],
                f.vertices[t[1] as usize],
                f.vertices[t[2] as usize],
            );
            assert!((b - a).cross(c - a).dot(DVec3::NEG_Y) > 0.0);
        }
    }

    #[test]
    fn collinear_points_are_not_returned_unused() {
        // A rectangle with an extra point on an edge: all vertices are used or dropped, never
        // returned unused.
        let r = [
            DVec3::new(0.0, 0.0, 5.0),
            DVec3::new(5.0, 0.0, 5.0),
            DVec3::new(10.0, 0.0, 5.0),
            DVec3::new(10.0, 4.0, 5.0),
            DVec3::new(0.0, 4.0, 5.0),
        ];
        let f = triangulate_face(&r, &[]).unwrap();
        let mut used = vec![false; f.vertices.len()];
        for t in &f.triangles {
            for &i in t {
                used[i as usize] = true;
            }
        }
        assert!(used.iter().all(|u| *u));
        assert!((area_3d(&f) - 40.0).abs() < 1e-9);
    }

    /// A star-shaped ring around the origin (every chord stays at least 1 m from it), with an
    /// optional clockwise square hole of half-size < 0.7 at the origin.
    fn star_polygon() -> impl Strategy<Value = (Vec<DVec2>, Option<Vec<DVec2>>)> {
        (6usize..30)
            .prop_flat_map(|n| {
                (
                    prop::collection::vec((2.0f64..10.0, 0.0f64..0.8), n),
                    prop::option::of(0.1f64..0.69),
                )
            })
            .prop_map(|(pts, hole)| {
                let n = pts.len() as f64;
                let outer = pts
                    .iter()
                    .enumerate()
                    .map(|(i, (r, j))| {
                        let a = (i as f64 + j) * std::f64::consts::TAU / n;
                        DVec2::new(r * a.cos(), r * a.sin())
                    })
                    .collect();
                let hole = hole.map(|s| vec![v2(-s, -s), v2(-s, s), v2(s, s), v2(s, -s)]);
                (outer, hole)
            })
    }

    proptest! {
        #[test]
        fn triangles_cover_face_with_its_orientation(
            (outer, hole) in star_polygon(),
            theta in 0.0f64..std::f64::consts::PI,
            phi in 0.0f64..std::f64::consts::TAU,
            spin in 0.0f64..std::f64::consts::TAU,
            offset in prop::array::uniform3(-500.0f64..500.0),
        ) {
            let holes: Vec<Vec<DVec2>> = hole.into_iter().collect();
            let expected = ring_signed_area(&outer) + holes.iter().map(|h| ring_signed_area(h)).sum::<f64>();
            // Embed in 3D: a right-handed frame (e1, e2, n) so CCW in 2D is CCW around n.
            let n = DVec3::new(theta.sin() * phi.cos(), theta.sin() * phi.sin(), theta.cos());
            let (b1, b2) = n.any_orthonormal_pair();
            let e1 = b1 * spin.cos() + b2 * spin.sin();
            let e2 = n.cross(e1);
            let o = DVec3::from(offset);
            let lift = |r: &Vec<DVec2>| -> Vec<DVec3> { r.iter().map(|p| o + e1 * p.x + e2 * p.y).collect() };
            let outer3 = lift(&outer);
            let holes3: Vec<Vec<DVec3>> = holes.iter().map(lift).collect();

            let f = triangulate_face(&outer3, &holes3).expect("non-degenerate face");
            prop_assert!((f.normal - n).length() < 1e-9);
            prop_assert!((area_3d(&f) - expected).abs() < 1e-7 * expected.max(1.0));
            for t in &f.triangles {
                prop_assert!(t.iter().all(|&i| (i as usize) < f.vertices.len()));
                let (a, b, c) = (f.vertices[t[0] as usize], f.vertices[t[1] as usize], f.vertices[t[2] as usize]);
                prop_assert!((b - a).cross(c - a).dot(n) > 0.0);
            }
            prop_assert!(f.vertices.iter().all(|p| p.is_finite()));

            // Same in 2D.
            let tris = triangulate_2d(&outer, &holes);
            let all: Vec<DVec2> = outer.iter().chain(holes.iter().flatten()).copied().collect();
            prop_assert!((area_2d(&all, &tris) - expected).abs() < 1e-7 * expected.max(1.0));
        }
    }

    /// Earcut's own triangles of a ring without holes.
    fn earcut_of(data: &[[f64; 2]]) -> Vec<u32> {
        let mut out = Vec::new();
        earcut::Earcut::new().earcut(data.iter().copied(), &[] as &[u32], &mut out);
        out
    }

    #[test]
    fn ear_slice_cuts_convex_and_concave_rings_as_earcut() {
        let mut ring = Vec::new();
        let mut out = Vec::new();
        let rings: [&[[f64; 2]]; 5] = [
            &[[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]],
            &[[0.0, 0.0], [0.0, 1.0], [1.0, 1.0], [1.0, 0.0]],
            &[[0.0, 0.0], [4.0, 0.0], [4.0, 4.0], [2.0, 1.0], [0.0, 4.0]],
            &[
                [0.0, 0.0],
                [2.0, 0.0],
                [4.0, 0.0],
                [4.0, 3.0],
                [0.0, 3.0],
                [0.0, 0.0],
            ],
            &[[0.0, 0.0], [1.0, 0.0], [2.0, 0.0]],
        ];
        for r in rings {
            let done = ear_slice(r, &mut ring, &mut out);
            assert!(!done || out == earcut_of(r), "{r:?}: {out:?}");
        }
    }

    proptest! {
        /// Wherever the ear-slicing replica finishes, it gives earcut's triangles in earcut's
        /// order (so the glTF bytes do not depend on which of the two cut a face).
        #[test]
        fn ear_slice_matches_earcut(
            pts in prop::collection::vec((-8i32..8, -8i32..8), 3..12),
            star in prop::collection::vec((1.0f64..10.0, 0.0f64..0.9), 3..40),
            scale in 0.001f64..1000.0,
        ) {
            let mut ring = Vec::new();
            let mut out = Vec::new();
            let grid: Vec<[f64; 2]> = pts.iter().map(|&(x, y)| [x as f64 * scale, y as f64 * 0.7]).collect();
            if ear_slice(&grid, &mut ring, &mut out) {
                prop_assert_eq!(&out, &earcut_of(&grid));
            }
            let n = star.len() as f64;
            let round: Vec<[f64; 2]> = star
                .iter()
                .enumerate()
                .map(|(i, (r, j))| {
                    let a = (i as f64 + j) * std::f64::consts::TAU / n;
                    [scale * r * a.cos() + 0.1, r * a.sin() - 3.0]
                })
                .collect();
            prop_assert!(ear_slice(&round, &mut ring, &mut out) || round.len() > 3);
            if ear_slice(&round, &mut ring, &mut out) {
                prop_assert_eq!(&out, &earcut_of(&round));
            }
        }
    }

    proptest! {
        /// Arbitrary rings (self-intersecting, holes anywhere, repeated points): never a panic,
        /// indices in range, every triangle CCW with positive area.
        #[test]
        fn arbitrary_rings_never_panic(
            outer in prop::collection::vec((-50i32..50, -50i32..50), 0..20),
            holes in prop::collection::vec(prop::collection::vec((-50i32..50, -50i32..50), 0..8), 0..3),
        ) {
            let ring = |r: &Vec<(i32, i32)>| r.iter().map(|&(x, y)| v2(x as f64 * 0.5, y as f64 * 0.5)).collect::<Vec<_>>();
            let outer = ring(&outer);
            let holes: Vec<Vec<DVec2>> = holes.iter().map(ring).collect();
            let all: Vec<DVec2> = outer.iter().chain(holes.iter().flatten()).copied().collect();
            for t in triangulate_2d(&outer, &holes) {
                prop_assert!(t.iter().all(|&i| (i as usize) < all.len()));
                let (a, b, c) = (all[t[0] as usize], all[t[1] as usize], all[t[2] as usize]);
                prop_assert!((b - a).perp_dot(c - a) > 0.0);
            }
            let outer3: Vec<DVec3> = outer.iter().map(|p| DVec3::new(p.x, 0.3 * p.y, p.y)).collect();
            let holes3: Vec<Vec<DVec3>> = holes.iter().map(|h| h.iter().map(|p| DVec3::new(p.x, 0.3 * p.y, p.y)).collect()).collect();
            if let Some(f) = triangulate_face(&outer3, &holes3) {
                prop_assert!(f.normal.is_finite());
                prop_assert!(f.triangles.iter().flatten().all(|&i| (i as usize) < f.vertices.len()));
            }
        }
    }
}

#[cfg(test)]
mod many_holes_tests {
    use super::*;

    fn square(x: f64, y: f64, s: f64, ccw: bool) -> Vec<DVec2> {
        let mut r = vec![
            DVec2::new(x, y),
            DVec2::new(x + s, y),
            DVec2::new(x + s, y + s),
            DVec2::new(x, y + s),
        ];
        if !ccw {
            r.reverse();
        }
        r
    }

    fn area(pts: &[DVec2], tris: &[[u32; 3]]) -> f64 {
        tris.iter()
            .map(|t| {
                let (a, b, c) = (pts[t[0] as usize], pts[t[1] as usize], pts[t[2] as usize]);
                0.5 * (b - a).perp_dot(c - a)
            })
            .sum()
    }

    /// Issue 43: a face with thousands of holes (the rest of an outline with many parts) is
    /// cut in O(n log n), covering exactly the polygon minus its holes, every triangle
    /// counter-clockwise and on the input's vertices; earcut's result past `MANY_HOLES` only
    /// differs in which triangles, not in what they cover.
    #[test]
    fn a_face_with_many_holes_is_covered_exactly_and_quickly() {
        for n in [MANY_HOLES + 1, 2_500] {
            let side = (n as f64).sqrt().ceil() as usize;
            let outer = square(0.0, 0.0, 10.0 * side as f64 + 10.0, true);
            let holes: Vec<Vec<DVec2>> = (0..n)
                .map(|k| {
                    let (i, j) = ((k % side) as f64, (k / side) as f64);
                    square(
                        10.0 + 10.0 * i,
                        10.0 + 10.0 * j,
                        4.0 + (k % 3) as f64,
                        false,
                    )
                })
                .collect();
            let start = std::time::Instant::now();
            let tris = triangulate_2d(&outer, &holes);
            let took = start.elapsed();
            let mut pts = outer.clone();
            pts.extend(holes.iter().flatten());
            let want = (10.0 * side as f64 + 10.0).powi(2)
                - holes
                    .iter()
                    .map(|h| (h[1].x - h[0].x).abs().powi(2))
                    .sum::<f64>();
            let got = area(&pts, &tris);
            assert!(
                (got - want).abs() < 1e-6 * want,
                "{n} holes: {got} vs {want}"
            );
            for t in &tris {
                let (a, b, c) = (pts[t[0] as usize], pts[t[1] as usize], pts[t[2] as usize]);
                assert!((b - a).perp_dot(c - a) > 0.0, "CCW");
                // No triangle's centre is in a hole.
                let m = (a + b + c) / 3.0;
                assert!(!holes.iter().any(|h| m.x > h[0].x.min(h[1].x)
                    && m.x < h[0].x.max(h[1].x)
                    && m.y > h[0].y.min(h[2].y)
                    && m.y < h[0].y.max(h[2].y)));
            }
            // Generous for debug builds on shared machines: earcut took minutes here.
            assert!(took.as_secs_f64() < 20.0, "{n} holes took {took:?}");
        }
    }

    /// The same polygon cut by earcut (few holes) and by the triangulation (many) covers the
    /// same area; a hole touching the outer ring at a vertex is one vertex, not a crash.
    #[test]
    fn shared_vertices_and_touching_rings_do_not_break_the_cut() {
        let outer = square(0.0, 0.0, 1000.0, true);
        let mut holes: Vec<Vec<DVec2>> = (0..100)
            .map(|k| {
                square(
                    20.0 + 90.0 * (k % 10) as f64,
                    20.0 + 90.0 * (k / 10) as f64,
                    30.0,
                    false,
                )
            })
            .collect();
        // A hole sharing the outer ring's corner.
        holes.push(vec![
            DVec2::new(0.0, 0.0),
            DVec2::new(5.0, 10.0),
            DVec2::new(10.0, 5.0),
        ]);
        let tris = triangulate_2d(&outer, &holes);
        let mut pts = outer.clone();
        pts.extend(holes.iter().flatten());
        let got = area(&pts, &tris);
        let want = 1_000_000.0 - 100.0 * 900.0 - 37.5;
        assert!((got - want).abs() < 1e-6 * want, "{got} vs {want}");
    }
}
