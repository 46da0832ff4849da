//! LOD4 additions of the CityGML writer: a part's stairs and rooms ([`Part::interior`]).
//!
//! The exterior is written as at LOD3 but in the `lod4` properties. Then, in the schema's
//! order (`bldg:AbstractBuildingType`: installations, boundary surfaces, solid, rooms):
//!
//! - per storey with a stair, a `bldg:interiorBuildingInstallation` /
//!   `bldg:IntBuildingInstallation` named `stair` (class `stairs`) whose `bldg:lod4Geometry` is a
//!   `gml:MultiSurface` of its steps, each a closed block ([`lod4geom::stair_steps`]);
//! - per room a `bldg:interiorRoom` / `bldg:Room` (`gml:name` = the room's name, `bldg:usage`
//!   = its usage) with `bldg:lod4Solid` (references to its polygons, which close the shell) and
//!   `bldg:boundedBy` a `bldg:FloorSurface`, a `bldg:CeilingSurface` and one
//!   `bldg:InteriorWallSurface` per side of the room ([`lod4geom::room_shell`]: polygons on the
//!   room polygon's edges, i.e. the interior walls' centre lines, pointing out of the room),
//!   each side with one hole per interior door in it.
//! - An interior door is one `bldg:Door` with one polygon in `bldg:lod4MultiSurface`, written
//!   in the first room it opens (its polygon facing out of that room) and referenced from the
//!   other room's wall surface by `bldg:opening xlink:href`; the other room's solid uses the
//!   polygon reversed (`gml:OrientableSurface orientation="-"`).
//!
//! Identifiers, from the part's id `P` and the index `k` of the storey in [`Part::interior`]:
//! room `P_s{k}_r{r}` with polygons `..._f` (floor), `..._c` (ceiling), `..._w{i}` (side i)
//! and boundary surfaces `<polygon id>_s`; door `P_s{k}_d{j}` with polygon `P_s{k}_d{j}_p`;
//! stair `P_s{k}_stair` with polygons `P_s{k}_stair_{step}_{face}`. Colours are X3D materials
//! `<building id>_i{n}` of the building's appearance (floors, ceilings, walls, doors, stairs).

use glam::DVec3;

use super::material::{x3d_material, ColorKey};
use super::surfaces::surfaces;
use super::xml::Xml;
use crate::color::material::Material;
use crate::color::Color;
use crate::export::lod4geom::{self, prism_faces, room_shell, RoomShell};
use crate::model::{Building, Face, Part};

/// A `gml:Polygon` with id `id`: the face's exterior and interiors at `origin + p`.
fn polygon(x: &mut Xml, id: &str, face: &Face, origin: DVec3) {
    x.s("<gml:Polygon gml:id=\"");
    x.s(id);
    x.s("\">\n<gml:exterior>\n");
    x.linear_ring(&face.outer, origin);
    x.s("</gml:exterior>\n");
    for h in &face.holes {
        x.s("<gml:interior>\n");
        x.linear_ring(h, origin);
        x.s("</gml:interior>\n");
    }
    x.s("</gml:Polygon>\n");
}

/// `<gml:surfaceMember xlink:href="#id"/>`.
fn member(x: &mut Xml, id: &str) {
    x.s("<gml:surfaceMember xlink:href=\"#");
    x.s(id);
    x.s("\"/>\n");
}

/// A multi-surface property `element` holding one polygon.
fn multi_surface(x: &mut Xml, element: &str, id: &str, face: &Face, origin: DVec3, srs: &str) {
    x.s("<");
    x.s(element);
    x.s(">\n<gml:MultiSurface srsName=\"");
    x.s(srs);
    x.s("\">\n<gml:surfaceMember>\n");
    polygon(x, id, face, origin);
    x.s("</gml:surfaceMember>\n</gml:MultiSurface>\n</");
    x.s(element);
    x.s(">\n");
}

/// The shells of a storey's rooms and, per door, the first room whose shell has it (that room
/// writes the door).
fn shells_and_owners(s: &crate::model::StoreyInterior) -> (Vec<Option<RoomShell>>, Vec<usize>) {
    let shells: Vec<Option<RoomShell>> = (0..s.rooms.len()).map(|r| room_shell(s, r)).collect();
    let mut owner = vec![usize::MAX; s.doors.len()];
    for (r, shell) in shells.iter().enumerate().rev() {
        for d in shell
            .iter()
            .flat_map(|sh| &sh.sides)
            .flat_map(|side| &side.doors)
        {
            owner[d.door] = r;
        }
    }
    (shells, owner)
}

/// The stairs of `part` as interior building installations.
pub(super) fn stairs(x: &mut Xml, part: &Part, pid: &str, origin: DVec3, srs: &str) {
    for (k, s) in part.interior.iter().enumerate() {
        let Some(st) = &s.stair else {
            continue;
        };
        let steps = lod4geom::stair_steps(s, st);
        if steps.is_empty() {
            continue;
        }
        let id = format!("{pid}_s{k}_stair");
        x.s("<bldg:interiorBuildingInstallation>\n<bldg:IntBuildingInstallation gml:id=\"");
        x.s(&id);
        x.s("\">\n<gml:name>stair</gml:name>\n<bldg:class>stairs</bldg:class>\n");
        x.s("<bldg:lod4Geometry>\n<gml:MultiSurface srsName=\"");
        x.s(srs);
        x.s("\">\n");
        for (j, step) in steps.iter().enumerate() {
            for (f, face) in prism_faces(&step.ring, step.z0, step.z1).iter().enumerate() {
                x.s("<gml:surfaceMember>\n");
                polygon(x, &format!("{id}_{j}_{f}"), face, origin);
                x.s("</gml:surfaceMember>\n");
            }
        }
        x.s("</gml:MultiSurface>\n</bldg:lod4Geometry>\n");
        x.s("</bldg:IntBuildingInstallation>\n</bldg:interiorBuildingInstallation>\n");
    }
}

/// The rooms of `part` (see the module documentation).
pub(super) fn rooms(x: &mut Xml, part: &Part, pid: &str, origin: DVec3, srs: &str) {
    for (k, s) in part.interior.iter().enumerate() {
        let (shells, owner) = shells_and_owners(s);
        for (r, shell) in shells.iter().enumerate() {
            let Some(shell) = shell else {
                continue;
            };
            let room = &s.rooms[r];
            let rid = format!("{pid}_s{k}_r{r}");
            let door_id = |d: usize| format!("{pid}_s{k}_d{d}");
            x.s("<bldg:interiorRoom>\n<bldg:Room gml:id=\"");
            x.s(&rid);
            x.s("\">\n");
            if !room.name.is_empty() {
                x.s("<gml:name>");
                x.escaped(&room.name, false);
                x.s("</gml:name>\n");
            }
            if !room.usage.is_empty() {
                x.s("<bldg:usage>");
                x.escaped(&room.usage, false);
                x.s("</bldg:usage>\n");
            }
            // The closed shell: floor, ceiling, sides, and the doors filling the sides' holes.
            x.s("<bldg:lod4Solid>\n<gml:Solid srsName=\"");
            x.s(srs);
            x.s("\">\n<gml:exterior>\n<gml:CompositeSurface>\n");
            member(x, &format!("{rid}_f"));
            member(x, &format!("{rid}_c"));
            for i in 0..shell.sides.len() {
                member(x, &format!("{rid}_w{i}"));
            }
            for d in shell.sides.iter().flat_map(|side| &side.doors) {
                let poly = format!("{}_p", door_id(d.door));
                if owner[d.door] == r {
                    member(x, &poly);
                } else {
                    x.s("<gml:surfaceMember>\n<gml:OrientableSurface orientation=\"-\">\n");
                    x.s("<gml:baseSurface xlink:href=\"#");
                    x.s(&poly);
                    x.s("\"/>\n</gml:OrientableSurface>\n</gml:surfaceMember>\n");
                }
            }
            x.s("</gml:CompositeSurface>\n</gml:exterior>\n</gml:Solid>\n</bldg:lod4Solid>\n");
            for (element, id, face) in [
                ("bldg:FloorSurface", format!("{rid}_f"), &shell.floor),
                ("bldg:CeilingSurface", format!("{rid}_c"), &shell.ceiling),
            ] {
                x.s("<bldg:boundedBy>\n<");
                x.s(element);
                x.s(" gml:id=\"");
                x.s(&id);
                x.s("_s\">\n");
                multi_surface(x, "bldg:lod4MultiSurface", &id, face, origin, srs);
                x.s("</");
                x.s(element);
                x.s(">\n</bldg:boundedBy>\n");
            }
            for (i, side) in shell.sides.iter().enumerate() {
                let id = format!("{rid}_w{i}");
                x.s("<bldg:boundedBy>\n<bldg:InteriorWallSurface gml:id=\"");
                x.s(&id);
                x.s("_s\">\n");
                multi_surface(x, "bldg:lod4MultiSurface", &id, &side.face, origin, srs);
                for (d, face) in side.doors.iter().zip(&side.door_faces) {
                    let did = door_id(d.door);
                    if owner[d.door] == r {
                        x.s("<bldg:opening>\n<bldg:Door gml:id=\"");
                        x.s(&did);
                        x.s("\">\n");
                        let poly = format!("{did}_p");
                        multi_surface(x, "bldg:lod4MultiSurface", &poly, face, origin, srs);
                        x.s("</bldg:Door>\n</bldg:opening>\n");
                    } else {
                        x.s("<bldg:opening xlink:href=\"#");
                        x.s(&did);
                        x.s("\"/>\n");
                    }
                }
                x.s("</bldg:InteriorWallSurface>\n</bldg:boundedBy>\n");
            }
            x.s("</bldg:Room>\n</bldg:interiorRoom>\n");
        }
    }
}

/// The X3D materials of the building's interiors (one per class colour), appended to its
/// appearance. Only parts whose geometry is written (see [`surfaces`]) have their rooms.
pub(super) fn materials(x: &mut Xml, building_id: &str, b: &Building, part_ids: &[String]) {
    let mut classes: Vec<(Color, Vec<String>)> = [
        lod4geom::FLOOR_COLOR,
        lod4geom::SLAB_COLOR,
        lod4geom::INTERIOR_WALL_COLOR,
        lod4geom::DOOR_COLOR,
        lod4geom::STAIR_COLOR,
    ]
    .into_iter()
    .map(|c| (c, Vec::new()))
    .collect();
    for (part, pid) in b.parts.iter().zip(part_ids) {
        if surfaces(part).next().is_none() {
            continue;
        }
        for (k, s) in part.interior.iter().enumerate() {
            if let Some(st) = &s.stair {
                let steps = lod4geom::stair_steps(s, st);
                for (j, step) in steps.iter().enumerate() {
                    for f in 0..prism_faces(&step.ring, step.z0, step.z1).len() {
                        classes[4].1.push(format!("{pid}_s{k}_stair_{j}_{f}"));
                    }
                }
            }
            let (shells, owner) = shells_and_owners(s);
            for (r, shell) in shells.iter().enumerate() {
                let Some(shell) = shell else {
                    continue;
                };
                let rid = format!("{pid}_s{k}_r{r}");
                classes[0].1.push(format!("{rid}_f"));
                classes[1].1.push(format!("{rid}_c"));
                for (i, side) in shell.sides.iter().enumerate() {
                    classes[2].1.push(format!("{rid}_w{i}"));
                    for d in side.doors.iter().filter(|d| owner[d.door] == r) {
                        classes[3].1.push(format!("{pid}_s{k}_d{}_p", d.door));
                    }
                }
            }
        }
    }
    for (n, (color, targets)) in classes.iter().enumerate() {
        if targets.is_empty() {
            continue;
        }
        // The interior colours are opaque: no app:transparency is written.
        let key = ColorKey::of(*color);
        x3d_material(
            x,
            [building_id, "_i"],
            n,
            (key, Material::Unspecified),
            targets,
            |x, t| x.s(t),
        );
    }
}
