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
//! [`Programme::for_building`] maps `building=*`; the knowledge base may override it.
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

mod geom;
mod programme;
#[cfg(test)]
mod tests;
pub(crate) mod to_model;

use geo::{BooleanOps, Buffer};
use glam::DVec2;

use crate::geometry::Polygon;
use crate::rng::Rng;
use geom::{Axis, GMulti};
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
    pub a: usize,
    pub b: usize,
    pub segment: (DVec2, DVec2),
}

/// One storey's plan.
#[derive(Clone, Debug, PartialEq)]
pub struct StoreyPlan {
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
    pub form: StairForm,
    /// Flight width (metres).
    pub flight_width: f64,
    /// Risers per storey and their height (metres).
    pub risers: u32,
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
    pub programme: Programme,
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

/// A corridor along `axis` between `lo` and `hi` on the other axis.
#[derive(Clone, Copy, Debug)]
struct Spine {
    axis: Axis,
    lo: f64,
    hi: f64,
}

/// A room in the making (frame coordinates).
#[derive(Clone, Debug)]
struct Proto {
    kind: RoomKind,
    name: String,
    unit: Option<usize>,
    min_area: Option<f64>,
    poly: Polygon,
}

struct Planner {
    usable: Polygon,
    region: GMulti,
    programme: Programme,
    stair: Option<StairCore>,
    spine: Option<Spine>,
}

fn perimeter(r: &[DVec2]) -> f64 {
    (0..r.len())
        .map(|i| r[i].distance(r[(i + 1) % r.len()]))
        .sum()
}

/// Ring bounds (min, max).
fn ring_bounds(r: &[DVec2]) -> (DVec2, DVec2) {
    r.iter().fold(
        (DVec2::splat(f64::INFINITY), DVec2::splat(f64::NEG_INFINITY)),
        |(lo, hi), p| (lo.min(*p), hi.max(*p)),
    )
}

impl Planner {
    /// A corridor for large storeys of multi-unit programmes.
    fn spine_for(&self) -> Option<Spine> {
        if !matches!(
            self.programme,
            Programme::Apartments | Programme::Office | Programme::Retail
        ) {
            return None;
        }
        let (lo, hi) = self.usable.bounds();
        let ext = hi - lo;
        if self.usable.area() < 150.0 || ext.x < 9.0 || ext.y < 9.0 {
            return None;
        }
        // The corridor runs along the longer extent; it sits on the line that halves the area.
        let (axis, across) = if ext.x >= ext.y {
            (Axis::X, Axis::Y)
        } else {
            (Axis::Y, Axis::X)
        };
        let c = geom::cut_at_fraction(&self.region, across, 0.5);
        let w = if self.programme == Programme::Office {
            1.6
        } else {
            1.4
        };
        Some(Spine {
            axis,
            lo: c - 0.5 * w,
            hi: c + 0.5 * w,
        })
    }

    /// Finds the stair core: the first form that fits, nearest to the target point.
    fn place_stair(&self, height: f64) -> Option<StairCore> {
        let risers = ((height / 0.18).ceil() as u32).clamp(3, 120);
        let going = 0.27;
        let fw = if self.programme == Programme::House {
            0.9
        } else {
            1.2
        };
        let half = risers.div_ceil(2) as f64;
        let forms = [
            (
                StairForm::DogLeg,
                DVec2::new(2.0 * fw + 0.1, half * going + fw),
            ),
            (
                StairForm::Straight,
                DVec2::new(fw, risers as f64 * going + 0.3),
            ),
            (StairForm::Spiral, DVec2::new(1.6, 1.6)),
        ];
        let (lo, hi) = self.usable.bounds();
        let centroid = {
            let c = geo::Centroid::centroid(&self.region);
            c.map_or(0.5 * (lo + hi), |p| DVec2::new(p.x(), p.y()))
        };
        for (form, size) in forms {
            let mut best: Option<(f64, DVec2, DVec2)> = None;
            for dims in [size, DVec2::new(size.y, size.x)] {
                // Target: beside the corridor (on its far side), else the centroid.
                let target_lo = match self.spine {
                    Some(s) if s.axis == Axis::X => DVec2::new(centroid.x - 0.5 * dims.x, s.hi),
                    Some(s) => DVec2::new(s.hi, centroid.y - 0.5 * dims.y),
                    None => centroid - 0.5 * dims,
                };
                if let Some(p) = self.nearest_fit(target_lo, dims, lo, hi) {
                    let d = p.distance(target_lo);
                    if best.is_none_or(|b| d < b.0) {
                        best = Some((d, p, dims));
                    }
                }
            }
            if let Some((_, p, dims)) = best {
                let q = p + dims;
                let polygon = Polygon::new(
                    vec![p, DVec2::new(q.x, p.y), q, DVec2::new(p.x, q.y)],
                    vec![],
                );
                let up = if dims.y >= dims.x { DVec2::Y } else { DVec2::X };
                return Some(StairCore {
                    polygon,
                    form,
                    flight_width: if form == StairForm::Spiral { 0.7 } else { fw },
                    risers,
                    riser_height: height / risers as f64,
                    going,
                    up,
                });
            }
        }
        None
    }

    /// The grid position (lower corner) nearest `target` where a `dims` rectangle fits.
    fn nearest_fit(&self, target: DVec2, dims: DVec2, lo: DVec2, hi: DVec2) -> Option<DVec2> {
        if dims.x > hi.x - lo.x || dims.y > hi.y - lo.y {
            return None;
        }
        let ext = (hi - lo).max_element();
        let step = (ext / 60.0).max(0.25);
        let axis_positions = |t: f64, a: f64, b: f64| -> Vec<f64> {
            // Positions t + k*step within [a, b], plus the two ends.
            let mut v = vec![a, b];
            let k0 = ((a - t) / step).ceil() as i64;
            let k1 = ((b - t) / step).floor() as i64;
            for k in k0.max(-400)..=k1.min(400) {
                v.push(t + k as f64 * step);
            }
            v
        };
        let xs = axis_positions(target.x, lo.x, hi.x - dims.x);
        let ys = axis_positions(target.y, lo.y, hi.y - dims.y);
        let mut cand: Vec<(f64, DVec2)> = Vec::with_capacity(xs.len() * ys.len());
        for &x in &xs {
            for &y in &ys {
                let p = DVec2::new(x, y);
                cand.push((p.distance_squared(target), p));
            }
        }
        cand.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.x.total_cmp(&b.1.x)));
        cand.into_iter()
            .map(|c| c.1)
            .find(|p| geom::rect_inside(&self.usable, *p, *p + dims))
    }

    /// The room list of a single-unit storey (or of a house storey).
    fn storey_items(&self, level: usize, levels: usize, house_t: Option<usize>) -> Vec<Item> {
        match self.programme {
            Programme::House => {
                let t = house_t;
                let part = if levels == 1 {
                    DwellingPart::Whole
                } else if level == 0 {
                    DwellingPart::Ground
                } else {
                    let x = t.unwrap_or(0);
                    let uppers = levels - 1;
                    let per = x.div_ceil(uppers.max(1));
                    let first = ((level - 1) * per).min(x);
                    DwellingPart::Upper {
                        first,
                        count: per.min(x - first),
                    }
                };
                programme::dwelling(t, part, "")
            }
            _ => Vec::new(),
        }
    }

    /// The storey's usable region without the stair.
    fn free_region(&self) -> GMulti {
        match &self.stair {
            Some(s) => self
                .region
                .difference(&GMulti::new(vec![geom::to_geo(&s.polygon)])),
            None => self.region.clone(),
        }
    }

    /// Lays out one storey; `None` when the result fails its own checks.
    fn layout(&self, level: usize, house_items: &[Item], rng: &mut Rng) -> Option<StoreyPlan> {
        let free = self.free_region();
        let free_area = geom::garea(&free);
        let mut leaves: Vec<(Item, Option<usize>, GMulti)> = Vec::new();
        if let Some(sp) = self.spine {
            self.spine_layout(level, sp, &free, rng, &mut leaves);
        } else {
            let mut items: Vec<Item> = match self.programme {
                Programme::House => house_items.to_vec(),
                _ => self.unit_items(free_area, "", rng),
            };
            programme::distribute(&mut items, free_area, rng);
            let areas: Vec<f64> = items.iter().map(|i| i.area).collect();
            let parts = treemap(&free, &areas, None);
            for (it, g) in items.into_iter().zip(parts) {
                leaves.push((it, None, g));
            }
        }
        let mut protos = explode(leaves);
        if let Some(s) = &self.stair {
            protos.push(Proto {
                kind: RoomKind::Stair,
                name: "Stair".into(),
                unit: None,
                min_area: None,
                poly: s.polygon.clone(),
            });
        }
        finish(&self.usable, protos, level == 0)
    }

    /// Items for one unit (or a single-unit storey) of the non-house programmes.
    fn unit_items(&self, area: f64, unit: &str, _rng: &mut Rng) -> Vec<Item> {
        let mk = |kind: RoomKind, name: String, w: f64| programme::item(kind, name, w);
        let pre = |s: &str| {
            if unit.is_empty() {
                s.to_string()
            } else {
                format!("{unit} {s}")
            }
        };
        if area < 12.0 {
            let kind = match self.programme {
                Programme::Office => RoomKind::Office,
                Programme::Retail => RoomKind::Shop,
                Programme::Apartments | Programme::House => RoomKind::Living,
                Programme::OpenPlan => RoomKind::OpenPlan,
            };
            return vec![mk(kind, pre(kind.label()), 1.0)];
        }
        match self.programme {
            Programme::Apartments | Programme::House => {
                programme::dwelling(typology(area), DwellingPart::Whole, unit)
            }
            Programme::Office => {
                let n = ((area / 16.0).round() as usize).clamp(1, 8);
                let mut v = vec![mk(RoomKind::Hall, pre("Reception"), 1.0)];
                for i in 0..n {
                    v.push(mk(RoomKind::Office, pre(&format!("Office {}", i + 1)), 1.5));
                }
                v.push(mk(RoomKind::Wc, pre("WC"), 0.2));
                v
            }
            Programme::Retail => {
                let mut v = vec![
                    mk(RoomKind::Shop, pre("Shop"), 5.0),
                    mk(RoomKind::Storage, pre("Storage"), 0.8),
                ];
                if area >= 40.0 {
                    v.push(mk(RoomKind::Wc, pre("WC"), 0.2));
                }
                v
            }
            Programme::OpenPlan => vec![mk(RoomKind::OpenPlan, pre("Open plan"), 1.0)],
        }
    }

    /// Corridor, entrance hall and units cut across the corridor.
    fn spine_layout(
        &self,
        level: usize,
        sp: Spine,
        free: &GMulti,
        rng: &mut Rng,
        leaves: &mut Vec<(Item, Option<usize>, GMulti)>,
    ) {
        let across = match sp.axis {
            Axis::X => Axis::Y,
            Axis::Y => Axis::X,
        };
        let corridor = geom::band(free, across, sp.lo, sp.hi);
        let (low, _) = geom::split(free, across, sp.lo);
        let (_, high) = geom::split(free, across, sp.hi);
        let mut low = low;
        if level == 0 && sp.axis == Axis::X {
            // An entrance hall from the front to the corridor, in line with the stair.
            let (blo, _) = self.usable.bounds();
            let cx = self.stair.as_ref().map_or_else(
                || {
                    let (a, b) = geom::gbounds(free);
                    0.5 * (a.x + b.x)
                },
                |s| {
                    let (a, b) = ring_bounds(&s.polygon.outer);
                    0.5 * (a.x + b.x)
                },
            );
            let r = geom::rect(
                DVec2::new(cx - 1.0, blo.y - 1.0),
                DVec2::new(cx + 1.0, sp.lo),
            );
            let hall = low.intersection(&GMulti::new(vec![r]));
            if geom::garea(&hall) > 1.0 {
                low = low.difference(&hall);
                leaves.push((
                    programme::item(RoomKind::Hall, "Entrance hall".into(), 1.0),
                    None,
                    hall,
                ));
            }
        }
        leaves.push((
            programme::item(RoomKind::Corridor, "Corridor".into(), 1.0),
            None,
            corridor,
        ));
        let target = match self.programme {
            Programme::Office => 18.0,
            Programme::Retail => 60.0,
            _ => 85.0,
        };
        let mut unit_no = 0usize;
        let mut cells: Vec<(Item, Option<usize>, GMulti)> = Vec::new();
        for side in [low, high] {
            for piece in side.0 {
                let piece = GMulti::new(vec![piece]);
                let a = geom::garea(&piece);
                if a < 1e-6 {
                    continue;
                }
                let n = ((a / target).round() as usize).max(1);
                let weights: Vec<f64> = (0..n).map(|_| rng.range(0.85, 1.15)).collect();
                let units = treemap(&piece, &weights, Some(sp.axis));
                for u in units {
                    let ua = geom::garea(&u);
                    if ua < 1e-6 {
                        continue;
                    }
                    unit_no += 1;
                    match self.programme {
                        Programme::Apartments | Programme::House => {
                            let label = format!("Flat {unit_no}");
                            let mut items = self.unit_items(ua, &label, rng);
                            programme::distribute(&mut items, ua, rng);
                            let areas: Vec<f64> = items.iter().map(|i| i.area).collect();
                            let parts = treemap(&u, &areas, None);
                            for (it, g) in items.into_iter().zip(parts) {
                                leaves.push((it, Some(unit_no), g));
                            }
                        }
                        Programme::Office => cells.push((
                            programme::item(RoomKind::Office, format!("Office {unit_no}"), 1.0),
                            Some(unit_no),
                            u,
                        )),
                        _ => {
                            let kind = if self.programme == Programme::Retail {
                                RoomKind::Shop
                            } else {
                                RoomKind::OpenPlan
                            };
                            leaves.push((
                                programme::item(kind, format!("{} {unit_no}", kind.label()), 1.0),
                                Some(unit_no),
                                u,
                            ))
                        }
                    }
                }
            }
        }
        // The smallest office cell is the storey's WC.
        if let Some(i) = (0..cells.len())
            .min_by(|a, b| geom::garea(&cells[*a].2).total_cmp(&geom::garea(&cells[*b].2)))
        {
            if cells.len() > 2 {
                cells[i].0 = programme::item(RoomKind::Wc, "WC".into(), 1.0);
                cells[i].1 = None;
            }
        }
        leaves.extend(cells);
    }

    /// The fallback storey: the usable polygon (minus the stair) cut at its holes into open
    /// rooms, with doors.
    fn simple_storey(&self, ground: bool) -> StoreyPlan {
        let free = self.free_region();
        let kind = match self.programme {
            Programme::Apartments | Programme::House => RoomKind::Living,
            Programme::Office => RoomKind::Office,
            Programme::Retail => RoomKind::Shop,
            Programme::OpenPlan => RoomKind::OpenPlan,
        };
        let mut protos = explode(vec![(
            programme::item(kind, kind.label().into(), 1.0),
            None,
            free,
        )]);
        if let Some(s) = &self.stair {
            protos.push(Proto {
                kind: RoomKind::Stair,
                name: "Stair".into(),
                unit: None,
                min_area: None,
                poly: s.polygon.clone(),
            });
        }
        finish(&self.usable, protos.clone(), ground).unwrap_or_else(|| {
            // Even the graph failed: rooms without doors (reported by the checks).
            let (rooms, stair_room) = to_rooms(protos);
            StoreyPlan {
                rooms,
                walls: Vec::new(),
                doors: Vec::new(),
                entrance: None,
                stair_room,
            }
        })
    }
}

/// Weighted treemap of `region` into one piece per weight, in order (seeds 002/004 §3.3, with
/// bisection): the list is split where its weight halves, the region is cut perpendicular to
/// its longer extent (or across `fixed`'s lines) so that the area below the cut matches the
/// first group's share, and both sides recurse.
fn treemap(region: &GMulti, weights: &[f64], fixed: Option<Axis>) -> Vec<GMulti> {
    let n = weights.len();
    if n == 0 {
        return Vec::new();
    }
    if n == 1 {
        return vec![region.clone()];
    }
    let w: Vec<f64> = weights
        .iter()
        .map(|x| if x.is_finite() && *x > 0.0 { *x } else { 1e-6 })
        .collect();
    let total: f64 = w.iter().sum();
    let mut k = 1;
    let mut acc = w[0];
    let mut best = ((acc - 0.5 * total).abs(), 1);
    for (i, x) in w.iter().enumerate().take(n - 1).skip(1) {
        acc += x;
        let d = (acc - 0.5 * total).abs();
        if d < best.0 {
            best = (d, i + 1);
        }
    }
    k = k.max(best.1);
    let frac = w[..k].iter().sum::<f64>() / total;
    let (lo, hi) = geom::gbounds(region);
    if !(lo.is_finite() && hi.is_finite()) {
        return vec![GMulti::new(Vec::new()); n];
    }
    let axis = fixed.unwrap_or(if hi.x - lo.x >= hi.y - lo.y {
        Axis::X
    } else {
        Axis::Y
    });
    let t = geom::cut_at_fraction(region, axis, frac);
    let (a, b) = geom::split(region, axis, t);
    let mut out = treemap(&a, &w[..k], fixed);
    out.extend(treemap(&b, &w[k..], fixed));
    out
}

/// Each leaf's pieces become rooms (the largest keeps the name; the others are named as parts),
/// cleaned and cut at their holes until simple.
fn explode(leaves: Vec<(Item, Option<usize>, GMulti)>) -> Vec<Proto> {
    let mut out = Vec::new();
    for (it, unit, g) in leaves {
        let mut pieces: Vec<Polygon> =
            g.0.iter()
                .map(geom::from_geo)
                .filter(|p| p.outer.len() >= 3 && p.area() > 1e-6)
                .flat_map(|p| simple_pieces(p, 0))
                .filter(|p| p.outer.len() >= 3 && p.area() > 1e-6)
                .collect();
        pieces.sort_by(|a, b| b.area().total_cmp(&a.area()));
        for (i, p) in pieces.into_iter().enumerate() {
            out.push(Proto {
                kind: it.kind,
                name: if i == 0 {
                    it.name.clone()
                } else {
                    format!("{} ({})", it.name, i + 1)
                },
                unit,
                min_area: if i == 0 { it.min_area } else { None },
                poly: p,
            });
        }
    }
    out
}

/// The simple pieces of a polygon: cut through its holes ([`split_holes`]), then each piece's
/// ring cut where it touches itself ([`geom::simple_parts`]); a hole pinched onto the ring
/// becomes a hole of the piece around it and is cut through in turn.
fn simple_pieces(p: Polygon, depth: usize) -> Vec<Polygon> {
    let mut out = Vec::new();
    for q in split_holes(p, 0) {
        let (outers, pinched) = geom::simple_parts(&q.outer);
        for o in outers {
            let holes: Vec<Vec<DVec2>> = pinched
                .iter()
                .filter(|h| {
                    let c = h.iter().copied().sum::<DVec2>() / h.len() as f64;
                    crate::geometry::ring_contains(&o, c)
                })
                .map(|h| h.iter().rev().copied().collect())
                .collect();
            if holes.is_empty() || depth >= 4 {
                out.push(Polygon::new(o, Vec::new()));
            } else {
                out.extend(simple_pieces(Polygon::new(o, holes), depth + 1));
            }
        }
    }
    out
}

/// Cuts a polygon through the middle of its first hole (across the hole's longer extent) until
/// no piece has a hole.
fn split_holes(p: Polygon, depth: usize) -> Vec<Polygon> {
    if p.holes.is_empty() || depth > 12 {
        return vec![p];
    }
    let (lo, hi) = ring_bounds(&p.holes[0]);
    let (axis, t) = if hi.x - lo.x >= hi.y - lo.y {
        (Axis::X, 0.5 * (lo.x + hi.x))
    } else {
        (Axis::Y, 0.5 * (lo.y + hi.y))
    };
    let (a, b) = geom::split(&GMulti::new(vec![geom::to_geo(&p)]), axis, t);
    a.0.iter()
        .chain(b.0.iter())
        .map(geom::from_geo)
        .filter(|q| q.outer.len() >= 3 && q.area() > 1e-6)
        .flat_map(|q| split_holes(q, depth + 1))
        .collect()
}

/// A segment (start, end).
type Seg = (DVec2, DVec2);
/// Two rooms (i < j) and the segments they share.
type Adjacency = (usize, usize, Vec<Seg>);

/// Adjacency: for each pair of rooms that share boundary, the shared segments.
struct Graph {
    /// (i, j, segments) with i < j.
    pairs: Vec<Adjacency>,
}

fn graph(protos: &[Proto]) -> Graph {
    let bounds: Vec<(DVec2, DVec2)> = protos.iter().map(|p| ring_bounds(&p.poly.outer)).collect();
    let mut pairs = Vec::new();
    for i in 0..protos.len() {
        for j in (i + 1)..protos.len() {
            let (a, b) = (bounds[i], bounds[j]);
            let e = geom::EPS;
            if a.0.x > b.1.x + e || b.0.x > a.1.x + e || a.0.y > b.1.y + e || b.0.y > a.1.y + e {
                continue;
            }
            let segs = geom::shared_segments(&protos[i].poly.outer, &protos[j].poly.outer);
            if !segs.is_empty() {
                pairs.push((i, j, segs));
            }
        }
    }
    Graph { pairs }
}

/// The rooms sharing boundary with room `r`, with the shared length.
fn neighbours(protos: &[Proto], r: usize) -> Vec<(f64, usize)> {
    let a = ring_bounds(&protos[r].poly.outer);
    let e = geom::EPS;
    (0..protos.len())
        .filter(|&j| j != r)
        .filter_map(|j| {
            let b = ring_bounds(&protos[j].poly.outer);
            if a.0.x > b.1.x + e || b.0.x > a.1.x + e || a.0.y > b.1.y + e || b.0.y > a.1.y + e {
                return None;
            }
            let l: f64 = geom::shared_segments(&protos[r].poly.outer, &protos[j].poly.outer)
                .iter()
                .map(seg_len)
                .sum();
            (l > 0.0).then_some((l, j))
        })
        .collect()
}

fn seg_len(s: &(DVec2, DVec2)) -> f64 {
    s.0.distance(s.1)
}

fn longest(segs: &[(DVec2, DVec2)]) -> Option<(DVec2, DVec2)> {
    segs.iter()
        .copied()
        .max_by(|a, b| seg_len(a).total_cmp(&seg_len(b)))
}

/// A door of up to `width` centred on `s`, keeping `margin` to each end.
fn door_on(s: (DVec2, DVec2), width: f64, margin: f64) -> ((DVec2, DVec2), f64) {
    let l = seg_len(&s);
    let w = width.min(l - 2.0 * margin).max(0.0);
    let mid = 0.5 * (s.0 + s.1);
    let dir = if l > 0.0 { (s.1 - s.0) / l } else { DVec2::X };
    ((mid - dir * 0.5 * w, mid + dir * 0.5 * w), w)
}

/// Merges room `r` into room `into` when their union is one simple polygon; returns whether it
/// did.
fn merge(protos: &mut Vec<Proto>, r: usize, into: usize) -> bool {
    let u = geom::to_geo(&protos[r].poly).union(&geom::to_geo(&protos[into].poly));
    if u.0.len() != 1 {
        return false;
    }
    let p = geom::from_geo(&u.0[0]);
    if !p.holes.is_empty() || p.outer.len() < 3 || !geom::is_valid(&geom::to_geo(&p)) {
        return false;
    }
    // A union that touches itself (two rooms meeting at a corner and along a seam) is not one
    // room a writer can build.
    let (mut outers, pinched) = geom::simple_parts(&p.outer);
    if outers.len() != 1 || !pinched.is_empty() {
        return false;
    }
    protos[into].poly = Polygon::new(outers.remove(0), Vec::new());
    protos.remove(r);
    true
}

/// Merges slivers, grows the doors, merges unreachable rooms and builds the storey plan.
fn finish(usable: &Polygon, mut protos: Vec<Proto>, ground: bool) -> Option<StoreyPlan> {
    // 1. Slivers into the neighbour with the longest shared boundary.
    let is_sliver = |p: &Proto| {
        let a = p.poly.area();
        p.kind != RoomKind::Stair
            && (a < SLIVER_AREA || 2.0 * a / perimeter(&p.poly.outer) < SLIVER_WIDTH)
    };
    let mut kept = vec![false; protos.len()];
    for _ in 0..500 {
        let bad = (0..protos.len())
            .filter(|&i| !kept[i] && is_sliver(&protos[i]))
            .min_by(|a, b| protos[*a].poly.area().total_cmp(&protos[*b].poly.area()));
        let Some(r) = bad else { break };
        let mut nbrs: Vec<(f64, usize)> = neighbours(&protos, r)
            .into_iter()
            .filter(|(_, o)| protos[*o].kind != RoomKind::Stair)
            .collect();
        nbrs.sort_by(|a, b| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1)));
        let mut merged = false;
        for (_, o) in nbrs {
            if merge(&mut protos, r, o) {
                kept.remove(r);
                merged = true;
                break;
            }
        }
        if !merged {
            if protos[r].poly.area() < 1e-3 {
                protos.remove(r);
                kept.remove(r);
            } else {
                // Nothing takes it: it stays a small room.
                kept[r] = true;
            }
        }
    }
    // 2. Doors, merging rooms that no door reaches.
    for _ in 0..100 {
        let g = graph(&protos);
        let entrance = if ground {
            entrance_for(usable, &protos)
        } else {
            None
        };
        let start = if ground {
            entrance.as_ref().map(|d| d.a)
        } else {
            protos.iter().position(|p| p.kind == RoomKind::Stair)
        };
        let start = start.or(if protos.is_empty() { None } else { Some(0) })?;
        let (doors, reached) = grow_doors(&protos, &g, start);
        let unreached: Vec<usize> = (0..protos.len()).filter(|i| !reached[*i]).collect();
        if unreached.is_empty() && (!ground || entrance.is_some()) {
            let (rooms, stair_room) = to_rooms(protos);
            let walls = g
                .pairs
                .iter()
                .flat_map(|(i, j, segs)| {
                    segs.iter().map(move |s| Wall {
                        a: *i,
                        b: *j,
                        segment: *s,
                    })
                })
                .collect();
            return Some(StoreyPlan {
                rooms,
                walls,
                doors,
                entrance,
                stair_room,
            });
        }
        if unreached.is_empty() {
            return None;
        }
        // Merge the smallest unreachable room into its best neighbour, reached ones first.
        let r = *unreached
            .iter()
            .filter(|i| protos[**i].kind != RoomKind::Stair)
            .min_by(|a, b| protos[**a].poly.area().total_cmp(&protos[**b].poly.area()))?;
        let mut nbrs: Vec<(bool, f64, usize)> = g
            .pairs
            .iter()
            .filter(|(i, j, _)| *i == r || *j == r)
            .map(|(i, j, s)| {
                let o = if *i == r { *j } else { *i };
                (!reached[o], s.iter().map(seg_len).sum::<f64>(), o)
            })
            .filter(|(_, _, o)| protos[*o].kind != RoomKind::Stair)
            .collect();
        nbrs.sort_by(|a, b| a.0.cmp(&b.0).then(b.1.total_cmp(&a.1)).then(a.2.cmp(&b.2)));
        if !nbrs.iter().any(|(_, _, o)| merge(&mut protos, r, *o)) {
            return None;
        }
    }
    None
}

fn to_rooms(protos: Vec<Proto>) -> (Vec<Room>, Option<usize>) {
    let stair_room = protos.iter().position(|p| p.kind == RoomKind::Stair);
    let rooms = protos
        .into_iter()
        .map(|p| Room {
            polygon: p.poly,
            kind: p.kind,
            name: p.name,
            unit: p.unit,
            min_area: p.min_area,
        })
        .collect();
    (rooms, stair_room)
}

/// Prim-style spanning tree of doors from `start` (see the module documentation).
fn grow_doors(protos: &[Proto], g: &Graph, start: usize) -> (Vec<Door>, Vec<bool>) {
    let n = protos.len();
    let mut reached = vec![false; n];
    let mut doors = Vec::new();
    if start >= n {
        return (doors, reached);
    }
    reached[start] = true;
    let edges: Vec<(usize, usize, (DVec2, DVec2))> = g
        .pairs
        .iter()
        .filter_map(|(i, j, s)| longest(s).map(|l| (*i, *j, l)))
        .filter(|(_, _, l)| seg_len(l) >= MIN_DOOR_WALL)
        .collect();
    let level = |s: usize, t: usize| -> u32 {
        let (a, b) = (&protos[s], &protos[t]);
        match (a.unit, b.unit) {
            (x, y) if x == y => 0,
            (None, Some(_)) if b.kind == RoomKind::Hall => 0,
            (Some(_), None) if a.kind == RoomKind::Hall => 0,
            (None, _) | (_, None) => 1,
            _ => 2,
        }
    };
    let mut adj: Vec<Vec<(usize, (DVec2, DVec2))>> = vec![Vec::new(); n];
    for &(i, j, seg) in &edges {
        adj[i].push((j, seg));
        adj[j].push((i, seg));
    }
    // Min-heap of candidate doors from reached rooms; the key orders by short wall, dwelling
    // crossing, passage rank of the source, then the longest wall (millimetres), then indices
    // so that ties break the same way everywhere.
    type Key = (u32, u32, u32, i64, usize, usize);
    let mut heap: std::collections::BinaryHeap<std::cmp::Reverse<Key>> =
        std::collections::BinaryHeap::new();
    let push = |heap: &mut std::collections::BinaryHeap<std::cmp::Reverse<Key>>,
                s: usize,
                adj: &[Vec<(usize, (DVec2, DVec2))>],
                reached: &[bool]| {
        for (t, seg) in &adj[s] {
            if reached[*t] {
                continue;
            }
            let l = seg_len(seg);
            heap.push(std::cmp::Reverse((
                u32::from(l < DOOR_WALL),
                level(s, *t),
                protos[s].kind.passage_rank(),
                -((l * 1000.0).round() as i64),
                s,
                *t,
            )));
        }
    };
    push(&mut heap, start, &adj, &reached);
    while let Some(std::cmp::Reverse((_, _, _, _, s, t))) = heap.pop() {
        if reached[t] {
            continue;
        }
        let Some(seg) = adj[s].iter().find(|(o, _)| *o == t).map(|x| x.1) else {
            continue;
        };
        reached[t] = true;
        let (segment, width) = door_on(seg, DOOR_WIDTH, 0.1);
        doors.push(Door {
            a: s,
            b: Some(t),
            segment,
            width,
        });
        push(&mut heap, t, &adj, &reached);
    }
    (doors, reached)
}

/// The entrance: on the outer ring of the usable polygon, front-facing first, then the best
/// circulation room, then the longest wall.
fn entrance_for(usable: &Polygon, protos: &[Proto]) -> Option<Door> {
    let mut best: Option<((u32, u32, f64), usize, Seg)> = None;
    for (k, p) in protos.iter().enumerate() {
        if p.kind == RoomKind::Stair {
            continue;
        }
        for s in geom::shared_segments(&p.poly.outer, &usable.outer) {
            let l = seg_len(&s);
            if l < MIN_ENTRANCE_WALL {
                continue;
            }
            // Room rings are CCW: the outward normal is the edge turned clockwise; the front
            // is -y in the plan frame.
            let d = (s.1 - s.0) / l;
            let facing = DVec2::new(d.y, -d.x).dot(DVec2::new(0.0, -1.0));
            // Common circulation (a corridor, an entrance hall) before any dwelling's hall.
            let key = (
                u32::from(l < ENTRANCE_WIDTH + 0.3) * 4
                    + u32::from(facing < 0.5) * 2
                    + u32::from(p.unit.is_some()),
                p.kind.passage_rank(),
                -l,
            );
            let better = best.as_ref().is_none_or(|b| {
                (key.0, key.1)
                    .cmp(&(b.0 .0, b.0 .1))
                    .then(key.2.total_cmp(&b.0 .2))
                    .is_lt()
            });
            if better {
                best = Some((key, k, s));
            }
        }
    }
    best.map(|(_, k, s)| {
        let (segment, width) = door_on(s, ENTRANCE_WIDTH, 0.05);
        Door {
            a: k,
            b: None,
            segment,
            width,
        }
    })
}
