//! LOD4 geometry shared by the writers: room shells (floor, ceiling and one side per room edge,
//! with the holes of the room's interior doors), interior wall bodies, door leaves, stair steps
//! and floor slabs, all built from a [`StoreyInterior`] in the model's local frame.
//!
//! Conventions, the same for every writer:
//!
//! - A room is its polygon's outer ring (rooms are simple polygons), cleaned of repeated and
//!   collinear vertices, extruded from the storey's `floor_z` to its `ceiling_z`. Its faces point
//!   out of the room (the room is a closed solid), so a side is counter-clockwise seen from the
//!   neighbouring room. Sides lie on the room polygon's edges, i.e. on the centre lines of the
//!   interior walls.
//! - An interior door is cut from `DOOR_SILL` above the floor (so that its hole never touches
//!   the border of the wall or room side it is in) up to `floor_z + height`, and never closer
//!   than `DOOR_SILL` to the ceiling. A door whose rectangle does not fit on one side of each
//!   of its wall's two rooms gets no hole in that room.
//! - A stair flight is `risers` steps, each a solid block from the floor up to its tread
//!   (`floor_z + k * rise / risers` for step k = 1..=risers), over equal slices of the bounding
//!   rectangle of the stair's footprint along its run.

use glam::{DVec2, DVec3};

use crate::color::Color;
use crate::geometry::{clean_ring, is_simple, Polygon};
use crate::model::{Face, InteriorDoor, InteriorWall, Stair, StoreyInterior, OPENING_MARGIN};

/// Colour of interior walls (the model gives them none): off-white plaster.
pub(crate) const INTERIOR_WALL_COLOR: Color = Color::rgb(0.93, 0.92, 0.88);
/// Colour of room floors: light oak.
pub(crate) const FLOOR_COLOR: Color = Color::rgb(0.72, 0.58, 0.4);
/// Colour of interior door leaves: mid-brown wood.
pub(crate) const DOOR_COLOR: Color = Color::rgb(0.55, 0.38, 0.22);
/// Colour of interior door frames.
pub(crate) const DOOR_FRAME_COLOR: Color = Color::rgb(0.95, 0.95, 0.95);
/// Colour of stairs: concrete grey.
pub(crate) const STAIR_COLOR: Color = Color::rgb(0.62, 0.62, 0.6);
/// Colour of floor slabs' edges and undersides (ceilings): white.
pub(crate) const SLAB_COLOR: Color = Color::rgb(0.97, 0.97, 0.97);

/// Height of an interior door's sill above the floor, and the least gap between the door and
/// the ceiling (metres).
pub(crate) const DOOR_SILL: f64 = OPENING_MARGIN;
/// Thickness of a floor slab when the storey below gives none (metres).
pub(crate) const DEFAULT_SLAB_THICKNESS: f64 = 0.2;
/// A stair never gets more steps than this, whatever its `risers` says.
pub(crate) const MAX_STEPS: u32 = 64;
/// Lengths below this are zero (metres).
const EPS: f64 = 1e-6;
/// Least distance between a door and the ends of the room side holding it, and how far a door
/// may lie off the side's line (metres).
const DOOR_FIT: f64 = 0.005;

/// The ring of a room: its polygon's outer ring cleaned (`clean_ring`), or `None` when it is
/// degenerate or not simple (two non-adjacent edges touch or cross, e.g. two pieces joined by a
/// zero-width seam), which no writer can build a valid solid from. The model promises simple
/// rooms; this guards the writers against a plan that breaks the promise.
pub fn room_ring(room: &crate::model::Room) -> Option<Vec<DVec2>> {
    let r = clean_ring(&room.polygon.outer)?;
    is_simple(&r).then_some(r)
}

/// The faces of a vertical prism over a counter-clockwise ring from `z0` up to `z1`, pointing
/// out: bottom (clockwise seen from above), top, then one quad per edge.
pub(crate) fn prism_faces(ring: &[DVec2], z0: f64, z1: f64) -> Vec<Face> {
    let mut faces = Vec::with_capacity(ring.len() + 2);
    faces.push(Face::new(ring.iter().rev().map(|p| p.extend(z0)).collect()));
    faces.push(Face::new(ring.iter().map(|p| p.extend(z1)).collect()));
    for i in 0..ring.len() {
        let (a, b) = (ring[i], ring[(i + 1) % ring.len()]);
        faces.push(Face::new(vec![
            a.extend(z0),
            b.extend(z0),
            b.extend(z1),
            a.extend(z1),
        ]));
    }
    faces
}

/// Where a door lies on a room side: `t0 < t1` along the side from its first vertex, and the
/// door's height range.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct DoorSpan {
    /// Index of the door in [`StoreyInterior::doors`].
    pub door: usize,
    /// Start of the door along the side, metres from the side's first vertex.
    pub t0: f64,
    /// End of the door along the side (metres, `t0 < t1`, both inside the side).
    pub t1: f64,
    /// Bottom of the door leaf (metres, local frame: the storey's floor).
    pub z0: f64,
    /// Top of the door leaf (metres).
    pub z1: f64,
}

/// One side of a room: the vertical face on the room edge from `a` to `b` (pointing out of the
/// room) with one hole per door in it, and the doors' own rectangles (same orientation as the
/// side, each filling its hole exactly).
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct RoomSide {
    /// The side's first vertex (the room ring's vertex it starts at, local metres).
    pub a: DVec2,
    /// The side's last vertex.
    pub b: DVec2,
    /// The vertical face from floor to ceiling over `a`-`b`, pointing out of the room, with a
    /// hole per door.
    pub face: Face,
    /// The interior wall this side lies on, if any (none: the side is on an exterior wall).
    pub wall: Option<usize>,
    /// The doors on this side, in the order of their holes in `face`.
    pub doors: Vec<DoorSpan>,
    /// The doors' rectangles, in the order of `doors`.
    pub door_faces: Vec<Face>,
}

/// A room as a closed solid: floor (pointing down), ceiling (pointing up) and sides. Together
/// with the sides' door rectangles, every edge of the shell is shared by exactly two faces.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct RoomShell {
    /// The room's polygon at floor height, pointing down.
    pub floor: Face,
    /// The room's polygon at ceiling height, pointing up.
    pub ceiling: Face,
    /// One vertical side per edge of the room's ring, in ring order.
    pub sides: Vec<RoomSide>,
}

impl RoomShell {
    /// Every face of the closed shell: floor, ceiling, sides, then the door rectangles.
    #[cfg(test)]
    pub(crate) fn faces(&self) -> impl Iterator<Item = &Face> {
        [&self.floor, &self.ceiling]
            .into_iter()
            .chain(self.sides.iter().map(|s| &s.face))
            .chain(self.sides.iter().flat_map(|s| s.door_faces.iter()))
    }
}

/// The door's height range on its storey: from [`DOOR_SILL`] above the floor to its height,
/// at most [`DOOR_SILL`] under the ceiling; `None` when nothing is left.
pub(crate) fn door_heights(s: &StoreyInterior, d: &InteriorDoor) -> Option<(f64, f64)> {
    let z0 = s.floor_z + DOOR_SILL;
    let z1 = (s.floor_z + d.height).min(s.ceiling_z - DOOR_SILL);
    (z0.is_finite() && z1.is_finite() && z1 - z0 > 0.01).then_some((z0, z1))
}

/// The door's end points on its wall's centre line, or `None` for a door outside its wall or a
/// wall without length.
pub(crate) fn door_points(s: &StoreyInterior, d: &InteriorDoor) -> Option<(DVec2, DVec2)> {
    let w = s.walls.get(d.wall)?;
    let len = w.a.distance(w.b);
    let inside = len > EPS && d.u0 >= 0.0 && d.u1 <= len && d.u1 - d.u0 > 0.01;
    if !inside {
        return None;
    }
    let dir = (w.b - w.a) / len;
    Some((w.a + dir * d.u0, w.a + dir * d.u1))
}

/// The shell of room `room` of storey `s`, or `None` when its polygon or height is degenerate.
pub(crate) fn room_shell(s: &StoreyInterior, room: usize) -> Option<RoomShell> {
    let ring = room_ring(s.rooms.get(room)?)?;
    let (f, c) = (s.floor_z, s.ceiling_z);
    if !(f.is_finite() && c.is_finite() && c - f > 0.01) {
        return None;
    }
    let n = ring.len();
    // Every side a door fits on, with how far the door lies off the side's line. A door goes on
    // one side only, the nearest: a room with a fold (two sides a few millimetres apart, back
    // to back) would otherwise hold it twice.
    let mut fits: Vec<(usize, DoorSpan, f64)> = Vec::new();
    for i in 0..n {
        let (a, b) = (ring[i], ring[(i + 1) % n]);
        let len = a.distance(b);
        let dir = (b - a) / len;
        let off = |p: DVec2| (p - a).perp_dot(dir).abs();
        for (di, d) in s.doors.iter().enumerate() {
            let Some(w) = s.walls.get(d.wall) else {
                continue;
            };
            if !w.rooms.contains(&room) {
                continue;
            }
            let (Some((p, q)), Some((z0, z1))) = (door_points(s, d), door_heights(s, d)) else {
                continue;
            };
            if off(p) > DOOR_FIT || off(q) > DOOR_FIT {
                continue;
            }
            let (mut t0, mut t1) = ((p - a).dot(dir), (q - a).dot(dir));
            if t0 > t1 {
                std::mem::swap(&mut t0, &mut t1);
            }
            if t0 >= DOOR_FIT && t1 <= len - DOOR_FIT {
                let span = DoorSpan {
                    door: di,
                    t0,
                    t1,
                    z0,
                    z1,
                };
                fits.push((i, span, off(p).max(off(q))));
            }
        }
    }
    let best = |di: usize| {
        fits.iter()
            .filter(|f| f.1.door == di)
            .min_by(|x, y| x.2.total_cmp(&y.2).then(x.0.cmp(&y.0)))
            .map(|f| f.0)
    };
    let mut sides = Vec::with_capacity(n);
    for i in 0..n {
        let (a, b) = (ring[i], ring[(i + 1) % n]);
        let len = a.distance(b);
        let dir = (b - a) / len;
        let mut doors: Vec<DoorSpan> = Vec::new();
        for (_, span, _) in fits.iter().filter(|f| f.0 == i) {
            if best(span.door) != Some(i) {
                continue;
            }
            let (t0, t1) = (span.t0, span.t1);
            let overlaps = doors
                .iter()
                .any(|o| t0 < o.t1 + DOOR_FIT && o.t0 < t1 + DOOR_FIT);
            if !overlaps {
                doors.push(*span);
            }
        }
        doors.sort_by(|x, y| x.t0.total_cmp(&y.t0));
        let at = |t: f64, z: f64| (a + dir * t).extend(z);
        let holes = doors
            .iter()
            .map(|d| {
                vec![
                    at(d.t0, d.z0),
                    at(d.t0, d.z1),
                    at(d.t1, d.z1),
                    at(d.t1, d.z0),
                ]
            })
            .collect();
        let door_faces = doors
            .iter()
            .map(|d| {
                Face::new(vec![
                    at(d.t0, d.z0),
                    at(d.t1, d.z0),
                    at(d.t1, d.z1),
                    at(d.t0, d.z1),
                ])
            })
            .collect();
        let wall = s
            .walls
            .iter()
            .position(|w| w.rooms.contains(&room) && on_segment(w, a, b));
        sides.push(RoomSide {
            a,
            b,
            face: Face {
                outer: vec![a.extend(f), b.extend(f), b.extend(c), a.extend(c)],
                holes,
            },
            wall,
            doors,
            door_faces,
        });
    }
    Some(RoomShell {
        floor: Face::new(ring.iter().rev().map(|p| p.extend(f)).collect()),
        ceiling: Face::new(ring.iter().map(|p| p.extend(c)).collect()),
        sides,
    })
}

/// Whether the wall's centre line overlaps the segment `a`-`b` (collinear, with a common part
/// longer than 1 cm).
fn on_segment(w: &InteriorWall, a: DVec2, b: DVec2) -> bool {
    let len = a.distance(b);
    if len <= EPS {
        return false;
    }
    let dir = (b - a) / len;
    let off = |p: DVec2| (p - a).perp_dot(dir).abs();
    if off(w.a) > DOOR_FIT || off(w.b) > DOOR_FIT {
        return false;
    }
    let (t0, t1) = ((w.a - a).dot(dir), (w.b - a).dot(dir));
    t0.max(t1).min(len) - t0.min(t1).max(0.0) > 0.01
}

/// The body of an interior wall: a box of its thickness centred on its centre line, from the
/// floor to the ceiling, with the door holes through it. Faces point out of the wall: the two
/// long faces (with one hole per door), the two ends, top and bottom, and per door its
/// reveals (two jambs and the head, facing into the hole). `None` for a degenerate wall.
pub(crate) fn wall_body(s: &StoreyInterior, wall: usize) -> Option<Vec<Face>> {
    let w = s.walls.get(wall)?;
    let len = w.a.distance(w.b);
    let h = w.thickness / 2.0;
    let (f, c) = (s.floor_z, s.ceiling_z);
    if !(len > 0.01 && h > EPS && c - f > 0.01 && f.is_finite() && c.is_finite()) {
        return None;
    }
    let dir = (w.b - w.a) / len;
    let left = dir.perp();
    let p = |u: f64, side: f64, z: f64| (w.a + dir * u + left * side).extend(z);
    let mut doors: Vec<(f64, f64, f64, f64)> = s
        .doors
        .iter()
        .filter(|d| d.wall == wall)
        .filter_map(|d| {
            let (z0, z1) = door_heights(s, d)?;
            (d.u0 >= DOOR_FIT && d.u1 <= len - DOOR_FIT).then_some((d.u0, d.u1, z0, z1))
        })
        .collect();
    doors.sort_by(|x, y| x.0.total_cmp(&y.0));
    // Drop doors overlapping an earlier one: holes must not touch.
    let mut kept: Vec<(f64, f64, f64, f64)> = Vec::with_capacity(doors.len());
    for d in doors {
        if kept.last().is_none_or(|k| d.0 > k.1 + DOOR_FIT) {
            kept.push(d);
        }
    }
    // Right face (side -h) runs a -> b seen from the right; left face (side +h) runs b -> a.
    let right = Face {
        outer: vec![p(0.0, -h, f), p(len, -h, f), p(len, -h, c), p(0.0, -h, c)],
        holes: kept
            .iter()
            .map(|&(u0, u1, z0, z1)| {
                vec![p(u0, -h, z0), p(u0, -h, z1), p(u1, -h, z1), p(u1, -h, z0)]
            })
            .collect(),
    };
    let left_face = Face {
        outer: vec![p(len, h, f), p(0.0, h, f), p(0.0, h, c), p(len, h, c)],
        holes: kept
            .iter()
            .map(|&(u0, u1, z0, z1)| vec![p(u1, h, z0), p(u1, h, z1), p(u0, h, z1), p(u0, h, z0)])
            .collect(),
    };
    let mut faces = vec![
        right,
        left_face,
        Face::new(vec![
            p(0.0, h, f),
            p(0.0, -h, f),
            p(0.0, -h, c),
            p(0.0, h, c),
        ]),
        Face::new(vec![
            p(len, -h, f),
            p(len, h, f),
            p(len, h, c),
            p(len, -h, c),
        ]),
        Face::new(vec![
            p(0.0, -h, c),
            p(len, -h, c),
            p(len, h, c),
            p(0.0, h, c),
        ]),
        Face::new(vec![
            p(0.0, -h, f),
            p(0.0, h, f),
            p(len, h, f),
            p(len, -h, f),
        ]),
    ];
    for &(u0, u1, z0, z1) in &kept {
        // Jambs face into the opening (+u at u0, -u at u1); the head faces down, the sill up.
        faces.push(Face::new(vec![
            p(u0, -h, z0),
            p(u0, h, z0),
            p(u0, h, z1),
            p(u0, -h, z1),
        ]));
        faces.push(Face::new(vec![
            p(u1, h, z0),
            p(u1, -h, z0),
            p(u1, -h, z1),
            p(u1, h, z1),
        ]));
        faces.push(Face::new(vec![
            p(u0, -h, z1),
            p(u0, h, z1),
            p(u1, h, z1),
            p(u1, -h, z1),
        ]));
        faces.push(Face::new(vec![
            p(u0, h, z0),
            p(u0, -h, z0),
            p(u1, -h, z0),
            p(u1, h, z0),
        ]));
    }
    Some(faces)
}

/// A door leaf in the plane of its wall's centre line: the door's rectangle, seen from the
/// wall's right (`front`) and its mirror seen from the left.
pub(crate) fn door_leaf(s: &StoreyInterior, d: &InteriorDoor) -> Option<[Face; 2]> {
    let (p, q) = door_points(s, d)?;
    let (z0, z1) = door_heights(s, d)?;
    let front = Face::new(vec![p.extend(z0), q.extend(z0), q.extend(z1), p.extend(z1)]);
    let back = Face::new(vec![q.extend(z0), p.extend(z0), p.extend(z1), q.extend(z1)]);
    Some([front, back])
}

/// One step of a stair: a block over `ring` (counter-clockwise) from `z0` up to its tread `z1`.
#[derive(Clone, Debug, PartialEq)]
pub struct Step {
    /// The step's plan rectangle (local metres, counter-clockwise).
    pub ring: [DVec2; 4],
    /// Bottom of the block: the storey's floor (metres).
    pub z0: f64,
    /// Top of the block: this step's tread (metres).
    pub z1: f64,
}

/// The steps of the stair of storey `s` (see the module documentation); empty for a degenerate
/// stair (no run direction, no area, no rise or no riser).
pub(crate) fn stair_steps(s: &StoreyInterior, stair: &Stair) -> Vec<Step> {
    let Some(run) = stair.run.try_normalize() else {
        return Vec::new();
    };
    let across = run.perp();
    let pts = &stair.footprint.outer;
    if pts.len() < 3 || !pts.iter().all(|p| p.is_finite()) {
        return Vec::new();
    }
    let (mut s0, mut s1, mut t0, mut t1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
    for p in pts {
        let (u, v) = (p.dot(run), p.dot(across));
        s0 = s0.min(u);
        s1 = s1.max(u);
        t0 = t0.min(v);
        t1 = t1.max(v);
    }
    let n = stair.risers.min(MAX_STEPS);
    if n == 0 || !(s1 - s0 > 0.05 && t1 - t0 > 0.05 && stair.rise > 0.01 && stair.rise.is_finite())
    {
        return Vec::new();
    }
    let ds = (s1 - s0) / f64::from(n);
    let at = |u: f64, v: f64| run * u + across * v;
    (0..n)
        .map(|k| {
            let (ua, ub) = (s0 + ds * f64::from(k), s0 + ds * f64::from(k + 1));
            Step {
                ring: [at(ua, t0), at(ub, t0), at(ub, t1), at(ua, t1)],
                z0: s.floor_z,
                z1: s.floor_z + stair.rise * f64::from(k + 1) / f64::from(n),
            }
        })
        .collect()
}

/// The floor slab of storey `s` (above the storey `below`, if planned): the storey's rooms
/// minus the stair well of the stair rising from `below`, as polygons (outer CCW, holes CW),
/// with the slab's thickness (down from `s.floor_z`). Empty for the ground storey (the base
/// slab is the exterior's) or when nothing is left.
pub(crate) fn floor_slab(
    below: Option<&StoreyInterior>,
    s: &StoreyInterior,
) -> (Vec<Polygon>, f64) {
    use geo::BooleanOps;
    if s.storey == 0 {
        return (Vec::new(), 0.0);
    }
    let thickness = below
        .map(|b| s.floor_z - b.ceiling_z)
        .filter(|t| t.is_finite() && *t > 0.01)
        .unwrap_or(DEFAULT_SLAB_THICKNESS);
    let to_geo = |r: &[DVec2]| {
        geo::Polygon::new(
            geo::LineString::from(r.iter().map(|p| (p.x, p.y)).collect::<Vec<_>>()),
            vec![],
        )
    };
    let well = below.and_then(|b| b.stair.as_ref()).and_then(|st| {
        let steps = stair_steps(s, st);
        let ring = clean_ring(&st.footprint.outer)?;
        (!steps.is_empty()).then(|| to_geo(&ring))
    });
    let mut out = Vec::new();
    for room in &s.rooms {
        let Some(ring) = room_ring(room) else {
            continue;
        };
        let Some(well) = &well else {
            out.push(Polygon::new(ring, Vec::new()));
            continue;
        };
        let piece = to_geo(&ring).difference(well);
        for g in piece.0 {
            let conv = |l: &geo::LineString| -> Vec<DVec2> {
                l.0.iter().map(|c| DVec2::new(c.x, c.y)).collect()
            };
            let Some(outer) = clean_ring(&conv(g.exterior())) else {
                continue;
            };
            let holes = g
                .interiors()
                .iter()
                .filter_map(|h| clean_ring(&conv(h)))
                .map(|mut h| {
                    h.reverse();
                    h
                })
                .collect();
            out.push(Polygon::new(outer, holes));
        }
    }
    (out, thickness)
}

/// The faces of a slab piece: top at `z_top`, bottom `thickness` lower, sides of every ring.
pub(crate) fn slab_faces(p: &Polygon, z_top: f64, thickness: f64) -> Vec<Face> {
    let z0 = z_top - thickness;
    let lift = |r: &Vec<DVec2>, z: f64| r.iter().map(|q| q.extend(z)).collect::<Vec<DVec3>>();
    let rev = |r: &Vec<DVec2>, z: f64| r.iter().rev().map(|q| q.extend(z)).collect::<Vec<DVec3>>();
    let mut faces = vec![
        Face {
            outer: lift(&p.outer, z_top),
            holes: p.holes.iter().map(|h| lift(h, z_top)).collect(),
        },
        Face {
            outer: rev(&p.outer, z0),
            holes: p.holes.iter().map(|h| rev(h, z0)).collect(),
        },
    ];
    for r in p.rings() {
        for i in 0..r.len() {
            let (a, b) = (r[i], r[(i + 1) % r.len()]);
            faces.push(Face::new(vec![
                a.extend(z0),
                b.extend(z0),
                b.extend(z_top),
                a.extend(z_top),
            ]));
        }
    }
    faces
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::export::fixtures;
    use crate::geometry::ring_signed_area;

    /// Every directed edge of the faces (outer rings and holes) has its reverse exactly once.
    pub(crate) fn is_closed(faces: &[&Face]) -> bool {
        let k = |p: DVec3| {
            [
                (p.x * 1e4).round() as i64,
                (p.y * 1e4).round() as i64,
                (p.z * 1e4).round() as i64,
            ]
        };
        let mut edges = std::collections::BTreeMap::new();
        for f in faces {
            for r in std::iter::once(&f.outer).chain(f.holes.iter()) {
                for i in 0..r.len() {
                    *edges.entry((k(r[i]), k(r[(i + 1) % r.len()]))).or_insert(0) += 1;
                }
            }
        }
        edges
            .iter()
            .all(|((a, b), n)| *n == 1 && edges.get(&(*b, *a)) == Some(&1))
    }

    #[test]
    fn room_shells_are_closed_and_doors_cut_both_rooms() {
        let b = fixtures::lod4_house();
        for s in &b.parts[0].interior {
            let mut holes = 0;
            for r in 0..s.rooms.len() {
                let shell = room_shell(s, r).unwrap();
                let faces: Vec<&Face> = shell.faces().collect();
                assert!(is_closed(&faces), "storey {} room {r}", s.storey);
                holes += shell
                    .sides
                    .iter()
                    .map(|x| x.face.holes.len())
                    .sum::<usize>();
                // Normals point out: the signed volume is positive (holes, oriented the other
                // way, subtract themselves).
                let vol: f64 = faces
                    .iter()
                    .flat_map(|f| std::iter::once(&f.outer).chain(f.holes.iter()))
                    .map(|r| crate::geometry::newell_normal(r).dot(r[0]) / 6.0)
                    .sum();
                assert!(vol > 0.0);
            }
            assert_eq!(holes, 2 * s.doors.len(), "each door cuts its two rooms");
        }
    }

    /// A room whose ring folds back along its shared wall (two sides 3 mm apart, back to back:
    /// seen on a real Monaco plan) holds each door once, on the nearest side.
    #[test]
    fn a_door_goes_on_one_side_of_a_folded_room() {
        let v = DVec2::new;
        let room = |outer: Vec<DVec2>| crate::model::Room {
            polygon: Polygon::new(outer, Vec::new()),
            usage: "bedroom".into(),
            name: "Bedroom".into(),
        };
        let folded = room(vec![
            v(0.0, 0.0),
            v(4.0, 0.0),
            v(4.0, 2.0),
            v(0.5, 2.0),
            v(3.5, 2.003),
            v(0.0, 2.003),
        ]);
        assert!(room_ring(&folded).is_some(), "simple, so written");
        let above = room(vec![v(0.0, 2.003), v(4.0, 2.003), v(4.0, 4.0), v(0.0, 4.0)]);
        let s = StoreyInterior {
            storey: 0,
            floor_z: 0.0,
            ceiling_z: 2.8,
            rooms: vec![folded, above],
            walls: vec![InteriorWall {
                a: v(0.0, 2.0),
                b: v(4.0, 2.0),
                thickness: 0.1,
                rooms: [0, 1],
            }],
            doors: vec![InteriorDoor {
                wall: 0,
                u0: 1.6,
                u1: 2.4,
                height: 2.1,
            }],
            stair: None,
        };
        let shell = room_shell(&s, 0).unwrap();
        let placed: Vec<usize> = shell
            .sides
            .iter()
            .enumerate()
            .filter(|(_, x)| !x.doors.is_empty())
            .map(|(i, _)| i)
            .collect();
        // Side 2 runs along the wall itself.
        assert_eq!(placed, vec![2]);
        assert_eq!(shell.sides[2].doors.len(), 1);
    }

    #[test]
    fn rooms_that_are_not_simple_are_refused() {
        let v = DVec2::new;
        let room = |outer: Vec<DVec2>| crate::model::Room {
            polygon: Polygon::new(outer, Vec::new()),
            usage: "bedroom".into(),
            name: "Bedroom".into(),
        };
        // Two squares joined by a zero-width seam along y = 0 (seen in a real plan).
        let seam = room(vec![
            v(0.0, 0.0),
            v(0.0, -2.0),
            v(1.0, -2.0),
            v(1.0, 0.0),
            v(2.0, 0.0),
            v(2.0, -2.0),
            v(3.0, -2.0),
            v(3.0, 0.0),
        ]);
        assert!(clean_ring(&seam.polygon.outer).is_some());
        assert!(room_ring(&seam).is_none());
        let bow = room(vec![v(0.0, 0.0), v(2.0, 2.0), v(2.0, 0.0), v(0.0, 2.0)]);
        assert!(room_ring(&bow).is_none());
        let l = room(vec![
            v(0.0, 0.0),
            v(2.0, 0.0),
            v(2.0, 1.0),
            v(1.0, 1.0),
            v(1.0, 2.0),
            v(0.0, 2.0),
        ]);
        assert_eq!(room_ring(&l).map(|r| r.len()), Some(6));
    }

    #[test]
    fn wall_bodies_are_closed_with_their_door_holes() {
        let b = fixtures::lod4_house();
        let s = &b.parts[0].interior[0];
        for w in 0..s.walls.len() {
            let faces = wall_body(s, w).unwrap();
            let refs: Vec<&Face> = faces.iter().collect();
            assert!(is_closed(&refs), "wall {w}");
            let holes: usize = faces.iter().map(|f| f.holes.len()).sum();
            let doors = s.doors.iter().filter(|d| d.wall == w).count();
            assert_eq!(holes, 2 * doors);
        }
    }

    #[test]
    fn stair_steps_climb_to_the_next_floor() {
        let b = fixtures::lod4_house();
        let s = &b.parts[0].interior[0];
        let st = s.stair.as_ref().unwrap();
        let steps = stair_steps(s, st);
        assert_eq!(steps.len() as u32, st.risers);
        assert!((steps.last().unwrap().z1 - (s.floor_z + st.rise)).abs() < 1e-9);
        let area: f64 = steps.iter().map(|x| ring_signed_area(&x.ring)).sum();
        assert!((area - st.footprint.area()).abs() < 1e-6, "{area}");
        for x in &steps {
            let faces = prism_faces(&x.ring, x.z0, x.z1);
            assert!(is_closed(&faces.iter().collect::<Vec<_>>()));
        }
    }

    #[test]
    fn upper_slab_leaves_the_stair_well_open() {
        let b = fixtures::lod4_house();
        let i = &b.parts[0].interior;
        assert!(floor_slab(None, &i[0]).0.is_empty());
        let (pieces, t) = floor_slab(Some(&i[0]), &i[1]);
        assert!((t - (i[1].floor_z - i[0].ceiling_z)).abs() < 1e-9);
        let rooms: f64 = i[1].rooms.iter().map(|r| r.polygon.area()).sum();
        let well = i[0].stair.as_ref().unwrap().footprint.area();
        let area: f64 = pieces.iter().map(|p| p.area()).sum();
        assert!(
            (area - (rooms - well)).abs() < 1e-6,
            "{area} {rooms} {well}"
        );
        for p in &pieces {
            let faces = slab_faces(p, i[1].floor_z, t);
            assert!(is_closed(&faces.iter().collect::<Vec<_>>()));
        }
    }
}
