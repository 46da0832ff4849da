//! From a [`BuildingPlan`] to the model's [`StoreyInterior`]s of one part (LOD4).

use glam::DVec2;

use super::{BuildingPlan, Door, StoreyPlan};
use crate::model::{InteriorDoor, InteriorWall, Part, Room, Stair, StoreyInterior, OPENING_MARGIN};

/// Interior wall thickness (metres): a 10 cm partition.
pub(crate) const INTERIOR_WALL_THICKNESS: f64 = 0.1;
/// Thickness of a floor slab (metres): the ceiling of a storey is this far below the next
/// storey's floor.
pub(crate) const SLAB_THICKNESS: f64 = 0.2;
/// Interior door height (metres), lowered to fit a low storey.
pub(crate) const DOOR_HEIGHT: f64 = 2.1;

/// The interior of every storey of `part` from its plan. A plan without a stair covers the
/// ground storey only (the upper storeys cannot be reached), so the other storeys stay empty.
/// A plan with a stair gives every storey: storeys beyond the plan's repeat its last one.
pub(crate) fn storeys_of(part: &Part, plan: &BuildingPlan) -> Vec<StoreyInterior> {
    let levels = &part.levels;
    let planned = if plan.stair.is_some() {
        levels.len()
    } else {
        plan.storeys.len().min(1)
    };
    let mut out = Vec::with_capacity(planned);
    for (i, &floor_z) in levels.iter().enumerate().take(planned) {
        let Some(sp) = plan.storeys.get(i).or_else(|| plan.storeys.last()) else {
            break;
        };
        let next = levels.get(i + 1).copied().unwrap_or(part.eave_z);
        let ceiling_z = (next - SLAB_THICKNESS).max(floor_z + 0.5 * (next - floor_z));
        if ceiling_z.partial_cmp(&floor_z) != Some(std::cmp::Ordering::Greater) {
            continue;
        }
        out.push(storey(i, floor_z, ceiling_z, sp, plan));
    }
    out
}

fn storey(
    index: usize,
    floor_z: f64,
    ceiling_z: f64,
    sp: &StoreyPlan,
    plan: &BuildingPlan,
) -> StoreyInterior {
    let rooms = sp
        .rooms
        .iter()
        .map(|r| Room {
            polygon: r.polygon.clone(),
            usage: r.kind.label().to_lowercase(),
            name: r.name.clone(),
        })
        .collect();
    let walls: Vec<InteriorWall> = sp
        .walls
        .iter()
        .map(|w| InteriorWall {
            a: w.segment.0,
            b: w.segment.1,
            thickness: INTERIOR_WALL_THICKNESS,
            rooms: [w.a, w.b],
        })
        .collect();
    let height = DOOR_HEIGHT.min(ceiling_z - floor_z - 0.1);
    let doors = if height > 1.0 {
        sp.doors
            .iter()
            .filter_map(|d| door_on_walls(d, &walls, height))
            .collect()
    } else {
        Vec::new()
    };
    // The stair of the top storey would lead nowhere.
    let stair = match (&plan.stair, sp.stair_room) {
        (Some(core), Some(_)) => Some(Stair {
            footprint: core.polygon.clone(),
            run: core.up,
            rise: f64::from(core.risers) * core.riser_height,
            risers: core.risers,
        }),
        _ => None,
    };
    StoreyInterior {
        storey: index,
        floor_z,
        ceiling_z,
        rooms,
        walls,
        doors,
        stair,
    }
}

/// The door as `u0..u1` along the interior wall between its two rooms that holds its segment;
/// `None` when no wall holds it with [`OPENING_MARGIN`] to spare at both ends.
fn door_on_walls(d: &Door, walls: &[InteriorWall], height: f64) -> Option<InteriorDoor> {
    let b = d.b?;
    let (p, q) = d.segment;
    walls.iter().enumerate().find_map(|(i, w)| {
        let same = (w.rooms[0] == d.a && w.rooms[1] == b) || (w.rooms[0] == b && w.rooms[1] == d.a);
        if !same {
            return None;
        }
        let len = w.a.distance(w.b);
        let dir = (w.b - w.a).try_normalize()?;
        let off = |x: DVec2| (x - w.a).perp_dot(dir).abs();
        if off(p) > 1e-3 || off(q) > 1e-3 {
            return None;
        }
        let (mut u0, mut u1) = ((p - w.a).dot(dir), (q - w.a).dot(dir));
        if u0 > u1 {
            std::mem::swap(&mut u0, &mut u1);
        }
        (u0 >= OPENING_MARGIN && u1 <= len - OPENING_MARGIN && u1 - u0 > 0.3).then_some(
            InteriorDoor {
                wall: i,
                u0,
                u1,
                height,
            },
        )
    })
}
