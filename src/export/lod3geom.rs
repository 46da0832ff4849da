//! LOD3 detail geometry shared by the writers: opening rectangles, their reveals, and balcony
//! slabs with railings (handrail, posts, infill), built from a [`Wall`] and the wall-coordinate
//! values of the model.
//!
//! Every face returned is planar, its outer ring counter-clockwise seen from the side its normal
//! points to (as [`Face`] requires). A wall's frame: `dir` runs along the wall from `start` to
//! `end`, `outward` is horizontal and to the right of it (outside the building, as the footprint's
//! outer ring is counter-clockwise) and `inward` is its opposite, where the wall body lies.

use glam::{DVec2, DVec3};

use crate::color::material::Material;
use crate::color::Color;
use crate::model::{Balcony, Face, Opening, OpeningKind, Part, Wall};

/// The horizontal frame of a wall: unit `dir` along start->end and unit `inward` (left of it).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct WallFrame {
    /// The wall's start point on the footprint (u = 0).
    pub start: DVec2,
    /// Unit vector from start to end (increasing u).
    pub dir: DVec2,
    /// Unit horizontal vector into the building (left of `dir`).
    pub inward: DVec2,
}

impl WallFrame {
    /// The frame of `wall`, or `None` when its edge has no length or is not finite.
    pub(crate) fn of(wall: &Wall) -> Option<WallFrame> {
        let d = wall.end - wall.start;
        let len = d.length();
        if !(len.is_finite() && len > 0.0 && wall.start.is_finite()) {
            return None;
        }
        let dir = d / len;
        Some(WallFrame {
            start: wall.start,
            dir,
            inward: dir.perp(),
        })
    }

    /// The point `u` metres along the wall at height `z`, moved `depth` metres inward (negative:
    /// outward).
    pub(crate) fn at(&self, u: f64, z: f64, depth: f64) -> DVec3 {
        (self.start + self.dir * u + self.inward * depth).extend(z)
    }

    fn dir3(&self) -> DVec3 {
        self.dir.extend(0.0)
    }

    fn inward3(&self) -> DVec3 {
        self.inward.extend(0.0)
    }
}

/// Quad `p, p+a, p+a+b, p+b`; its normal points along `a x b`.
fn quad(p: DVec3, a: DVec3, b: DVec3) -> Face {
    Face::new(vec![p, p + a, p + a + b, p + b])
}

/// The six faces of the box spanned from corner `p` by `a`, `b`, `c` (with `(a x b) . c > 0`),
/// each facing out of the box.
fn cuboid(p: DVec3, a: DVec3, b: DVec3, c: DVec3) -> Vec<Face> {
    vec![
        quad(p, b, a),     // -c
        quad(p + c, a, b), // +c
        quad(p, c, b),     // -a
        quad(p + a, b, c), // +a
        quad(p, a, c),     // -b
        quad(p + b, c, a), // +b
    ]
}

/// Whether an opening has a finite, non-empty rectangle.
pub(crate) fn opening_is_valid(o: &Opening) -> bool {
    [o.u0, o.u1, o.z0, o.z1].iter().all(|v| v.is_finite()) && o.width() > 0.0 && o.height() > 0.0
}

/// The opening's outline ([`Opening::outline`]: its rectangle, or the rectangle with rounded
/// corners) `depth` metres inward of the wall's outer face (0: in the wall plane, filling the
/// wall's hole exactly), facing outward like the wall. `None` for a degenerate wall or opening.
pub(crate) fn opening_face(wall: &Wall, o: &Opening, depth: f64) -> Option<Face> {
    let f = WallFrame::of(wall)?;
    if !opening_is_valid(o) {
        return None;
    }
    Some(Face::new(
        o.outline().iter().map(|p| f.at(p.x, p.y, depth)).collect(),
    ))
}

/// The reveal faces lining the wall's hole from its outer face to `depth` metres inward, each
/// facing into the opening: for a rectangle the sill, the head and the two jambs; for a rounded
/// outline one quad per edge of the outline, in its order. Empty for a degenerate wall,
/// opening or depth.
pub(crate) fn opening_reveals(wall: &Wall, o: &Opening, depth: f64) -> Vec<Face> {
    let Some(f) = WallFrame::of(wall) else {
        return Vec::new();
    };
    if !(opening_is_valid(o) && depth.is_finite() && depth > 0.0) {
        return Vec::new();
    }
    if o.rounding.is_some_and(|r| r.is_rounded()) {
        return ring_band(&f, &o.outline(), 0.0, depth, true);
    }
    let into = f.inward3() * depth;
    let along = f.dir3() * o.width();
    let up = DVec3::Z * o.height();
    vec![
        quad(f.at(o.u0, o.z0, 0.0), along, into), // sill, facing up
        quad(f.at(o.u0, o.z1, 0.0), into, along), // head, facing down
        quad(f.at(o.u0, o.z0, 0.0), into, up),    // jamb at u0, facing +dir
        quad(f.at(o.u1, o.z0, 0.0), up, into),    // jamb at u1, facing -dir
    ]
}

/// One quad per edge of `ring` (wall coordinates, counter-clockwise seen from outside),
/// spanning the depths `from..to` inward of the wall's outer face (`from < to`), each facing
/// the inside of the ring (`inside`) or its outside.
fn ring_band(f: &WallFrame, ring: &[DVec2], from: f64, to: f64, inside: bool) -> Vec<Face> {
    let n = ring.len();
    let span = f.inward3() * (to - from);
    (0..n)
        .filter_map(|i| {
            let (a, b) = (ring[i], ring[(i + 1) % n]);
            let p = f.at(a.x, a.y, from);
            let e = f.at(b.x, b.y, from) - p;
            (e.length() > 1e-9).then(|| {
                if inside {
                    quad(p, e, span)
                } else {
                    quad(p, span, e)
                }
            })
        })
        .collect()
}

/// A frame drawn round the pane: its members `width` wide in the wall's plane, from its front
/// (`protrusion` metres outside the wall's outer face for an explicit size
/// ([`Opening::frame_size`]), or set back into the reveal for the standard one) to the pane
/// `depth` metres inward of it.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct FrameFaces {
    /// The pane: the outline inset by the frame's width, `depth` inward, facing out.
    pub pane: Face,
    /// The frame's front (the outline with the pane's outline as a hole, at the frame's
    /// front), its outer side where it stands out of the wall, and its inner side down to the
    /// pane.
    pub frame: Vec<Face>,
}

/// Width of the standard frame, in the wall's plane (metres): the IFC writer's.
pub(crate) const FRAME_WIDTH: f64 = 0.06;

/// The frame and pane of a framed opening ([`Opening::framed`], see [`FrameFaces`]): an
/// explicitly sized frame ([`Opening::frame_size`]) stands out of the wall by its protrusion;
/// the standard one, [`FRAME_WIDTH`] wide, is set back into the reveal, its front halfway
/// between the wall's outer face and the pane (so it needs a `depth` above zero). `None` for an
/// opening without a frame, or one too small to hold it (a frame is at most a quarter of the
/// opening's smaller side wide).
pub(crate) fn opening_frame(wall: &Wall, o: &Opening, depth: f64) -> Option<FrameFaces> {
    if !o.framed {
        return None;
    }
    let (width, front) = match o.frame_size {
        Some(size) => (size.width, -size.protrusion.clamp(0.0, 2.0)),
        None if depth > 1e-3 => (FRAME_WIDTH, 0.5 * depth),
        None => return None,
    };
    let f = WallFrame::of(wall)?;
    let fw = width.min(0.25 * o.width().min(o.height()));
    if !(opening_is_valid(o) && fw.is_finite() && fw > 1e-3 && depth.is_finite()) {
        return None;
    }
    let inner = o.inset(fw);
    let (outer_ring, inner_ring) = (o.outline(), inner.outline());
    let pane = Face::new(inner_ring.iter().map(|p| f.at(p.x, p.y, depth)).collect());
    let mut frame = vec![Face {
        outer: outer_ring.iter().map(|p| f.at(p.x, p.y, front)).collect(),
        holes: vec![inner_ring
            .iter()
            .rev()
            .map(|p| f.at(p.x, p.y, front))
            .collect()],
    }];
    if front < 0.0 {
        frame.extend(ring_band(&f, &outer_ring, front, 0.0, false));
    }
    frame.extend(ring_band(&f, &inner_ring, front, depth, true));
    Some(FrameFaces { pane, frame })
}

/// A balcony's geometry: the slab, the railing's metal (handrail and posts) and its infill,
/// each in its own colour ([`BalconyFaces::colored`]).
///
/// The railing stands on the slab's three free edges, its centre line [`RAILING_INSET`] in from
/// them: a handrail (a closed U-shaped bar, [`HANDRAIL_WIDTH`] by [`HANDRAIL_HEIGHT`], its top
/// at [`RAILING_HEIGHT`] above the slab), square posts ([`POST_WIDTH`]) at the two front
/// corners and at most [`POST_SPACING`] apart between them and the wall, and a thin infill
/// panel of tinted glass (a closed U of [`INFILL_THICKNESS`], from [`INFILL_BOTTOM`] to
/// [`INFILL_TOP`] above the slab) that the posts pass through. The three have different
/// widths, so no face of one lies in the plane of a face of another. A post is its four sides:
/// its ends stand on the slab and under the handrail, where a cap would only coincide with their
/// faces. The slab box and the two U prisms are closed, so each has faces in the wall's plane
/// ([`BalconyFaces::against_wall`]).
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct BalconyFaces {
    /// Six faces: the slab from `z - SLAB_THICKNESS` to `z`, `depth` metres out from the wall.
    pub slab: Vec<Face>,
    /// The handrail's ten faces, then four per post; in [`RAILING_COLOR`]. Empty when the
    /// balcony is too small for a railing (narrower or shallower than [`MIN_RAILED`]).
    pub railing: Vec<Face>,
    /// The infill's ten faces, in [`INFILL_COLOR`]; empty with `railing`.
    pub infill: Vec<Face>,
    /// The wall's frame, for [`BalconyFaces::against_wall`].
    frame: WallFrame,
}

impl BalconyFaces {
    /// All faces: slab, railing, infill.
    pub(crate) fn all(&self) -> impl Iterator<Item = &Face> {
        self.slab.iter().chain(&self.railing).chain(&self.infill)
    }

    /// All faces in the order of [`BalconyFaces::all`], each with its colour: the slab in the
    /// balcony's, the railing in [`RAILING_COLOR`], the infill in [`INFILL_COLOR`].
    pub(crate) fn colored<'a>(
        &'a self,
        b: &Balcony,
    ) -> impl Iterator<Item = (&'a Face, Color)> + 'a {
        let slab = b.color;
        self.slab
            .iter()
            .map(move |f| (f, slab))
            .chain(self.railing.iter().map(|f| (f, RAILING_COLOR)))
            .chain(self.infill.iter().map(|f| (f, INFILL_COLOR)))
    }

    /// Whether `face` (one of these) lies in the wall's outer plane, facing into the wall: the
    /// slab's back and the ends of the handrail and infill. A closed solid needs them; a view
    /// never sees them, and they coincide with the wall's face.
    pub(crate) fn against_wall(&self, face: &Face) -> bool {
        face.outer.iter().all(|p| {
            (p.truncate() - self.frame.start)
                .dot(self.frame.inward)
                .abs()
                < 1e-9
        })
    }
}

/// Thickness of a balcony slab below its floor height (metres).
pub(crate) const SLAB_THICKNESS: f64 = 0.2;
/// Height of a balcony railing's top above the slab (metres): the model's, which the facade
/// rules keep clear of neighbours.
pub(crate) const RAILING_HEIGHT: f64 = crate::model::RAILING_HEIGHT;
/// How far the railing's centre line lies in from the slab's free edges (metres).
pub(crate) const RAILING_INSET: f64 = 0.05;
/// Width of the handrail's section (metres).
pub(crate) const HANDRAIL_WIDTH: f64 = 0.06;
/// Height of the handrail's section (metres).
pub(crate) const HANDRAIL_HEIGHT: f64 = 0.05;
/// Side of a post's square section (metres).
pub(crate) const POST_WIDTH: f64 = 0.04;
/// The longest distance between two posts along the railing (metres).
pub(crate) const POST_SPACING: f64 = 1.25;
/// Thickness of the infill panel (metres).
pub(crate) const INFILL_THICKNESS: f64 = 0.015;
/// Height of the infill's bottom above the slab (metres).
pub(crate) const INFILL_BOTTOM: f64 = 0.1;
/// Height of the infill's top above the slab (metres; below the handrail, not touching it).
pub(crate) const INFILL_TOP: f64 = 0.9;
/// A balcony narrower or shallower than this (metres) gets no railing.
pub(crate) const MIN_RAILED: f64 = 0.3;
/// Colour of the railing's handrail and posts: dark painted iron.
pub(crate) const RAILING_COLOR: Color = Color::rgb(0.2, 0.21, 0.23);
/// Colour of the railing's infill: grey-green tinted glass, half transparent.
pub(crate) const INFILL_COLOR: Color = Color {
    r: 0.55,
    g: 0.65,
    b: 0.65,
    a: 0.5,
};

/// The faces of a closed vertical prism over `ring` (either orientation) from `z0` to `z1`,
/// each facing out.
fn prism(mut ring: Vec<DVec2>, z0: f64, z1: f64) -> Vec<Face> {
    if crate::geometry::ring_signed_area(&ring) < 0.0 {
        ring.reverse();
    }
    crate::export::lod4geom::prism_faces(&ring, z0, z1)
}

/// The geometry of balcony `b` on `wall`, or `None` for a degenerate wall or balcony.
pub(crate) fn balcony_faces(wall: &Wall, b: &Balcony) -> Option<BalconyFaces> {
    let f = WallFrame::of(wall)?;
    let ok =
        [b.u0, b.u1, b.z, b.depth].iter().all(|v| v.is_finite()) && b.u1 > b.u0 && b.depth > 0.0;
    if !ok {
        return None;
    }
    let along = f.dir3() * (b.u1 - b.u0);
    let out = -f.inward3() * b.depth;
    // (out, along, up) is right-handed: out x along points up.
    let slab = cuboid(
        f.at(b.u0, b.z - SLAB_THICKNESS, 0.0),
        out,
        along,
        DVec3::Z * SLAB_THICKNESS,
    );
    let mut faces = BalconyFaces {
        slab,
        railing: Vec::new(),
        infill: Vec::new(),
        frame: f,
    };
    if b.u1 - b.u0 < MIN_RAILED || b.depth < MIN_RAILED {
        return Some(faces);
    }
    // Plan points by (u along the wall, o out of it).
    let plan = |u: f64, o: f64| f.start + f.dir * u - f.inward * o;
    let e = RAILING_INSET;
    let (ua, ub, front) = (b.u0 + e, b.u1 - e, b.depth - e);
    // The U of width `w` around the centre line (wall, ua) -> (front, ua) -> (front, ub) -> wall.
    let u_ring = |w: f64| {
        let h = w / 2.0;
        vec![
            plan(ua - h, 0.0),
            plan(ua - h, front + h),
            plan(ub + h, front + h),
            plan(ub + h, 0.0),
            plan(ub - h, 0.0),
            plan(ub - h, front - h),
            plan(ua + h, front - h),
            plan(ua + h, 0.0),
        ]
    };
    let top = b.z + RAILING_HEIGHT;
    faces.railing = prism(u_ring(HANDRAIL_WIDTH), top - HANDRAIL_HEIGHT, top);
    // Posts: the front corners, then evenly between them and along the arms (none at the wall,
    // which holds the handrail).
    let mut posts: Vec<(f64, f64)> = vec![(ua, front), (ub, front)];
    let mut between = |(u0, o0): (f64, f64), (u1, o1): (f64, f64)| {
        let n = ((u1 - u0).hypot(o1 - o0) / POST_SPACING).ceil().max(1.0) as usize;
        for k in 1..n {
            let t = k as f64 / n as f64;
            posts.push((u0 + (u1 - u0) * t, o0 + (o1 - o0) * t));
        }
    };
    between((ua, 0.0), (ua, front));
    between((ua, front), (ub, front));
    between((ub, front), (ub, 0.0));
    let h = POST_WIDTH / 2.0;
    for (u, o) in posts {
        let ring = vec![
            plan(u - h, o - h),
            plan(u + h, o - h),
            plan(u + h, o + h),
            plan(u - h, o + h),
        ];
        // The four sides only: the prism's bottom and top come first.
        faces
            .railing
            .extend(prism(ring, b.z, top - HANDRAIL_HEIGHT).into_iter().skip(2));
    }
    faces.infill = prism(
        u_ring(INFILL_THICKNESS),
        b.z + INFILL_BOTTOM,
        b.z + INFILL_TOP,
    );
    Some(faces)
}

/// How far a window sill stands out of the wall's outer face (metres).
pub(crate) const SILL_PROJECTION: f64 = 0.06;
/// Thickness of a window sill below the window's bottom edge (metres).
pub(crate) const SILL_THICKNESS: f64 = 0.05;
/// How far a window sill runs past each jamb (metres), where nothing is in its way.
pub(crate) const SILL_EAR: f64 = 0.04;
/// The least clearance a sill keeps from another opening, a balcony and the wall's ends
/// (metres).
pub(crate) const SILL_CLEARANCE: f64 = 0.01;
/// Colour of the window sills: light stone.
pub(crate) const SILL_COLOR: Color = Color::rgb(0.83, 0.81, 0.76);

/// A window sill: a box in front of the wall under a window, its top flush with the window's
/// bottom edge, [`SILL_THICKNESS`] thick, [`SILL_PROJECTION`] out of the wall's outer face, and
/// running from `u0` to `u1` along the wall (the window's width and up to [`SILL_EAR`] past each
/// jamb).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Sill {
    /// Index of the window in the wall's openings.
    pub opening: usize,
    /// Start along the wall (metres from its `start`).
    pub u0: f64,
    /// End along the wall.
    pub u1: f64,
    /// Height of the sill's top: the window's bottom edge.
    pub top: f64,
}

/// The sills of `wall`'s windows, in the order of its openings: one under every window whose
/// bottom edge stands [`LOW_SILL`] or more above the wall's base (not under a door or a French
/// window). A sill's ears are cut to keep [`SILL_CLEARANCE`] from the wall's ends and halfway
/// to another opening at its height; a window whose sill would meet another opening (a window
/// just below it) or a balcony (its slab or railing) gets none.
pub(crate) fn sills(wall: &Wall) -> Vec<Sill> {
    let len = wall.length();
    if WallFrame::of(wall).is_none() || !len.is_finite() {
        return Vec::new();
    }
    let t = SILL_THICKNESS;
    let c = SILL_CLEARANCE;
    let mut out = Vec::new();
    for (i, o) in wall.openings.iter().enumerate() {
        let rise = o.z0 - wall.base_z;
        if o.kind != OpeningKind::Window || !opening_is_valid(o) || rise.is_nan() || rise < LOW_SILL
        {
            continue;
        }
        let (zb, zt) = (o.z0 - t, o.z0);
        let (mut u0, mut u1) = ((o.u0 - SILL_EAR).max(c), (o.u1 + SILL_EAR).min(len - c));
        let mut blocked = false;
        for (j, p) in wall.openings.iter().enumerate() {
            if j == i || !opening_is_valid(p) || p.z1 + c <= zb || p.z0 - c >= zt {
                continue;
            }
            if p.u1 <= o.u0 {
                u0 = u0.max(0.5 * (p.u1 + o.u0));
            } else if p.u0 >= o.u1 {
                u1 = u1.min(0.5 * (o.u1 + p.u0));
            } else {
                blocked = true;
            }
        }
        // The balcony's slab and railing, with the clearance round them.
        blocked |= wall.balconies.iter().any(|b| {
            b.u0 - c < u1
                && b.u1 + c > u0
                && b.z - SLAB_THICKNESS - c < zt
                && b.z + RAILING_HEIGHT + c > zb
        });
        // Never narrower than the window (an opening lies at least `OPENING_MARGIN` in).
        let (u0, u1) = (u0.min(o.u0), u1.max(o.u1));
        if blocked || !(u0.is_finite() && u1.is_finite() && zb.is_finite()) {
            continue;
        }
        out.push(Sill {
            opening: i,
            u0,
            u1,
            top: o.z0,
        });
    }
    out
}

/// Every face of `wall`'s sills ([`sills`], each box's six [`sill_faces`] in turn): what a
/// writer that keeps a wall's sills together (a CityGML or CityJSON installation) draws.
pub(crate) fn wall_sill_faces(wall: &Wall) -> Vec<Face> {
    sills(wall)
        .iter()
        .filter_map(|s| sill_faces(wall, s))
        .flatten()
        .collect()
}

/// The six faces of sill `s` on `wall` (a closed box, each face facing out of it; the first
/// lies in the wall's outer plane, facing into the wall: [`sill_against_wall`]), or `None` for
/// a degenerate wall.
pub(crate) fn sill_faces(wall: &Wall, s: &Sill) -> Option<Vec<Face>> {
    let f = WallFrame::of(wall)?;
    let out = -f.inward3() * SILL_PROJECTION;
    let along = f.dir3() * (s.u1 - s.u0);
    // (out, along, up) is right-handed: out x along points up.
    let mut faces = cuboid(
        f.at(s.u0, s.top - SILL_THICKNESS, 0.0),
        out,
        along,
        DVec3::Z * SILL_THICKNESS,
    );
    // `cuboid`'s third face (-out) is the one against the wall: put it first.
    faces.swap(0, 2);
    Some(faces)
}

/// Whether `index` is the face of [`sill_faces`] against the wall (hidden: a view leaves it out).
pub(crate) fn sill_against_wall(index: usize) -> bool {
    index == 0
}

/// A closed solid of a cornice run or an eaves board (issue 49): its faces, each facing out of
/// it, and the index of the one that lies in the wall's outer plane, facing into the wall
/// (hidden: a view leaves it out, as it does a sill's).
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct TrimSolid {
    /// The faces of the closed solid.
    pub faces: Vec<Face>,
    /// Index in `faces` of the face against the wall.
    pub against_wall: usize,
}

impl TrimSolid {
    /// The faces a view draws: all but the one against the wall.
    pub(crate) fn shown(&self) -> impl Iterator<Item = (usize, &Face)> {
        let hidden = self.against_wall;
        self.faces
            .iter()
            .enumerate()
            .filter(move |(i, _)| *i != hidden)
    }
}

/// The colour and material of face `index` of one of `part`'s cornice (`eaves` false) or eaves
/// solids, as every writer draws it: a cornice in its colour and the wall's material; the eaves'
/// top (0) and fascia (3) in the roof's colour and material, the rest (the soffit and the
/// board's ends) in the soffit's colour.
pub(crate) fn trim_color(part: &Part, eaves: bool, index: usize) -> (Color, Material) {
    match (&part.cornice, &part.eaves) {
        (Some(c), _) if !eaves => (c.color, part.wall_material),
        (_, Some(_)) if eaves && (index == 0 || index == 3) => {
            (part.roof_color, part.roof_material)
        }
        (_, Some(e)) if eaves => (e.soffit, Material::Unspecified),
        _ => (part.wall_color, part.wall_material),
    }
}

/// The sharpest corner a cornice or the eaves are mitred round (the cosine of the angle between
/// the two edges' outward normals, plus one): past it (a turn of more than 120°) both end
/// square at the corner.
const MITRE_MIN: f64 = 0.5;

/// The cornice's section, from the wall's face out (`s`, a share of its depth) and from its top
/// down (`z`, a share of its height), counter-clockwise seen from the start of the wall: a bed
/// mould 0.3 deep over the bottom 0.3 of the height, a sloped soffit (the cove) out to the full
/// depth, and the corona's square front over the top 0.35.
pub(crate) const CORNICE_PROFILE: [(f64, f64); 6] = [
    (0.0, -1.0),
    (0.3, -1.0),
    (0.3, -0.7),
    (1.0, -0.35),
    (1.0, 0.0),
    (0.0, 0.0),
];

/// Per footprint edge of `part` (rings in order, as [`crate::model::Cornice::edges`]) that
/// `edges` marks: its start and end on the footprint, its outward unit normal and the
/// vectors that offset its start and end by one metre out (a mitre where the edge before or
/// after is marked too and the corner is not sharper than [`MITRE_MIN`], else the normal).
/// `None` for an unmarked or degenerate edge.
#[allow(clippy::type_complexity)]
fn marked_edges(part: &Part, edges: &[bool]) -> Vec<Option<(DVec2, DVec2, DVec2, DVec2, DVec2)>> {
    let mut out = Vec::new();
    let mut k0 = 0;
    for ring in part.footprint.rings() {
        let n = ring.len();
        let marked = |i: usize| edges.get(k0 + (i % n)).copied().unwrap_or(false);
        let normal = |i: usize| {
            let (a, b) = (ring[i % n], ring[(i + 1) % n]);
            let d = (b - a).normalize_or_zero();
            DVec2::new(d.y, -d.x)
        };
        let mitre = |i: usize, n0: DVec2, n1: DVec2, own: DVec2| {
            let c = 1.0 + n0.dot(n1);
            if marked(i + n - 1) && c > MITRE_MIN && n0 != DVec2::ZERO {
                (n0 + n1) / c
            } else {
                own
            }
        };
        for i in 0..n {
            let (a, b) = (ring[i], ring[(i + 1) % n]);
            let nn = normal(i);
            if !marked(i) || nn == DVec2::ZERO || !(a.is_finite() && b.is_finite()) {
                out.push(None);
                continue;
            }
            let ma = mitre(i, normal(i + n - 1), nn, nn);
            // At the end: the next edge's mitre at its start, when it is marked.
            let next = normal(i + 1);
            let c = 1.0 + nn.dot(next);
            let mb = if marked(i + 1) && c > MITRE_MIN && next != DVec2::ZERO {
                (nn + next) / c
            } else {
                nn
            };
            out.push(Some((a, b, nn, ma, mb)));
        }
        k0 += n;
    }
    out
}

/// The closed solids of `part`'s cornice ([`crate::model::Cornice`]), one per edge it runs
/// along, in edge order: [`CORNICE_PROFILE`] drawn along the edge from the wall's top down,
/// its ends mitred or square (faces: the section at the start and at the end, then one per
/// edge of the section; its back is `against_wall`). A run whose front the mitres would
/// shorten to nothing is left out. Empty without a cornice.
pub(crate) fn cornice_solids(part: &Part) -> Vec<TrimSolid> {
    let Some(c) = &part.cornice else {
        return Vec::new();
    };
    let (depth, height, top) = (c.depth, c.height, part.eave_z);
    if !([depth, height, top].iter().all(|v| v.is_finite()) && depth > 0.0 && height > 0.0) {
        return Vec::new();
    }
    let section: Vec<(f64, f64)> = CORNICE_PROFILE
        .iter()
        .map(|&(s, z)| (s * depth, top + z * height))
        .collect();
    let m = section.len();
    let mut out = Vec::new();
    for (a, b, _, ma, mb) in marked_edges(part, &c.edges).into_iter().flatten() {
        let d = (b - a).normalize();
        let front = (b + mb * depth) - (a + ma * depth);
        if front.dot(d) < 0.01 {
            continue;
        }
        let at = |p: DVec2, mv: DVec2, (s, z): (f64, f64)| (p + mv * s).extend(z);
        let sa: Vec<DVec3> = section.iter().map(|&q| at(a, ma, q)).collect();
        let sb: Vec<DVec3> = section.iter().map(|&q| at(b, mb, q)).collect();
        // The section is counter-clockwise seen from the wall's start: its face there faces
        // back along the wall, the one at the end forward.
        let mut faces = vec![
            Face::new(sa.clone()),
            Face::new(sb.iter().rev().copied().collect()),
        ];
        let mut against_wall = 0;
        for j in 0..m {
            let k = (j + 1) % m;
            if section[j].0 == 0.0 && section[k].0 == 0.0 {
                against_wall = faces.len();
            }
            faces.push(Face::new(vec![sa[j], sb[j], sb[k], sa[k]]));
        }
        out.push(TrimSolid {
            faces,
            against_wall,
        });
    }
    out
}

/// The closed solids of `part`'s eaves ([`crate::model::Eaves`]): for every stretch of a
/// marked footprint edge that a pitched roof face meets (an eave, or a gable's verge), a board
/// in the face's plane from the wall's line out by the overhang (mitred at a corner with
/// another marked edge, square elsewhere), its top the roof's surface carried on and its
/// bottom `thickness` below. Faces: top (the roof's, index 0), bottom (the soffit, 1), then
/// the sides: the start's end, the front (the fascia, 3), the end's end and the one against
/// the wall (5). Empty without eaves.
pub(crate) fn eaves_solids(part: &Part) -> Vec<TrimSolid> {
    let Some(e) = &part.eaves else {
        return Vec::new();
    };
    let (o, t) = (e.overhang, e.thickness);
    if !([o, t].iter().all(|v| v.is_finite()) && o > 0.0 && t > 0.0) {
        return Vec::new();
    }
    const ON: f64 = 0.01;
    let planes: Vec<Option<(DVec3, DVec3)>> = part
        .roof
        .iter()
        .map(|f| {
            let n = f.normal();
            let q = f.outer.iter().copied().sum::<DVec3>() / f.outer.len().max(1) as f64;
            (n.z > 0.05 && n.z < 0.999 && q.is_finite()).then_some((n, q))
        })
        .collect();
    let mut out = Vec::new();
    for (a, b, nn, ma, mb) in marked_edges(part, &e.edges).into_iter().flatten() {
        let len = a.distance(b);
        let d = (b - a) / len;
        for (face, plane) in part.roof.iter().zip(&planes) {
            let Some((n, q)) = *plane else {
                continue;
            };
            let z_at = |p: DVec2| q.z - (n.x * (p.x - q.x) + n.y * (p.y - q.y)) / n.z;
            let r = &face.outer;
            for i in 0..r.len() {
                let (p0, p1) = (r[i].truncate(), r[(i + 1) % r.len()].truncate());
                let on = |p: DVec2| {
                    let u = (p - a).dot(d);
                    ((p - a).dot(nn)).abs() < ON && u > -ON && u < len + ON
                };
                let (u0, u1) = (
                    (p0 - a).dot(d).clamp(0.0, len),
                    (p1 - a).dot(d).clamp(0.0, len),
                );
                if !(on(p0) && on(p1)) || u1 - u0 < 0.05 {
                    continue;
                }
                let m0 = if u0 < ON { ma } else { nn };
                let m1 = if u1 > len - ON { mb } else { nn };
                let (c0, c1) = (a + d * u0, a + d * u1);
                let (f0, f1) = (c0 + m0 * o, c1 + m1 * o);
                if (f1 - f0).dot(d) < 0.01 {
                    continue;
                }
                // Counter-clockwise in plan: along the wall, out, back, in.
                let plan = [c0, f0, f1, c1];
                let top: Vec<DVec3> = plan.iter().map(|p| p.extend(z_at(*p))).collect();
                if !top.iter().all(|p| p.is_finite()) {
                    continue;
                }
                let bottom: Vec<DVec3> = top.iter().map(|p| *p - DVec3::Z * t).collect();
                let mut faces = vec![
                    Face::new(top.clone()),
                    Face::new(bottom.iter().rev().copied().collect()),
                ];
                for j in 0..4 {
                    let k = (j + 1) % 4;
                    faces.push(Face::new(vec![bottom[j], bottom[k], top[k], top[j]]));
                }
                out.push(TrimSolid {
                    faces,
                    against_wall: 5,
                });
            }
        }
    }
    out
}

/// Sills lower than this above their wall's base (metres: a door, a French window) stand over
/// vertices of the base ([`seated_faces`]).
pub(crate) const LOW_SILL: f64 = 0.3;

/// The ground and wall outlines of a LOD3 part as a solid writes them: a vertex on a wall's
/// base under each jamb of an opening whose sill is lower than [`LOW_SILL`], and the same
/// vertex in the face below that shares the base (the ground, or the storey below's wall), so
/// the shell stays closed (every edge twice, no T-junction).
///
/// Why: a door stands [`crate::model::OPENING_MARGIN`] (2 cm) above its floor. Without these
/// vertices the strip of wall under it meets the base only at the wall's corners, and a
/// validator's triangulation of the wall spans it with long needles from the door's corners to
/// a far corner; the door's corners, rounded to the millimetre, sit a fraction of a millimetre
/// either side of the wall's plane, which tilts such a needle by tens of degrees (val3dity's
/// 204). With a vertex under each jamb (at the jamb's own point, so the jamb is exactly
/// vertical once rounded) the strip is a rectangle with vertical sides.
///
/// `None` when no wall has such an opening (write the model's faces), else every ground and
/// wall face, in the model's order.
#[cfg(test)]
pub(crate) fn seated_faces(part: &Part) -> Option<(Face, Vec<Face>)> {
    let changes = seated_changes(part);
    if changes.is_empty() {
        return None;
    }
    let mut faces: Vec<Face> = std::iter::once(part.ground.clone())
        .chain(part.walls.iter().map(|w| w.outline.clone()))
        .collect();
    for (fi, face) in changes {
        faces[fi] = face;
    }
    let ground = faces.remove(0);
    Some((ground, faces))
}

/// The faces [`seated_faces`] changes, and only those, as (index, face): index 0 is the
/// ground, `i + 1` wall `i`'s outline; in increasing index order. Empty when it changes none.
pub(crate) fn seated_changes(part: &Part) -> Vec<(usize, Face)> {
    let is_low = |w: &Wall, o: &Opening| opening_is_valid(o) && o.z0 - w.base_z < LOW_SILL;
    let low = |w: &Wall| w.openings.iter().any(|o| is_low(w, o));
    if !part.walls.iter().any(low) {
        return Vec::new();
    }
    type Mm = (i64, i64, i64);
    let key = crate::model::grid_key;
    let face = |fi: usize| match fi {
        0 => &part.ground,
        _ => &part.walls[fi - 1].outline,
    };
    // The grid keys of every ring's points, and per ring (face, ring, where its keys start).
    let mut keys: Vec<Mm> = Vec::new();
    let mut rings: Vec<(usize, usize, usize)> = Vec::new();
    for fi in 0..=part.walls.len() {
        let f = face(fi);
        for (ri, r) in std::iter::once(&f.outer).chain(f.holes.iter()).enumerate() {
            rings.push((fi, ri, keys.len()));
            keys.extend(r.iter().map(|p| key(*p)));
        }
    }
    rings.push((usize::MAX, 0, keys.len()));
    // The first directed edge (ka, kb) of the faces, in face, ring, point order: (face, ring,
    // index of its start).
    let first_edge = |ka: Mm, kb: Mm| -> Option<(usize, usize, usize)> {
        rings.windows(2).find_map(|w| {
            let ((fi, ri, start), end) = (w[0], w[1].2);
            let k = &keys[start..end];
            let n = k.len();
            (0..n)
                .find(|&i| k[i] == ka && k[(i + 1) % n] == kb)
                .map(|i| (fi, ri, i))
        })
    };
    // (face, ring, after which index, points), applied last.
    let mut inserts: Vec<(usize, usize, usize, Vec<DVec3>)> = Vec::new();
    for (wi, wall) in part.walls.iter().enumerate() {
        if !low(wall) {
            continue;
        }
        let Some(f) = WallFrame::of(wall) else {
            continue;
        };
        let mut us: Vec<f64> = wall
            .openings
            .iter()
            .filter(|o| is_low(wall, o))
            .flat_map(|o| [o.u0, o.u1])
            .collect();
        us.sort_by(f64::total_cmp);
        let (a, b) = (wall.start.extend(wall.base_z), wall.end.extend(wall.base_z));
        // The points, a grid step and more from each other and from the base's ends.
        let mut points: Vec<DVec3> = Vec::new();
        for u in us {
            let p = f.at(u, wall.base_z, 0.0);
            let k = key(p);
            let apart = |q: DVec3| {
                let kq = key(q);
                (kq.0 - k.0).abs().max((kq.1 - k.1).abs()) > 1
            };
            if apart(a) && apart(b) && points.iter().all(|q| apart(*q)) {
                points.push(p);
            }
        }
        if points.is_empty() {
            continue;
        }
        // The base (a then b) in the wall's own outline, and the face that runs b then a.
        let (ka, kb) = (key(a), key(b));
        let own = first_edge(ka, kb).filter(|e| e.0 == wi + 1 && e.1 == 0);
        let Some((fo, ro, io)) = own else {
            continue;
        };
        let below = first_edge(kb, ka).filter(|e| e.0 != wi + 1);
        let Some((fb, rb, ib)) = below else {
            continue;
        };
        inserts.push((fo, ro, io, points.clone()));
        points.reverse();
        inserts.push((fb, rb, ib, points));
    }
    // Later places in a ring first, so the earlier indices still hold.
    inserts.sort_by(|x, y| (x.0, x.1, y.2).cmp(&(y.0, y.1, x.2)));
    let mut changed: Vec<(usize, Face)> = Vec::new();
    for (fi, ri, i, pts) in inserts {
        if changed.last().is_none_or(|c| c.0 != fi) {
            changed.push((fi, face(fi).clone()));
        }
        let Some((_, face)) = changed.last_mut() else {
            continue;
        };
        let r = if ri == 0 {
            &mut face.outer
        } else {
            &mut face.holes[ri - 1]
        };
        r.splice(i + 1..i + 1, pts);
    }
    changed
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::color::Color;
    use crate::model::OpeningKind;

    fn wall(start: DVec2, end: DVec2) -> Wall {
        Wall {
            start,
            end,
            base_z: 0.0,
            top_z: 3.0,
            thickness: 0.3,
            outline: Face::new(vec![
                start.extend(0.0),
                end.extend(0.0),
                end.extend(3.0),
                start.extend(3.0),
            ]),
            storey: 0,
            openings: Vec::new(),
            balconies: Vec::new(),
            party: 0.0,
        }
    }

    fn window() -> Opening {
        Opening {
            kind: OpeningKind::Window,
            u0: 1.0,
            u1: 2.0,
            z0: 1.0,
            z1: 2.5,
            color: Color::WHITE,
            frame_color: Color::WHITE,
            glazed: true,
            framed: false,
            frame_size: None,
            rounding: None,
        }
    }

    /// Normal of a face as a unit vector.
    fn n(f: &Face) -> DVec3 {
        f.normal()
    }

    #[test]
    fn opening_faces_outward_and_reveals_inward() {
        // Front wall of a CCW footprint: outside is -y.
        let w = wall(DVec2::new(0.0, 0.0), DVec2::new(10.0, 0.0));
        let pane = opening_face(&w, &window(), 0.1).unwrap();
        assert!((n(&pane) - w.outline.normal()).length() < 1e-12);
        assert!(pane.outer.iter().all(|p| (p.y - 0.1).abs() < 1e-12));
        let r = opening_reveals(&w, &window(), 0.1);
        let normals: Vec<DVec3> = r.iter().map(n).collect();
        assert!((normals[0] - DVec3::Z).length() < 1e-12);
        assert!((normals[1] + DVec3::Z).length() < 1e-12);
        assert!((normals[2] - DVec3::X).length() < 1e-12);
        assert!((normals[3] + DVec3::X).length() < 1e-12);
        assert!(opening_reveals(&w, &window(), 0.0).is_empty());
    }

    fn arched(segments: u32, profile: f64) -> Opening {
        Opening {
            rounding: Some(crate::model::Rounding {
                corners: [true, true, false, false],
                radius: 0.9,
                segments,
                profile,
            }),
            ..window()
        }
    }

    /// Twice the signed area of a ring (positive: counter-clockwise).
    fn area2(r: &[DVec2]) -> f64 {
        (0..r.len())
            .map(|i| r[i].perp_dot(r[(i + 1) % r.len()]))
            .sum()
    }

    #[test]
    fn a_rounded_outline_is_an_arch_of_its_segments_inside_the_rectangle() {
        let o = window();
        assert_eq!(o.outline().len(), 4, "a rectangle without rounding");
        for profile in [0.0, 0.25, 0.5, 0.8, 1.0] {
            let a = arched(5, profile);
            let r = a.outline();
            // Two bottom corners, then two arcs of 6 points meeting at the top's middle (the
            // radius is clamped to half the 1 m width).
            assert_eq!(r.len(), 2 + 6 + 5, "profile {profile}");
            assert!(area2(&r) > 0.0, "counter-clockwise seen from outside");
            for p in &r {
                assert!(p.x >= 1.0 - 1e-12 && p.x <= 2.0 + 1e-12);
                assert!(p.y >= 1.0 - 1e-12 && p.y <= 2.5 + 1e-12);
            }
            assert_eq!(
                r[0],
                DVec2::new(1.0, 1.0),
                "starts at the bottom-left corner"
            );
        }
        // Profile 0.5: a half circle of radius 0.5 round (1.5, 2.0).
        let r = arched(8, 0.5).outline();
        for p in &r[2..] {
            assert!((p.distance(DVec2::new(1.5, 2.0)) - 0.5).abs() < 1e-9, "{p}");
        }
        // Profile 0.25: straight chamfers, so the area is the rectangle less two triangles.
        let r = arched(4, 0.25).outline();
        assert!((area2(&r) / 2.0 - (1.5 - 2.0 * 0.125)).abs() < 1e-9);
        // Convex profiles keep more of the corner than a circle; concave ones less.
        let areas: Vec<f64> = [0.0, 0.5, 1.0]
            .iter()
            .map(|p| area2(&arched(16, *p).outline()))
            .collect();
        assert!(areas[0] < areas[1] && areas[1] < areas[2], "{areas:?}");
    }

    #[test]
    fn a_rounded_opening_has_a_reveal_per_edge_facing_into_it() {
        let w = wall(DVec2::new(0.0, 0.0), DVec2::new(10.0, 0.0));
        let o = arched(5, 0.5);
        let ring = o.outline();
        let reveals = opening_reveals(&w, &o, 0.1);
        assert_eq!(reveals.len(), ring.len());
        let centre = DVec3::new(1.5, 0.05, 1.75);
        for f in &reveals {
            let c = f.outer.iter().copied().sum::<DVec3>() / 4.0;
            assert!(
                n(f).dot(centre - c) > 0.0,
                "a reveal faces into the opening"
            );
            assert!(planar(f));
        }
        // The pane is the outline, facing out like the wall.
        let pane = opening_face(&w, &o, 0.0).unwrap();
        assert_eq!(pane.outer.len(), ring.len());
        assert!((n(&pane) - w.outline.normal()).length() < 1e-12);
    }

    #[test]
    fn an_explicit_frame_stands_out_round_a_smaller_pane() {
        let w = wall(DVec2::new(0.0, 0.0), DVec2::new(10.0, 0.0)); // outside is -y
        let o = Opening {
            framed: true,
            frame_size: Some(crate::model::FrameSize {
                width: 0.1,
                protrusion: 0.05,
            }),
            ..arched(5, 0.5)
        };
        assert!(
            opening_frame(&w, &window(), 0.1).is_none(),
            "no explicit frame"
        );
        let f = opening_frame(&w, &o, 0.1).unwrap();
        // The pane: the outline inset by 0.1 m, 0.1 m into the wall.
        assert!(f.pane.outer.iter().all(|p| (p.y - 0.1).abs() < 1e-12));
        let xs = f.pane.outer.iter().map(|p| p.x);
        assert!(xs.clone().fold(f64::MAX, f64::min) >= 1.1 - 1e-12);
        assert!(xs.fold(f64::MIN, f64::max) <= 1.9 + 1e-12);
        // The front ring 5 cm out of the wall, facing out, with the pane's outline as its hole.
        let front = &f.frame[0];
        assert!(front.outer.iter().all(|p| (p.y + 0.05).abs() < 1e-12));
        assert!((n(front) - w.outline.normal()).length() < 1e-12);
        assert_eq!(front.holes.len(), 1);
        let ring = o.outline().len();
        let inner = o.inset(0.1).outline().len();
        assert_eq!(
            f.frame.len(),
            1 + ring + inner,
            "front, outer and inner sides"
        );
        // The outer sides face away from the opening, the inner ones into it.
        let centre = DVec3::new(1.5, 0.0, 1.75);
        for (i, face) in f.frame[1..].iter().enumerate() {
            let c = face.outer.iter().copied().sum::<DVec3>() / 4.0;
            let towards = DVec3::new(centre.x - c.x, 0.0, centre.z - c.z);
            let into = n(face).dot(towards) > 0.0;
            assert_eq!(into, i >= ring, "side {i}");
        }
        // Flush frames have no outer sides.
        let flush = Opening {
            frame_size: Some(crate::model::FrameSize {
                width: 0.1,
                protrusion: 0.0,
            }),
            ..o.clone()
        };
        assert_eq!(
            opening_frame(&w, &flush, 0.1).unwrap().frame.len(),
            1 + inner
        );
    }

    /// The sum of the area vectors of `faces`: zero for a closed surface.
    fn area_sum(faces: &[Face]) -> DVec3 {
        faces
            .iter()
            .map(|f| crate::geometry::newell_normal(&f.outer))
            .sum()
    }

    /// Whether every face of a closed solid faces away from a point inside it.
    fn faces_out_of(faces: &[Face], inside: DVec3) -> bool {
        faces.iter().all(|f| {
            let c = f.outer.iter().copied().sum::<DVec3>() / f.outer.len() as f64;
            n(f).dot(c - inside) > 0.0
        })
    }

    /// Whether every vertex of `face` lies in its plane (within 1e-9 m).
    fn planar(face: &Face) -> bool {
        let (nm, p0) = (n(face), face.outer[0]);
        face.outer.iter().all(|p| (p - p0).dot(nm).abs() < 1e-9)
    }

    #[test]
    fn balcony_slab_handrail_posts_and_infill() {
        let w = wall(DVec2::new(10.0, 0.0), DVec2::new(10.0, 6.0)); // east wall, outside +x
        let b = Balcony {
            u0: 1.0,
            u1: 4.0,
            z: 3.0,
            depth: 1.2,
            color: Color::WHITE,
        };
        let f = balcony_faces(&w, &b).unwrap();
        assert!(f.all().all(planar));
        // Slab: a closed box facing out.
        assert_eq!(f.slab.len(), 6);
        assert!(area_sum(&f.slab).length() < 1e-9, "closed box");
        assert!(faces_out_of(&f.slab, DVec3::new(10.6, 2.5, 2.9)));
        // Handrail: a closed U of ten faces, its top 1 m above the slab.
        let rail = &f.railing[..10];
        assert!(area_sum(rail).length() < 1e-9, "closed handrail");
        let top = rail.iter().flat_map(|f| &f.outer).map(|p| p.z);
        assert!((top.fold(f64::MIN, f64::max) - 4.0).abs() < 1e-12);
        // Its front arm's outside faces +x, 2 cm in from the slab's edge.
        let front = rail
            .iter()
            .find(|f| (n(f) - DVec3::X).length() < 1e-12 && f.outer[0].x > 11.0)
            .unwrap();
        assert!(front.outer.iter().all(|p| (p.x - 11.18).abs() < 1e-9));
        // Posts: four sides each; the two front corners and two between them along the 2.9 m
        // front (1.25 m apart at most); the 1.15 m arms need none.
        let posts = &f.railing[10..];
        assert_eq!(posts.len(), 4 * 4);
        for post in posts.chunks(4) {
            assert!(
                area_sum(post).truncate().length() < 1e-9,
                "sides of a square"
            );
            let zs: Vec<f64> = post.iter().flat_map(|f| &f.outer).map(|p| p.z).collect();
            assert!(zs.iter().all(|z| (3.0..=3.95 + 1e-9).contains(z)));
        }
        // Infill: a closed U below the handrail, not touching it or the slab.
        assert_eq!(f.infill.len(), 10);
        assert!(area_sum(&f.infill).length() < 1e-9, "closed infill");
        let zs: Vec<f64> = f
            .infill
            .iter()
            .flat_map(|f| &f.outer)
            .map(|p| p.z)
            .collect();
        assert!(zs.iter().all(|z| (3.1 - 1e-9..=3.9 + 1e-9).contains(z)));
        // Everything out of the wall, within the slab's plan.
        let xs: Vec<f64> = f.all().flat_map(|f| f.outer.iter().map(|p| p.x)).collect();
        assert!(xs.iter().all(|x| (10.0..=11.2 + 1e-9).contains(x)));
        // In the wall's plane: the slab's back and the two U's two ends each.
        let against: Vec<&Face> = f.all().filter(|x| f.against_wall(x)).collect();
        assert_eq!(against.len(), 5);
        assert!(against.iter().all(|x| (n(x) + DVec3::X).length() < 1e-12));
        // Colours: slab in the balcony's, the railing dark, the infill translucent.
        let colors: Vec<Color> = f.colored(&b).map(|(_, c)| c).collect();
        assert_eq!(colors.len(), f.all().count());
        assert_eq!(colors[0], Color::WHITE);
        assert_eq!(colors[6], RAILING_COLOR);
        assert_eq!(*colors.last().unwrap(), INFILL_COLOR);
        // A long balcony's posts stay at most 1.25 m apart; a tiny one has no railing.
        let long = Balcony {
            u1: 11.0,
            ..b.clone()
        };
        let f = balcony_faces(&w, &long).unwrap();
        assert_eq!(f.railing.len(), 10 + 4 * (2 + 7));
        let tiny = Balcony {
            u1: 1.2,
            ..b.clone()
        };
        let f = balcony_faces(&w, &tiny).unwrap();
        assert_eq!((f.slab.len(), f.railing.len(), f.infill.len()), (6, 0, 0));
        let bad = Balcony { depth: 0.0, ..b };
        assert!(balcony_faces(&w, &bad).is_none());
    }

    /// A point in millimetres.
    type Mm = (i64, i64, i64);

    /// Directed edges, in millimetres, of every ring of `faces` that have no reverse twin.
    fn unpaired(faces: &[Face]) -> Vec<(Mm, Mm)> {
        let k = crate::model::grid_key;
        let mut edges = std::collections::HashMap::new();
        for r in faces
            .iter()
            .flat_map(|f| std::iter::once(&f.outer).chain(f.holes.iter()))
        {
            for i in 0..r.len() {
                *edges.entry((k(r[i]), k(r[(i + 1) % r.len()]))).or_insert(0) += 1;
            }
        }
        let mut out: Vec<_> = edges
            .iter()
            .filter(|((a, b), c)| **c != 1 || edges.get(&(*b, *a)) != Some(&1))
            .map(|(e, _)| *e)
            .collect();
        out.sort();
        out
    }

    #[test]
    fn low_openings_stand_over_vertices_of_the_base_and_the_face_below() {
        use super::samples::{door, part, window};
        // An oblique quadrilateral on the millimetre grid, two storeys of 3 m: a door 2 cm
        // above the ground on edge 0, a French window 2 cm above the first floor on edge 1,
        // an ordinary window on edge 2.
        let footprint = crate::geometry::Polygon::new(
            vec![
                DVec2::new(0.0, 0.0),
                DVec2::new(8.003, 3.001),
                DVec2::new(5.004, 11.002),
                DVec2::new(-3.001, 8.0),
            ],
            vec![],
        );
        let p = part(
            "p0",
            footprint,
            vec![0.0, 3.0],
            6.0,
            &[
                (0, 0, door(3.0, 4.1, 0.02, 2.2)),
                (1, 1, window(2.0, 3.2, 3.02, 5.4)),
                (2, 0, window(2.0, 3.0, 0.9, 2.2)),
            ],
            &[],
        );
        let shell = |ground: &Face, walls: &[Face]| -> Vec<Face> {
            let mut all = vec![ground.clone()];
            all.extend(walls.iter().cloned());
            all.extend(p.roof.iter().cloned());
            for w in &p.walls {
                all.extend(w.openings.iter().filter_map(|o| opening_face(w, o, 0.0)));
            }
            all
        };
        let model: Vec<Face> = p.walls.iter().map(|w| w.outline.clone()).collect();
        assert!(
            unpaired(&shell(&p.ground, &model)).is_empty(),
            "the fixture is closed"
        );
        let (ground, walls) = seated_faces(&p).expect("two low openings");
        assert!(unpaired(&shell(&ground, &walls)).is_empty(), "still closed");
        // Edge 0, storey 0: the door's jambs on the base, in order, and in the ground reversed.
        let w0 = &p.walls[0];
        let f = WallFrame::of(w0).unwrap();
        let (j0, j1) = (f.at(3.0, 0.0, 0.0), f.at(4.1, 0.0, 0.0));
        assert_eq!(walls[0].outer.len(), 6);
        assert_eq!(&walls[0].outer[1..3], &[j0, j1]);
        assert_eq!(ground.outer.len(), 6);
        let at = ground.outer.iter().position(|q| *q == j1).unwrap();
        assert_eq!(ground.outer[at + 1], j0);
        // Edge 1, storey 1 (wall 5): the French window's jambs on its base, and on the top of
        // the wall below it (wall 1).
        let f = WallFrame::of(&p.walls[5]).unwrap();
        let (k0, k1) = (f.at(2.0, 3.0, 0.0), f.at(3.2, 3.0, 0.0));
        assert_eq!(&walls[5].outer[1..3], &[k0, k1]);
        assert_eq!(walls[1].outer.len(), 6);
        assert!(walls[1].outer.windows(2).any(|w| w == [k1, k0]));
        // Nothing else moved.
        for i in [2, 3, 4, 6, 7] {
            assert_eq!(walls[i], p.walls[i].outline);
        }
        // No low opening, nothing to seat.
        let mut q = p.clone();
        for w in &mut q.walls {
            w.openings.retain(|o| o.z0 - w.base_z >= LOW_SILL);
        }
        assert!(seated_faces(&q).is_none());
    }

    /// Signed volume of a closed set of faces (positive when they face out).
    fn volume(faces: &[Face]) -> f64 {
        faces
            .iter()
            .map(|f| {
                let n = crate::geometry::newell_normal(&f.outer);
                let c = f.outer.iter().copied().sum::<DVec3>() / f.outer.len() as f64;
                c.dot(n) / 2.0
            })
            .sum::<f64>()
            / 3.0
    }

    #[test]
    fn cornices_and_eaves_are_closed_solids_facing_out_mitred_at_corners() {
        use crate::export::lod3geom::samples;
        use crate::model::{Cornice, Eaves};
        // The house: 10 x 6 m, flat roof at 6 m; a cornice on three edges (not edge 2).
        let mut p = samples::house().parts.remove(0);
        p.cornice = Some(Cornice {
            depth: 0.4,
            height: 0.5,
            edges: vec![true, true, false, true],
            color: Color::WHITE,
        });
        let runs = cornice_solids(&p);
        assert_eq!(runs.len(), 3);
        for r in &runs {
            assert_eq!(r.faces.len(), 8);
            assert!(r.faces.iter().all(planar));
            assert!(area_sum(&r.faces).length() < 1e-9, "closed");
            assert!(volume(&r.faces) > 0.0, "facing out");
            // The back is in the wall's plane, facing in.
            let back = &r.faces[r.against_wall];
            assert!(back
                .outer
                .iter()
                .all(|q| q.z >= 5.5 - 1e-9 && q.z <= 6.0 + 1e-9));
            assert!(r
                .faces
                .iter()
                .flat_map(|f| &f.outer)
                .all(|q| q.z <= 6.0 + 1e-9));
        }
        // Edge 0 (y = 0, outside -y): mitred with edge 3 at (0, 0) and edge 1 at (10, 0).
        let front = &runs[0].faces[0];
        assert!(front
            .outer
            .iter()
            .any(|q| (q.x + 0.4).abs() < 1e-9 && (q.y + 0.4).abs() < 1e-9));
        // Edge 1 ends square at (10, 6), before the bare edge 2.
        let end = &runs[1].faces[1];
        assert!(end.outer.iter().all(|q| (q.y - 6.0).abs() < 1e-9));
        // Volume: the section's area along the 10 m edge, and a wedge at each mitred end (at
        // most the area times the depth).
        let area = {
            let q = CORNICE_PROFILE;
            (0..q.len())
                .map(|i| {
                    let (a, b) = (q[i], q[(i + 1) % q.len()]);
                    a.0 * b.1 - b.0 * a.1
                })
                .sum::<f64>()
                / 2.0
                * 0.4
                * 0.5
        };
        let v = volume(&runs[0].faces);
        assert!(v > 10.0 * area && v < 10.8 * area, "{v} {area}");
        // Eaves on the gable: the two eaves and the east verge's two halves.
        let mut g = samples::gable().parts.remove(0);
        g.eaves = Some(Eaves {
            overhang: 0.5,
            thickness: 0.12,
            edges: vec![true, true, true, false],
            soffit: Color::WHITE,
        });
        let boards = eaves_solids(&g);
        assert_eq!(boards.len(), 4);
        for b in &boards {
            assert!(b.faces.iter().all(planar));
            assert!(area_sum(&b.faces).length() < 1e-9, "closed");
            assert!(volume(&b.faces) > 0.0, "facing out");
            assert!(b.faces[0].normal().z > 0.0 && b.faces[1].normal().z < 0.0);
        }
        // The south eave drops along the roof's slope (eave 3, ridge 5 over 3 m): 0.5 m out
        // is 1/3 m lower; mitred at the east corner, square at the west (edge 3 is bare).
        let top = &boards[0].faces[0].outer;
        assert!(top.iter().any(|q| (q.x - 100.5).abs() < 1e-9
            && (q.y + 0.5).abs() < 1e-9
            && (q.z - (3.0 - 1.0 / 3.0)).abs() < 1e-9));
        assert!(top
            .iter()
            .any(|q| (q.x - 90.0).abs() < 1e-9 && (q.y + 0.5).abs() < 1e-9));
        // The verge halves meet at the ridge's height, 0.5 m past the gable.
        let ridge = DVec3::new(100.5, 3.0, 5.0);
        let at_ridge = boards
            .iter()
            .filter(|b| b.faces[0].outer.iter().any(|q| q.distance(ridge) < 1e-9))
            .count();
        assert_eq!(at_ridge, 2);
        // A flat part has no eaves; no cornice or eaves, nothing.
        assert!(eaves_solids(&p).is_empty());
        p.cornice = None;
        assert!(cornice_solids(&p).is_empty());
    }

    #[test]
    fn a_sill_is_a_closed_box_under_each_raised_window_clear_of_its_neighbours() {
        // Front wall of a CCW footprint: outside is -y.
        let mut w = wall(DVec2::new(0.0, 0.0), DVec2::new(10.0, 0.0));
        let a = window(); // 1.0..2.0 at 1.0..2.5
        let near = Opening {
            u0: 2.05,
            u1: 3.0,
            ..window()
        };
        let door = Opening {
            kind: OpeningKind::Door,
            u0: 5.0,
            u1: 6.0,
            z0: 0.02,
            ..window()
        };
        let french = Opening {
            u0: 7.0,
            u1: 8.0,
            z0: 0.1,
            ..window()
        };
        let edge = Opening {
            u0: 9.0,
            u1: 9.98,
            ..window()
        };
        w.openings = vec![a.clone(), near, door, french, edge];
        let s = sills(&w);
        // No sill under the door or the French window.
        assert_eq!(
            s.iter().map(|s| s.opening).collect::<Vec<_>>(),
            vec![0, 1, 4]
        );
        // Ears: a full ear on the free side, halfway to the neighbour on the other, cut at the
        // wall's end.
        assert!((s[0].u0 - (1.0 - SILL_EAR)).abs() < 1e-12);
        assert!((s[0].u1 - 2.025).abs() < 1e-12);
        assert!((s[1].u0 - 2.025).abs() < 1e-12);
        assert!((s[2].u1 - (10.0 - SILL_CLEARANCE)).abs() < 1e-12);
        assert!(s.iter().all(|s| s.top == 1.0));
        let faces = sill_faces(&w, &s[0]).unwrap();
        assert_eq!(faces.len(), 6);
        assert!(faces.iter().all(planar));
        assert!(area_sum(&faces).length() < 1e-9, "closed");
        let inside = DVec3::new(1.5, -SILL_PROJECTION / 2.0, 1.0 - SILL_THICKNESS / 2.0);
        assert!(faces_out_of(&faces, inside));
        // The first face lies in the wall's plane (y = 0), facing into the wall (+y); the rest
        // stand out of it, down to the window's bottom edge.
        assert!(sill_against_wall(0) && !sill_against_wall(1));
        assert!(faces[0].outer.iter().all(|p| p.y.abs() < 1e-12));
        assert!(n(&faces[0]).y > 0.99);
        let pts = faces.iter().flat_map(|f| f.outer.iter());
        assert!(pts
            .clone()
            .all(|p| p.y <= 1e-12 && p.y >= -SILL_PROJECTION - 1e-12));
        assert!(pts.clone().all(|p| p.z <= 1.0 + 1e-12));
        // A balcony in front of the window takes its sill away.
        w.balconies.push(Balcony {
            u0: 0.5,
            u1: 3.5,
            z: 0.3,
            depth: 1.0,
            color: Color::WHITE,
        });
        assert_eq!(
            sills(&w).iter().map(|s| s.opening).collect::<Vec<_>>(),
            vec![4]
        );
    }
}

/// Hand-built LOD3 buildings for the writers' tests, laid out as the model's LOD3 contract says
/// (walls per storey and edge, one hole per opening in the same order, holes oriented opposite
/// to the outline).
#[cfg(test)]
pub(crate) mod samples {
    use glam::{DVec2, DVec3};

    use crate::color::Color;
    use crate::geometry::Polygon;
    use crate::model::SourceId;
    use crate::model::{
        Balcony, Building, Face, Lod, Opening, OpeningKind, Part, PartRole, RoofShape, Wall,
    };

    pub(crate) const GLASS: Color = Color::rgb(0.55, 0.7, 0.8);
    pub(crate) const DOOR: Color = Color::rgb(0.4, 0.25, 0.1);
    pub(crate) const FRAME: Color = Color::rgb(0.95, 0.95, 0.95);
    pub(crate) const BALCONY: Color = Color::rgb(0.6, 0.6, 0.6);

    pub fn window(u0: f64, u1: f64, z0: f64, z1: f64) -> Opening {
        Opening {
            kind: OpeningKind::Window,
            u0,
            u1,
            z0,
            z1,
            color: GLASS,
            frame_color: FRAME,
            glazed: true,
            framed: true,
            frame_size: None,
            rounding: None,
        }
    }

    pub fn door(u0: f64, u1: f64, z0: f64, z1: f64) -> Opening {
        Opening {
            kind: OpeningKind::Door,
            color: DOOR,
            glazed: false,
            framed: false,
            frame_size: None,
            rounding: None,
            ..window(u0, u1, z0, z1)
        }
    }

    fn rect(x0: f64, y0: f64, x1: f64, y1: f64) -> Vec<DVec2> {
        vec![
            DVec2::new(x0, y0),
            DVec2::new(x1, y0),
            DVec2::new(x1, y1),
            DVec2::new(x0, y1),
        ]
    }

    /// A flat-roofed LOD3 part: walls per storey (`levels`, the last up to `eave`) and edge of
    /// `footprint` (outer ring then holes), with `openings` and `balconies` given as
    /// (edge index, storey, item).
    pub fn part(
        key: &str,
        footprint: Polygon,
        levels: Vec<f64>,
        eave: f64,
        openings: &[(usize, usize, Opening)],
        balconies: &[(usize, usize, Balcony)],
    ) -> Part {
        let edges: Vec<(DVec2, DVec2)> = footprint
            .rings()
            .flat_map(|r| (0..r.len()).map(move |i| (r[i], r[(i + 1) % r.len()])))
            .collect();
        let mut walls = Vec::new();
        for (storey, &lo) in levels.iter().enumerate() {
            let hi = levels.get(storey + 1).copied().unwrap_or(eave);
            for (e, &(a, b)) in edges.iter().enumerate() {
                let ops: Vec<Opening> = openings
                    .iter()
                    .filter(|(oe, os, _)| *oe == e && *os == storey)
                    .map(|(_, _, o)| o.clone())
                    .collect();
                let dir = (b - a).normalize();
                let p = |u: f64, z: f64| (a + dir * u).extend(z);
                let holes = ops
                    .iter()
                    .map(|o| vec![p(o.u0, o.z0), p(o.u0, o.z1), p(o.u1, o.z1), p(o.u1, o.z0)])
                    .collect();
                walls.push(Wall {
                    start: a,
                    end: b,
                    base_z: lo,
                    top_z: hi,
                    thickness: 0.3,
                    outline: Face {
                        outer: vec![a.extend(lo), b.extend(lo), b.extend(hi), a.extend(hi)],
                        holes,
                    },
                    storey,
                    openings: ops,
                    balconies: balconies
                        .iter()
                        .filter(|(be, bs, _)| *be == e && *bs == storey)
                        .map(|(_, _, b)| b.clone())
                        .collect(),
                    party: 0.0,
                });
            }
        }
        let lift = |r: &Vec<DVec2>, z: f64| r.iter().map(|p| p.extend(z)).collect::<Vec<_>>();
        let roof = Face {
            outer: lift(&footprint.outer, eave),
            holes: footprint.holes.iter().map(|h| lift(h, eave)).collect(),
        };
        let rev = |r: &Vec<DVec2>| {
            let mut v = lift(r, levels[0]);
            v.reverse();
            v
        };
        let ground = Face {
            outer: rev(&footprint.outer),
            holes: footprint.holes.iter().map(rev).collect(),
        };
        Part {
            key: key.into(),
            footprint,
            base_z: levels[0],
            eave_z: eave,
            top_z: eave,
            storeys: levels.len() as u32,
            levels,
            wall_color: Color::rgb(0.96, 0.96, 0.86),
            roof_color: Color::rgb(0.7, 0.2, 0.1),
            wall_material: Default::default(),
            roof_material: Default::default(),
            roof_shape: RoofShape::Flat,
            walls,
            roof: vec![roof],
            ground,
            interior: Vec::new(),
            source: None,
            role: PartRole::Own,
            structure: None,
            rhythm: None,
            cornice: None,
            eaves: None,
        }
    }

    pub fn building(id: SourceId, parts: Vec<Part>) -> Building {
        let base = parts.iter().map(|p| p.base_z).fold(f64::INFINITY, f64::min);
        let top = parts
            .iter()
            .map(|p| p.top_z)
            .fold(f64::NEG_INFINITY, f64::max);
        Building {
            id,
            name: None,
            zone: "earth/Europe/Monaco".into(),
            appearance: "Monaco#1".into(),
            base_z: base,
            ground_z: base,
            measured_height: top - base,
            storeys_above_ground: parts.iter().map(|p| p.storeys).max().unwrap_or(1),
            roof_shape: parts[0].roof_shape,
            parts,
            lod: Lod::Lod3,
            facade: Default::default(),
            provenance: Default::default(),
            attributes: None,
        }
    }

    /// 10 x 6 m box, 2 storeys of 3 m; the front wall (edge 0, y = 0) has 4 windows and a door.
    pub fn house() -> Building {
        let openings = [
            (0, 0, window(1.0, 2.2, 0.9, 2.2)),
            (0, 0, door(4.5, 5.5, 0.02, 2.2)),
            (0, 0, window(7.8, 9.0, 0.9, 2.2)),
            (0, 1, window(1.0, 2.2, 3.9, 5.2)),
            (0, 1, window(7.8, 9.0, 3.9, 5.2)),
        ];
        let p = part(
            "p0",
            Polygon::new(rect(0.0, 0.0, 10.0, 6.0), vec![]),
            vec![0.0, 3.0],
            6.0,
            &openings,
            &[],
        );
        building(SourceId::Way(301), vec![p])
    }

    /// 20 x 20 m block with an 8 x 8 m courtyard, one storey; windows on an outer and a
    /// courtyard wall (edge 4 is the courtyard's first edge).
    pub fn courtyard() -> Building {
        let fp = Polygon::new(
            rect(30.0, 0.0, 50.0, 20.0),
            vec![rect(36.0, 6.0, 44.0, 14.0)],
        );
        let mut opaque = window(5.0, 6.0, 1.0, 2.0);
        opaque.glazed = false;
        opaque.color = Color::rgb(0.2, 0.3, 0.2);
        let openings = [
            (1, 0, window(2.0, 3.0, 1.0, 2.2)),
            (4, 0, window(2.0, 3.5, 1.0, 2.2)),
            (4, 0, opaque),
        ];
        let p = part("p0", fp, vec![0.0], 3.5, &openings, &[]);
        building(SourceId::Relation(302), vec![p])
    }

    /// Two parts: a 2-storey box with a balcony and a French window on its first floor, and a
    /// lower annex with a door.
    pub(crate) fn with_balcony() -> Building {
        let balcony = Balcony {
            u0: 3.0,
            u1: 7.0,
            z: 3.0,
            depth: 1.2,
            color: BALCONY,
        };
        let a = part(
            "p0",
            Polygon::new(rect(60.0, 0.0, 70.0, 6.0), vec![]),
            vec![0.0, 3.0],
            6.0,
            &[(0, 1, window(4.0, 6.0, 3.02, 5.4))],
            &[(0, 1, balcony)],
        );
        let b = part(
            "p1",
            Polygon::new(rect(70.0, 0.0, 76.0, 6.0), vec![]),
            vec![0.0],
            3.0,
            &[(0, 0, door(2.0, 3.0, 0.02, 2.1))],
            &[],
        );
        building(SourceId::Way(303), vec![a, b])
    }

    /// 10 x 6 m, one storey, gable roof (eave 3, ridge 5 along x at y = 3): the east and west
    /// walls are pentagons; the east one has a window.
    pub fn gable() -> Building {
        let (x0, e, r) = (90.0, 3.0, 5.0);
        let mut p = part(
            "p0",
            Polygon::new(rect(x0, 0.0, x0 + 10.0, 6.0), vec![]),
            vec![0.0],
            e,
            &[(1, 0, window(2.0, 4.0, 1.0, 2.5))],
            &[],
        );
        let q = |x: f64, y: f64, z: f64| DVec3::new(x0 + x, y, z);
        for w in [1, 3] {
            let wall = &mut p.walls[w];
            let o = &mut wall.outline.outer;
            o.insert(3, ((o[2] + o[3]) * 0.5).truncate().extend(r));
        }
        p.roof = vec![
            Face::new(vec![
                q(0.0, 0.0, e),
                q(10.0, 0.0, e),
                q(10.0, 3.0, r),
                q(0.0, 3.0, r),
            ]),
            Face::new(vec![
                q(10.0, 6.0, e),
                q(0.0, 6.0, e),
                q(0.0, 3.0, r),
                q(10.0, 3.0, r),
            ]),
        ];
        p.top_z = r;
        p.roof_shape = RoofShape::Gabled;
        building(SourceId::Way(304), vec![p])
    }

    /// All LOD3 samples.
    pub fn all() -> Vec<Building> {
        vec![house(), courtyard(), with_balcony(), gable()]
    }

    /// (windows, doors) of a building, counted on the model.
    pub fn counts(b: &Building) -> (usize, usize) {
        let all = b
            .parts
            .iter()
            .flat_map(|p| &p.walls)
            .flat_map(|w| &w.openings);
        let doors = all.clone().filter(|o| o.kind == OpeningKind::Door).count();
        (all.count() - doors, doors)
    }

    /// Wall area minus opening area of a building, from the model (rectangles and the gable
    /// pentagons via their Newell normals).
    pub(crate) fn net_wall_area(b: &Building) -> f64 {
        b.parts
            .iter()
            .flat_map(|p| &p.walls)
            .map(|w| {
                let outer = crate::geometry::newell_normal(&w.outline.outer).length() / 2.0;
                let open: f64 = w.openings.iter().map(|o| o.width() * o.height()).sum();
                outer - open
            })
            .sum()
    }
}
