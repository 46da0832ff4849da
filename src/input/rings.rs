//! Ring helpers shared by the readers: cleaning, orientation, containment, and grouping a bag
//! of rings into polygons with holes by how they nest.
//!
//! Both OSM multipolygons and shapefile records hand us rings whose declared role (OSM `outer` /
//! `inner`, ESRI clockwise / counter-clockwise) is sometimes wrong. Nesting is the ground truth:
//! a ring inside an odd number of other rings is a hole. Declared roles are only compared with
//! it, so that the report can say when they were corrected.

use super::{Ring, SourcePolygon};

/// Signed area (shoelace), positive when counter-clockwise with y up. The ring is not closed.
pub fn signed_area(ring: &[(f64, f64)]) -> f64 {
    let n = ring.len();
    if n < 3 {
        return 0.0;
    }
    // Relative to the first vertex, for precision with large projected coordinates.
    let (ox, oy) = ring[0];
    let mut s = 0.0;
    for i in 0..n {
        let (ax, ay) = ring[i];
        let (bx, by) = ring[(i + 1) % n];
        s += (ax - ox) * (by - oy) - (bx - ox) * (ay - oy);
    }
    0.5 * s
}

/// Even-odd point-in-ring test. Points exactly on an edge may go either way.
pub(crate) fn ring_contains(ring: &[(f64, f64)], p: (f64, f64)) -> bool {
    let n = ring.len();
    let mut inside = false;
    let mut j = n.wrapping_sub(1);
    for i in 0..n {
        let (xi, yi) = ring[i];
        let (xj, yj) = ring[j];
        if (yi > p.1) != (yj > p.1) && p.0 < (xj - xi) * (p.1 - yi) / (yj - yi) + xi {
            inside = !inside;
        }
        j = i;
    }
    inside
}

/// Why a ring of WGS84 (lon, lat) degrees cannot be a place on the Earth, if it cannot: a
/// latitude beyond ±90° or a longitude beyond ±180° (a broken writer or a projected file read
/// as OSM), which a projection would otherwise wrap and use.
pub(crate) fn lonlat_problem(ring: &[(f64, f64)]) -> Option<String> {
    let &(lon, lat) = ring
        .iter()
        .find(|&&(lon, lat)| !(-180.0..=180.0).contains(&lon) || !(-90.0..=90.0).contains(&lat))?;
    Some(format!(
        "coordinates outside the Earth (longitude {lon:.5}, latitude {lat:.5}; WGS84 allows -180..180 and -90..90)"
    ))
}

/// Why a cleaned ring cannot be used, if it cannot.
pub(crate) fn ring_problem(ring: &[(f64, f64)]) -> Option<&'static str> {
    if ring.iter().any(|&(x, y)| !x.is_finite() || !y.is_finite()) {
        return Some("non-finite coordinates");
    }
    // Three points that differ bit for bit.
    let bits = |&(x, y): &(f64, f64)| (x.to_bits(), y.to_bits());
    let mut pts = ring.iter().map(bits);
    let a = pts.next();
    let b = pts.find(|p| Some(*p) != a);
    let c = pts.find(|p| Some(*p) != a && Some(*p) != b);
    if c.is_none() {
        Some("fewer than 3 distinct points")
    } else if signed_area(ring) == 0.0 && collinear(ring) {
        // A bow tie also has a signed area of 0, but it is not empty: the preparation repairs
        // it into its two triangles.
        Some("zero area")
    } else {
        None
    }
}

/// Whether all the points of the ring lie on one line (exactly, in the coordinates given).
fn collinear(ring: &[(f64, f64)]) -> bool {
    let Some(&a) = ring.first() else {
        return true;
    };
    let Some(&b) = ring.iter().find(|p| **p != a) else {
        return true;
    };
    ring.iter()
        .all(|&c| (b.0 - a.0) * (c.1 - a.1) - (b.1 - a.1) * (c.0 - a.0) == 0.0)
}

/// Whether ring `a` lies inside ring `b`. Vertices `a` shares with `b` say nothing (rings may
/// touch), so up to five of the others vote; with none, `a` is not inside.
fn ring_inside(a: &[(f64, f64)], b: &[(f64, f64)], area_a: f64, area_b: f64) -> bool {
    if area_a >= area_b {
        return false;
    }
    let mut inside = 0;
    let mut outside = 0;
    for p in a.iter().filter(|p| !b.contains(p)).take(5) {
        if ring_contains(b, *p) {
            inside += 1;
        } else {
            outside += 1;
        }
    }
    inside > outside
}

/// The outcome of grouping rings: each polygon as (outer ring index, hole ring indices), in
/// input order of their outer rings, plus how many declared roles disagreed with the nesting.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Grouping {
    pub polygons: Vec<(usize, Vec<usize>)>,
    pub role_fixes: usize,
}

/// Groups cleaned, valid rings by nesting. `claims[i]` is the declared role of ring i
/// (`Some(true)` outer, `Some(false)` hole, `None` unknown). A ring's parent is the smallest
/// ring containing it; rings at even depth are outers, at odd depth holes of their parent. An
/// island inside a courtyard is thus an outer again (its own polygon).
pub(crate) fn group_rings(rings: &[Ring], claims: &[Option<bool>]) -> Grouping {
    let n = rings.len();
    let areas: Vec<f64> = rings.iter().map(|r| signed_area(r).abs()).collect();
    let mut parent: Vec<Option<usize>> = vec![None; n];
    let around = Around::new(rings);
    let mut near = Vec::new();
    for i in 0..n {
        around.candidates(i, &mut near);
        for &j in &near {
            if i != j && ring_inside(&rings[i], &rings[j], areas[i], areas[j]) {
                let better = match parent[i] {
                    None => true,
                    Some(k) => areas[j] < areas[k],
                };
                if better {
                    parent[i] = Some(j);
                }
            }
        }
    }
    // Depth by walking up; areas strictly decrease along the chain, so it ends.
    let depth = |mut i: usize| {
        let mut d = 0usize;
        while let Some(p) = parent[i] {
            d += 1;
            i = p;
            if d > n {
                break;
            }
        }
        d
    };
    let depths: Vec<usize> = (0..n).map(depth).collect();
    let mut g = Grouping::default();
    let mut slot: Vec<Option<usize>> = vec![None; n];
    for i in 0..n {
        let is_outer = depths[i] % 2 == 0;
        if let Some(Some(claim)) = claims.get(i) {
            if *claim != is_outer {
                g.role_fixes += 1;
            }
        }
        if is_outer {
            slot[i] = Some(g.polygons.len());
            g.polygons.push((i, Vec::new()));
        }
    }
    for i in 0..n {
        if depths[i] % 2 == 1 {
            if let Some(s) = parent[i].and_then(|p| slot[p]) {
                g.polygons[s].1.push(i);
            }
        }
    }
    g
}

/// A ring's bounding box in an R-tree, with the ring's index.
type RingBox = rstar::primitives::GeomWithData<rstar::primitives::Rectangle<[f64; 2]>, usize>;

/// The rings that may contain a ring: those whose bounding box meets its own (a ring holds a
/// point only within its box; a relation of 10,000 courtyards then costs O(n log n), not
/// 10⁸ ring tests). Boxes are widened by a billionth of the coordinates' size, so that
/// rounding in the point test cannot matter; with a coordinate that is not finite every ring
/// is a candidate, as before.
struct Around {
    boxes: Vec<[[f64; 2]; 2]>,
    tree: Option<rstar::RTree<RingBox>>,
}

impl Around {
    fn new(rings: &[Ring]) -> Around {
        let boxes: Vec<[[f64; 2]; 2]> = rings
            .iter()
            .map(|r| {
                let mut b = [[f64::INFINITY; 2], [f64::NEG_INFINITY; 2]];
                for &(x, y) in r {
                    b[0] = [b[0][0].min(x), b[0][1].min(y)];
                    b[1] = [b[1][0].max(x), b[1][1].max(y)];
                }
                let pad = 1e-9 * (1.0 + b.iter().flatten().fold(0.0f64, |m, v| m.max(v.abs())));
                [
                    [b[0][0] - pad, b[0][1] - pad],
                    [b[1][0] + pad, b[1][1] + pad],
                ]
            })
            .collect();
        let finite = boxes.iter().flatten().flatten().all(|v| v.is_finite());
        let tree = finite.then(|| {
            rstar::RTree::bulk_load(
                boxes
                    .iter()
                    .enumerate()
                    .map(|(i, b)| {
                        rstar::primitives::GeomWithData::new(
                            rstar::primitives::Rectangle::from_corners(b[0], b[1]),
                            i,
                        )
                    })
                    .collect(),
            )
        });
        Around { boxes, tree }
    }

    /// The candidates for ring `i`, in index order (the order the grouping decides ties by).
    fn candidates(&self, i: usize, out: &mut Vec<usize>) {
        out.clear();
        match &self.tree {
            Some(tree) => {
                let b = self.boxes[i];
                let env = rstar::AABB::from_corners(b[0], b[1]);
                out.extend(tree.locate_in_envelope_intersecting(env).map(|g| g.data));
                out.sort_unstable();
            }
            None => out.extend(0..self.boxes.len()),
        }
    }
}

/// Builds a [`SourcePolygon`] with the citygen orientation: outer counter-clockwise, holes
/// clockwise.
pub(crate) fn oriented_polygon(mut outer: Ring, mut holes: Vec<Ring>) -> SourcePolygon {
    if signed_area(&outer) < 0.0 {
        outer.reverse();
    }
    for h in &mut holes {
        if signed_area(h) > 0.0 {
            h.reverse();
        }
    }
    SourcePolygon { outer, holes }
}

/// The polygons of a record's rings as declared (`(ring, declared outer)`), each cleaned
/// (repeated points dropped) and grouped by nesting: what the shapefile and GIS feature readers
/// share. `Err` says why none is usable ("no rings", or each ring's problem).
pub(crate) struct Polygons {
    /// The polygons, oriented the citygen way.
    pub(crate) polygons: Vec<super::SourcePolygon>,
    /// `ring i dropped: why`, for the rings left out (a repair when some polygon remains).
    pub(crate) problems: Vec<String>,
    /// How many rings had a declared role their nesting contradicts.
    pub(crate) role_fixes: usize,
}

/// See [`Polygons`].
pub(crate) fn polygons_of(rings: Vec<(Ring, bool)>) -> Result<Polygons, String> {
    let mut problems = Vec::new();
    let mut kept: Vec<Ring> = Vec::new();
    let mut claims = Vec::new();
    for (i, (mut r, outer)) in rings.into_iter().enumerate() {
        crate::geometry::ring::dedup_by(&mut r, |a, b| a == b);
        if let Some(why) = ring_problem(&r) {
            problems.push(format!("ring {i} dropped: {why}"));
            continue;
        }
        kept.push(r);
        claims.push(Some(outer));
    }
    let g = group_rings(&kept, &claims);
    if g.polygons.is_empty() {
        return Err(if problems.is_empty() {
            "no rings".to_string()
        } else {
            format!("no usable ring: {}", problems.join("; "))
        });
    }
    let polygons = g
        .polygons
        .iter()
        .map(|(o, hs)| {
            oriented_polygon(
                kept[*o].clone(),
                hs.iter().map(|h| kept[*h].clone()).collect(),
            )
        })
        .collect();
    Ok(Polygons {
        polygons,
        problems,
        role_fixes: g.role_fixes,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn square(x: f64, y: f64, s: f64) -> Ring {
        vec![(x, y), (x + s, y), (x + s, y + s), (x, y + s)]
    }

    #[test]
    fn nesting_gives_holes_and_islands() {
        let rings = vec![
            square(2.0, 2.0, 6.0),  // courtyard of 1
            square(0.0, 0.0, 10.0), // outer
            square(4.0, 4.0, 2.0),  // island in the courtyard
            square(20.0, 0.0, 5.0), // second outer
        ];
        let g = group_rings(&rings, &[Some(true), Some(true), None, Some(true)]);
        assert_eq!(g.polygons, vec![(1, vec![0]), (2, vec![]), (3, vec![])]);
        assert_eq!(g.role_fixes, 1, "ring 0 claimed outer but is a hole");
    }

    #[test]
    fn touching_hole_is_still_a_hole() {
        // The hole shares two vertices with the outer ring.
        let outer = vec![(0.0, 0.0), (10.0, 0.0), (10.0, 10.0), (0.0, 10.0)];
        let hole = vec![(0.0, 0.0), (5.0, 2.0), (5.0, 5.0), (2.0, 5.0), (0.0, 10.0)];
        let g = group_rings(&[outer, hole], &[None, None]);
        assert_eq!(g.polygons, vec![(0, vec![1])]);
    }

    #[test]
    fn problems_and_cleaning() {
        let mut r = vec![(0.0, 0.0), (0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 0.0)];
        crate::geometry::ring::dedup_by(&mut r, |a, b| a == b);
        assert_eq!(r, vec![(0.0, 0.0), (1.0, 0.0), (1.0, 1.0)]);
        assert_eq!(ring_problem(&r), None);
        assert!(ring_problem(&[(0.0, 0.0), (1.0, 1.0), (0.0, 0.0)]).is_some());
        assert_eq!(
            ring_problem(&[(0.0, 0.0), (1.0, 1.0), (2.0, 2.0)]),
            Some("zero area")
        );
        assert!(ring_problem(&[(0.0, f64::NAN), (1.0, 1.0), (2.0, 0.0)]).is_some());
    }

    proptest! {
        #[test]
        fn oriented_polygon_orientation(pts in proptest::collection::vec((-1e3f64..1e3, -1e3f64..1e3), 3..12)) {
            let p = oriented_polygon(pts.clone(), vec![pts.clone()]);
            prop_assert!(signed_area(&p.outer) >= 0.0);
            prop_assert!(signed_area(&p.holes[0]) <= 0.0);
            prop_assert_eq!(p.outer.len(), pts.len());
        }

        #[test]
        fn grouping_covers_every_ring_once(n in 1usize..6, seed in 0u64..1000) {
            // Concentric squares of decreasing size: alternate outer / hole.
            let rings: Vec<Ring> = (0..n).map(|i| {
                let s = 100.0 - 10.0 * i as f64 - (seed % 5) as f64;
                square(-s / 2.0, -s / 2.0, s)
            }).collect();
            let g = group_rings(&rings, &vec![None; n]);
            let mut seen: Vec<usize> = g.polygons.iter()
                .flat_map(|(o, h)| std::iter::once(*o).chain(h.iter().copied())).collect();
            seen.sort();
            prop_assert_eq!(seen, (0..n).collect::<Vec<_>>());
            prop_assert_eq!(g.polygons.len(), n.div_ceil(2));
        }
    }
}
