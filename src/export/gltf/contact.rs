//! Where the parts of a building touch: the faces, or the pieces of them, that lie against an
//! opposite face of another part of the same building, which the glTF leaves out.
//!
//! Two parts that share a boundary each have a wall on it, in the same plane and facing each
//! other; a part standing on a flat roof has its ground in the roof's plane, facing it. Each
//! part's solid needs those faces (CityGML and IFC write them), but a view never sees them: they
//! are inside the building. Drawn, their edges meet the outside surfaces exactly where the parts
//! meet, and a renderer's depth test speckles the seam with the hidden face's colour (a hidden
//! wall's top edge along the roofs' join, a ground under a roof). Without them the seam is only
//! the outside surfaces' shared edge.
//!
//! Only hollow parts (no LOD4 interior) lose faces: a part with rooms is seen into through its
//! glass, and the wall of the part next to it closes its rooms.
//!
//! Walls are matched by their footprint edge (the other part's wall stands on the same edge
//! reversed, as `prepare::share_vertices` makes shared boundaries carry the same vertices) and
//! cut in the wall's plane, so a taller part keeps the piece of its wall above the lower one;
//! flat roofs and grounds are matched by height and cut in plan. What is left of a face is the
//! face itself when nothing covers it (no new vertices), else its uncovered pieces.

use std::borrow::Cow;
use std::collections::HashMap;

use glam::{DVec2, DVec3};

use crate::geometry::clip::difference;
use crate::geometry::Polygon;
use crate::model::{grid_key, Building, Face, Part, Wall};

/// A point in whole millimetres ([`grid_key`]).
type Mm = (i64, i64, i64);

/// Faces closer to horizontal than this (the z component of their unit normal) are matched in
/// plan.
const HORIZONTAL: f64 = 1.0 - 1e-9;

/// Leftovers smaller than this (square metres) are dropped, and a face that loses less than
/// this is kept whole.
const MIN_PIECE: f64 = 1e-6;

/// The faces of one part that the glTF draws.
pub(super) struct Exposed<'a> {
    /// Per wall (in the part's order), the pieces of its outline no other part's wall covers:
    /// empty when the wall lies wholly against other parts.
    pub(super) walls: Vec<Vec<Cow<'a, Face>>>,
    /// The roof faces' uncovered pieces.
    pub(super) roof: Vec<Cow<'a, Face>>,
    /// The ground's uncovered pieces.
    pub(super) ground: Vec<Cow<'a, Face>>,
}

/// For each part of `b`, its exposed faces (see the module documentation). A building of one
/// part is all exposed.
pub(super) fn exposed(b: &Building) -> Vec<Exposed<'_>> {
    if b.parts.len() < 2 {
        return b.parts.iter().map(whole).collect();
    }
    let flat = |z: f64| grid_key(DVec3::new(0.0, 0.0, z)).2;
    // Walls by footprint edge, flat roofs (facing up) and grounds (facing down) by height.
    let mut walls: HashMap<(Mm, Mm), Vec<(usize, &Wall)>> = HashMap::new();
    let mut roofs: HashMap<i64, Vec<(usize, &Face)>> = HashMap::new();
    let mut grounds: HashMap<i64, Vec<(usize, &Face)>> = HashMap::new();
    for (pi, p) in b.parts.iter().enumerate().filter(|(_, p)| hollow(p)) {
        for w in &p.walls {
            walls.entry(edge_key(w)).or_default().push((pi, w));
        }
        for f in &p.roof {
            if let Some(z) = level(f, 1.0) {
                roofs.entry(flat(z)).or_default().push((pi, f));
            }
        }
        if let Some(z) = level(&p.ground, -1.0) {
            grounds.entry(flat(z)).or_default().push((pi, &p.ground));
        }
    }
    let others = |list: Option<&Vec<(usize, &'_ Face)>>, pi: usize| -> Vec<Face> {
        list.into_iter()
            .flatten()
            .filter(|(pj, _)| *pj != pi)
            .map(|(_, f)| (*f).clone())
            .collect()
    };
    b.parts
        .iter()
        .enumerate()
        .map(|(pi, p)| {
            if !hollow(p) {
                return whole(p);
            }
            let walls = p
                .walls
                .iter()
                .map(|w| {
                    let (a, e) = edge_key(w);
                    let against: Vec<&Face> = walls
                        .get(&(e, a))
                        .into_iter()
                        .flatten()
                        .filter(|(pj, _)| *pj != pi)
                        .map(|(_, o)| &o.outline)
                        .collect();
                    uncovered_wall(w, &against)
                })
                .collect();
            let roof = p
                .roof
                .iter()
                .flat_map(|f| match level(f, 1.0) {
                    Some(z) => uncovered_flat(f, &others(grounds.get(&flat(z)), pi), false),
                    None => vec![Cow::Borrowed(f)],
                })
                .collect();
            let ground = match level(&p.ground, -1.0) {
                Some(z) => uncovered_flat(&p.ground, &others(roofs.get(&flat(z)), pi), true),
                None => vec![Cow::Borrowed(&p.ground)],
            };
            Exposed {
                walls,
                roof,
                ground,
            }
        })
        .collect()
}

/// Whether `p` has no interior (LOD4 rooms). Only hollow parts lose faces to each other: seen
/// through a part's transparent glass (LOD4), the wall of the part behind it closes the room.
fn hollow(p: &Part) -> bool {
    p.interior.is_empty()
}

/// All of `p`'s faces, borrowed.
fn whole(p: &Part) -> Exposed<'_> {
    Exposed {
        walls: p
            .walls
            .iter()
            .map(|w| vec![Cow::Borrowed(&w.outline)])
            .collect(),
        roof: p.roof.iter().map(Cow::Borrowed).collect(),
        ground: vec![Cow::Borrowed(&p.ground)],
    }
}

/// A wall's footprint edge, start to end, in millimetres.
fn edge_key(w: &Wall) -> (Mm, Mm) {
    (grid_key(w.start.extend(0.0)), grid_key(w.end.extend(0.0)))
}

/// The height of `f` when it is flat and faces `up` (1: up, -1: down), else `None`.
fn level(f: &Face, up: f64) -> Option<f64> {
    let n = crate::geometry::newell_normal(&f.outer).normalize_or_zero();
    let z = f.outer.first()?.z;
    (n.z * up > HORIZONTAL && f.outer.iter().all(|p| (p.z - z).abs() < 1e-9)).then_some(z)
}

/// What of `face` (mapped into 2D by `to2`, back by `to3`) lies outside every face of `cutters`:
/// the face itself when nothing covers it.
fn uncovered<'a>(
    face: &'a Face,
    cutters: &[&Face],
    to2: impl Fn(DVec3) -> DVec2,
    to3: impl Fn(DVec2) -> DVec3,
) -> Vec<Cow<'a, Face>> {
    if cutters.is_empty() {
        return vec![Cow::Borrowed(face)];
    }
    let flat = |f: &Face| {
        Polygon::new(
            f.outer.iter().map(|p| to2(*p)).collect(),
            f.holes
                .iter()
                .map(|h| h.iter().map(|p| to2(*p)).collect())
                .collect(),
        )
    };
    let own = flat(face);
    let cut: Vec<Polygon> = cutters.iter().map(|f| flat(f)).collect();
    let rest = difference(std::slice::from_ref(&own), &cut);
    let left: f64 = rest.iter().map(Polygon::area).sum();
    if (own.area() - left).abs() < MIN_PIECE {
        return vec![Cow::Borrowed(face)];
    }
    let lift = |r: &Vec<DVec2>| r.iter().map(|p| to3(*p)).collect::<Vec<_>>();
    rest.iter()
        .filter(|p| p.area() >= MIN_PIECE)
        .map(|p| {
            Cow::Owned(Face {
                outer: lift(&p.outer),
                holes: p.holes.iter().map(lift).collect(),
            })
        })
        .collect()
}

/// The pieces of `w`'s outline that no face of `against` (walls of other parts on the same
/// edge, facing the other way) covers, cut in the wall's plane: (u along the edge, z), where
/// counter-clockwise is counter-clockwise seen from outside.
fn uncovered_wall<'a>(w: &'a Wall, against: &[&Face]) -> Vec<Cow<'a, Face>> {
    let d = w.end - w.start;
    let len = d.length();
    if against.is_empty() || len.is_nan() || len <= 0.0 {
        return vec![Cow::Borrowed(&w.outline)];
    }
    let dir = d / len;
    uncovered(
        &w.outline,
        against,
        |p| DVec2::new((p.truncate() - w.start).dot(dir), p.z),
        |q| (w.start + dir * q.x).extend(q.y),
    )
}

/// The pieces of flat `face` that no face of `cutters` covers, cut in plan; `down` for a face
/// that faces down (its rings run the other way in plan).
fn uncovered_flat<'a>(face: &'a Face, cutters: &[Face], down: bool) -> Vec<Cow<'a, Face>> {
    let z = face.outer[0].z;
    let refs: Vec<&Face> = cutters.iter().collect();
    let mut out = uncovered(face, &refs, |p| p.truncate(), |q| q.extend(z));
    if down {
        for f in &mut out {
            if let Cow::Owned(f) = f {
                f.outer.reverse();
                f.holes.iter_mut().for_each(|h| h.reverse());
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::export::lod3geom::samples;
    use crate::model::SourceId;

    fn rect(x0: f64, y0: f64, x1: f64, y1: f64) -> Vec<DVec2> {
        vec![
            DVec2::new(x0, y0),
            DVec2::new(x1, y0),
            DVec2::new(x1, y1),
            DVec2::new(x0, y1),
        ]
    }

    fn area(faces: &[Cow<'_, Face>]) -> f64 {
        let ring = |r: &Vec<DVec3>| crate::geometry::newell_normal(r).length() / 2.0;
        faces
            .iter()
            .map(|f| ring(&f.outer) - f.holes.iter().map(ring).sum::<f64>())
            .sum()
    }

    #[test]
    fn shared_walls_and_a_roof_under_a_ground_are_left_out() {
        // A 10 x 6 m block of 2 storeys (0-6 m) and, east of it, a 6 x 6 m tower of 4 storeys
        // (0-12 m) sharing the edge x = 10; a 4 x 4 m kiosk standing on the block's roof.
        let block = samples::part(
            "p0",
            Polygon::new(rect(0.0, 0.0, 10.0, 6.0), vec![]),
            vec![0.0, 3.0],
            6.0,
            &[],
            &[],
        );
        let tower = samples::part(
            "p1",
            Polygon::new(rect(10.0, 0.0, 16.0, 6.0), vec![]),
            vec![0.0, 3.0, 6.0, 9.0],
            12.0,
            &[],
            &[],
        );
        let kiosk = samples::part(
            "p2",
            Polygon::new(rect(2.0, 1.0, 6.0, 5.0), vec![]),
            vec![6.0],
            9.0,
            &[],
            &[],
        );
        let b = samples::building(SourceId::Way(1), vec![block, tower, kiosk]);
        let e = exposed(&b);
        // The block's east walls (edge 1, both storeys) face the tower's west walls (edge 3,
        // storeys 0 and 1): all four are gone; the tower's upper west walls stay whole.
        assert!(e[0].walls[1].is_empty() && e[0].walls[5].is_empty());
        assert!(e[1].walls[3].is_empty() && e[1].walls[7].is_empty());
        for w in [11, 15] {
            assert!(matches!(e[1].walls[w][..], [Cow::Borrowed(_)]));
        }
        // Every other wall is whole and borrowed.
        let whole = e
            .iter()
            .flat_map(|p| &p.walls)
            .filter(|w| matches!(w[..], [Cow::Borrowed(_)]))
            .count();
        assert_eq!(whole, 8 + 16 + 4 - 4);
        // The block's roof loses the kiosk's 16 m2 (the kiosk's ground is gone), facing up.
        assert!((area(&e[0].roof) - (60.0 - 16.0)).abs() < 1e-9);
        assert!(e[0]
            .roof
            .iter()
            .all(|f| crate::geometry::newell_normal(&f.outer).z > 0.0));
        assert!(e[2].ground.is_empty());
        assert!(matches!(e[0].ground[..], [Cow::Borrowed(_)]));
        // A part with rooms keeps its faces, and so do the faces against it.
        let mut with_rooms = b.clone();
        with_rooms.parts[1].interior = crate::export::fixtures::lod4_house().parts[0]
            .interior
            .clone();
        let e = exposed(&with_rooms);
        assert!(!e[0].walls[1].is_empty() && !e[1].walls[3].is_empty());
        assert!(
            e[2].ground.is_empty(),
            "the kiosk on the block still loses its ground"
        );
        // One part: all borrowed.
        let one = samples::house();
        let e = exposed(&one);
        assert!(e[0]
            .walls
            .iter()
            .all(|w| matches!(w[..], [Cow::Borrowed(_)])));
    }

    #[test]
    fn a_taller_wall_keeps_its_piece_above_the_lower_part() {
        // One storey each, the block 4 m high, the tower 10 m: the tower's west wall keeps
        // 6 m of its 10 over the shared 6 m edge, facing west.
        let block = samples::part(
            "p0",
            Polygon::new(rect(0.0, 0.0, 10.0, 6.0), vec![]),
            vec![0.0],
            4.0,
            &[],
            &[],
        );
        let tower = samples::part(
            "p1",
            Polygon::new(rect(10.0, 0.0, 16.0, 6.0), vec![]),
            vec![0.0],
            10.0,
            &[],
            &[],
        );
        let b = samples::building(SourceId::Way(2), vec![block, tower]);
        let e = exposed(&b);
        assert!(e[0].walls[1].is_empty());
        let west = &e[1].walls[3];
        assert!((area(west) - 36.0).abs() < 1e-9);
        for f in west {
            let n = crate::geometry::newell_normal(&f.outer);
            assert!(n.x < 0.0 && n.y.abs() < 1e-9 && n.z.abs() < 1e-9);
            assert!(f.outer.iter().all(|p| p.z >= 4.0 - 1e-9 && p.x == 10.0));
        }
    }
}
