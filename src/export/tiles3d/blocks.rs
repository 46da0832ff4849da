//! [`Detail::Blocks`](super::Detail::Blocks): a coarse LOD1 of a building for the upper levels
//! of a tileset, and how much detail it loses.
//!
//! Every part's footprint (with its holes) is extruded from the part's base to its top (the
//! ridge, so that the silhouette keeps the building's height): one wall quad per footprint edge
//! in the part's wall colour, the footprint at the top in its roof colour, and the footprint at
//! the base facing down only for a part raised above the building's base (an overhang or a
//! bridge would otherwise be open from below). A house is then ten to twenty triangles.

use glam::DVec3;

use crate::color::Color;
use crate::export::gltf::{
    add_textured_edge, add_textured_roof, group, Group, SurfaceClass, Texturing, OPENING_SETBACK,
};
use crate::model::{Building, Face, Part};

/// A part raised more than this above its building's base gets a bottom face (metres).
const RAISED: f64 = 0.5;

/// The least geometric error of a Blocks content (metres): even where the blocks are the
/// buildings (LOD1), refining to the full content up close costs little and shows the parts'
/// joins as the full writer draws them.
pub(crate) const MIN_BLOCKS_ERROR: f64 = 0.5;

/// Colour of the raised parts' undersides (as the glTF writer's grounds).
const UNDERSIDE: Color = Color::GREY;

/// The Blocks faces of `b`, grouped as the glTF writer groups a building's
/// ([`crate::export::gltf::building_groups`]): walls, roof (the tops) and ground (the raised
/// parts' undersides), by colour; with `tex` (`--textures`) the walls and tops textured as
/// the full content's (at LOD2 each wall with the picture of its bays up to the eaves and the
/// material's pattern above, the top with the roof material's pattern), so that the far
/// tiles look like the near ones.
pub(crate) fn block_groups(b: &Building, tex: Texturing) -> Vec<(SurfaceClass, Vec<Group>)> {
    let mut walls: Vec<Group> = Vec::new();
    let mut tops: Vec<Group> = Vec::new();
    let mut grounds: Vec<Group> = Vec::new();
    for part in &b.parts {
        let (z0, z1) = (part.base_z, part.top_z);
        if z1 <= z0 {
            continue;
        }
        for ring in std::iter::once(&part.footprint.outer).chain(&part.footprint.holes) {
            for (i, &a) in ring.iter().enumerate() {
                let c = ring[(i + 1) % ring.len()];
                // Outer rings are counter-clockwise and holes clockwise: the outside is on the
                // right of a -> c, and this quad is counter-clockwise seen from there.
                let quad = Face::new(vec![a.extend(z0), c.extend(z0), c.extend(z1), a.extend(z1)]);
                if tex == Texturing::Off {
                    group(&mut walls, part.wall_color).add_face(&quad);
                } else {
                    add_textured_edge(&mut walls, part, (a, c), &quad, tex);
                }
            }
        }
        let top = flat(part, z1, false);
        if tex == Texturing::Off {
            group(&mut tops, part.roof_color).add_face(&top);
        } else {
            add_textured_roof(&mut tops, part, &top);
        }
        if z0 > b.base_z + RAISED {
            group(&mut grounds, UNDERSIDE).add_face(&flat(part, z0, true));
        }
    }
    [
        (SurfaceClass::Walls, walls),
        (SurfaceClass::Roof, tops),
        (SurfaceClass::Ground, grounds),
    ]
    .into_iter()
    .map(|(c, mut gs)| {
        gs.retain(|g| !g.mesh.indices.is_empty());
        (c, gs)
    })
    .filter(|(_, gs)| !gs.is_empty())
    .collect()
}

/// The part's footprint at height `z`, facing up, or down when `down`.
fn flat(part: &Part, z: f64, down: bool) -> Face {
    let ring = |r: &[glam::DVec2]| -> Vec<DVec3> {
        let mut v: Vec<DVec3> = r.iter().map(|p| p.extend(z)).collect();
        if down {
            v.reverse();
        }
        v
    };
    Face {
        outer: ring(&part.footprint.outer),
        holes: part.footprint.holes.iter().map(|h| ring(h)).collect(),
    }
}

/// How far, in metres, the Blocks of `b` stray from its full geometry at `lod`: the highest a
/// part's roof rises above its eaves (the block is flat at the ridge), and at LOD3 and above
/// the facade's relief (the deepest balcony, or the setback of the openings' panes).
pub(crate) fn blocks_error(b: &Building, detailed: bool) -> f64 {
    let roofs = b
        .parts
        .iter()
        .map(|p| p.top_z - p.eave_z)
        .filter(|d| d.is_finite())
        .fold(0.0, f64::max);
    let relief = if detailed {
        let walls = b.parts.iter().flat_map(|p| &p.walls);
        let balconies = walls
            .clone()
            .flat_map(|w| &w.balconies)
            .map(|bc| bc.depth)
            .filter(|d| d.is_finite())
            .fold(0.0, f64::max);
        let openings = if walls.into_iter().any(|w| !w.openings.is_empty()) {
            OPENING_SETBACK
        } else {
            0.0
        };
        balconies.max(openings)
    } else {
        0.0
    };
    roofs.max(relief)
}
