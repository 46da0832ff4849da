//! Geometric entities of the IFC writer: points, directions, placements, profiles, extrusions
//! through a wall, product shapes and representations, faces and faceted breps; ring cleaning
//! and vertex keys.

use std::collections::BTreeMap;

use glam::{DVec2, DVec3};

use crate::export::step::Id;
use crate::export::ExportError;
use crate::geometry::ring;

use super::{Render, EPS};

impl Render<'_> {
    fn point3(&mut self, p: DVec3) -> Result<Id, ExportError> {
        if p == DVec3::ZERO {
            return Ok(self.g.origin3);
        }
        Ok(self.w.entity("IFCCARTESIANPOINT", |a| {
            a.reals(&[p.x, p.y, p.z]);
        })?)
    }

    pub(super) fn point2(&mut self, p: DVec2) -> Result<Id, ExportError> {
        if p == DVec2::ZERO {
            return Ok(self.g.origin2);
        }
        Ok(self.w.entity("IFCCARTESIANPOINT", |a| {
            a.reals(&[p.x, p.y]);
        })?)
    }

    fn direction(&mut self, d: DVec3) -> Result<Id, ExportError> {
        if d == DVec3::X {
            return Ok(self.g.dir_x);
        }
        Ok(self.w.entity("IFCDIRECTION", |a| {
            a.reals(&[d.x, d.y, d.z]);
        })?)
    }

    /// An `IfcLocalPlacement` relative to `rel`, at `loc`, with X along `x_dir` (Z up).
    pub(super) fn placement(
        &mut self,
        rel: Id,
        loc: DVec3,
        x_dir: DVec3,
    ) -> Result<Id, ExportError> {
        let a2p = self.axes(loc, x_dir)?;
        Ok(self.w.entity("IFCLOCALPLACEMENT", |a| {
            a.id(rel).id(a2p);
        })?)
    }

    /// An `IfcAxis2Placement3D` at `loc`, with X along `x_dir` (Z up).
    pub(super) fn axes(&mut self, loc: DVec3, x_dir: DVec3) -> Result<Id, ExportError> {
        Ok(if loc == DVec3::ZERO && x_dir == DVec3::X {
            self.g.identity
        } else {
            let p = self.point3(loc)?;
            if x_dir == DVec3::X {
                self.w.entity("IFCAXIS2PLACEMENT3D", |a| {
                    a.id(p).null().null();
                })?
            } else {
                let d = self.direction(x_dir)?;
                let z = self.g.dir_z;
                self.w.entity("IFCAXIS2PLACEMENT3D", |a| {
                    a.id(p).id(z).id(d);
                })?
            }
        })
    }

    pub(super) fn shape(&mut self, reps: &[Id]) -> Result<Id, ExportError> {
        Ok(self.w.entity("IFCPRODUCTDEFINITIONSHAPE", |a| {
            a.null().null().ids(reps);
        })?)
    }

    pub(super) fn representation(
        &mut self,
        ctx: Id,
        ident: &str,
        kind: &str,
        items: &[Id],
    ) -> Result<Id, ExportError> {
        Ok(self.w.entity("IFCSHAPEREPRESENTATION", |a| {
            a.id(ctx).string(ident).string(kind).ids(items);
        })?)
    }

    /// A closed 2D polyline (first point repeated at the end).
    pub(super) fn closed_polyline2(&mut self, ring: &[DVec2]) -> Result<Id, ExportError> {
        let mut pts = Vec::with_capacity(ring.len() + 1);
        for p in ring {
            pts.push(self.point2(*p)?);
        }
        pts.push(pts[0]);
        Ok(self.w.entity("IFCPOLYLINE", |a| {
            a.ids(&pts);
        })?)
    }

    /// An area profile bounded by the closed polyline `outer` with the closed polylines `inner`
    /// as voids: an `IfcArbitraryClosedProfileDef`, or an `IfcArbitraryProfileDefWithVoids`.
    pub(super) fn arbitrary_profile(
        &mut self,
        outer: &[DVec2],
        inner: &[Vec<DVec2>],
    ) -> Result<Id, ExportError> {
        let outer = self.closed_polyline2(outer)?;
        if inner.is_empty() {
            return Ok(self.w.entity("IFCARBITRARYCLOSEDPROFILEDEF", |a| {
                a.enumeration("AREA").null().id(outer);
            })?);
        }
        let mut voids = Vec::with_capacity(inner.len());
        for r in inner {
            voids.push(self.closed_polyline2(r)?);
        }
        Ok(self.w.entity("IFCARBITRARYPROFILEDEFWITHVOIDS", |a| {
            a.enumeration("AREA").null().id(outer).ids(&voids);
        })?)
    }

    /// The shared `IfcAxis2Placement3D(origin, -Y, X)` of profiles drawn in a wall's plane.
    fn vertical(&mut self) -> Result<Id, ExportError> {
        if let Some(id) = self.shared.vertical.get(&()) {
            return Ok(id);
        }
        let (o, ny, x) = (self.g.origin3, self.g.dir_neg_y, self.g.dir_x);
        let id = self.w.entity("IFCAXIS2PLACEMENT3D", |a| {
            a.id(o).id(ny).id(x);
        })?;
        self.shared.vertical.insert((), id);
        Ok(id)
    }

    /// A rectangle `w` x `h` with its lower-left corner at (x0, y0), as a profile.
    pub(super) fn rect_profile(
        &mut self,
        x0: f64,
        y0: f64,
        w: f64,
        h: f64,
    ) -> Result<Id, ExportError> {
        let centre = self.point2(DVec2::new(x0 + w / 2.0, y0 + h / 2.0))?;
        let pos = self.w.entity("IFCAXIS2PLACEMENT2D", |a| {
            a.id(centre).null();
        })?;
        Ok(self.w.entity("IFCRECTANGLEPROFILEDEF", |a| {
            a.enumeration("AREA").null().id(pos).positive(w).positive(h);
        })?)
    }

    /// A profile drawn in the wall's plane (x along, y up) extruded by `depth` into the wall
    /// (+Y) from `y0`.
    pub(super) fn through_wall(
        &mut self,
        profile: Id,
        y0: f64,
        depth: f64,
    ) -> Result<Id, ExportError> {
        let pos = if y0 == 0.0 {
            self.vertical()?
        } else {
            let p = self.point3(DVec3::new(0.0, y0, 0.0))?;
            let (ny, x) = (self.g.dir_neg_y, self.g.dir_x);
            self.w.entity("IFCAXIS2PLACEMENT3D", |a| {
                a.id(p).id(ny).id(x);
            })?
        };
        let nz = self.g.dir_neg_z;
        Ok(self.w.entity("IFCEXTRUDEDAREASOLID", |a| {
            a.id(profile).id(pos).id(nz).positive(depth);
        })?)
    }

    /// Writes one face (outer bound and holes, points shared through `points`).
    pub(super) fn face(
        &mut self,
        rings: &[Vec<DVec3>],
        points: &mut BTreeMap<[i64; 3], Id>,
    ) -> Result<Id, ExportError> {
        let mut bounds = Vec::with_capacity(rings.len());
        for (i, ring) in rings.iter().enumerate() {
            let mut ids = Vec::with_capacity(ring.len());
            for p in ring {
                let k = vkey(*p);
                let id = match points.get(&k) {
                    Some(&id) => id,
                    None => {
                        let id = self.point3(*p)?;
                        points.insert(k, id);
                        id
                    }
                };
                ids.push(id);
            }
            let lp = self.w.entity("IFCPOLYLOOP", |a| {
                a.ids(&ids);
            })?;
            let kind = if i == 0 {
                "IFCFACEOUTERBOUND"
            } else {
                "IFCFACEBOUND"
            };
            bounds.push(self.w.entity(kind, |a| {
                a.id(lp).boolean(true);
            })?);
        }
        Ok(self.w.entity("IFCFACE", |a| {
            a.ids(&bounds);
        })?)
    }

    /// A closed shell as an `IfcFacetedBrep`.
    pub(super) fn brep(&mut self, faces: &[Vec<Vec<DVec3>>]) -> Result<Id, ExportError> {
        let mut points = BTreeMap::new();
        let mut ids = Vec::with_capacity(faces.len());
        for f in faces {
            ids.push(self.face(f, &mut points)?);
        }
        let shell = self.w.entity("IFCCLOSEDSHELL", |a| {
            a.ids(&ids);
        })?;
        Ok(self.w.entity("IFCFACETEDBREP", |a| {
            a.id(shell);
        })?)
    }
}

/// A 2D ring without consecutive (or closing) points within `EPS` ([`ring::dedup_within`]).
pub(super) fn clean2(r: &[DVec2]) -> Vec<DVec2> {
    let mut v = r.to_vec();
    ring::dedup_within(&mut v, EPS);
    v
}

/// [`clean2`] for a 3D ring.
pub(super) fn clean3(r: &[DVec3]) -> Vec<DVec3> {
    let mut v = r.to_vec();
    ring::dedup_within(&mut v, EPS);
    v
}

/// Key of a vertex quantised to micrometres, to share points and match edges.
pub(super) fn vkey(p: DVec3) -> [i64; 3] {
    let q = |v: f64| (v * 1e6).round() as i64;
    [q(p.x), q(p.y), q(p.z)]
}
