//! Solids and boundary surfaces of the CityGML writer: which polygons a part has (ground, walls,
//! roof), their semantic surfaces and the LOD1/LOD2 solids.

use glam::DVec3;

use crate::model::{Face, Part, Wall};

use super::{GeometryLod, Renderer};

/// What a polygon is in the building's semantics.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum SurfaceKind {
    Ground,
    Wall,
    Roof,
    /// An opening of wall `wall` (the surface's index is the opening's).
    Opening {
        wall: usize,
    },
    /// A face of balcony `balcony` of wall `wall` (the surface's index is the face's).
    Balcony {
        wall: usize,
        balcony: usize,
    },
    /// A face of the window sills of wall `wall` (the surface's index counts the faces of all
    /// its sills, six each).
    Sill {
        wall: usize,
    },
    /// A face of the part's cornice or eaves solids (`eaves`), in
    /// `crate::export::lod3geom::cornice_solids` or `eaves_solids` order (the surface's index
    /// counts them).
    Trim {
        eaves: bool,
    },
}

/// One polygon to write: its kind, its index in the model's list (for openings and balcony
/// faces, in the wall's or the balcony's list), and its face.
pub(super) struct Surface<'a> {
    pub(super) kind: SurfaceKind,
    pub(super) index: usize,
    pub(super) face: &'a Face,
}

impl Renderer<'_> {
    /// The part's geometry properties, in the schema's order (`lodXSolid` before `boundedBy`).
    pub(super) fn geometry(&mut self, part: &Part, pid: &str) {
        if surfaces(part).next().is_none() {
            // A solid needs at least one surface member; a part without any writes none.
            return;
        }
        if self.lod >= GeometryLod::Lod3 {
            self.geometry_lod3(part, pid);
            return;
        }
        let tex = self.tex.tex;
        let x = &mut *self.x;
        let lod = self.lod.digit();
        x.s("<bldg:lod");
        x.s(lod);
        x.s("Solid>\n<gml:Solid srsName=\"");
        x.s(self.srs);
        x.s("\">\n<gml:exterior>\n<gml:CompositeSurface>\n");
        for s in surfaces(part) {
            match self.lod {
                GeometryLod::Lod1 => {
                    x.s("<gml:surfaceMember>\n");
                    x.polygon_rings(pid, &s, self.origin, super::textured(tex, s.kind));
                    x.s("</gml:surfaceMember>\n");
                }
                GeometryLod::Lod2 | GeometryLod::Lod3 | GeometryLod::Lod4 => {
                    x.s("<gml:surfaceMember xlink:href=\"#");
                    x.polygon_id(pid, s.kind, s.index);
                    x.s("\"/>\n");
                }
            }
        }
        x.s("</gml:CompositeSurface>\n</gml:exterior>\n</gml:Solid>\n</bldg:lod");
        x.s(lod);
        x.s("Solid>\n");
        if self.lod == GeometryLod::Lod1 {
            return;
        }
        for s in surfaces(part) {
            let element = boundary_element(s.kind);
            x.s("<bldg:boundedBy>\n<");
            x.s(element);
            x.s(" gml:id=\"");
            x.polygon_id(pid, s.kind, s.index);
            x.s("_s\">\n<bldg:lod2MultiSurface>\n<gml:MultiSurface srsName=\"");
            x.s(self.srs);
            x.s("\">\n<gml:surfaceMember>\n");
            x.polygon_rings(pid, &s, self.origin, super::textured(tex, s.kind));
            x.s("</gml:surfaceMember>\n</gml:MultiSurface>\n</bldg:lod2MultiSurface>\n</");
            x.s(element);
            x.s(">\n</bldg:boundedBy>\n");
        }
    }
}

/// The writable polygons of a part in output order: ground, walls, roof faces.
pub(super) fn surfaces(part: &Part) -> impl Iterator<Item = Surface<'_>> {
    let ground = std::iter::once(Surface {
        kind: SurfaceKind::Ground,
        index: 0,
        face: &part.ground,
    });
    let walls = part.walls.iter().enumerate().map(|(i, w)| Surface {
        kind: SurfaceKind::Wall,
        index: i,
        face: &w.outline,
    });
    let roofs = part.roof.iter().enumerate().map(|(i, f)| Surface {
        kind: SurfaceKind::Roof,
        index: i,
        face: f,
    });
    ground
        .chain(walls)
        .chain(roofs)
        .filter(|s| ring(&s.face.outer).is_some())
}

/// [`surfaces`] with the ground and walls that `seated` changes (the LOD3 solid's, see
/// [`crate::export::lod3geom::seated_changes`]) in place of the model's.
pub(super) fn seated_surfaces<'a>(
    part: &'a Part,
    seated: &'a [(usize, Face)],
) -> impl Iterator<Item = Surface<'a>> {
    surfaces(part).map(move |s| {
        let fi = match s.kind {
            SurfaceKind::Ground => Some(0),
            SurfaceKind::Wall => Some(s.index + 1),
            _ => None,
        };
        let face = fi
            .and_then(|fi| seated.iter().find(|c| c.0 == fi))
            .map_or(s.face, |c| &c.1);
        Surface { face, ..s }
    })
}

/// The ring without a closing duplicate of its first vertex, or `None` if fewer than 3 remain.
pub(super) fn ring(points: &[DVec3]) -> Option<&[DVec3]> {
    let mut r = points;
    while r.len() > 1 && r.first() == r.last() {
        r = &r[..r.len() - 1];
    }
    (r.len() >= 3).then_some(r)
}

/// The boundary surface element of a part's own polygon kind.
pub(super) fn boundary_element(kind: SurfaceKind) -> &'static str {
    match kind {
        SurfaceKind::Ground => "bldg:GroundSurface",
        SurfaceKind::Roof => "bldg:RoofSurface",
        // Openings and balconies are not boundary surfaces; never asked for.
        SurfaceKind::Wall
        | SurfaceKind::Opening { .. }
        | SurfaceKind::Balcony { .. }
        | SurfaceKind::Sill { .. }
        | SurfaceKind::Trim { .. } => "bldg:WallSurface",
    }
}

/// The walls that are written (see [`surfaces`]) with their indices: only their openings and
/// balconies are.
pub(super) fn written_walls(part: &Part) -> impl Iterator<Item = (usize, &Wall)> {
    surfaces(part)
        .filter(|s| s.kind == SurfaceKind::Wall)
        .filter_map(|s| part.walls.get(s.index).map(|w| (s.index, w)))
}
