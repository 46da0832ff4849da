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
pub struct FaceTriangles {
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
    if outer.len() < 3 {
        return Vec::new();
    }
    let all_finite = std::iter::once(outer)
        .chain(holes.iter().map(Vec::as_slice))
        .flatten()
        .all(|p| p.is_finite());
    if !all_finite {
        return Vec::new();
    }
    let total: usize = outer.len() + holes.iter().map(Vec::len).sum::<usize>();
    if u32::try_from(total).is_err() {
        return Vec::new();
    }

    // Earcut's vertex numbering skips ignored holes; `index_map` takes it back to ours. Coordinates
    // are taken relative to the first vertex so that large offsets do not eat the precision.
    let origin = outer[0];
    let mut data: Vec<[f64; 2]> = Vec::with_capacity(total);
    let mut index_map: Vec<u32> = Vec::with_capacity(total);
    let mut hole_starts: Vec<u32> = Vec::new();
    let mut push_ring = |ring: &[DVec2], first: usize, data: &mut Vec<[f64; 2]>| {
        for (k, p) in ring.iter().enumerate() {
            let q = *p - origin;
            data.push([q.x, q.y]);
            index_map.push((first + k) as u32);
        }
    };
    push_ring(outer, 0, &mut data);
    let mut first = outer.len();
    for h in holes {
        if h.len() >= 3 {
            hole_starts.push(data.len() as u32);
            push_ring(h, first, &mut data);
        }
        first += h.len();
    }

    let (lo, hi) = data.iter().fold(
        (DVec2::splat(f64::INFINITY), DVec2::splat(f64::NEG_INFINITY)),
        |(lo, hi), p| (lo.min(DVec2::from(*p)), hi.max(DVec2::from(*p))),
    );
    let extent = (hi - lo).max_element();
    // `extent` is finite here (all points are); zero means all points coincide.
    if extent <= 0.0 {
        return Vec::new();
    }
    let min_area = REL_EPS * extent * extent;

    let mut raw: Vec<u32> = Vec::new();
    earcut::Earcut::new().earcut(data.iter().copied(), &hole_starts, &mut raw);

    let mut out = Vec::with_capacity(raw.len() / 3);
    for t in raw.chunks_exact(3) {
        let (a, b, c) = (t[0] as usize, t[1] as usize, t[2] as usize);
        let (Some(pa), Some(pb), Some(pc)) = (data.get(a), data.get(b), data.get(c)) else {
            continue;
        };
        let (pa, pb, pc) = (DVec2::from(*pa), DVec2::from(*pb), DVec2::from(*pc));
        let twice_area = (pb - pa).perp_dot(pc - pa);
        if twice_area.abs() <= 2.0 * min_area {
            continue;
        }
        let (ia, ib, ic) = (index_map[a], index_map[b], index_map[c]);
        if twice_area > 0.0 {
            out.push([ia, ib, ic]);
        } else {
            out.push([ia, ic, ib]);
        }
    }
    out
}

/// Triangulates a planar 3D polygon with holes (a model face).
///
/// The face is projected onto its own plane, whose orientation is given by the Newell normal of
/// the outer ring, so triangles come out counter-clockwise seen from the normal's side. Returns
/// `None` for a degenerate face: fewer than 3 points, non-finite coordinates, zero area, or no
/// triangle left. Only vertices used by a triangle are returned.
pub fn triangulate_face(outer: &[DVec3], holes: &[Vec<DVec3>]) -> Option<FaceTriangles> {
    if outer.len() < 3 {
        return None;
    }
    let rings = || std::iter::once(outer).chain(holes.iter().map(Vec::as_slice));
    if !rings().flatten().all(|p| p.is_finite()) {
        return None;
    }
    let origin = outer[0];
    let rel: Vec<DVec3> = outer.iter().map(|p| *p - origin).collect();
    let newell = super::newell_normal(&rel);
    let extent = rel.iter().fold(0.0f64, |m, p| m.max(p.abs().max_element()));
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
    let project = |ring: &[DVec3]| -> Vec<DVec2> {
        ring.iter()
            .map(|p| {
                let q = *p - origin;
                DVec2::new(q.dot(u), q.dot(v))
            })
            .collect()
    };
    let outer2 = project(outer);
    let holes2: Vec<Vec<DVec2>> = holes.iter().map(|h| project(h)).collect();
    let tris = triangulate_2d(&outer2, &holes2);
    if tris.is_empty() {
        return None;
    }

    // Keep only used vertices, numbered in ring order (deterministic).
    let all: Vec<DVec3> = rings().flatten().copied().collect();
    let mut new_index = vec![u32::MAX; all.len()];
    for t in &tris {
        for &i in t {
            new_index[i as usize] = 0;
        }
    }
    let mut vertices = Vec::new();
    for (i, slot) in new_index.iter_mut().enumerate() {
        if *slot == 0 {
            *slot = vertices.len() as u32;
            vertices.push(all[i]);
        }
    }
    let triangles = tris
        .iter()
        .map(|t| {
            [
                new_index[t[0] as usize],
                new_index[t[1] as usize],
                new_index[t[2] as usize],
            ]
        })
        .collect();
    Some(FaceTriangles {
        normal,
        vertices,
        triangles,
    })
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
