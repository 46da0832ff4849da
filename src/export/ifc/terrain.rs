//! The terrain of a file as an `IfcGeographicElement` `.TERRAIN.` in the site: its body an
//! `IfcTriangulatedFaceSet` (IFC4's tessellated geometry: the TIN's points in one
//! `IfcCartesianPointList3D`, its triangles counter-clockwise seen from above, so that they
//! face up) in the `Body` context, placed at the site's placement (the local frame), and
//! contained in the site (`IfcRelContainedInSpatialStructure`). IFC2X3 has neither: there the
//! terrain is an `IfcBuildingElementProxy` whose body is an `IfcShellBasedSurfaceModel` of the
//! same triangles (`IfcFace`s of shared `IfcCartesianPoint`s).

use std::io::Write;

use crate::export::step::{global_id, Id};
use crate::export::ExportError;
use crate::model::Terrain;

use super::Open;

impl<W: Write> Open<W> {
    /// Writes the terrain `t` and its containment in the site.
    pub(super) fn terrain(&mut self, t: &Terrain) -> Result<(), ExportError> {
        let schema = self.g.schema;
        let (faces, kind) = if schema.ifc4_attributes() {
            let points = self.w.entity("IFCCARTESIANPOINTLIST3D", |a| {
                a.list(|l| {
                    for v in &t.vertices {
                        l.reals(&[v.x, v.y, v.z]);
                    }
                });
                if schema.point_list_tags() {
                    a.null();
                }
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
            (faces, "Tessellation")
        } else {
            (self.terrain_surface(t)?, "SurfaceModel")
        };
        let body_ctx = self.g.body_ctx;
        let rep = self.w.entity("IFCSHAPEREPRESENTATION", |a| {
            a.id(body_ctx).string("Body").string(kind).ids(&[faces]);
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
        let owner = self.g.owner;
        let element = self.w.entity(schema.terrain(), |a| {
            a.guid(&ns, "terrain")
                .opt_id(owner)
                .string("Terrain")
                .string(&description)
                .null()
                .id(placement)
                .id(shape)
                .null();
            if schema.ifc4_attributes() {
                a.enumeration("TERRAIN");
            } else {
                a.null();
            }
        })?;
        let (gid, site) = (global_id(&ns, "site/terrain"), self.site);
        self.w.entity("IFCRELCONTAINEDINSPATIALSTRUCTURE", |a| {
            a.string(&gid)
                .opt_id(owner)
                .null()
                .null()
                .ids(&[element])
                .id(site);
        })?;
        Ok(())
    }

    /// IFC2X3's terrain body: an `IfcShellBasedSurfaceModel` of one `IfcOpenShell` of the
    /// triangles, each an `IfcFace` of an `IfcPolyLoop` of the shared vertices.
    fn terrain_surface(&mut self, t: &Terrain) -> Result<Id, ExportError> {
        let mut points = Vec::with_capacity(t.vertices.len());
        for v in &t.vertices {
            points.push(self.w.entity("IFCCARTESIANPOINT", |a| {
                a.reals(&[v.x, v.y, v.z]);
            })?);
        }
        let mut faces = Vec::with_capacity(t.triangles.len());
        for tri in &t.triangles {
            let Some(corners) = tri
                .iter()
                .map(|&k| points.get(k as usize).copied())
                .collect::<Option<Vec<Id>>>()
            else {
                return Err(ExportError::Invalid(
                    "IFC writer: a terrain triangle names a vertex it does not have".into(),
                ));
            };
            let lp = self.w.entity("IFCPOLYLOOP", |a| {
                a.ids(&corners);
            })?;
            let bound = self.w.entity("IFCFACEOUTERBOUND", |a| {
                a.id(lp).boolean(true);
            })?;
            faces.push(self.w.entity("IFCFACE", |a| {
                a.ids(&[bound]);
            })?);
        }
        let shell = self.w.entity("IFCOPENSHELL", |a| {
            a.ids(&faces);
        })?;
        Ok(self.w.entity("IFCSHELLBASEDSURFACEMODEL", |a| {
            a.ids(&[shell]);
        })?)
    }
}
