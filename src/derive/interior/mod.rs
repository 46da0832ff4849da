//! LOD4 floor plans on real footprints: rooms, circulation, a stair core aligned across
//! storeys, interior walls as shared segments and doors on them (issue 8, build points 1-2).
//!
//! The module is self-contained: it takes a storey polygon (local metres, outer ring CCW, holes
//! CW; concave and holed footprints allowed), the storey count and height, the `building=*`
//! value (or a programme set by the knowledge base) and a seeded [`Rng`], and returns a
//! [`BuildingPlan`]. It never panics and never fails: a footprint too small or too odd for a
//! plan gets the documented fallback (see [`Fallback`]).
//!
//! # Algorithm
//!
//! 1. **Frame.** The front is `front` (outward direction) or the outward normal of the longest
//!    outer edge. All work happens in a frame with `y` pointing into the building from the
//!    front, so "low y" is the street side.
//! 2. **Usable area.** The footprint is inset by the exterior wall thickness (the model's walls
//!    are that thick towards the inside, see `massing::WALL_THICKNESS`) with `geo`'s buffer
//!    (mitred). When the inset splits the footprint, the largest piece is kept; when nothing
//!    is left, the footprint itself is used ([`Fallback::NoInset`]). Rooms partition this
//!    [`BuildingPlan::usable`] polygon exactly.
//! 3. **Stair core** (more than one storey). A rectangle sized from the storey height (risers
//!    ≤ 0.18 m, goings 0.27 m; flights 0.9 m wide in houses, RGEU Art. 46 asks ≥ 0.80 m, 1.2 m
//!    elsewhere): a dog-leg stair, else a straight flight, else a 1.6 m spiral, placed at the
//!    nearest grid position to a target point (the centroid, or beside the corridor) where it
//!    lies inside the usable polygon. The same rectangle is cut out of every storey and is a
//!    room of kind [`RoomKind::Stair`] on each. No position fits: one storey is planned
//!    ([`Fallback::NoStair`]).
//! 4. **Circulation and units.** Large storeys (≥ 150 m², both frame extents ≥ 9 m) of
//!    apartments, offices and shops get a corridor (1.4-1.6 m) along their longer axis, on the
//!    line that halves the area; the stair sits against it, and on the ground floor an entrance
//!    hall (2 m) joins the front to the corridor when the corridor runs parallel to the front.
//!    The two sides are cut across the corridor into units (flats of about 85 m², office cells
//!    of about 18 m², shops of about 60 m²), so every unit touches the corridor on a convex
//!    side. Smaller storeys are one unit: a dwelling (its own hall) or a reception with cells.
//! 5. **Rooms.** Each unit's programme (below) is laid out by a weighted treemap on the polygon
//!    (seeds 002/004 §3.3): the list is split where the area halves, the region is cut
//!    perpendicular to its longer extent at the position where the area below the cut equals
//!    the first group's share (found by bisection on an exact half-plane area), and each side
//!    recurses. Public rooms come first in the list, so they land on the front side.
//! 6. **Clean-up.** A leaf that comes out as a multipolygon (concave footprints) becomes one
//!    room per piece; a room with a hole (a courtyard or the stair inside it) is cut through
//!    the hole until it is simple; pieces smaller than 1 m² or thinner than about 0.6 m are
//!    merged into the neighbour with the longest shared wall (never into the stair).
//! 7. **Doors.** Shared walls are the overlaps of collinear room edges. Doors grow a spanning
//!    tree from the entrance room (ground floor) or the stair (upper floors), Prim-style: the
//!    next door is the one on a wall of at least 1.2 m (0.8 m as a last resort, with a narrower
//!    leaf) that stays within one dwelling, leaves from the best passage room (circulation,
//!    then living rooms, kitchens, bedrooms, bathrooms last: seed 001, L91) and has the longest
//!    wall. A room that no door reaches is merged into a neighbour and the doors are grown
//!    again. The entrance is on the longest front-facing part of the outer boundary of the
//!    best circulation room (common parts before a dwelling's own hall).
//!
//! # Programmes
//!
//! `Programme::for_building` maps `building=*`; the knowledge base may override it.
//! Dwellings follow seed 001: the typology Tx (x bedrooms) is the largest whose RGEU Art. 67
//! gross area fits the dwelling's usable area, rooms start at the RGEU Art. 66 minimum and the
//! surplus is shared by weight. When the minimums do not fit the area, they are dropped for
//! that storey (the programme is beyond the area; such rooms carry no `min_area`). A house
//! keeps hall, living room, kitchen and WC on the ground floor and spreads the bedrooms and a
//! bathroom over the upper floors; a flat holds everything on one storey.
//!
//! RGEU minimum areas used (m²), from the seed notes `docs/seeds/001-houses.md`, Appendix A
//! ("Art. 66 n.º 1", "Art. 67", "Art. 68"; external and marked unverified there):
//!
//! | Type | Gross (Art. 67) | Bedrooms (Art. 66)       | Living | Kitchen | Sanitary (Art. 68)      |
//! |------|-----------------|--------------------------|--------|---------|-------------------------|
//! | T0   | 35              | –                        | 10     | 6       | 3.5                     |
//! | T1   | 52              | 10.5                     | 10     | 6       | 3.5                     |
//! | T2   | 72              | 10.5, 9                  | 12     | 6       | 3.5                     |
//! | T3   | 91              | 10.5, 9, 9               | 12     | 6       | 4.5 in two: 3.0 + 1.5   |
//! | T4   | 105             | 10.5, 9, 9, 6.5          | 12     | 6       | 4.5 in two: 3.0 + 1.5   |
//! | T5   | 122             | 10.5, 9, 9, 9, 6.5       | 16     | 6       | 6 in two: 3.5 + 2.5     |
//!
//! The split of the two-space sanitary totals is ours. Halls and landings are not RGEU rooms
//! (Art. 66 n.º 2); they get a 2.5 m² floor. Below T0 (35 m²) a dwelling is a studio without
//! legal minimums. Other programmes: offices get a reception, cells and a WC (or corridor
//! cells on large storeys, the smallest cell being the WC); retail gets a shop, storage and a
//! WC; open plan is one room per storey.
//!
//! # Conventions for writers
//!
//! Everything is in the input's local frame (metres). Room polygons are simple (no holes),
//! CCW, and meet along interior wall centre lines: [`Wall`]s are the shared segments, each
//! listed once with the two rooms it separates, so a writer can give them thickness centred
//! on the segment. Exterior walls are not listed (they are the model's walls); rooms stop at
//! their inner face. The entrance door lies on the usable polygon's outer ring (the inner face
//! of the exterior wall) and crosses the wall along its outward normal.

mod doors;
mod geom;
mod planner;
mod programme;
#[cfg(test)]
mod tests;
pub(crate) mod to_model;

use geo::{BooleanOps, Buffer};
use glam::DVec2;

use crate::geometry::Polygon;
use crate::rng::Rng;
use doors::*;
use geom::{Axis, GMulti};
use planner::*;
pub use programme::{typology, Programme, RoomKind, RGEU_GROSS};
use programme::{DwellingPart, Item};

/// Everything a plan needs for one building (or building part).
#[derive(Clone, Debug)]
pub struct PlanInput<'a> {
    /// The storey outline (local metres, outer CCW, holes CW), the same for every storey.
    pub footprint: &'a Polygon,
    /// Storeys above ground (0 is treated as 1; capped at 200).
    pub storeys: u32,
    /// Floor-to-floor height (metres); sizes the stair. Non-finite or ≤ 0 means 3 m.
    pub storey_height: f64,
    /// `building=*` value (`yes`, `house`, `apartments`, `office`, ...).
    pub building: Option<&'a str>,
    /// A programme set by the knowledge base; overrides `building`.
    pub programme: Option<Programme>,
    /// Outward direction of the front facade (the entrance side); `None`: the longest edge.
    pub front: Option<DVec2>,
    /// Exterior wall thickness (metres), inset from the footprint; non-finite or < 0 means 0.
    pub wall_thickness: f64,
}

/// One room (an `IfcSpace`, a CityGML `bldg:Room`).
#[derive(Clone, Debug, PartialEq)]
pub struct Room {
    /// Simple polygon (no holes, CCW) inside [`BuildingPlan::usable`].
    pub polygon: Polygon,
    /// What the room is used for (its IFC `LongName` and CityGML `function`).
    pub kind: RoomKind,
    /// Display name, unique within a dwelling ("Flat 2 Bedroom 1", "Office 3", "Stair").
    pub name: String,
    /// The dwelling or tenancy the room belongs to; `None` for common parts (corridor, stair,
    /// entrance hall) and for single-unit storeys.
    pub unit: Option<usize>,
    /// The legal minimum area (RGEU) this room must meet, when its programme fits the storey.
    pub min_area: Option<f64>,
}

impl Room {
    /// Floor area (m²).
    pub fn area(&self) -> f64 {
        self.polygon.area()
    }
}

/// A door on a wall between two rooms, or between a room and the outside (the entrance).
#[derive(Clone, Debug, PartialEq)]
pub struct Door {
    /// Room index (into [`StoreyPlan::rooms`]) on the side the door was reached from.
    pub a: usize,
    /// The other room; `None` for the entrance (outside).
    pub b: Option<usize>,
    /// The door's opening on the wall centre line (interior) or on the usable polygon's outer
    /// ring (entrance); its length is `width`.
    pub segment: (DVec2, DVec2),
    /// Clear width (metres): 0.9 inside and 1.0 for the entrance; less on short walls (≥ 0.6
    /// inside; an entrance on a round wall of short edges takes the edge less 0.1 m, ≥ 0.5).
    pub width: f64,
}

/// An interior wall: one straight piece of boundary shared by two rooms, listed once.
#[derive(Clone, Debug, PartialEq)]
pub struct Wall {
    /// Index (into [`StoreyPlan::rooms`]) of the room on one side.
    pub a: usize,
    /// Index of the room on the other side.
    pub b: usize,
    /// The shared segment on the wall centre line (local metres); writers centre the wall's
    /// thickness on it.
    pub segment: (DVec2, DVec2),
}

/// One storey's plan.
#[derive(Clone, Debug, PartialEq)]
pub struct StoreyPlan {
    /// The rooms: they partition [`BuildingPlan::usable`].
    pub rooms: Vec<Room>,
    /// Interior walls, each shared segment once.
    pub walls: Vec<Wall>,
    /// Interior doors (`b` is always `Some`).
    pub doors: Vec<Door>,
    /// The entrance (ground floor only): `b` is `None`.
    pub entrance: Option<Door>,
    /// Index of the stair room, when the building has a stair core.
    pub stair_room: Option<usize>,
}

/// The shape of the stair core.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StairForm {
    /// Two flights side by side with a half landing (U-shaped).
    DogLeg,
    /// One straight flight.
    Straight,
    /// A spiral stair in a square well.
    Spiral,
}

/// The stair core, identical on every storey.
#[derive(Clone, Debug, PartialEq)]
pub struct StairCore {
    /// The rectangle (the stair room's polygon on every storey).
    pub polygon: Polygon,
    /// Dog-leg, straight or spiral.
    pub form: StairForm,
    /// Flight width (metres).
    pub flight_width: f64,
    /// Risers per storey.
    pub risers: u32,
    /// Height of one riser (metres): the storey height over [`StairCore::risers`], at most
    /// 0.18 m.
    pub riser_height: f64,
    /// Going (tread depth, metres).
    pub going: f64,
    /// Direction of the first flight's climb (unit vector in the local frame).
    pub up: DVec2,
}

/// Why a plan is simpler than its programme.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Fallback {
    /// The footprint vanished when inset by the wall thickness: rooms use the footprint itself.
    NoInset,
    /// The usable area is under 6 m²: one room per storey, no stair.
    TooSmall,
    /// No stair fits: only the ground storey is planned (`storeys` has one entry).
    NoStair,
    /// The layout failed its own checks: each storey is the usable polygon cut at its holes
    /// into open rooms.
    Simplified,
}

/// The floor plans of one building.
#[derive(Clone, Debug, PartialEq)]
pub struct BuildingPlan {
    /// The usable storey polygon (the footprint inset by the wall thickness): the rooms of each
    /// storey partition it.
    pub usable: Polygon,
    /// The layout family the plan follows (from `building=*` or the knowledge base).
    pub programme: Programme,
    /// The stair core, the same on every storey; `None` for one storey or when none fits.
    pub stair: Option<StairCore>,
    /// Ground floor first.
    pub storeys: Vec<StoreyPlan>,
    /// Set when a simpler plan was produced.
    pub fallback: Option<Fallback>,
}

/// Below this usable area a storey is one room (m²).
const MIN_PLAN_AREA: f64 = 6.0;
/// Interior door: leaf width and the wall it needs (leaf + 0.15 m each side).
const DOOR_WIDTH: f64 = 0.9;
const DOOR_WALL: f64 = 1.2;
/// Shortest wall that can hold a (narrowed) door.
const MIN_DOOR_WALL: f64 = 0.8;
const ENTRANCE_WIDTH: f64 = 1.0;
/// Shortest outer wall that can hold a (narrowed) entrance: round buildings drawn with short
/// edges get an entrance as wide as one edge allows (edge - 0.1 m).
const MIN_ENTRANCE_WALL: f64 = 0.6;
/// Pieces under this area are merged into a neighbour (m²).
const SLIVER_AREA: f64 = 1.0;
/// Pieces thinner than this (twice area over perimeter) are merged (m).
const SLIVER_WIDTH: f64 = 0.3;

/// The plan frame: `x` along the front, `y` into the building.
#[derive(Clone, Copy, Debug)]
struct Frame {
    o: DVec2,
    u: DVec2,
    v: DVec2,
}

impl Frame {
    fn to_local(self, p: DVec2) -> DVec2 {
        DVec2::new((p - self.o).dot(self.u), (p - self.o).dot(self.v))
    }
    fn to_world(self, q: DVec2) -> DVec2 {
        self.o + self.u * q.x + self.v * q.y
    }
    fn poly_local(&self, p: &Polygon) -> Polygon {
        Polygon::new(
            p.outer.iter().map(|q| self.to_local(*q)).collect(),
            p.holes
                .iter()
                .map(|h| h.iter().map(|q| self.to_local(*q)).collect())
                .collect(),
        )
    }
    fn poly_world(&self, p: &Polygon) -> Polygon {
        Polygon {
            outer: p.outer.iter().map(|q| self.to_world(*q)).collect(),
            holes: p
                .holes
                .iter()
                .map(|h| h.iter().map(|q| self.to_world(*q)).collect())
                .collect(),
        }
    }
}

fn frame_for(footprint: &Polygon, front: Option<DVec2>) -> Frame {
    let o = footprint.outer.first().copied().unwrap_or(DVec2::ZERO);
    let o = DVec2::new(o.x.round(), o.y.round());
    let mut n = front
        .filter(|f| f.is_finite() && f.length() > 1e-9)
        .map(|f| f.normalize());
    if n.is_none() {
        let r = &footprint.outer;
        let mut best = (0.0, DVec2::new(0.0, -1.0));
        for i in 0..r.len() {
            let d = r[(i + 1) % r.len()] - r[i];
            let l = d.length();
            if l.is_finite() && l > best.0 {
                // Outward normal of a CCW ring: the edge direction turned clockwise.
                best = (l, DVec2::new(d.y, -d.x) / l);
            }
        }
        n = Some(best.1);
    }
    let v = -n.unwrap_or(DVec2::new(0.0, -1.0));
    let u = DVec2::new(v.y, -v.x);
    Frame { o, u, v }
}

/// Plans every storey of one building. Deterministic for a given input and generator state;
/// never panics. See the module documentation for the algorithm and the fallbacks.
pub fn plan_building(input: &PlanInput, rng: &mut Rng) -> BuildingPlan {
    let storeys = input.storeys.clamp(1, 200) as usize;
    let height = if input.storey_height.is_finite() && input.storey_height > 0.0 {
        input.storey_height.min(20.0)
    } else {
        3.0
    };
    let wall = if input.wall_thickness.is_finite() && input.wall_thickness > 0.0 {
        input.wall_thickness
    } else {
        0.0
    };
    let footprint_ok = input
        .footprint
        .rings()
        .all(|r| r.iter().all(|p| p.is_finite()))
        && input.footprint.outer.len() >= 3
        && input.footprint.area() > 0.0;
    if !footprint_ok {
        return BuildingPlan {
            usable: input.footprint.clone(),
            programme: input.programme.unwrap_or(Programme::OpenPlan),
            stair: None,
            storeys: Vec::new(),
            fallback: Some(Fallback::TooSmall),
        };
    }
    let frame = frame_for(input.footprint, input.front);
    let local = frame.poly_local(input.footprint);
    let mut fallback = None;
    let usable = match inset(&local, wall) {
        Some(u) => u,
        None => {
            fallback = Some(Fallback::NoInset);
            local.clone()
        }
    };
    let area = usable.area();
    let programme = input
        .programme
        .unwrap_or_else(|| Programme::for_building(input.building, area * storeys as f64));
    let mut plan = Planner {
        usable: usable.clone(),
        region: GMulti::new(vec![geom::to_geo(&usable)]),
        programme,
        stair: None,
        spine: None,
    };
    let mut storeys_out = Vec::new();
    if area < MIN_PLAN_AREA {
        fallback = Some(Fallback::TooSmall);
        storeys_out.push(plan.simple_storey(true));
    } else {
        plan.spine = plan.spine_for();
        let mut stair = None;
        if storeys > 1 {
            stair = plan.place_stair(height);
            if stair.is_none() {
                fallback = Some(Fallback::NoStair);
            }
        }
        let levels = if stair.is_some() { storeys } else { 1 };
        plan.stair = stair;
        let house_t = (programme == Programme::House).then(|| {
            let stair_area = plan.stair.as_ref().map_or(0.0, |s| s.polygon.area());
            let total = (area - stair_area) * levels as f64;
            let t = typology(total).unwrap_or(0).min(5);
            if levels > 1 {
                t.max((levels - 1).min(5))
            } else {
                t
            }
        });
        for level in 0..levels {
            // Storeys above the first upper one repeat it unless a house spreads its bedrooms.
            if level >= 2 && programme != Programme::House {
                let prev: StoreyPlan = storeys_out[1].clone();
                storeys_out.push(prev);
                continue;
            }
            let items = plan.storey_items(level, levels, house_t);
            match plan.layout(level, &items, rng) {
                Some(s) => storeys_out.push(s),
                None => {
                    fallback = fallback.or(Some(Fallback::Simplified));
                    storeys_out.push(plan.simple_storey(level == 0));
                }
            }
        }
    }
    let to_world = |s: &mut StoreyPlan| {
        for r in &mut s.rooms {
            r.polygon = frame.poly_world(&r.polygon);
        }
        for w in &mut s.walls {
            w.segment = (frame.to_world(w.segment.0), frame.to_world(w.segment.1));
        }
        for d in s.doors.iter_mut().chain(s.entrance.iter_mut()) {
            d.segment = (frame.to_world(d.segment.0), frame.to_world(d.segment.1));
        }
    };
    for s in &mut storeys_out {
        to_world(s);
    }
    let stair = plan.stair.map(|mut s| {
        s.polygon = frame.poly_world(&s.polygon);
        s.up = frame.u * s.up.x + frame.v * s.up.y;
        s
    });
    BuildingPlan {
        usable: frame.poly_world(&usable),
        programme,
        stair,
        storeys: storeys_out,
        fallback,
    }
}

/// The footprint inset by `d` (largest piece), or `None` when nothing usable is left.
fn inset(p: &Polygon, d: f64) -> Option<Polygon> {
    if d <= 0.0 {
        return Some(p.clone());
    }
    let style = geo::algorithm::buffer::BufferStyle::new(-d).line_join(
        geo::algorithm::buffer::LineJoin::Miter(0.1 * std::f64::consts::PI),
    );
    let m = geom::to_geo(p).buffer_with_style(style);
    let best =
        m.0.iter()
            .map(geom::from_geo)
            .filter(|q| q.outer.len() >= 3)
            .max_by(|a, b| a.area().total_cmp(&b.area()))?;
    (best.area() >= 1.0).then_some(best)
}
