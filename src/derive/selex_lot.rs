//! A SELEX program's own box lot as one building (`citygen selex derive FILE --ifc ...`): the
//! volumes and faces of its shape tree ([`crate::selex::eval::Derivation`]) become the parts
//! of a [`Building`], built by the generator's own machinery ([`massing::build_part`], and at
//! LOD3 `facade::apply`), and its elements the parts' openings and balconies.
//!
//! # Parts
//!
//! - Every volume is a part with a flat roof, in tree order: a box of `createShape` (or the
//!   `--lot` box) on its plan rectangle, a bay of `addVolume` on its own box in plan, standing
//!   against the wall it was pushed out of, from the bay's bottom to its top. Volumes are
//!   axis-aligned boxes (every `createShape` box and every bay of one is).
//! - A free-standing face on the root (`addShape(label, w, h)`, Jiang's facade) is the front of
//!   a block `FREE_FACE_DEPTH` deep behind it.
//! - A bay rounded by `roundShape("front", direction, degree, segments, ...)` with a vertical
//!   (or no) axis has its front drawn as a circular arc of `segments` chords, ending on the
//!   bay's sides. `degree` is the arc's rise as a share of the most it can be: the rise is
//!   `degree` (clamped to 0..1) times the smaller of the bay's depth and half its width, so 1
//!   gives a half-round front on a bay at least half as deep as it is wide, and the side walls
//!   are shortened by the rise. `outside` bulges out (the arc stays inside the bay's box, its
//!   apex on the box's front); `inside` curves in by the same rise (at most the depth less
//!   `MIN_EDGE`). Chords are at least `MIN_EDGE` long (fewer segments otherwise, with a
//!   note). Other roundings (`top`, `left`, a horizontal axis, a rounded box) are drawn square,
//!   with a note.
//!
//! # Storeys
//!
//! A face of the part whose latest grid has rows of storey height (2 to 4.5 m each) gives the
//! storeys (Jiang's 4 × 3.2 m). Otherwise the part has storeys of about
//! `DEFAULT_STOREY` (n = round(H / 3), as `createStoreyGrid` makes on a box), each floor
//! moved to the nearest height that cuts no element (a floor must lie at least a lintel above
//! an opening's top and `OPENING_MARGIN` below its bottom), within half a storey and keeping
//! storeys at least `MIN_STOREY` high; a top storey up to two storeys high is kept whole
//! rather than cut through elements it holds whole. An element that still spans floors becomes one opening
//! per storey, as in city runs ([`crate::derive::selex`]).
//!
//! # Elements
//!
//! Labels decide what an element is, as in city runs: `door…` and `entrance…` doors,
//! `balcony…` and `ledge…` balconies, `wall` (the cover) nothing, anything else a window;
//! rounded corners and frames are kept (`FrameSize { width: thickness, protrusion: width }`).
//! An element on a flat face goes on the footprint edge its face stands on (same line, same
//! outward normal), `u` from the edge's start, which is its left end seen from outside, as the
//! face's `x` is. Each is inset by `OPENING_MARGIN` at its sides and top, so that elements on
//! neighbouring cells stay apart as the writers need.
//!
//! On the rounded front of a bay, each element is put on one flat facet of the arc: the arc's
//! vertices within an element's span (its ends placed on the arc at the angles that split it
//! as they split the flat front's width; overlapping spans merged) are dropped, so the chord
//! between its ends carries it, as a polygonal bay window does, and the rest of the arc keeps
//! its chords. The element keeps its width, centred on the chord at the share of the span its
//! centre is at (a chord is never shorter than the flat width it replaces).
//!
//! An element that lands on no wall (a face on no footprint edge, the part of a bay's side the
//! rounding took away) is not placed, and each one is named in a note, as are the openings
//! `facade::apply` leaves out (too small or overlapping).

use glam::{DVec2, DVec3};

use crate::derive::facade::{self, Facades, FoundOpening, Level, OpeningColors};
use crate::derive::massing::{self, Mass};
use crate::derive::selex_place::{
    element_on_edge, element_spans, is_cover, on_facets, rounded_front, Facet, Placed,
};
use crate::derive::Note;
use crate::geometry::Polygon;
use crate::kb::defaults;
use crate::model::{
    Building, FacadeCounts, Lod, Part, RoofShape, SourceId, LINTEL, OPENING_MARGIN,
};
use crate::report::Outcome;
use crate::selex::eval::{Derivation, Element, Frame, ShapeId, ShapeKind, DEFAULT_STOREY};

/// How deep (metres) the block behind a free-standing face is.
pub(crate) const FREE_FACE_DEPTH: f64 = 8.0;
pub(crate) use crate::derive::selex_place::MIN_EDGE;
/// The lowest storey the floors are moved to make, metres.
pub(crate) const MIN_STOREY: f64 = 2.0;
/// How far (metres) a face may lie from a footprint edge's line and still stand on it.
const ON_EDGE: f64 = 0.01;

/// One part to build.
struct PartPlan {
    /// Its footprint, on the output grid, outer ring counter-clockwise.
    footprint: Polygon,
    base_z: f64,
    eave_z: f64,
    /// The faces whose elements go on its edges.
    faces: Vec<ShapeId>,
    /// The rounded front: its face and the facets carrying its elements.
    arc: Option<(ShapeId, Vec<Facet>)>,
}

/// The building of `d`, the shape tree of a program run on its own box lot, cut at `lod`:
/// `id`, zone `selex`, `appearance` (the program's file name). Notes say what was not drawn as
/// asked and every element not placed. An error when the tree holds no volume or face.
pub fn building(
    d: &Derivation,
    id: SourceId,
    appearance: &str,
    lod: Lod,
) -> Result<(Building, Vec<Note>), String> {
    if let Some(why) = too_large(d) {
        return Err(format!("{appearance}: {why}"));
    }
    let mut notes: Vec<Note> = Vec::new();
    let mut plans: Vec<PartPlan> = Vec::new();
    for (i, s) in d.shapes.iter().enumerate() {
        match &s.kind {
            ShapeKind::Volume { .. } => {
                if let Some(p) = volume_plan(d, i, &mut notes) {
                    plans.push(p);
                }
            }
            ShapeKind::Face { frame, .. } if s.parent == Some(0) => {
                if let Some(p) = free_face_plan(i, frame) {
                    plans.push(p);
                } else {
                    notes.push(note(format!("face `{}` is too small to build", s.label)));
                }
            }
            _ => {}
        }
    }
    if plans.is_empty() {
        return Err(format!(
            "{appearance}: the program makes no volume (createShape, addVolume) and no face \
             (addShape): nothing to build"
        ));
    }
    let colors = OpeningColors {
        window: defaults::WINDOW_COLOR,
        frame: defaults::FRAME_COLOR,
        door: defaults::DOOR_COLOR,
        min_width: defaults::MIN_OPENING_WIDTH,
    };
    let mut placed_faces = vec![false; d.shapes.len()];
    let mut unplaced: Vec<String> = Vec::new();
    let mut parts = Vec::with_capacity(plans.len());
    for (n, plan) in plans.iter().enumerate() {
        let levels = part_levels(d, plan);
        let mass = Mass {
            footprint: plan.footprint.clone(),
            base_z: plan.base_z,
            eave_z: plan.eave_z,
            storeys: levels.len() as u32,
            roof: RoofShape::Flat,
            roof_angle_deg: defaults::ROOF_ANGLE_DEG,
            roof_direction: None,
            roof_across: false,
            roof_height: None,
            wall_color: defaults::WALL_COLOR,
            roof_color: defaults::ROOF_COLOR,
        };
        let roof = crate::derive::roof::flat(&mass.footprint);
        let mut part = massing::build_part(format!("p{n}"), &mass, &roof, lod);
        part.source = Some(id);
        for &f in plan.faces.iter().chain(plan.arc.as_ref().map(|(f, _)| f)) {
            placed_faces[f] = true;
        }
        if lod >= Lod::Lod3 {
            let facades = facades_of(d, plan, &part, levels, &mut unplaced);
            let dropped = facade::apply(&mut part, &facades, &colors);
            if dropped > 0 {
                notes.push(note(format!(
                    "{dropped} opening(s) too small or overlapping were left out"
                )));
            }
        }
        parts.push(part);
    }
    if lod >= Lod::Lod3 {
        // Elements on faces of no part.
        for (s, e) in element_shapes(d) {
            let face = d.shapes[s].parent.unwrap_or(0);
            if !placed_faces[face] {
                unplaced.push(format!(
                    "{} at ({:.2}, {:.2}) on `{}`: its face belongs to no part",
                    d.shapes[s].label, e.rect.x, e.rect.y, d.shapes[face].label
                ));
            }
        }
    }
    if !unplaced.is_empty() {
        notes.push(note(format!(
            "{} element(s) not placed: {}",
            unplaced.len(),
            unplaced.join("; ")
        )));
    }
    notes.extend(
        d.warnings
            .iter()
            .map(|w| note(format!("{appearance}:{}:{}: {}", w.line, w.col, w.message))),
    );
    let base_z = parts.iter().map(|p| p.base_z).fold(f64::INFINITY, f64::min);
    let top = parts
        .iter()
        .map(|p| p.top_z)
        .fold(f64::NEG_INFINITY, f64::max);
    let storeys = parts
        .iter()
        .max_by(|a, b| a.top_z.total_cmp(&b.top_z))
        .map_or(1, |p| p.storeys);
    Ok((
        Building {
            id,
            name: None,
            zone: "selex".into(),
            appearance: appearance.to_string(),
            base_z,
            ground_z: base_z,
            measured_height: top - base_z,
            storeys_above_ground: storeys,
            roof_shape: RoofShape::Flat,
            parts,
            lod,
            facade: FacadeCounts::default(),
            provenance: Default::default(),
            attributes: None,
        },
        notes,
    ))
}

/// The largest side of a volume or face `selex derive` builds, metres (the `--lot` limit):
/// storeys, walls and openings are made for the whole size, so a 1e300 m box would ask for
/// more memory than there is.
pub(crate) const MAX_SIDE: f64 = 10_000.0;

/// Why the tree is too large to build, if it is: a volume or a face with a side over
/// [`MAX_SIDE`] (or not finite), named with its size.
pub(crate) fn too_large(d: &Derivation) -> Option<String> {
    let fits = |v: f64| v.is_finite() && v <= MAX_SIDE;
    let m = |v: f64| {
        if v.abs() < 1e6 {
            format!("{v}")
        } else {
            format!("{v:e}")
        }
    };
    d.shapes.iter().find_map(|s| match &s.kind {
        ShapeKind::Volume { min, max, .. } => {
            let size = *max - *min;
            (!(fits(size.x) && fits(size.y) && fits(size.z))).then(|| {
                format!(
                    "volume `{}` of {} x {} x {} m is larger than the limit of {MAX_SIDE} m a \
                     side: nothing is built",
                    s.label,
                    m(size.x),
                    m(size.y),
                    m(size.z)
                )
            })
        }
        ShapeKind::Face { frame, .. } => (!(fits(frame.width) && fits(frame.height))).then(|| {
            format!(
                "face `{}` of {} x {} m is larger than the limit of {MAX_SIDE} m a side: \
                 nothing is built",
                s.label,
                m(frame.width),
                m(frame.height)
            )
        }),
        _ => None,
    })
}

fn note(text: String) -> Note {
    (Outcome::Note, text)
}

/// The elements of the tree with their shape ids.
fn element_shapes(d: &Derivation) -> impl Iterator<Item = (ShapeId, &Element)> + '_ {
    d.shapes
        .iter()
        .enumerate()
        .filter_map(|(i, s)| match &s.kind {
            ShapeKind::Element(e) => Some((i, e)),
            _ => None,
        })
}

/// The faces that are children of shape `id`.
fn child_faces(d: &Derivation, id: ShapeId) -> Vec<ShapeId> {
    d.shapes[id]
        .children
        .iter()
        .copied()
        .filter(|&c| matches!(d.shapes[c].kind, ShapeKind::Face { .. }))
        .collect()
}

/// The plan of volume `v`: its box, or a bay with a rounded front.
fn volume_plan(d: &Derivation, v: ShapeId, notes: &mut Vec<Note>) -> Option<PartPlan> {
    let ShapeKind::Volume { min, max, rounding } = &d.shapes[v].kind else {
        return None;
    };
    let (min, max) = (*min, *max);
    let usable = max.x - min.x > MIN_EDGE
        && max.y - min.y > MIN_EDGE
        && max.z - min.z > 0.1
        && min.is_finite()
        && max.is_finite();
    if !usable {
        notes.push(note(format!(
            "volume `{}` is too small to build",
            d.shapes[v].label
        )));
        return None;
    }
    let faces = child_faces(d, v);
    let rect = || {
        Polygon::new(
            vec![
                DVec2::new(min.x, min.y),
                DVec2::new(max.x, min.y),
                DVec2::new(max.x, max.y),
                DVec2::new(min.x, max.y),
            ],
            vec![],
        )
    };
    let square = |faces: Vec<ShapeId>| PartPlan {
        footprint: on_grid(rect()),
        base_z: min.z,
        eave_z: max.z,
        faces,
        arc: None,
    };
    let Some(r) = rounding else {
        return Some(square(faces));
    };
    // A bay: the wall it stands on gives its axes.
    let wall = d.shapes[v].parent.and_then(|p| d.frame(p));
    let front = faces.first().and_then(|&f| d.frame(f).map(|fr| (f, fr)));
    let vertical = r.axis.as_deref().is_none_or(|a| a == "vertical");
    let (Some(wall), Some((front_id, front)), true, true) =
        (wall, front, r.face == "front", vertical)
    else {
        notes.push(note(format!(
            "roundShape(\"{}\", \"{}\", ...) on `{}` is drawn square (only a bay's front, \
             rounded about a vertical axis, is drawn round)",
            r.face, r.direction, d.shapes[v].label
        )));
        return Some(square(faces));
    };
    let u = wall.u.truncate();
    let n = wall.normal().truncate();
    let w = front.width;
    let depth = (max - min).truncate().dot(n.abs());
    let a = front.origin.truncate() - n * depth;
    let spans = element_spans(d, front_id);
    let outside = r.direction != "inside";
    let Some((local, facets, asked)) =
        rounded_front(w, depth, r.degree, r.segments, outside, &spans)
    else {
        return Some(square(faces));
    };
    if asked < r.segments {
        notes.push(note(format!(
            "the rounded front of `{}` has {asked} segments, not {}: chords shorter than {MIN_EDGE} m are not drawn",
            d.shapes[v].label, r.segments
        )));
    }
    let world = |p: DVec2| a + u * p.x + n * p.y;
    let footprint = Polygon::new(local.iter().map(|&p| world(p)).collect(), vec![]);
    let simple = crate::geometry::is_simple(&footprint.outer)
        && edges(&footprint).all(|(s, e)| s.distance(e) >= MIN_EDGE - 1e-6);
    if !simple {
        notes.push(note(format!(
            "the rounded front of `{}` would not make a valid footprint: drawn square",
            d.shapes[v].label
        )));
        return Some(square(faces));
    }
    let facets = facets
        .into_iter()
        .map(|f| Facet {
            a: world(f.a),
            b: world(f.b),
            ..f
        })
        .collect();
    Some(PartPlan {
        footprint: on_grid(footprint),
        base_z: min.z,
        eave_z: max.z,
        faces: faces.into_iter().filter(|&f| f != front_id).collect(),
        arc: Some((front_id, facets)),
    })
}

fn free_face_plan(face: ShapeId, f: &Frame) -> Option<PartPlan> {
    let (u, n) = (f.u.truncate(), f.normal().truncate());
    if !(f.width > MIN_EDGE && f.height > 0.1 && u.is_finite() && n.length() > 0.5) {
        return None;
    }
    let o = f.origin.truncate();
    let footprint = Polygon::new(
        vec![
            o,
            o + u * f.width,
            o + u * f.width - n * FREE_FACE_DEPTH,
            o - n * FREE_FACE_DEPTH,
        ],
        vec![],
    );
    Some(PartPlan {
        footprint: on_grid(footprint),
        base_z: f.origin.z,
        eave_z: f.origin.z + f.height,
        faces: vec![face],
        arc: None,
    })
}

fn on_grid(p: Polygon) -> Polygon {
    massing::grid::polygon_on_grid(&p).unwrap_or(p)
}

/// The edges of a polygon's rings, in the order the walls are built.
fn edges(p: &Polygon) -> impl Iterator<Item = (DVec2, DVec2)> + '_ {
    p.rings()
        .flat_map(|r| (0..r.len()).map(move |i| (r[i], r[(i + 1) % r.len()])))
}

/// The storeys of a part (see the module docs).
fn part_levels(d: &Derivation, plan: &PartPlan) -> Vec<Level> {
    let (base, eave) = (plan.base_z, plan.eave_z);
    let faces: Vec<ShapeId> = plan
        .faces
        .iter()
        .chain(plan.arc.as_ref().map(|(f, _)| f))
        .copied()
        .collect();
    // A storey grid on one of its faces.
    for &f in &faces {
        let Some(frame) = d.frame(f) else { continue };
        let grid = d.shapes[f]
            .children
            .iter()
            .rev()
            .find_map(|&c| match &d.shapes[c].kind {
                ShapeKind::Grid(g) => Some(g),
                _ => None,
            });
        let Some(g) = grid else { continue };
        let rows = g.row_heights();
        let storey_like = rows.len() > 1 && rows.iter().all(|h| (2.0..=4.5).contains(h));
        let z0 = frame.origin.z;
        if storey_like && (z0 - base).abs() < 0.01 && (z0 + g.height() - eave).abs() < 0.01 {
            let mut z = z0;
            return rows
                .iter()
                .map(|h| {
                    let l = Level { z0: z, z1: z + h };
                    z += h;
                    l
                })
                .collect();
        }
    }
    // About 3 m storeys, floors moved off the elements.
    let mut busy: Vec<(f64, f64)> = faces
        .iter()
        .flat_map(|&f| {
            let z0 = d.frame(f).map_or(base, |fr| fr.origin.z);
            d.shapes[f]
                .children
                .iter()
                .filter_map(move |&c| match &d.shapes[c].kind {
                    ShapeKind::Element(e) if !is_cover(&d.shapes[c].label) => Some((
                        z0 + e.rect.y - OPENING_MARGIN,
                        z0 + e.rect.y + e.rect.h + LINTEL,
                    )),
                    _ => None,
                })
        })
        .collect();
    busy.sort_by(|a, b| a.0.total_cmp(&b.0));
    let floors = floors_between(base, eave, &busy);
    let mut levels = Vec::with_capacity(floors.len() + 1);
    let mut lo = base;
    for z in floors.into_iter().chain(std::iter::once(eave)) {
        levels.push(Level { z0: lo, z1: z });
        lo = z;
    }
    levels
}

/// The floors between `base` and `eave` (both left out) for storeys of about
/// [`DEFAULT_STOREY`], each moved to the nearest height outside every `busy` range within half
/// a storey, storeys at least [`MIN_STOREY`] high; where none is free, the top storey is kept
/// whole up to two storeys high when that keeps its elements whole, else the floor cuts them.
fn floors_between(base: f64, eave: f64, busy: &[(f64, f64)]) -> Vec<f64> {
    let height = eave - base;
    let n = (height / DEFAULT_STOREY).round().max(1.0);
    let h = height / n;
    let inside = |z: f64| busy.iter().any(|&(a, b)| z > a && z < b);
    let free_near = |target: f64, lo: f64, hi: f64| -> Option<f64> {
        if lo > hi {
            return None;
        }
        if !inside(target) && (lo..=hi).contains(&target) {
            return Some(target);
        }
        busy.iter()
            .flat_map(|&(a, b)| [a, b])
            .filter(|&z| (lo..=hi).contains(&z) && !inside(z))
            .filter(|&z| (z - target).abs() <= h / 2.0)
            .min_by(|x, y| (x - target).abs().total_cmp(&(y - target).abs()))
    };
    let mut floors = Vec::new();
    let mut prev = base;
    while eave - prev > 1.5 * h + 1e-9 {
        let target = prev + h;
        let (lo, hi) = (prev + MIN_STOREY, eave - MIN_STOREY);
        match free_near(target, lo, hi) {
            Some(z) => floors.push(z),
            // A top storey up to two storeys high rather than a floor through elements it
            // holds whole.
            None if eave - prev <= 2.0 * h + 1e-9
                && busy
                    .iter()
                    .filter(|&&(a, b)| target > a && target < b)
                    .all(|&(a, b)| a >= prev - OPENING_MARGIN - 1e-9 && b <= eave + 1e-9) =>
            {
                break
            }
            None => floors.push(target),
        }
        prev = *floors.last().unwrap_or(&base);
    }
    floors
}

/// The openings and balconies of a part's edges from the elements of its faces; those that
/// land on no edge are added to `unplaced`.
fn facades_of(
    d: &Derivation,
    plan: &PartPlan,
    part: &Part,
    levels: Vec<Level>,
    unplaced: &mut Vec<String>,
) -> Facades {
    let edges: Vec<(DVec2, DVec2)> = edges(&part.footprint).collect();
    let mut out = Facades {
        levels,
        openings: vec![Vec::new(); edges.len()],
        balconies: vec![Vec::new(); edges.len()],
        off_envelope: 0,
        programmed: true,
    };
    let put =
        |out: &mut Facades, k: usize, label: &str, e: &Element, u: (f64, f64), z: (f64, f64)| {
            match element_on_edge(label, e, u, z, &out.levels) {
                Placed::Nothing => {}
                Placed::Balcony(b) => out.balconies[k].push(b),
                Placed::Openings(v) => out.openings[k].extend(v.into_iter().map(inset)),
            }
        };
    for &f in &plan.faces {
        let Some(frame) = d.frame(f) else { continue };
        for &c in &d.shapes[f].children {
            let ShapeKind::Element(e) = &d.shapes[c].kind else {
                continue;
            };
            let label = &d.shapes[c].label;
            if is_cover(label) {
                continue;
            }
            let p0 = frame.at(e.rect.x, e.rect.y);
            let p1 = frame.at(e.rect.x + e.rect.w, e.rect.y);
            let z = (p0.z, p0.z + e.rect.h);
            match on_edge(&edges, &frame, p0, p1) {
                Some((k, u0, u1)) => put(&mut out, k, label, e, (u0, u1), z),
                None => unplaced.push(format!(
                    "{label} at ({:.2}, {:.2}) on `{}`: on no wall of the part",
                    e.rect.x, e.rect.y, d.shapes[f].label
                )),
            }
        }
    }
    if let Some((f, facets)) = &plan.arc {
        let z0 = d.frame(*f).map_or(plan.base_z, |fr| fr.origin.z);
        let placed = on_facets(d, *f, facets, &edges, z0, unplaced);
        for (k, label, e, u, z) in placed {
            put(&mut out, k, label, e, u, z);
        }
    }
    for v in &mut out.openings {
        v.sort_by(|a, b| a.z0.total_cmp(&b.z0).then(a.u0.total_cmp(&b.u0)));
    }
    out
}

/// An opening inset by [`OPENING_MARGIN`] at its sides and top.
fn inset(mut o: FoundOpening) -> FoundOpening {
    if o.u1 - o.u0 > 4.0 * OPENING_MARGIN {
        o.u0 += OPENING_MARGIN;
        o.u1 -= OPENING_MARGIN;
    }
    if o.z1 - o.z0 > 4.0 * OPENING_MARGIN {
        o.z1 -= OPENING_MARGIN;
    }
    o
}

/// The edge whose line holds the face points `p0` (the element's left end) and `p1` (its right
/// end), looking the same way as `frame`, with their places along it (clamped to the edge); the
/// edge it overlaps most when several do. `None` when the element lies on no edge.
fn on_edge(
    edges: &[(DVec2, DVec2)],
    frame: &Frame,
    p0: DVec3,
    p1: DVec3,
) -> Option<(usize, f64, f64)> {
    let n = frame.normal().truncate();
    let (p0, p1) = (p0.truncate(), p1.truncate());
    let mut best: Option<(usize, f64, f64, f64)> = None;
    for (k, &(s, e)) in edges.iter().enumerate() {
        let len = s.distance(e);
        if len <= 0.0 {
            continue;
        }
        let dir = (e - s) / len;
        let out = DVec2::new(dir.y, -dir.x);
        if out.dot(n) < 0.99 {
            continue;
        }
        let off = |p: DVec2| (p - s).dot(out).abs();
        if off(p0) > ON_EDGE || off(p1) > ON_EDGE {
            continue;
        }
        let (u0, u1) = ((p0 - s).dot(dir).max(0.0), (p1 - s).dot(dir).min(len));
        let overlap = u1 - u0;
        if overlap >= facade::MIN_OPENING && best.is_none_or(|b| overlap > b.3) {
            best = Some((k, u0, u1, overlap));
        }
    }
    best.map(|(k, u0, u1, _)| (k, u0, u1))
}

#[cfg(test)]
mod tests;
