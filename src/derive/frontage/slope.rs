//! LOD3 on slopes (issue 44; docs/terrain.md, "LOD3 on slopes"): a building seated on the
//! lowest terrain under it keeps level storeys, counted from that base; its facades look at the
//! terrain along their walls ([`crate::prepare::Lot::terrain`], heights above the building's
//! ground here):
//!
//! - **Nothing under the terrain.** A window, door or balcony whose bottom is below the terrain
//!   anywhere along its width is left out ([`drop_buried`]): the lower storeys of the hill side
//!   are a blank plinth up to the terrain, those of the valley side keep their windows.
//! - **The entrance at the terrain.** The door is placed where its sill can stand on the
//!   terrain: on each wall free of neighbours and on each storey, at the bay (or the place every
//!   [`POSITION_STEP`] along the wall's free stretch) nearest its middle where the terrain
//!   varies by at most [`STEP`] across the door and a door of at least the lowest height fits
//!   between the terrain and the storey's lintel; its sill is the highest terrain under it (a
//!   step of at most [`STEP`] on its low side). The street side first, as on flat ground
//!   (`frontage`'s tiers), then the rules' own door, the longer free stretch, the nearer bay,
//!   the lower storey. A door on the hill side may so open on an upper storey (a split-level
//!   hall); the storeys themselves never move, so the LOD4 floors stay level.
//! - **No place at the terrain.** When no wall has such a place, the door goes where it is
//!   least above the terrain (the street side first), its sill on its storey's floor: the steps
//!   up to it are not drawn, and the building gets a note saying how high it is.

use glam::DVec2;

use super::{longest_free, on_balcony, tier, Arrangement, Draft};
use super::{DOOR_MIN_HEIGHT, DOOR_MIN_WIDTH};
use crate::derive::facade::{self, FoundOpening, JAMB_SNAP};
use crate::model::{ElevationGrid, OpeningKind, LINTEL, OPENING_MARGIN};

/// The highest step (metres) between the terrain and a door's sill: the most the terrain may
/// vary across the door, and the most the sill may stand above the terrain's lowest point
/// under it.
pub(crate) const STEP: f64 = 0.25;
/// Distance (metres) between the places tried for a door along a wall's free stretch, and
/// between the terrain's samples along an opening.
pub(crate) const POSITION_STEP: f64 = 0.25;
/// How far (metres) an opening's bottom may be below the terrain's samples and still count as
/// above it (the millimetre the outputs round to).
const TOUCH: f64 = 0.001;

/// The terrain around one building, as heights above its ground.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Slope<'a> {
    grid: &'a ElevationGrid,
    ground: f64,
}

impl<'a> Slope<'a> {
    /// The terrain of `grid` seen from a building standing on `ground`.
    pub(crate) fn new(grid: &'a ElevationGrid, ground: f64) -> Slope<'a> {
        Slope { grid, ground }
    }

    /// The terrain's height above the building's ground at `p`, `None` where it is unknown.
    pub(crate) fn at(&self, p: DVec2) -> Option<f64> {
        self.grid.height_at(p).map(|z| z - self.ground)
    }

    /// The lowest and highest terrain along the wall from `start` to `end` over `u0..u1`
    /// (metres from `start`), sampled at both ends and every [`POSITION_STEP`] between; `None`
    /// where no sample is known.
    pub(crate) fn range(&self, start: DVec2, end: DVec2, u0: f64, u1: f64) -> Option<(f64, f64)> {
        let len = start.distance(end);
        if !(len > 0.0 && u1 >= u0) {
            return None;
        }
        let dir = (end - start) / len;
        let n = ((u1 - u0) / POSITION_STEP).ceil().clamp(1.0, 10_000.0) as usize;
        let mut out: Option<(f64, f64)> = None;
        for i in 0..=n {
            let u = u0 + (u1 - u0) * i as f64 / n as f64;
            if let Some(z) = self.at(start + dir * u) {
                out = Some(out.map_or((z, z), |(a, b)| (a.min(z), b.max(z))));
            }
        }
        out
    }
}

/// Leaves out every opening and balcony of the drafts whose bottom is below the terrain
/// along its width (module docs), and the doors onto a balcony left out; returns how many.
pub(crate) fn drop_buried(drafts: &mut [Draft<'_>], slope: Slope<'_>) -> usize {
    let mut dropped = 0;
    for d in drafts.iter_mut() {
        let walls = &d.part.walls;
        let f = &mut *d.facades;
        for (k, w) in walls.iter().enumerate() {
            let above = |u0: f64, u1: f64, z: f64| {
                slope
                    .range(w.start, w.end, u0, u1)
                    .is_none_or(|(_, high)| z >= high - TOUCH)
            };
            // A balcony under the terrain goes, and the doors onto it with it.
            let mut gone = Vec::new();
            if let Some(bal) = f.balconies.get_mut(k) {
                let before = bal.len();
                let (kept, under): (Vec<_>, Vec<_>) =
                    bal.drain(..).partition(|b| above(b.u0, b.u1, b.z0));
                *bal = kept;
                gone = under;
                dropped += before - bal.len();
            }
            let kept = f.balconies.get(k).map_or(&[][..], Vec::as_slice);
            if let Some(ops) = f.openings.get_mut(k) {
                let before = ops.len();
                ops.retain(|o| {
                    let stranded =
                        o.kind == OpeningKind::Door && on_balcony(o, &gone) && !on_balcony(o, kept);
                    !stranded && above(o.u0, o.u1, o.z0)
                });
                dropped += before - ops.len();
            }
        }
    }
    dropped
}

/// Where a door could go on one wall and storey: its key (lower is better), place and
/// height above the terrain's lowest point under it.
struct Place {
    key: (bool, u8, i64, bool, i64, usize, usize),
    p: usize,
    k: usize,
    u: (f64, f64),
    z: (f64, f64),
    normal: DVec2,
    gap: f64,
}

/// The best place for a door on storey `storey` (`lo..hi`) of wall `k` of draft `p`: the first
/// of the candidate places, in the order of preference, where it stands at the terrain, else
/// the one least above it; `None` where the storey has no free stretch or no place for a door
/// of the lowest height above the terrain.
fn place_on(
    (p, d): (usize, &Draft<'_>),
    (k, storey, lo, hi): (usize, usize, f64, f64),
    spans: &[crate::derive::surroundings::Span],
    (tier, rules_chose): (u8, bool),
    slope: Slope<'_>,
) -> Option<Place> {
    let w = &d.part.walls[k];
    let len = w.length();
    let top = hi - LINTEL;
    if len <= 0.0 || top - lo - OPENING_MARGIN < DOOR_MIN_HEIGHT {
        return None;
    }
    let blocked: Vec<(f64, f64)> = spans
        .iter()
        .filter(|s| s.z0 < top && lo < s.z1)
        .map(|s| (s.u0, s.u1))
        .collect();
    let free = longest_free(OPENING_MARGIN, len - OPENING_MARGIN, blocked)?;
    if free.1 - free.0 < DOOR_MIN_WIDTH + 2.0 * JAMB_SNAP {
        return None;
    }
    let width = d
        .style
        .door_width
        .max(DOOR_MIN_WIDTH + 2.0 * JAMB_SNAP)
        .min(free.1 - free.0);
    let (f0, f1) = (free.0 + 0.5 * width, free.1 - 0.5 * width);
    let mid = 0.5 * (f0 + f1);
    // The storey's bays first, then every POSITION_STEP: each by its distance to the middle.
    let mut bays: Vec<f64> = d.facades.openings[k]
        .iter()
        .filter(|o| o.kind == OpeningKind::Window && o.z0 >= lo && o.z0 < hi)
        .map(|o| 0.5 * (o.u0 + o.u1))
        .filter(|u| (f0..=f1).contains(u))
        .collect();
    let n = ((f1 - f0) / POSITION_STEP).floor().min(10_000.0) as usize;
    let mut steps: Vec<f64> = (0..=n).map(|i| f0 + i as f64 * POSITION_STEP).collect();
    steps.push(mid);
    let by_middle = |a: &f64, b: &f64| (a - mid).abs().total_cmp(&(b - mid).abs());
    bays.sort_by(by_middle);
    steps.sort_by(by_middle);
    let room = -((free.1 - free.0).min(6.0) * 100.0).round() as i64;
    let dir = (w.end - w.start) / len;
    let normal = DVec2::new(dir.y, -dir.x);
    let mut least: Option<Place> = None;
    for (rank, &c) in bays.iter().chain(&steps).enumerate() {
        let (u0, u1) = (c - 0.5 * width, c + 0.5 * width);
        let (low, high) = slope.range(w.start, w.end, u0, u1).unwrap_or((0.0, 0.0));
        let sill = high.max(lo + OPENING_MARGIN);
        let head = (sill + d.style.door_height).min(top);
        if head - sill < DOOR_MIN_HEIGHT {
            continue;
        }
        let gap = sill - low;
        let at_terrain = high - low <= STEP && gap <= STEP;
        let gap_cm = if at_terrain {
            0
        } else {
            (gap * 100.0).round() as i64
        };
        let place = Place {
            key: (!at_terrain, tier, gap_cm, !rules_chose, room, rank, storey),
            p,
            k,
            u: (u0, u1),
            z: (sill, head),
            normal,
            gap,
        };
        if at_terrain {
            return Some(place);
        }
        if least.as_ref().is_none_or(|l| place.key < l.key) {
            least = Some(place);
        }
    }
    least
}

/// Places the main entrance of a building on a slope (module docs); the flat-ground
/// counterpart is `frontage::entrance`.
pub(crate) fn entrance(
    drafts: &mut [Draft<'_>],
    front: Option<DVec2>,
    wanted: &[Option<(usize, f64, Option<crate::color::Color>)>],
    out: &mut Arrangement,
    slope: Slope<'_>,
) {
    let mut best: Option<Place> = None;
    let mut grounded = false;
    let towers = super::towers_take_entrance(drafts);
    for (p, d) in drafts.iter().enumerate() {
        if !d.takes_entrance(towers) {
            continue;
        }
        grounded = true;
        let storeys = facade::storeys(d.part, d.facades);
        let outer = d.part.footprint.outer.len().min(d.part.walls.len());
        for k in 0..outer {
            let w = &d.part.walls[k];
            let len = w.length();
            if len <= 0.0 {
                continue;
            }
            let dir = (w.end - w.start) / len;
            let t = tier(DVec2::new(dir.y, -dir.x), front);
            let rules_chose = wanted[p].is_some_and(|(wk, _, _)| wk == k);
            for (s, &(lo, hi)) in storeys.iter().enumerate() {
                let Some(place) = place_on(
                    (p, d),
                    (k, s, lo, hi),
                    &out.spans[p][k],
                    (t, rules_chose),
                    slope,
                ) else {
                    continue;
                };
                if best.as_ref().is_none_or(|b| place.key < b.key) {
                    best = Some(place);
                }
            }
        }
    }
    let Some(c) = best else {
        if grounded {
            out.counts.without_entrance += 1;
            out.note = Some(format!(
                "no entrance: no wall has {DOOR_MIN_WIDTH} m free of neighbours and room for a door of {DOOR_MIN_HEIGHT} m above the terrain"
            ));
        }
        return;
    };
    if c.key.0 {
        out.slope_notes.push(format!(
            "entrance {:.2} m above the terrain: no wall has room for a door at the terrain's level (the steps up to it are not drawn)",
            c.gap
        ));
    }
    let d = &mut drafts[c.p];
    let door = FoundOpening {
        kind: OpeningKind::Door,
        u0: c.u.0,
        u1: c.u.1,
        z0: c.z.0,
        z1: c.z.1,
        color: wanted[c.p].and_then(|w| w.2).or(Some(d.style.door_color)),
        frame_color: None,
        glazed: false,
        framed: false,
        frame_size: None,
        rounding: None,
    };
    super::put_entrance(&mut d.facades.openings[c.k], door, wanted, out);
    out.entrance = Some((c.p, c.normal));
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A plane rising 0.5 m a metre east from 10 m, seen from a building standing on 10 m.
    fn plane() -> ElevationGrid {
        let (nx, ny) = (11, 11);
        let z = (0..ny)
            .flat_map(|_| (0..nx).map(|i| 10.0 + 0.5 * i as f32))
            .collect();
        ElevationGrid {
            origin: DVec2::ZERO,
            step: 1.0,
            nx,
            ny,
            z,
        }
    }

    #[test]
    fn the_terrain_along_a_wall_is_its_lowest_and_highest_sample() {
        let g = plane();
        let s = Slope::new(&g, 10.0);
        assert_eq!(s.at(DVec2::new(4.0, 3.0)), Some(2.0));
        assert_eq!(s.at(DVec2::new(-1.0, 3.0)), None);
        // A wall running east from (2, 5): 1..3 m along it is x 3..5.
        let (lo, hi) = s
            .range(DVec2::new(2.0, 5.0), DVec2::new(9.0, 5.0), 1.0, 3.0)
            .unwrap();
        assert!(
            (lo - 1.5).abs() < 1e-9 && (hi - 2.5).abs() < 1e-9,
            "{lo} {hi}"
        );
        // Running north, the terrain is level; off the grid it is unknown.
        let (lo, hi) = s
            .range(DVec2::new(4.0, 0.0), DVec2::new(4.0, 9.0), 0.0, 9.0)
            .unwrap();
        assert!((lo - 2.0).abs() < 1e-9 && (hi - 2.0).abs() < 1e-9);
        assert_eq!(
            s.range(DVec2::new(20.0, 0.0), DVec2::new(20.0, 9.0), 0.0, 9.0),
            None
        );
        assert_eq!(s.range(DVec2::ZERO, DVec2::ZERO, 0.0, 1.0), None);
    }
}
