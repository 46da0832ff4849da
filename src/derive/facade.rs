//! LOD3 facades: what a derived mass says about its storeys and about the windows, doors and
//! balconies of each wall, in wall coordinates.
//!
//! The grammar's `comp` makes one side face per footprint edge of each storey; subdivisions of
//! those faces end in `window`, `door`, `balcony` and `wall` terminals. [`facades_of`] finds, for
//! every such terminal, the footprint edge it stands on and its place along that edge. Pieces
//! that are not on a footprint edge (a face turned by `R`, the inner faces where a `split` cut
//! the mass) are not on the envelope and are counted in [`Facades::off_envelope`].

use std::rc::Rc;

use glam::{DVec2, DVec3};

use crate::color::Color;
use crate::derive::massing::grid::along_on_grid;
use crate::geometry::Polygon;
use crate::grammar::{AttrValue, Attrs, FaceKind, Geometry, Label, ShapeNode, ShapeTree, Terminal};
pub use crate::model::OpeningKind;
use crate::model::{
    Balcony, Face, FrameSize, Opening, Part, Rounding, Wall, LINTEL, OPENING_MARGIN,
};

/// How far (metres) a face may be from a footprint edge and still stand on it.
const ON_EDGE: f64 = 0.01;

/// A storey of a mass: its floor and ceiling heights.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Level {
    pub z0: f64,
    pub z1: f64,
}

/// A window or door found on a wall: `u0..u1` along the footprint edge from its start (metres),
/// `z0..z1` absolute heights, and the terminal's attributes.
#[derive(Clone, Debug, PartialEq)]
pub struct FoundOpening {
    pub kind: OpeningKind,
    pub u0: f64,
    pub u1: f64,
    pub z0: f64,
    pub z1: f64,
    /// `color` attribute (glass or panel colour).
    pub color: Option<Color>,
    /// `framecolor` attribute.
    pub frame_color: Option<Color>,
    /// Glass: `material=glass`, or a window without a `material`.
    pub glazed: bool,
    /// `style=framed`.
    pub framed: bool,
    /// The frame's size, where not the standard one (SELEX).
    pub frame_size: Option<FrameSize>,
    /// Rounded corners (SELEX).
    pub rounding: Option<Rounding>,
}

/// A balcony found on a wall: the facade piece it belongs to.
#[derive(Clone, Debug, PartialEq)]
pub struct FoundBalcony {
    pub u0: f64,
    pub u1: f64,
    pub z0: f64,
    pub z1: f64,
    pub color: Option<Color>,
}

/// The facade details of one mass.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Facades {
    /// Storeys from bottom to top (one level spanning the mass when the rules make none).
    pub levels: Vec<Level>,
    /// Openings per footprint edge, edges numbered in ring order (outer ring first), sorted by
    /// height then place, the panes of one window joined.
    pub openings: Vec<Vec<FoundOpening>>,
    /// Balconies per footprint edge.
    pub balconies: Vec<Vec<FoundBalcony>>,
    /// Opening and balcony terminals that stand on no footprint edge.
    pub off_envelope: usize,
    /// Laid out by a SELEX program ([`crate::derive::selex::apply`]): its ground-storey doors
    /// are the building's entrances (`derive::frontage`).
    pub programmed: bool,
}

/// One footprint edge in the local frame.
struct Edge {
    start: DVec2,
    dir: DVec2,
    len: f64,
}

/// Reads the levels and the openings of the mass at node `mass` of `tree`, whose footprint is
/// `footprint` and whose walls span `z0..z1`. When the rules cut no storey, the walls get the
/// storeys of [`storeys_around_openings`] for the style's `floor_height`.
pub(crate) fn facades_of(
    tree: &ShapeTree,
    mass: usize,
    footprint: &Polygon,
    (z0, z1): (f64, f64),
    floor_height: f64,
) -> Facades {
    let edges: Vec<Edge> = footprint
        .rings()
        .flat_map(|r| {
            (0..r.len()).map(move |i| {
                let (a, b) = (r[i], r[(i + 1) % r.len()]);
                let len = a.distance(b);
                Edge {
                    start: a,
                    dir: if len > 0.0 { (b - a) / len } else { DVec2::X },
                    len,
                }
            })
        })
        .collect();
    let mut out = Facades {
        levels: Vec::new(),
        openings: vec![Vec::new(); edges.len()],
        balconies: vec![Vec::new(); edges.len()],
        off_envelope: 0,
        programmed: false,
    };
    let mut looks: Vec<(Rc<Attrs>, Look)> = Vec::new();
    let mut stack = vec![mass];
    while let Some(i) = stack.pop() {
        let node = &tree.nodes[i];
        if i != mass && matches!(node.label, Label::Building | Label::BuildingPart) {
            continue; // another mass: its facades are its own
        }
        if matches!(node.label, Label::Storey | Label::Room) {
            if let Geometry::Volume { z0, height, .. } = node.geometry {
                // Horizontal cuts of storeys (and the rooms of a vertical cut, which repeat
                // their storey's range) are sorted out by `levels`.
                out.levels.push(Level {
                    z0,
                    z1: z0 + height,
                });
            }
        }
        if let Some(t) = node.terminal {
            match t {
                Terminal::Window | Terminal::Door | Terminal::Balcony => {
                    place(node, t, &edges, &mut out, &mut looks)
                }
                Terminal::Wall | Terminal::Other => {}
            }
        }
        stack.extend(node.children.clone().rev());
    }
    for v in &mut out.openings {
        *v = panes_joined(v);
    }
    out.levels = if out.levels.is_empty() {
        storeys_around_openings(&out, z0, z1, floor_height)
    } else {
        levels(out.levels, z0, z1)
    };
    out
}

/// The lowest storey height [`storeys_around_openings`] makes, as a share of the floor height.
const LOWEST_STOREY: f64 = 0.6;

/// Storeys for walls `z0..z1` whose rules cut none (a ruleset written for a facade, like
/// `citygen evolve`'s): `⌊(z1 − z0) / floor_height⌋` storeys (at least one), each floor line
/// moved from its even place to the nearest height that crosses no opening or balcony of any
/// wall (kept [`OPENING_MARGIN`] clear of them), so a floor never cuts a window. A line that
/// would leave a storey under [`LOWEST_STOREY`] × `floor_height` is dropped. A non-finite or
/// non-positive floor height gives one storey over the whole wall.
pub fn storeys_around_openings(f: &Facades, z0: f64, z1: f64, floor_height: f64) -> Vec<Level> {
    let whole = vec![Level { z0, z1 }];
    let h = z1 - z0;
    if !(floor_height > 0.0 && floor_height.is_finite() && h.is_finite() && h > 0.0) {
        return whole;
    }
    // Past a few hundred storeys the walls are not a building's: one storey, like no rules.
    let n = (h / floor_height + 1e-9).floor().min(1000.0) as usize;
    if n < 2 {
        return whole;
    }
    let mut blocked: Vec<(f64, f64)> = f
        .openings
        .iter()
        .flatten()
        .map(|o| (o.z0, o.z1))
        .chain(f.balconies.iter().flatten().map(|b| (b.z0, b.z1)))
        .filter(|(a, b)| a.is_finite() && b.is_finite())
        .map(|(a, b)| (a.min(b) - OPENING_MARGIN, a.max(b) + OPENING_MARGIN))
        .collect();
    blocked.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.total_cmp(&b.1)));
    let mut merged: Vec<(f64, f64)> = Vec::with_capacity(blocked.len());
    for (a, b) in blocked {
        match merged.last_mut() {
            Some(last) if a <= last.1 => last.1 = last.1.max(b),
            _ => merged.push((a, b)),
        }
    }
    // The free height nearest to `z`: `z` itself, or an end of the blocked run holding it.
    let free_near = |z: f64| match merged.iter().find(|(a, b)| *a < z && z < *b) {
        Some(&(a, b)) if z - a <= b - z => a,
        Some(&(_, b)) => b,
        None => z,
    };
    let lowest = LOWEST_STOREY * floor_height;
    let mut floors = vec![z0];
    for k in 1..n {
        let z = free_near(z0 + h * k as f64 / n as f64);
        let last = floors.last().copied().unwrap_or(z0);
        if z - last >= lowest && z1 - z >= lowest {
            floors.push(z);
        }
    }
    (0..floors.len())
        .map(|i| Level {
            z0: floors[i],
            z1: floors.get(i + 1).copied().unwrap_or(z1),
        })
        .collect()
}

/// The finest storey partition of the ranges found: a storey cut again along Z (`building ->
/// split(Z, ...){groundfloor | upperfloors}`, `upperfloors -> repeat(Z, ...){floor}`) counts as
/// its pieces; ranges repeated by vertical cuts count once. One level over the whole wall when
/// there are none.
pub fn levels(mut found: Vec<Level>, z0: f64, z1: f64) -> Vec<Level> {
    found.sort_by(|a, b| a.z0.total_cmp(&b.z0).then(a.z1.total_cmp(&b.z1)));
    let mut out: Vec<Level> = Vec::with_capacity(found.len());
    for l in found {
        if l.z1 - l.z0 <= ON_EDGE {
            continue;
        }
        match out.last() {
            // Starts inside the last one kept: a coarser range holding it, or a repeat.
            Some(last) if l.z0 < last.z1 - ON_EDGE => {}
            _ => out.push(l),
        }
    }
    if out.is_empty() {
        out.push(Level { z0, z1 });
    }
    out
}

/// What a terminal's attributes say about its looks: colour, frame colour, whether its
/// material is glass (`None`: no material) and whether it is framed.
#[derive(Clone, Copy)]
struct Look {
    color: Option<Color>,
    frame_color: Option<Color>,
    glass: Option<bool>,
    framed: bool,
}

impl Look {
    fn of(attrs: &Attrs) -> Look {
        let text = |key: &str| match attrs.get(key) {
            Some(AttrValue::Str(s)) => Some(s.to_string()),
            Some(AttrValue::Num(n)) => Some(n.to_string()),
            None => None,
        };
        Look {
            color: text("color").and_then(|c| Color::parse(&c)),
            frame_color: text("framecolor").and_then(|c| Color::parse(&c)),
            glass: text("material").map(|m| m.eq_ignore_ascii_case("glass")),
            framed: text("style").is_some_and(|s| s.eq_ignore_ascii_case("framed")),
        }
    }
}

/// Finds the footprint edge a terminal face stands on and records it there. `looks` remembers
/// the [`Look`] of each attribute map met (the terminals of a facade share theirs).
fn place(
    node: &ShapeNode,
    t: Terminal,
    edges: &[Edge],
    out: &mut Facades,
    looks: &mut Vec<(Rc<Attrs>, Look)>,
) {
    let Geometry::Face {
        kind: FaceKind::Side,
        origin,
        x_axis,
        z_axis,
        width,
        height,
        ..
    } = node.geometry
    else {
        out.off_envelope += 1;
        return;
    };
    if (z_axis - DVec3::Z).length() > 1e-6 || width <= 0.0 || height <= 0.0 {
        out.off_envelope += 1;
        return;
    }
    let o = DVec2::new(origin.x, origin.y);
    let x = DVec2::new(x_axis.x, x_axis.y);
    let found = edges.iter().enumerate().find_map(|(k, e)| {
        let along = (o - e.start).dot(e.dir);
        let off = (o - e.start).perp_dot(e.dir).abs();
        let parallel = x.dot(e.dir) > 1.0 - 1e-6;
        (parallel && off <= ON_EDGE && along >= -ON_EDGE && along + width <= e.len + ON_EDGE)
            .then_some((k, along))
    });
    let Some((k, u0)) = found else {
        out.off_envelope += 1;
        return;
    };
    let look = match looks.iter().find(|(a, _)| Rc::ptr_eq(a, &node.attrs)) {
        Some((_, l)) => *l,
        None => {
            let l = Look::of(&node.attrs);
            if looks.len() < 64 {
                looks.push((node.attrs.clone(), l));
            }
            l
        }
    };
    let color = look.color;
    let u0 = u0.max(0.0);
    let u1 = (u0 + width).min(edges[k].len);
    let (z0, z1) = (origin.z, origin.z + height);
    match t {
        Terminal::Balcony => out.balconies[k].push(FoundBalcony {
            u0,
            u1,
            z0,
            z1,
            color,
        }),
        _ => out.openings[k].push(FoundOpening {
            kind: if t == Terminal::Door {
                OpeningKind::Door
            } else {
                OpeningKind::Window
            },
            u0,
            u1,
            z0,
            z1,
            color,
            frame_color: look.frame_color,
            // A window is glass unless its material says otherwise; a door only when it says so.
            glazed: look.glass.unwrap_or(t == Terminal::Window),
            framed: look.framed,
            frame_size: None,
            rounding: None,
        }),
    }
}

/// Default colours of openings whose terminals set none, and the narrowest opening drawn.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct OpeningColors {
    pub window: Color,
    pub frame: Color,
    pub door: Color,
    /// The narrowest window or door drawn, metres, once fitted to its wall and its jambs on
    /// the grid (the style's [`crate::kb::Style::min_opening_width`], issue 45): a narrower one
    /// is left out, never drawn as a slit.
    pub min_width: f64,
}

/// Smallest window or door kept (metres, each side).
pub(crate) const MIN_OPENING: f64 = 0.1;
/// How far (metres) a jamb may move into its opening to stand on a grid point by its wall's
/// line ([`along_on_grid`]).
pub(crate) const JAMB_SNAP: f64 = 0.02;
/// Default balcony depth (metres).
pub(crate) const BALCONY_DEPTH: f64 = 1.2;

/// The openings of one edge with the panes of one window joined: a drawn subdivision (the
/// knowledge base's `<opening>` splits) ends in panes that touch, each its own terminal; cut
/// one by one, every pane after the first would overlap its neighbour's margin and be left
/// out, halving the window. Panes of one kind on the same rows whose sides meet (closer than
/// two margins) become one opening, with the first pane's looks.
fn panes_joined(found: &[FoundOpening]) -> Vec<FoundOpening> {
    let mut v: Vec<FoundOpening> = found.to_vec();
    v.sort_by(|a, b| {
        a.z0.total_cmp(&b.z0)
            .then(a.z1.total_cmp(&b.z1))
            .then(a.u0.total_cmp(&b.u0))
    });
    let mut out: Vec<FoundOpening> = Vec::with_capacity(v.len());
    for f in v {
        match out.last_mut() {
            Some(last)
                if last.kind == f.kind
                    && (last.z0 - f.z0).abs() < 1e-6
                    && (last.z1 - f.z1).abs() < 1e-6
                    && f.u0 >= last.u0
                    && f.u0 - last.u1 < 2.0 * OPENING_MARGIN =>
            {
                last.u1 = last.u1.max(f.u1);
            }
            _ => out.push(f),
        }
    }
    out.sort_by(|a, b| a.z0.total_cmp(&b.z0).then(a.u0.total_cmp(&b.u0)));
    out
}

/// How far (metres) the sills and heads of two narrow openings [`merge_narrow`] joins may be
/// apart.
pub(crate) const MERGE_ROW: f64 = 0.1;

/// Merges neighbouring openings of one wall storey that are each narrower than `min` (the
/// style's minimum opening width, issue 45) into one when together they span at least `min`:
/// of one kind, on one row (sill and head within [`MERGE_ROW`]), the mullion between
/// them narrower than `min`, and the merged opening [`OPENING_MARGIN`] clear of every other.
/// The merged opening keeps the left one's looks, spans both rows' heights, and its jambs
/// are the pair's outer ones (on the grid already). Openings not merged keep their order.
/// How many pairs were merged.
pub(crate) fn merge_narrow(openings: &mut Vec<Opening>, min: f64) -> usize {
    let narrow = |o: &Opening| o.width() < min - 1e-9;
    let mut merged = 0;
    'again: loop {
        for i in 0..openings.len() {
            let a = &openings[i];
            if !narrow(a) {
                continue;
            }
            // The nearest narrow neighbour to the right on the same row.
            let right = (0..openings.len())
                .filter(|&j| j != i)
                .filter(|&j| {
                    let b = &openings[j];
                    narrow(b)
                        && b.kind == a.kind
                        && b.u0 >= a.u1
                        && b.u0 - a.u1 < min
                        && b.u1 - a.u0 >= min - 1e-9
                        && (b.z0 - a.z0).abs() <= MERGE_ROW
                        && (b.z1 - a.z1).abs() <= MERGE_ROW
                })
                .min_by(|&j, &k| openings[j].u0.total_cmp(&openings[k].u0));
            let Some(j) = right else {
                continue;
            };
            let b = &openings[j];
            let (u0, u1, z0, z1) = (a.u0, b.u1, a.z0.min(b.z0), a.z1.max(b.z1));
            let clear = openings.iter().enumerate().all(|(k, q)| {
                k == i
                    || k == j
                    || u1 + OPENING_MARGIN <= q.u0
                    || q.u1 + OPENING_MARGIN <= u0
                    || z1 + OPENING_MARGIN <= q.z0
                    || q.z1 + OPENING_MARGIN <= z0
            });
            if !clear {
                continue;
            }
            let o = &mut openings[i];
            (o.u1, o.z0, o.z1) = (u1, z0, z1);
            openings.remove(j);
            merged += 1;
            continue 'again;
        }
        return merged;
    }
}

/// The storey floors [`apply`] cuts `part`'s walls at: the levels' floors clamped to the walls,
/// the first at the base (the last storey reaches up to the eave).
pub fn floors(part: &Part, facades: &Facades) -> Vec<f64> {
    let mut floors: Vec<f64> = facades
        .levels
        .iter()
        .map(|l| l.z0)
        .filter(|z| *z > part.base_z + MIN_OPENING && *z < part.eave_z - MIN_OPENING)
        .collect();
    floors.insert(0, part.base_z);
    floors.dedup_by(|a, b| (*a - *b).abs() < MIN_OPENING);
    floors
}

/// The storeys of `part` as [`apply`] cuts them: `(floor, next floor or eave)`.
pub fn storeys(part: &Part, facades: &Facades) -> Vec<(f64, f64)> {
    let f = floors(part, facades);
    (0..f.len())
        .map(|i| (f[i], f.get(i + 1).copied().unwrap_or(part.eave_z)))
        .collect()
}

/// Turns a LOD2-style part (one wall per footprint edge, built by [`crate::derive::massing::build_part`])
/// into LOD3: one wall per storey and edge, with the openings and balconies of `facades` placed
/// on them and cut out of the wall outlines. Returns how many openings were left out because
/// they were too small once kept [`OPENING_MARGIN`] inside their wall, overlapped another, or
/// were narrower than [`OpeningColors::min_width`] once their jambs were on the grid and no
/// narrow neighbour could be merged with them ([`merge_narrow`]).
pub fn apply(part: &mut Part, facades: &Facades, colors: &OpeningColors) -> usize {
    let edges = part.walls.len();
    if edges != facades.openings.len() {
        return 0; // not the footprint the facades were read on: leave the part as it is
    }
    let floors = floors(part, facades);
    let mut dropped = 0;
    let mut walls = Vec::with_capacity(edges * floors.len());
    for (storey, &lo) in floors.iter().enumerate() {
        let top_storey = storey + 1 == floors.len();
        let hi = if top_storey {
            part.eave_z
        } else {
            floors[storey + 1]
        };
        for (k, full) in part.walls.iter().enumerate() {
            let mut outline = if top_storey {
                // Keeps a gable: only the base of the outline moves up to the storey's floor.
                let mut o = full.outline.clone();
                for p in o
                    .outer
                    .iter_mut()
                    .filter(|p| (p.z - full.base_z).abs() < 1e-9)
                {
                    p.z = lo;
                }
                o
            } else {
                let at = |p: DVec2, z: f64| DVec3::new(p.x, p.y, z);
                Face::new(vec![
                    at(full.start, lo),
                    at(full.end, lo),
                    at(full.end, hi),
                    at(full.start, hi),
                ])
            };
            let len = full.length();
            let dir = if len > 0.0 {
                (full.end - full.start) / len
            } else {
                DVec2::X
            };
            let mut openings: Vec<Opening> = Vec::new();
            for f in &facades.openings[k] {
                let mid = 0.5 * (f.z0 + f.z1);
                if mid < lo || mid >= hi {
                    continue;
                }
                let o = Opening {
                    kind: f.kind,
                    u0: f.u0.max(OPENING_MARGIN),
                    u1: f.u1.min(len - OPENING_MARGIN),
                    z0: f.z0.max(lo + OPENING_MARGIN),
                    z1: f.z1.min(hi - LINTEL),
                    color: f.color.unwrap_or(match f.kind {
                        OpeningKind::Window => colors.window,
                        OpeningKind::Door => colors.door,
                    }),
                    frame_color: f.frame_color.unwrap_or(colors.frame),
                    glazed: f.glazed,
                    framed: f.framed,
                    frame_size: f.frame_size,
                    rounding: f.rounding,
                };
                // Kept or dropped on its extent as derived; the kept ones narrowed after.
                let overlaps = openings.iter().any(|q| {
                    o.u0 < q.u1 + OPENING_MARGIN
                        && q.u0 < o.u1 + OPENING_MARGIN
                        && o.z0 < q.z1 + OPENING_MARGIN
                        && q.z0 < o.z1 + OPENING_MARGIN
                });
                if o.width() < MIN_OPENING || o.height() < MIN_OPENING || overlaps {
                    dropped += 1;
                    continue;
                }
                openings.push(o);
            }
            // Jambs on grid points by the wall's line (see `along_on_grid`), each opening
            // narrowed by at most JAMB_SNAP a side.
            for o in &mut openings {
                let snap = (0.25 * o.width()).clamp(0.0, JAMB_SNAP);
                o.u0 = along_on_grid(full.start, full.end, o.u0, snap);
                o.u1 = along_on_grid(full.start, full.end, o.u1, -snap);
            }
            // No slit (issue 45): two narrow neighbours become one opening; what is still
            // narrower than the minimum once fitted is left out.
            merge_narrow(&mut openings, colors.min_width);
            let before = openings.len();
            openings.retain(|o| o.width() >= colors.min_width - 1e-9);
            dropped += before - openings.len();
            outline.holes = openings
                .iter()
                .map(|o| {
                    // The outline reversed, from the same first point.
                    let mut ring = o.outline();
                    ring[1..].reverse();
                    ring.iter()
                        .map(|p| {
                            let q = full.start + dir * p.x;
                            DVec3::new(q.x, q.y, p.y)
                        })
                        .collect()
                })
                .collect();
            let balconies = facades.balconies[k]
                .iter()
                .filter(|b| b.z0 >= lo - 1e-9 && b.z0 < hi)
                .filter_map(|b| {
                    let (u0, u1) = (b.u0.max(0.0), b.u1.min(len));
                    (u1 - u0 >= MIN_OPENING).then(|| Balcony {
                        u0,
                        u1,
                        z: b.z0,
                        depth: BALCONY_DEPTH,
                        color: b.color.unwrap_or(part.wall_color),
                    })
                })
                .collect();
            walls.push(Wall {
                start: full.start,
                end: full.end,
                base_z: lo,
                top_z: if top_storey { full.top_z } else { hi },
                thickness: full.thickness,
                outline,
                storey,
                openings,
                balconies,
                party: 0.0,
            });
        }
    }
    part.storeys = floors.len() as u32;
    part.levels = floors;
    part.walls = walls;
    dropped
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::derive::mass_nodes;
    use crate::grammar::{derive, parse, Attrs, Caps};
    use crate::rng::Rng;

    fn rect(w: f64, d: f64) -> Polygon {
        let v = DVec2::new;
        Polygon::new(vec![v(0.0, 0.0), v(w, 0.0), v(w, d), v(0.0, d)], vec![])
    }

    #[test]
    fn a_simple_facade_gives_storeys_and_one_window_per_bay() {
        let rules = parse(
            "lot -> extrude(9){building}\n\
             building -> repeat(Z, 3){floor}\n\
             floor -> comp(){front: groundfront | others: facade}\n\
             facade -> repeat(X, 2){bay}\n\
             bay -> rsplit(X, 0.25, 0.5, 0.25){wall | col | wall}\n\
             col -> rsplit(Z, 0.3, 0.5, 0.2){wall | window: material=glass, color=lightblue | wall}\n\
             groundfront -> split(X, 4, 1.2, 4.8){facade | door: color=brown | facade}\n",
            "t.cga",
        )
        .unwrap();
        let lot = rect(10.0, 6.0);
        let tree = derive(
            &rules,
            &lot,
            Attrs::new(),
            &mut Rng::new(1, 1),
            &Caps::default(),
        )
        .unwrap();
        let masses = mass_nodes(&tree);
        assert_eq!(masses.len(), 1);
        let f = facades_of(&tree, masses[0], &lot, (0.0, 9.0), 3.0);
        assert_eq!(f.levels.len(), 3);
        assert!((f.levels[1].z0 - 3.0).abs() < 1e-9 && (f.levels[2].z1 - 9.0).abs() < 1e-9);
        assert_eq!(f.off_envelope, 0);
        let doors: Vec<&FoundOpening> = f
            .openings
            .iter()
            .flatten()
            .filter(|o| o.kind == OpeningKind::Door)
            .collect();
        assert_eq!(doors.len(), 3, "one door on the front of each storey");
        // The front is the south edge (edge 0, from (0,0) to (10,0)): the door sits 4 m along it.
        assert!(f.openings[0].iter().any(|o| o.kind == OpeningKind::Door
            && (o.u0 - 4.0).abs() < 1e-9
            && (o.u1 - 5.2).abs() < 1e-9));
        let d = doors[0];
        assert_eq!(d.color, Color::parse("brown"));
        // Windows: the 6 m sides get 3 bays, the 10 m back gets 5, per storey; the front's
        // two facade pieces (4 m and 4.8 m) get 2 each.
        let windows = f
            .openings
            .iter()
            .flatten()
            .filter(|o| o.kind == OpeningKind::Window)
            .count();
        assert_eq!(windows, 3 * (3 + 3 + 5 + 2 + 2));
        for (k, ops) in f.openings.iter().enumerate() {
            let len = [10.0, 6.0, 10.0, 6.0][k];
            for o in ops {
                assert!(o.u0 >= 0.0 && o.u1 <= len + 1e-9 && o.u0 < o.u1, "{o:?}");
                assert!(o.z0 >= 0.0 && o.z1 <= 9.0 + 1e-9 && o.z0 < o.z1, "{o:?}");
            }
        }
        assert!(f.openings[1].iter().all(|o| o.glazed));
    }

    /// A window drawn as two casements side by side is one opening of both widths (before,
    /// the second casement overlapped the first's margin and was left out).
    #[test]
    fn the_panes_of_one_window_are_one_opening() {
        let pane = |u0: f64, u1: f64, z0: f64| FoundOpening {
            kind: OpeningKind::Window,
            u0,
            u1,
            z0,
            z1: z0 + 1.5,
            color: None,
            frame_color: None,
            glazed: true,
            framed: false,
            frame_size: None,
            rounding: None,
        };
        let found = vec![
            pane(2.0, 2.5, 1.0),
            pane(0.5, 1.0, 1.0),
            pane(1.0, 1.5, 1.0),
            pane(0.5, 1.0, 4.0),
        ];
        let joined = panes_joined(&found);
        assert_eq!(joined.len(), 3, "{joined:?}");
        assert_eq!((joined[0].u0, joined[0].u1), (0.5, 1.5));
        assert_eq!((joined[1].u0, joined[1].u1), (2.0, 2.5));
        assert_eq!(joined[2].z0, 4.0);
    }

    #[test]
    fn without_storeys_one_level_spans_the_wall() {
        let rules = parse("lot -> extrude(5){building}\n", "t.cga").unwrap();
        let lot = rect(8.0, 8.0);
        let tree = derive(
            &rules,
            &lot,
            Attrs::new(),
            &mut Rng::new(1, 1),
            &Caps::default(),
        )
        .unwrap();
        let f = facades_of(&tree, 1, &lot, (0.0, 5.0), 3.0);
        assert_eq!(f.levels, vec![Level { z0: 0.0, z1: 5.0 }]);
        assert!(f.openings.iter().all(Vec::is_empty));
        // No opening: the storeys fall evenly (5 m of 2.5 m floors, 12.5 m of 3 m floors).
        let f = facades_of(&tree, 1, &lot, (0.0, 5.0), 2.5);
        assert_eq!(f.levels.len(), 2);
        assert!((f.levels[1].z0 - 2.5).abs() < 1e-12);
        let f = facades_of(&tree, 1, &lot, (0.0, 12.5), 3.0);
        let floors: Vec<f64> = f.levels.iter().map(|l| l.z0).collect();
        assert_eq!(floors, vec![0.0, 3.125, 6.25, 9.375]);
        assert_eq!(f.levels.last().unwrap().z1, 12.5);
    }

    fn opening_at(z0: f64, z1: f64) -> FoundOpening {
        FoundOpening {
            kind: OpeningKind::Window,
            u0: 1.0,
            u1: 2.0,
            z0,
            z1,
            color: None,
            frame_color: None,
            glazed: true,
            framed: false,
            frame_size: None,
            rounding: None,
        }
    }

    #[test]
    fn storeys_of_a_facade_ruleset_go_between_its_windows() {
        // A 12 m wall in rows of 2.4 m, a window in each row from 0.5 to 2.0 above its sill
        // line, on two walls, one of them with a balcony across the third row's window.
        let mut f = Facades {
            openings: vec![Vec::new(), Vec::new()],
            balconies: vec![Vec::new(), Vec::new()],
            ..Facades::default()
        };
        for r in 0..5 {
            let b = 2.4 * f64::from(r);
            f.openings[0].push(opening_at(b + 0.5, b + 2.0));
            f.openings[1].push(opening_at(b + 0.6, b + 2.1));
        }
        f.balconies[1].push(FoundBalcony {
            u0: 0.0,
            u1: 3.0,
            z0: 4.8,
            z1: 6.0,
            color: None,
        });
        let levels = storeys_around_openings(&f, 0.0, 12.0, 3.0);
        // Four storeys asked (12 / 3); their even lines 3, 6, 9 each move to a free height.
        assert_eq!(levels.len(), 4, "{levels:?}");
        assert_eq!(levels[0].z0, 0.0);
        assert_eq!(levels[3].z1, 12.0);
        for w in levels.windows(2) {
            assert_eq!(w[0].z1, w[1].z0);
            assert!(w[1].z0 - w[0].z0 >= LOWEST_STOREY * 3.0);
        }
        for l in &levels[1..] {
            let crossed = f
                .openings
                .iter()
                .flatten()
                .map(|o| (o.z0, o.z1))
                .chain(f.balconies.iter().flatten().map(|b| (b.z0, b.z1)))
                .any(|(a, b)| a - OPENING_MARGIN < l.z0 && l.z0 < b + OPENING_MARGIN);
            assert!(!crossed, "floor {} crosses an opening: {levels:?}", l.z0);
        }
        // 3.0 is inside the second row's windows (2.9-4.5, blocked 2.88-4.52 with the
        // margins): it goes to the nearer end, 2.88.
        assert!(
            (levels[1].z0 - (2.9 - OPENING_MARGIN)).abs() < 1e-9,
            "{levels:?}"
        );
        // One storey asked, or a bad floor height: the whole wall.
        for fh in [5.0, 0.0, -3.0, f64::NAN, f64::INFINITY] {
            let one = storeys_around_openings(&f, 0.0, 9.0, fh);
            assert_eq!(one, vec![Level { z0: 0.0, z1: 9.0 }], "{fh}");
        }
        // A wall glazed from top to bottom: no free line, one storey.
        let mut glass = Facades {
            openings: vec![vec![opening_at(0.05, 11.95)]],
            ..Facades::default()
        };
        glass.balconies = vec![Vec::new()];
        assert_eq!(storeys_around_openings(&glass, 0.0, 12.0, 3.0).len(), 1);
    }
}

#[cfg(test)]
mod merge_tests {
    use super::*;

    fn window(u0: f64, u1: f64, z0: f64, z1: f64) -> Opening {
        Opening {
            kind: OpeningKind::Window,
            u0,
            u1,
            z0,
            z1,
            color: Color::WHITE,
            frame_color: Color::GREY,
            glazed: true,
            framed: false,
            frame_size: None,
            rounding: None,
        }
    }

    #[test]
    fn two_narrow_neighbours_merge_and_a_lone_one_does_not() {
        // 0.25 and 0.3 m panes 0.1 m apart: one 0.65 m window. A 0.3 m one 2 m off stays
        // narrow (the caller leaves it out); wide windows are never touched.
        let mut v = vec![
            window(1.0, 1.25, 1.0, 2.2),
            window(5.0, 6.2, 1.0, 2.2),
            window(1.35, 1.65, 1.05, 2.2),
            window(3.65, 3.95, 1.0, 2.2),
        ];
        assert_eq!(merge_narrow(&mut v, 0.4), 1);
        assert_eq!(v.len(), 3);
        assert_eq!((v[0].u0, v[0].u1, v[0].z0, v[0].z1), (1.0, 1.65, 1.0, 2.2));
        assert_eq!((v[1].u0, v[1].u1), (5.0, 6.2), "order kept");
        assert_eq!((v[2].u0, v[2].u1), (3.65, 3.95));
        // Not merged: a door beside a window, another row, a mullion wider than the minimum,
        // or a third opening in the way.
        let mut door = window(1.35, 1.65, 0.1, 2.2);
        door.kind = OpeningKind::Door;
        for pair in [
            vec![window(1.0, 1.25, 1.0, 2.2), door],
            vec![window(1.0, 1.25, 1.0, 2.2), window(1.35, 1.65, 1.6, 2.2)],
            vec![window(1.0, 1.25, 1.0, 2.2), window(1.7, 1.95, 1.0, 2.2)],
            vec![
                window(1.0, 1.25, 1.0, 1.5),
                window(1.35, 1.65, 1.0, 1.5),
                window(1.0, 1.65, 1.51, 2.2),
            ],
        ] {
            let mut v = pair.clone();
            assert_eq!(merge_narrow(&mut v, 0.4), 0, "{pair:?}");
            assert_eq!(v, pair);
        }
        // Three slits in a row: the first two merge, the third stays narrow.
        let mut v = vec![
            window(1.0, 1.2, 1.0, 2.0),
            window(1.3, 1.5, 1.0, 2.0),
            window(1.6, 1.8, 1.0, 2.0),
        ];
        assert_eq!(merge_narrow(&mut v, 0.4), 1);
        assert_eq!(v.len(), 2);
        assert!(v[0].width() >= 0.4 - 1e-9);
    }
}

#[cfg(test)]
mod apply_tests {
    use super::*;
    use crate::derive::massing;
    use crate::derive::{mass_nodes, masses_of};
    use crate::geometry::ring_signed_area;
    use crate::grammar::{derive, parse, Caps};
    use crate::kb::{compile, KnowledgeBase};
    use crate::model::Lod;
    use crate::rng::Rng;
    use proptest::prelude::*;

    /// Area of a planar 3D ring seen along its own normal.
    fn area3(r: &[DVec3]) -> f64 {
        0.5 * crate::geometry::newell_normal(r).length()
    }

    /// Derives `lot` with the shipped KB's rules for the zone at (lon, lat) and returns the
    /// LOD3 parts.
    fn lod3_parts(lot: &Polygon, lon: f64, lat: f64, seed: u64) -> Vec<Part> {
        let (kb, _) = KnowledgeBase::load(std::path::Path::new(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/knowledge_base/kb.xml"
        )))
        .unwrap();
        let zone = kb.locate(lon, lat);
        let mut rng = Rng::new(seed, 1);
        let (style, _) = kb.style_for(zone, &Default::default(), &mut rng);
        let rules = parse(&compile::ruleset_text(&style), "kb").unwrap();
        let tree = derive(
            &rules,
            lot,
            compile::axiom_attrs(&style),
            &mut rng,
            &Caps::default(),
        )
        .unwrap();
        let colors = OpeningColors {
            window: style.window_color,
            frame: style.frame_color,
            door: style.door_color,
            min_width: style.min_opening_width,
        };
        masses_of(&tree, &style)
            .into_iter()
            .zip(mass_nodes(&tree))
            .map(|(m, i)| {
                let f = facades_of(&tree, i, &m.footprint, (m.base_z, m.eave_z), 3.0);
                let roof = massing::roof_geometry(&m)
                    .unwrap_or_else(|_| crate::derive::roof::flat(&m.footprint));
                let mut part = massing::build_part("p0".into(), &m, &roof, Lod::Lod3);
                apply(&mut part, &f, &colors);
                part
            })
            .collect()
    }

    /// Openings inside their walls with the margin, no overlaps, one hole per opening, and the
    /// facade closed: wall area = (wall minus holes) + openings.
    fn check_facades(part: &Part) {
        assert!(!part.levels.is_empty());
        for w in &part.walls {
            let len = w.length();
            assert_eq!(w.outline.holes.len(), w.openings.len());
            for (i, o) in w.openings.iter().enumerate() {
                assert!(
                    o.u0 >= OPENING_MARGIN - 1e-9 && o.u1 <= len - OPENING_MARGIN + 1e-9,
                    "{o:?} on a {len} m wall"
                );
                assert!(
                    o.z0 >= w.base_z + OPENING_MARGIN - 1e-9
                        && o.z1 <= w.top_z - OPENING_MARGIN + 1e-9,
                    "{o:?} in {}..{}",
                    w.base_z,
                    w.top_z
                );
                for q in &w.openings[i + 1..] {
                    let apart = o.u1 + OPENING_MARGIN <= q.u0 + 1e-9
                        || q.u1 + OPENING_MARGIN <= o.u0 + 1e-9
                        || o.z1 + OPENING_MARGIN <= q.z0 + 1e-9
                        || q.z1 + OPENING_MARGIN <= o.z0 + 1e-9;
                    assert!(apart, "{o:?} overlaps {q:?}");
                }
                let hole = area3(&w.outline.holes[i]);
                assert!((hole - o.width() * o.height()).abs() < 1e-6);
                // The hole runs against the outline, i.e. its normal points into the wall.
                let n = crate::geometry::newell_normal(&w.outline.outer);
                assert!(crate::geometry::newell_normal(&w.outline.holes[i]).dot(n) < 0.0);
            }
            // Every hole point lies inside the outline's rectangle, in the wall's own plane:
            // computed from the 3D rings, not from the opening fields.
            let dir = (w.end - w.start) / len;
            let uz = |p: &DVec3| (DVec2::new(p.x, p.y) - w.start).dot(dir);
            let (umin, umax) = w
                .outline
                .outer
                .iter()
                .map(uz)
                .fold((f64::MAX, f64::MIN), |(a, b), u| (a.min(u), b.max(u)));
            let zmin = w.outline.outer.iter().map(|p| p.z).fold(f64::MAX, f64::min);
            for p in w.outline.holes.iter().flatten() {
                let off = (DVec2::new(p.x, p.y) - w.start).perp_dot(dir).abs();
                assert!(off < 1e-9, "hole point off the wall plane");
                assert!(
                    uz(p) >= umin + OPENING_MARGIN - 1e-9 && uz(p) <= umax - OPENING_MARGIN + 1e-9
                );
                assert!(
                    p.z >= zmin + OPENING_MARGIN - 1e-9 && p.z <= w.top_z - OPENING_MARGIN + 1e-9
                );
            }
        }
        // The storeys' walls stack from the base to the eave on every edge.
        let edges = part.footprint.rings().map(Vec::len).sum::<usize>();
        assert_eq!(part.walls.len(), edges * part.levels.len());
        for k in 0..edges {
            let mut z = part.base_z;
            for w in part.walls.iter().skip(k).step_by(edges) {
                assert!((w.base_z - z).abs() < 1e-9);
                z = w.top_z;
            }
            assert!((z - part.eave_z).abs() < 1e-9);
        }
    }

    #[test]
    fn toulouse_house_has_windows_a_door_and_closed_facades() {
        let v = DVec2::new;
        let lot = Polygon::new(
            vec![v(0.0, 0.0), v(20.0, 0.0), v(20.0, 12.0), v(0.0, 12.0)],
            vec![],
        );
        let parts = lod3_parts(&lot, 1.4442, 43.6045, 3);
        let part = &parts[0];
        check_facades(part);
        assert!(part.levels.len() >= 2);
        let all = || part.walls.iter().flat_map(|w| w.openings.iter());
        assert!(
            all().filter(|o| o.kind == OpeningKind::Door).count() >= 1,
            "no door"
        );
        assert!(
            all().filter(|o| o.kind == OpeningKind::Window).count() >= 10,
            "few windows"
        );
        assert!(ring_signed_area(&part.footprint.outer) > 0.0);
    }

    #[test]
    fn appearances_with_balconies_give_balconies_and_balcony_doors() {
        let v = DVec2::new;
        let lot = Polygon::new(
            vec![v(0.0, 0.0), v(24.0, 0.0), v(24.0, 14.0), v(0.0, 14.0)],
            vec![],
        );
        let mut balconies = 0;
        for seed in 0..12 {
            // Monte-Carlo's appearances ask for balconies on 30-40 % of the upper bays.
            for part in lod3_parts(&lot, 7.4275, 43.7396, seed) {
                check_facades(&part);
                for w in part.walls.iter().filter(|w| !w.balconies.is_empty()) {
                    assert!(w.storey > 0, "no balcony on the ground floor");
                    for b in &w.balconies {
                        assert!(
                            (b.z - w.base_z).abs() < 1e-9,
                            "a balcony stands at its storey's floor"
                        );
                        // Each balcony has a door above it.
                        assert!(w
                            .openings
                            .iter()
                            .any(|o| o.kind == OpeningKind::Door && o.u0 < b.u1 && b.u0 < o.u1));
                    }
                    balconies += w.balconies.len();
                }
            }
        }
        assert!(balconies > 20, "{balconies} balconies");
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(48))]
        /// Rectangles and L shapes of many sizes in several zones: openings always inside their
        /// walls and facades closed.
        #[test]
        fn openings_stay_inside_and_facades_closed(
            w in 3.0f64..40.0, d in 3.0f64..25.0, notch in 0.0f64..0.6, zone in 0usize..3, seed in 0u64..1000,
        ) {
            let v = DVec2::new;
            let lot = if notch < 0.1 {
                Polygon::new(vec![v(0.0, 0.0), v(w, 0.0), v(w, d), v(0.0, d)], vec![])
            } else {
                let (nx, ny) = (w * (1.0 - notch), d * (1.0 - notch));
                Polygon::new(vec![v(0.0, 0.0), v(w, 0.0), v(w, ny), v(nx, ny), v(nx, d), v(0.0, d)], vec![])
            };
            let (lon, lat) = [(1.4442, 43.6045), (7.4206, 43.7308), (-1.15, 52.95)][zone];
            for part in lod3_parts(&lot, lon, lat, seed) {
                check_facades(&part);
            }
        }
    }
}
