//! Roofs and slabs of the IFC writer: the base slab and the `IfcRoof` (closed brep, flat roof
//! prisms or surface model).

use std::collections::BTreeMap;

use glam::{DVec2, DVec3};

use crate::export::step::Id;
use crate::export::ExportError;
use crate::model::Part;

use super::shapes::{clean2, clean3, vkey};
use super::{roof_type, ElementFrame, Render, EPS, FLAT_ROOF_THICKNESS, SLAB_THICKNESS};

impl Render<'_> {
    /// The base slab: the footprint extruded down by [`SLAB_THICKNESS`] from the part's base.
    pub(super) fn slab(
        &mut self,
        part: &Part,
        frame: &ElementFrame,
        gid: &str,
    ) -> Result<Option<Id>, ExportError> {
        let shift = frame.origin.truncate();
        let rel = |r: &Vec<DVec2>| clean2(&r.iter().map(|p| *p - shift).collect::<Vec<_>>());
        let outer = rel(&part.footprint.outer);
        if outer.len() < 3 || crate::geometry::ring_signed_area(&outer).abs() <= EPS {
            return Ok(None);
        }
        let holes: Vec<Vec<DVec2>> = part
            .footprint
            .holes
            .iter()
            .map(rel)
            .filter(|h| h.len() >= 3 && crate::geometry::ring_signed_area(h).abs() > EPS)
            .collect();
        let outer_curve = self.closed_polyline2(&outer)?;
        let profile = if holes.is_empty() {
            self.w.entity("IFCARBITRARYCLOSEDPROFILEDEF", |a| {
                a.enumeration("AREA").null().id(outer_curve);
            })?
        } else {
            let mut inner = Vec::with_capacity(holes.len());
            for h in &holes {
                inner.push(self.closed_polyline2(h)?);
            }
            self.w.entity("IFCARBITRARYPROFILEDEFWITHVOIDS", |a| {
                a.enumeration("AREA").null().id(outer_curve).ids(&inner);
            })?
        };
        let down = self.g.dir_neg_z;
        let solid = self.w.entity("IFCEXTRUDEDAREASOLID", |a| {
            a.id(profile)
                .opt_id(self.g.position)
                .id(down)
                .positive(SLAB_THICKNESS);
        })?;
        let body_ctx = self.g.body_ctx;
        let rep = self.representation(body_ctx, "Body", "SweptSolid", &[solid])?;
        let shape = self.shape(&[rep])?;
        let pl = self.placement(frame.placement, DVec3::ZERO, DVec3::X)?;
        Ok(Some(self.w.entity("IFCSLAB", |a| {
            a.string(gid)
                .opt_id(self.g.owner)
                .string("Ground slab")
                .null()
                .null()
                .id(pl)
                .id(shape)
                .null();
            a.enumeration("BASESLAB");
        })?))
    }

    /// The roof: see the module documentation for which representation is chosen.
    pub(super) fn roof(
        &mut self,
        part: &Part,
        frame: &ElementFrame,
        gid: &str,
    ) -> Result<Option<Id>, ExportError> {
        // Faces relative to the element frame, cleaned; degenerate ones dropped.
        let faces: Vec<Vec<Vec<DVec3>>> = part
            .roof
            .iter()
            .filter_map(|f| {
                let outer = clean3(
                    &f.outer
                        .iter()
                        .map(|p| *p - frame.origin)
                        .collect::<Vec<_>>(),
                );
                if outer.len() < 3 || crate::geometry::newell_normal(&outer).length() <= EPS * EPS {
                    return None;
                }
                let mut rings = vec![outer];
                for h in &f.holes {
                    let h = clean3(&h.iter().map(|p| *p - frame.origin).collect::<Vec<_>>());
                    if h.len() >= 3 && crate::geometry::newell_normal(&h).length() > EPS * EPS {
                        rings.push(h);
                    }
                }
                Some(rings)
            })
            .collect();
        if faces.is_empty() {
            return Ok(None);
        }
        let horizontal = |f: &Vec<Vec<DVec3>>| {
            crate::geometry::newell_normal(&f[0]).normalize_or_zero().z > 0.9999
        };

        let mut items = Vec::new();
        let kind;
        if faces.iter().all(horizontal) {
            // Thin prisms below each flat face: top, bottom (reversed), one quad per ring edge.
            let thickness = FLAT_ROOF_THICKNESS
                .min((part.top_z - part.base_z) / 2.0)
                .max(0.01);
            for f in &faces {
                let down = DVec3::new(0.0, 0.0, -thickness);
                let mut prism = vec![f.clone()];
                prism.push(
                    f.iter()
                        .map(|r| r.iter().rev().map(|p| *p + down).collect())
                        .collect(),
                );
                for ring in f {
                    for i in 0..ring.len() {
                        let (a, c) = (ring[i], ring[(i + 1) % ring.len()]);
                        prism.push(vec![vec![a, a + down, c + down, c]]);
                    }
                }
                items.push(self.brep(&prism)?);
            }
            kind = "Brep";
        } else {
            // Roof faces closed by the footprint at eave height, facing down.
            let eave = part.eave_z - frame.origin.z;
            let shift = frame.origin.truncate();
            let lift = |r: &Vec<DVec2>| -> Vec<DVec3> {
                clean3(
                    &r.iter()
                        .rev()
                        .map(|p| (*p - shift).extend(eave))
                        .collect::<Vec<_>>(),
                )
            };
            let bottom: Vec<Vec<DVec3>> = part
                .footprint
                .rings()
                .map(lift)
                .filter(|r| r.len() >= 3)
                .collect();
            let mut shell = faces.clone();
            if !bottom.is_empty() {
                shell.push(bottom);
            }
            if is_closed_shell(&shell) {
                items.push(self.brep(&shell)?);
                kind = "Brep";
            } else {
                let mut points = BTreeMap::new();
                let mut ids = Vec::with_capacity(faces.len());
                for f in &faces {
                    ids.push(self.face(f, &mut points)?);
                }
                let open_shell = self.w.entity("IFCOPENSHELL", |a| {
                    a.ids(&ids);
                })?;
                items.push(self.w.entity("IFCSHELLBASEDSURFACEMODEL", |a| {
                    a.ids(&[open_shell]);
                })?);
                kind = "SurfaceModel";
            }
        }
        for &item in &items {
            self.styled_as(item, part.roof_color, part.roof_material)?;
        }
        let body_ctx = self.g.body_ctx;
        let rep = self.representation(body_ctx, "Body", kind, &items)?;
        let shape = self.shape(&[rep])?;
        let pl = self.placement(frame.placement, DVec3::ZERO, DVec3::X)?;
        Ok(Some(self.w.entity("IFCROOF", |a| {
            a.string(gid)
                .opt_id(self.g.owner)
                .string("Roof")
                .null()
                .null()
                .id(pl)
                .id(shape)
                .null();
            a.enumeration(roof_type(part.roof_shape));
        })?))
    }
}

/// Whether the faces (outer rings and holes, each a cleaned ring) form a closed, consistently
/// oriented shell: every directed edge appears once and its reverse appears once.
pub(super) fn is_closed_shell(faces: &[Vec<Vec<DVec3>>]) -> bool {
    let mut edges: BTreeMap<([i64; 3], [i64; 3]), u32> = BTreeMap::new();
    for face in faces {
        for ring in face {
            for i in 0..ring.len() {
                let e = (vkey(ring[i]), vkey(ring[(i + 1) % ring.len()]));
                *edges.entry(e).or_insert(0) += 1;
            }
        }
    }
    !edges.is_empty()
        && edges
            .iter()
            .all(|(&(a, b), &n)| n == 1 && edges.get(&(b, a)) == Some(&1))
}
