//! The terrain of a file as an `IfcGeographicElement` `.TERRAIN.` in the site: its body an
//! `IfcTriangulatedFaceSet` (IFC4's tessellated geometry: the TIN's points in one
//! `IfcCartesianPointList3D`, its triangles counter-clockwise seen from above, so that they
//! face up) in the `Body` context, placed at the site's placement (the local frame), and
//! contained in the site (`IfcRelContainedInSpatialStructure`).

use std::io::Write;

use crate::export::step::global_id;
use crate::export::ExportError;
use crate::model::Terrain;

use super::Open;

impl<W: Write> Open<W> {
    /// Writes the terrain `t` and its containment in the site.
    pub(super) fn terrain(&mut self, t: &Terrain) -> Result<(), ExportError> {
        let points = self.w.entity("IFCCARTESIANPOINTLIST3D", |a| {
            a.list(|l| {
                for v in &t.vertices {
                    l.reals(&[v.x, v.y, v.z]);
                }
            });
        })?;
        let faces = self.w.entity("IFCTRIANGULATEDFACESET", |a| {
            a.id(points).null().boolean(false);
            a.list(|l| {
                for tri in &t.triangles {
                    l.ints(&tri.map(|k| i64::from(k) + 1));
                }
            });
            a.null();
        })?;
        let body_ctx = self.g.body_ctx;
        let rep = self.w.entity("IFCSHAPEREPRESENTATION", |a| {
            a.id(body_ctx)
                .string("Body")
                .string("Tessellation")
                .ids(&[faces]);
        })?;
        let shape = self.w.entity("IFCPRODUCTDEFINITIONSHAPE", |a| {
            a.null().null().ids(&[rep]);
        })?;
        let (site_pl, identity) = (self.g.site_placement, self.g.identity);
        let placement = self.w.entity("IFCLOCALPLACEMENT", |a| {
            a.id(site_pl).id(identity);
        })?;
        let ns = self.g.ns.clone();
        let description = format!("TIN within {} m of the elevation grid", t.tolerance);
        let element = self.w.entity("IFCGEOGRAPHICELEMENT", |a| {
            a.guid(&ns, "terrain")
                .null()
                .string("Terrain")
                .string(&description)
                .null()
                .id(placement)
                .id(shape)
                .null()
                .enumeration("TERRAIN");
        })?;
        let (gid, site) = (global_id(&ns, "site/terrain"), self.site);
        self.w.entity("IFCRELCONTAINEDINSPATIALSTRUCTURE", |a| {
            a.string(&gid).null().null().null().ids(&[element]).id(site);
        })?;
        Ok(())
    }
}
