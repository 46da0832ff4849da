//! Walls of the IFC writer (`IfcWallStandardCase`, rectangular or gable) and, at LOD3, the
//! balconies (`IfcSlab` `.FLOOR.` and `IfcRailing`) and window sills
//! (`IfcBuildingElementProxy`) on them.

use glam::{DVec2, DVec3};

use crate::export::lod3geom;
use crate::export::step::Id;
use crate::export::ExportError;
use crate::model::{Balcony, Part, Wall};

use super::shapes::clean2;
use super::{ElementFrame, Render, BALCONY_THICKNESS, EPS, RAILING_HEIGHT, RAILING_THICKNESS};

impl Render<'_> {
    /// One `IfcWallStandardCase` and its placement, or `None` for a degenerate wall (no length,
    /// height or thickness), which has no valid solid.
    pub(super) fn wall(
        &mut self,
        part: &Part,
        wall: &Wall,
        frame: &ElementFrame,
        gid: &str,
        index: usize,
    ) -> Result<Option<(Id, Id)>, ExportError> {
        let len = wall.length();
        let height = wall.top_z - wall.base_z;
        if len <= EPS || wall.thickness <= EPS {
            return Ok(None);
        }
        let dir2 = (wall.end - wall.start) / len;
        // The outline in the wall's plane: u along the wall, v up from the wall base.
        let uv: Vec<DVec2> = clean2(
            &wall
                .outline
                .outer
                .iter()
                .map(|p| DVec2::new((p.truncate() - wall.start).dot(dir2), p.z - wall.base_z))
                .collect::<Vec<_>>(),
        );
        let near = |a: f64, b: f64| (a - b).abs() <= 1e-3;
        let is_rect = uv.len() < 3
            || (uv.len() == 4
                && uv.iter().all(|p| {
                    (near(p.x, 0.0) || near(p.x, len)) && (near(p.y, 0.0) || near(p.y, height))
                }));
        if is_rect && height <= EPS {
            return Ok(None);
        }
        if !is_rect && (uv.len() < 3 || crate::geometry::ring_signed_area(&uv).abs() <= EPS * EPS) {
            return Ok(None);
        }

        let loc = DVec3::new(wall.start.x, wall.start.y, wall.base_z) - frame.origin;
        let placement = self.placement(frame.placement, loc, DVec3::new(dir2.x, dir2.y, 0.0))?;

        let end = self.point2(DVec2::new(len, 0.0))?;
        let origin2 = self.g.origin2;
        let axis_line = self.w.entity("IFCPOLYLINE", |a| {
            a.ids(&[origin2, end]);
        })?;
        let axis_ctx = self.g.axis_ctx;
        let axis_rep = self.representation(axis_ctx, "Axis", "Curve2D", &[axis_line])?;

        let solid = if is_rect {
            let centre = self.point2(DVec2::new(len / 2.0, wall.thickness / 2.0))?;
            let pos = self.w.entity("IFCAXIS2PLACEMENT2D", |a| {
                a.id(centre).null();
            })?;
            let profile = self.w.entity("IFCRECTANGLEPROFILEDEF", |a| {
                a.enumeration("AREA")
                    .null()
                    .id(pos)
                    .positive(len)
                    .positive(wall.thickness);
            })?;
            let up = self.g.dir_z;
            self.w.entity("IFCEXTRUDEDAREASOLID", |a| {
                a.id(profile)
                    .opt_id(self.g.position)
                    .id(up)
                    .positive(height);
            })?
        } else {
            // Profile in the wall's vertical plane: Position maps profile x to the wall's X and
            // profile y to Z (its own Z is -Y), so extruding along its -Z goes to +Y, inside.
            let curve = self.closed_polyline2(&uv)?;
            let profile = self.w.entity("IFCARBITRARYCLOSEDPROFILEDEF", |a| {
                a.enumeration("AREA").null().id(curve);
            })?;
            let (o, ny, x, nz) = (
                self.g.origin3,
                self.g.dir_neg_y,
                self.g.dir_x,
                self.g.dir_neg_z,
            );
            let pos = self.w.entity("IFCAXIS2PLACEMENT3D", |a| {
                a.id(o).id(ny).id(x);
            })?;
            self.w.entity("IFCEXTRUDEDAREASOLID", |a| {
                a.id(profile).id(pos).id(nz).positive(wall.thickness);
            })?
        };
        self.styled_as(solid, part.wall_color, part.wall_material)?;
        let body_ctx = self.g.body_ctx;
        let body_rep = self.representation(body_ctx, "Body", "SweptSolid", &[solid])?;
        let shape = self.shape(&[axis_rep, body_rep])?;
        let name = format!("Wall {index}");
        let schema = self.g.schema;
        let id = self.w.entity(schema.wall(), |a| {
            a.string(gid)
                .opt_id(self.g.owner)
                .string(&name)
                .null()
                .null()
                .id(placement)
                .id(shape)
                .null();
            if schema.ifc4_attributes() {
                a.enumeration("SOLIDWALL");
            }
        })?;
        Ok(Some((id, placement)))
    }

    /// A balcony of `wall`: an `IfcSlab` `.FLOOR.` (its top at the balcony's floor height) and
    /// an `IfcRailing` `.BALUSTRADE.` on its three free edges, both placed like the wall but at
    /// the balcony's height, relative to the storey. Nothing for a degenerate balcony.
    pub(super) fn balcony(
        &mut self,
        wall: &Wall,
        b: &Balcony,
        frame: &ElementFrame,
        key: &str,
        path: &str,
    ) -> Result<Vec<Id>, ExportError> {
        let len = wall.length();
        let (u0, u1) = (b.u0.max(0.0), b.u1.min(len));
        let (w, depth) = (u1 - u0, b.depth);
        if len <= EPS || w <= 4.0 * RAILING_THICKNESS || depth <= 2.0 * RAILING_THICKNESS {
            return Ok(Vec::new());
        }
        let dir2 = (wall.end - wall.start) / len;
        let loc = DVec3::new(wall.start.x, wall.start.y, b.z) - frame.origin;
        let axes = self.axes(loc, DVec3::new(dir2.x, dir2.y, 0.0))?;
        let body_ctx = self.g.body_ctx;

        // Slab: outside is -Y in the wall's frame.
        let profile = self.rect_profile(u0, -depth, w, depth)?;
        let down = self.g.dir_neg_z;
        let solid = self.w.entity("IFCEXTRUDEDAREASOLID", |a| {
            a.id(profile)
                .opt_id(self.g.position)
                .id(down)
                .positive(BALCONY_THICKNESS);
        })?;
        self.styled(solid, b.color)?;
        let rep = self.representation(body_ctx, "Body", "SweptSolid", &[solid])?;
        let shape = self.shape(&[rep])?;
        let fp = frame.placement;
        let pl = self.w.entity("IFCLOCALPLACEMENT", |a| {
            a.id(fp).id(axes);
        })?;
        let slab = self.w.entity("IFCSLAB", |a| {
            a.guid(key, path)
                .opt_id(self.g.owner)
                .string("Balcony")
                .null()
                .null()
                .id(pl)
                .id(shape)
                .null()
                .enumeration("FLOOR");
        })?;

        // Railing: a U along the three free edges, counter-clockwise.
        let t = RAILING_THICKNESS;
        let v = DVec2::new;
        let ring = [
            v(u0, 0.0),
            v(u0, -depth),
            v(u1, -depth),
            v(u1, 0.0),
            v(u1 - t, 0.0),
            v(u1 - t, t - depth),
            v(u0 + t, t - depth),
            v(u0 + t, 0.0),
        ];
        let curve = self.closed_polyline2(&ring)?;
        let profile = self.w.entity("IFCARBITRARYCLOSEDPROFILEDEF", |a| {
            a.enumeration("AREA").null().id(curve);
        })?;
        let up = self.g.dir_z;
        let solid = self.w.entity("IFCEXTRUDEDAREASOLID", |a| {
            a.id(profile)
                .opt_id(self.g.position)
                .id(up)
                .positive(RAILING_HEIGHT);
        })?;
        self.styled(solid, b.color)?;
        let rep = self.representation(body_ctx, "Body", "SweptSolid", &[solid])?;
        let shape = self.shape(&[rep])?;
        let pl = self.w.entity("IFCLOCALPLACEMENT", |a| {
            a.id(fp).id(axes);
        })?;
        let railing = self.w.entity("IFCRAILING", |a| {
            a.guid(key, &format!("{path}/railing"))
                .opt_id(self.g.owner)
                .string("Balcony railing")
                .null()
                .null()
                .id(pl)
                .id(shape)
                .null()
                .enumeration("BALUSTRADE");
        })?;
        Ok(vec![slab, railing])
    }

    /// The window sills of `wall` (`crate::export::lod3geom::sills`): one
    /// `IfcBuildingElementProxy` named `Window sills` (IFC4: `.USERDEFINED.`, ObjectType
    /// `WindowSill`), placed like the wall relative to the storey, its body one
    /// `IfcExtrudedAreaSolid` box per sill in front of the wall. `None` when the wall has none.
    pub(super) fn sills(
        &mut self,
        wall: &Wall,
        frame: &ElementFrame,
        key: &str,
        path: &str,
    ) -> Result<Option<Id>, ExportError> {
        let sills = lod3geom::sills(wall);
        let len = wall.length();
        if sills.is_empty() || len <= EPS {
            return Ok(None);
        }
        let dir2 = (wall.end - wall.start) / len;
        let loc = DVec3::new(wall.start.x, wall.start.y, wall.base_z) - frame.origin;
        let axes = self.axes(loc, DVec3::new(dir2.x, dir2.y, 0.0))?;
        let up = self.g.dir_z;
        let mut items = Vec::with_capacity(sills.len());
        for s in &sills {
            // Outside is -Y in the wall's frame.
            let profile = self.rect_profile(
                s.u0,
                -lod3geom::SILL_PROJECTION,
                s.u1 - s.u0,
                lod3geom::SILL_PROJECTION,
            )?;
            let bottom = s.top - lod3geom::SILL_THICKNESS - wall.base_z;
            let position = self.axes(DVec3::new(0.0, 0.0, bottom), DVec3::X)?;
            let solid = self.w.entity("IFCEXTRUDEDAREASOLID", |a| {
                a.id(profile)
                    .id(position)
                    .id(up)
                    .positive(lod3geom::SILL_THICKNESS);
            })?;
            self.styled(solid, lod3geom::SILL_COLOR)?;
            items.push(solid);
        }
        let body_ctx = self.g.body_ctx;
        let rep = self.representation(body_ctx, "Body", "SweptSolid", &items)?;
        let shape = self.shape(&[rep])?;
        let fp = frame.placement;
        let pl = self.w.entity("IFCLOCALPLACEMENT", |a| {
            a.id(fp).id(axes);
        })?;
        let id = self.proxy(
            |a| a.guid(key, path),
            "Window sills",
            "WindowSill",
            pl,
            shape,
        )?;
        Ok(Some(id))
    }
}
