//! LOD4 of the glTF writer: a part's interior (floors, interior walls and doors, stairs, slabs).

use crate::export::lod4geom;
use crate::model::{Face, Part};

use super::group::{group, Group};
use super::SurfaceClass;

/// Adds the faces of `part`'s interiors of one LOD4 class (see the module documentation).
pub(super) fn add_interior(groups: &mut Vec<Group>, part: &Part, class: SurfaceClass) {
    for (k, s) in part.interior.iter().enumerate() {
        match class {
            SurfaceClass::Floors => {
                let g = group(groups, lod4geom::FLOOR_COLOR);
                for r in &s.rooms {
                    if let Some(ring) = lod4geom::room_ring(r) {
                        g.add_face(&Face::new(
                            ring.iter().map(|p| p.extend(s.floor_z)).collect(),
                        ));
                    }
                }
            }
            SurfaceClass::InteriorWalls => {
                let g = group(groups, lod4geom::INTERIOR_WALL_COLOR);
                for w in 0..s.walls.len() {
                    lod4geom::wall_body(s, w)
                        .iter()
                        .flatten()
                        .for_each(|f| g.add_face(f));
                }
            }
            SurfaceClass::InteriorDoors => {
                let g = group(groups, lod4geom::DOOR_COLOR);
                for d in &s.doors {
                    lod4geom::door_leaf(s, d)
                        .iter()
                        .flatten()
                        .for_each(|f| g.add_face(f));
                }
            }
            SurfaceClass::Stairs => {
                let g = group(groups, lod4geom::STAIR_COLOR);
                if let Some(st) = &s.stair {
                    for step in lod4geom::stair_steps(s, st) {
                        lod4geom::prism_faces(&step.ring, step.z0, step.z1)
                            .iter()
                            .for_each(|f| g.add_face(f));
                    }
                }
            }
            SurfaceClass::Slabs => {
                let below = k
                    .checked_sub(1)
                    .and_then(|b| part.interior.get(b))
                    .filter(|b| b.storey + 1 == s.storey);
                let (pieces, thickness) = lod4geom::floor_slab(below, s);
                let g = group(groups, lod4geom::SLAB_COLOR);
                for p in &pieces {
                    // The top face is the rooms' floors: leave it out so they do not fight.
                    lod4geom::slab_faces(p, s.floor_z, thickness)
                        .iter()
                        .skip(1)
                        .for_each(|f| g.add_face(f));
                }
            }
            _ => {}
        }
    }
}
