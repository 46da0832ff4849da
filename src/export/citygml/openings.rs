//! LOD3 of the CityGML writer: boundary surfaces with their openings (`bldg:Window`, `bldg:Door`),
//! balconies as `bldg:BuildingInstallation`s, and the `lod3Solid` (also used at LOD4 with the
//! `lod4` properties).

use crate::export::lod3geom::{
    balcony_faces, cornice_solids, eaves_solids, opening_face, seated_changes, wall_sill_faces,
};
use crate::model::{Face, OpeningKind, Part};

use super::surfaces::{
    boundary_element, seated_surfaces, surfaces, written_walls, Surface, SurfaceKind,
};
use super::xml::Xml;
use super::{lod4, GeometryLod, Renderer};
use glam::DVec3;

impl Renderer<'_> {
    /// LOD3 geometry in the schema's order: balconies (`outerBuildingInstallation`), boundary
    /// surfaces with their openings, then `lod3Solid` referencing the closed shell's polygons.
    pub(super) fn geometry_lod3(&mut self, part: &Part, pid: &str) {
        let (origin, srs, d) = (self.origin, self.srs, self.lod.digit());
        let tex = self.tex.tex;
        let x = &mut *self.x;
        for (wi, wall) in written_walls(part) {
            for (k, bc) in wall.balconies.iter().enumerate() {
                let Some(faces) = balcony_faces(wall, bc) else {
                    continue;
                };
                x.s("<bldg:outerBuildingInstallation>\n<bldg:BuildingInstallation gml:id=\"");
                x.polygon_id(pid, SurfaceKind::Wall, wi);
                x.s("_b");
                x.uint(k as u64);
                let kind = SurfaceKind::Balcony {
                    wall: wi,
                    balcony: k,
                };
                let at = (pid, origin, srs, d);
                installation_rest(x, "balcony", at, kind, faces.all());
            }
            let boxes = wall_sill_faces(wall);
            if boxes.is_empty() {
                continue;
            }
            x.s("<bldg:outerBuildingInstallation>\n<bldg:BuildingInstallation gml:id=\"");
            x.polygon_id(pid, SurfaceKind::Wall, wi);
            x.s("_sills");
            let kind = SurfaceKind::Sill { wall: wi };
            installation_rest(x, "window sills", (pid, origin, srs, d), kind, boxes.iter());
        }
        // The cornice and eaves (issue 49): one installation each, a surface per face.
        for (eaves, name) in [(false, "cornice"), (true, "eaves")] {
            let solids = if eaves {
                eaves_solids(part)
            } else {
                cornice_solids(part)
            };
            if solids.is_empty() {
                continue;
            }
            x.s("<bldg:outerBuildingInstallation>\n<bldg:BuildingInstallation gml:id=\"");
            x.s(pid);
            x.s("_");
            x.s(name);
            let faces = solids.iter().flat_map(|s| s.faces.iter());
            let kind = SurfaceKind::Trim { eaves };
            installation_rest(x, name, (pid, origin, srs, d), kind, faces);
        }
        if self.lod == GeometryLod::Lod4 {
            lod4::stairs(x, part, pid, origin, srs);
        }
        // Opening polygons of the written walls, kept for the solid's references.
        let mut opening_refs: Vec<(usize, usize)> = Vec::new();
        let seated = seated_changes(part);
        for s in seated_surfaces(part, &seated) {
            let element = boundary_element(s.kind);
            x.s("<bldg:boundedBy>\n<");
            x.s(element);
            x.s(" gml:id=\"");
            x.polygon_id(pid, s.kind, s.index);
            x.s("_s\">\n");
            // A wall against a neighbour says how much of it is (model::Wall::party).
            let party = match s.kind {
                SurfaceKind::Wall => part.walls.get(s.index).map_or(0.0, |w| w.party),
                _ => 0.0,
            };
            if party >= 0.005 {
                x.s("<gen:doubleAttribute name=\"partyWallShare\">\n<gen:value>");
                x.s(&format!("{:.2}", party.min(1.0)));
                x.s("</gen:value>\n</gen:doubleAttribute>\n");
            }
            x.s("<bldg:lod");
            x.s(d);
            x.s("MultiSurface>\n<gml:MultiSurface srsName=\"");
            x.s(srs);
            x.s("\">\n<gml:surfaceMember>\n");
            x.polygon_rings(pid, &s, origin, super::textured(tex, s.kind));
            x.s("</gml:surfaceMember>\n</gml:MultiSurface>\n</bldg:lod");
            x.s(d);
            x.s("MultiSurface>\n");
            if s.kind == SurfaceKind::Wall {
                if let Some(wall) = part.walls.get(s.index) {
                    for (k, o) in wall.openings.iter().enumerate() {
                        let Some(face) = opening_face(wall, o, 0.0) else {
                            continue;
                        };
                        opening_refs.push((s.index, k));
                        let element = match o.kind {
                            OpeningKind::Window => "bldg:Window",
                            OpeningKind::Door => "bldg:Door",
                        };
                        x.s("<bldg:opening>\n<");
                        x.s(element);
                        x.s(" gml:id=\"");
                        x.polygon_id(pid, SurfaceKind::Wall, s.index);
                        x.s("_o");
                        x.uint(k as u64);
                        x.s("\">\n<bldg:lod");
                        x.s(d);
                        x.s("MultiSurface>\n<gml:MultiSurface srsName=\"");
                        x.s(srs);
                        x.s("\">\n<gml:surfaceMember>\n");
                        let kind = SurfaceKind::Opening { wall: s.index };
                        x.polygon(
                            pid,
                            &Surface {
                                kind,
                                index: k,
                                face: &face,
                            },
                            origin,
                        );
                        x.s("</gml:surfaceMember>\n</gml:MultiSurface>\n</bldg:lod");
                        x.s(d);
                        x.s("MultiSurface>\n</");
                        x.s(element);
                        x.s(">\n</bldg:opening>\n");
                    }
                }
            }
            x.s("</");
            x.s(element);
            x.s(">\n</bldg:boundedBy>\n");
        }
        x.s("<bldg:lod");
        x.s(d);
        x.s("Solid>\n<gml:Solid srsName=\"");
        x.s(srs);
        x.s("\">\n<gml:exterior>\n<gml:CompositeSurface>\n");
        let shell = surfaces(part).map(|s| (s.kind, s.index)).chain(
            opening_refs
                .iter()
                .map(|&(wall, k)| (SurfaceKind::Opening { wall }, k)),
        );
        for (kind, index) in shell {
            x.s("<gml:surfaceMember xlink:href=\"#");
            x.polygon_id(pid, kind, index);
            x.s("\"/>\n");
        }
        x.s("</gml:CompositeSurface>\n</gml:exterior>\n</gml:Solid>\n</bldg:lod");
        x.s(d);
        x.s("Solid>\n");
        if self.lod == GeometryLod::Lod4 {
            lod4::rooms(x, part, pid, origin, srs);
        }
    }
}

/// The rest of an outer `bldg:BuildingInstallation` whose `gml:id` is being written: the id's
/// closing quote, its `name`, its `faces` as one `lodN` MultiSurface (polygon `i` of `kind`),
/// and the closing tags. `at` is the part's id, the origin, the SRS name and the LOD digit.
fn installation_rest<'a>(
    x: &mut Xml,
    name: &str,
    (pid, origin, srs, d): (&str, DVec3, &str, &str),
    kind: SurfaceKind,
    faces: impl Iterator<Item = &'a Face>,
) {
    x.s("\">\n<gml:name>");
    x.s(name);
    x.s("</gml:name>\n<bldg:lod");
    x.s(d);
    x.s("Geometry>\n<gml:MultiSurface srsName=\"");
    x.s(srs);
    x.s("\">\n");
    for (i, face) in faces.enumerate() {
        x.s("<gml:surfaceMember>\n");
        x.polygon(
            pid,
            &Surface {
                kind,
                index: i,
                face,
            },
            origin,
        );
        x.s("</gml:surfaceMember>\n");
    }
    x.s("</gml:MultiSurface>\n</bldg:lod");
    x.s(d);
    x.s("Geometry>\n</bldg:BuildingInstallation>\n</bldg:outerBuildingInstallation>\n");
}
