//! LOD4 additions of the IFC writer: a part's interiors ([`Part::interior`]) in its LOD3 storeys.
//!
//! Per [`StoreyInterior`], in the `IfcBuildingStorey` of its `storey`:
//!
//! - one `IfcSpace` `.SPACE.` per room (Name = the room's name, LongName = its usage), whose
//!   `Body` is the room polygon extruded from the floor to the ceiling (`SweptSolid`), with an
//!   `IfcElementQuantity` `Qto_SpaceBaseQuantities` (NetFloorArea, GrossPerimeter, Height,
//!   NetVolume); the storey aggregates its spaces (`IfcRelAggregates`);
//! - one `IfcWallStandardCase` `.PARTITIONING.` per interior wall: a rectangle profile centred
//!   on the wall's centre line (the element is placed half its thickness to the right of the
//!   line, so that its body spans +Y from 0 to the thickness like the exterior walls), extruded
//!   from the floor to the ceiling, with an `Axis`, the shared `IfcMaterialLayerSetUsage` of its
//!   thickness and a `Pset_WallCommon` with IsExternal false;
//! - one `IfcOpeningElement` per interior door voiding its wall, filled by an `IfcDoor` of a
//!   shared `IfcDoorType` (the LOD3 machinery: same type key, mapped item, placement centred in
//!   the wall), from [`lod4geom::DOOR_SILL`] above the floor;
//! - an `IfcStair` `.STRAIGHT_RUN_STAIR.` when the storey has a stair: one extruded block per
//!   step ([`lod4geom::stair_steps`]);
//! - above the ground storey, an `IfcSlab` `.FLOOR.`: the rooms minus the well of the stair
//!   coming up from the storey below, extruded down by the slab thickness from the floor (it
//!   is also the ceiling of the storey below).
//!
//! Everything but the spaces is contained in the storey with the LOD3 elements.

use std::collections::BTreeMap;

use glam::{DVec2, DVec3};

use super::openings::Host;
use super::{ElementFrame, Render, EPS};
use crate::export::lod4geom;
use crate::export::step::Id;
use crate::export::ExportError;
use crate::model::{Face, Opening, OpeningKind, Part, StoreyInterior, Wall};

impl Render<'_> {
    /// Writes the interiors of `part` into its storeys (`storeys[i]` placed by `frames[i]`),
    /// adding the contained elements to `contained[i]` and the interior walls to `by_usage`.
    pub(super) fn interiors(
        &mut self,
        part: &Part,
        key: &str,
        storeys: &[Id],
        frames: &[ElementFrame],
        contained: &mut [Vec<Id>],
        by_usage: &mut BTreeMap<Id, Vec<Id>>,
    ) -> Result<(), ExportError> {
        let pk = &part.key;
        let mut partitions = Vec::new();
        for (k, s) in part.interior.iter().enumerate() {
            let i = s.storey;
            if !(s.floor_z.is_finite() && s.ceiling_z.is_finite()) {
                continue;
            }
            let (Some(&storey), Some(frame)) = (storeys.get(i), frames.get(i)) else {
                continue;
            };
            let path = format!("{pk}/interior/{i}");
            // Spaces, aggregated under the storey.
            let mut spaces = Vec::with_capacity(s.rooms.len());
            for r in 0..s.rooms.len() {
                if let Some(id) = self.space(s, r, frame, key, &format!("{path}/space/{r}"))? {
                    spaces.push(id);
                }
            }
            if !spaces.is_empty() {
                self.w.entity("IFCRELAGGREGATES", |a| {
                    a.guid(key, &format!("{path}/spaces"))
                        .opt_id(self.g.owner)
                        .null()
                        .null()
                        .id(storey)
                        .ids(&spaces);
                })?;
            }
            // Interior walls and their doors.
            for (wi, w) in s.walls.iter().enumerate() {
                let wpath = format!("{path}/wall/{wi}");
                let Some((wall, id, pl)) = self.partition(s, wi, frame, key, &wpath)? else {
                    continue;
                };
                let usage = self.usage(w.thickness)?;
                by_usage.entry(usage).or_default().push(id);
                partitions.push(id);
                contained[i].push(id);
                for (di, d) in s.doors.iter().enumerate().filter(|(_, d)| d.wall == wi) {
                    let Some((z0, z1)) = lod4geom::door_heights(s, d) else {
                        continue;
                    };
                    if !(d.u0 > 0.0 && d.u1 <= wall.length() && d.u1 - d.u0 > 0.01) {
                        continue;
                    }
                    let o = Opening {
                        kind: OpeningKind::Door,
                        u0: d.u0,
                        u1: d.u1,
                        z0,
                        z1,
                        color: lod4geom::DOOR_COLOR,
                        frame_color: lod4geom::DOOR_FRAME_COLOR,
                        glazed: false,
                        framed: true,
                        frame_size: None,
                        rounding: None,
                    };
                    let dpath = format!("{path}/door/{di}");
                    if let Some(fill) = self.opening(
                        &Host {
                            wall: &wall,
                            id,
                            placement: pl,
                        },
                        &o,
                        key,
                        &dpath,
                        (wi, di),
                    )? {
                        contained[i].push(fill);
                    }
                }
            }
            if let Some(st) = &s.stair {
                if let Some(id) = self.stair(s, st, frame, key, &format!("{path}/stair"))? {
                    contained[i].push(id);
                }
            }
            let below = k
                .checked_sub(1)
                .and_then(|b| part.interior.get(b))
                .filter(|b| b.storey + 1 == i);
            if let Some(id) = self.floor(below, s, frame, key, &format!("{path}/slab"))? {
                contained[i].push(id);
            }
        }
        if !partitions.is_empty() {
            self.wall_common(key, &format!("{pk}/partitions/pset"), false, &partitions)?;
        }
        Ok(())
    }

    /// A placement in `frame` at height `z` (local frame), axes unrotated.
    fn level_placement(&mut self, frame: &ElementFrame, z: f64) -> Result<Id, ExportError> {
        let fp = frame.placement;
        self.placement(fp, DVec3::new(0.0, 0.0, z - frame.origin.z), DVec3::X)
    }

    /// A ring relative to the frame, as an `IfcArbitraryClosedProfileDef` (with voids when
    /// `holes` is not empty).
    fn plan_profile(
        &mut self,
        frame: &ElementFrame,
        outer: &[DVec2],
        holes: &[Vec<DVec2>],
    ) -> Result<Id, ExportError> {
        let shift = frame.origin.truncate();
        let rel = |r: &[DVec2]| r.iter().map(|p| *p - shift).collect::<Vec<_>>();
        let curve = self.closed_polyline2(&rel(outer))?;
        if holes.is_empty() {
            return Ok(self.w.entity("IFCARBITRARYCLOSEDPROFILEDEF", |a| {
                a.enumeration("AREA").null().id(curve);
            })?);
        }
        let mut inner = Vec::with_capacity(holes.len());
        for h in holes {
            inner.push(self.closed_polyline2(&rel(h))?);
        }
        Ok(self.w.entity("IFCARBITRARYPROFILEDEFWITHVOIDS", |a| {
            a.enumeration("AREA").null().id(curve).ids(&inner);
        })?)
    }

    /// The `IfcSpace` of room `r`, with its base quantities; `None` for a degenerate room.
    fn space(
        &mut self,
        s: &StoreyInterior,
        r: usize,
        frame: &ElementFrame,
        key: &str,
        path: &str,
    ) -> Result<Option<Id>, ExportError> {
        let room = &s.rooms[r];
        let Some(ring) = lod4geom::room_ring(room) else {
            return Ok(None);
        };
        let height = s.ceiling_z - s.floor_z;
        if height.is_nan() || height <= EPS {
            return Ok(None);
        }
        let profile = self.plan_profile(frame, &ring, &[])?;
        let up = self.g.dir_z;
        let solid = self.w.entity("IFCEXTRUDEDAREASOLID", |a| {
            a.id(profile)
                .opt_id(self.g.position)
                .id(up)
                .positive(height);
        })?;
        let body_ctx = self.g.body_ctx;
        let rep = self.representation(body_ctx, "Body", "SweptSolid", &[solid])?;
        let shape = self.shape(&[rep])?;
        let pl = self.level_placement(frame, s.floor_z)?;
        let space = self.w.entity("IFCSPACE", |a| {
            a.guid(key, path)
                .opt_id(self.g.owner)
                .string(&room.name)
                .null()
                .null()
                .id(pl)
                .id(shape)
                .string(&room.usage)
                .enumeration("ELEMENT")
                // (IFC2X3: InteriorOrExteriorSpace.)
                .enumeration(if self.g.schema.ifc4_attributes() {
                    "SPACE"
                } else {
                    "INTERNAL"
                })
                .null();
        })?;
        let area = crate::geometry::ring_signed_area(&ring).abs();
        let perimeter: f64 = (0..ring.len())
            .map(|i| ring[i].distance(ring[(i + 1) % ring.len()]))
            .sum();
        let mut quantities = Vec::with_capacity(4);
        for (name, kind, value) in [
            ("NetFloorArea", "IFCQUANTITYAREA", area),
            ("GrossPerimeter", "IFCQUANTITYLENGTH", perimeter),
            ("Height", "IFCQUANTITYLENGTH", height),
            ("NetVolume", "IFCQUANTITYVOLUME", area * height),
        ] {
            quantities.push(self.w.entity(kind, |a| {
                a.string(name).null().null().real(value);
                // Formula (IFC4).
                if self.g.schema.ifc4_attributes() {
                    a.null();
                }
            })?);
        }
        let qto = self.w.entity("IFCELEMENTQUANTITY", |a| {
            a.guid(key, &format!("{path}/qto"))
                .opt_id(self.g.owner)
                .string("Qto_SpaceBaseQuantities")
                .null()
                .null()
                .ids(&quantities);
        })?;
        self.w.entity("IFCRELDEFINESBYPROPERTIES", |a| {
            a.guid(key, &format!("{path}/qto/rel"))
                .opt_id(self.g.owner)
                .null()
                .null()
                .ids(&[space])
                .id(qto);
        })?;
        Ok(Some(space))
    }

    /// Interior wall `wi` of `s` as an `IfcWallStandardCase`: returns the wall as the LOD3
    /// opening code sees it (its body's right face from `start` to `end`), its id and placement.
    fn partition(
        &mut self,
        s: &StoreyInterior,
        wi: usize,
        frame: &ElementFrame,
        key: &str,
        path: &str,
    ) -> Result<Option<(Wall, Id, Id)>, ExportError> {
        let w = &s.walls[wi];
        let len = w.a.distance(w.b);
        let height = s.ceiling_z - s.floor_z;
        if !(len > EPS && w.thickness > EPS && height > EPS) {
            return Ok(None);
        }
        let dir = (w.b - w.a) / len;
        // The body spans +Y (left of a->b) from 0 to the thickness: start half of it right.
        let shift = -dir.perp() * (w.thickness / 2.0);
        let (start, end) = (w.a + shift, w.b + shift);
        let loc = start.extend(s.floor_z) - frame.origin;
        let placement = self.placement(frame.placement, loc, dir.extend(0.0))?;

        // The axis is the reference line of the shared layer set usage (offset 0, body on +Y),
        // as for the exterior walls.
        let (origin2, end2) = (self.g.origin2, self.point2(DVec2::new(len, 0.0))?);
        let axis_line = self.w.entity("IFCPOLYLINE", |a| {
            a.ids(&[origin2, end2]);
        })?;
        let axis_ctx = self.g.axis_ctx;
        let axis_rep = self.representation(axis_ctx, "Axis", "Curve2D", &[axis_line])?;
        let profile = self.rect_profile(0.0, 0.0, len, w.thickness)?;
        let up = self.g.dir_z;
        let solid = self.w.entity("IFCEXTRUDEDAREASOLID", |a| {
            a.id(profile)
                .opt_id(self.g.position)
                .id(up)
                .positive(height);
        })?;
        self.styled(solid, lod4geom::INTERIOR_WALL_COLOR)?;
        let body_ctx = self.g.body_ctx;
        let body_rep = self.representation(body_ctx, "Body", "SweptSolid", &[solid])?;
        let shape = self.shape(&[axis_rep, body_rep])?;
        let name = format!("Interior wall {}.{wi}", s.storey);
        let schema = self.g.schema;
        let id = self.w.entity(schema.wall(), |a| {
            a.guid(key, path)
                .opt_id(self.g.owner)
                .string(&name)
                .null()
                .null()
                .id(placement)
                .id(shape)
                .null();
            if schema.ifc4_attributes() {
                a.enumeration("PARTITIONING");
            }
        })?;
        let (f, c) = (s.floor_z, s.ceiling_z);
        let wall = Wall {
            start,
            end,
            base_z: f,
            top_z: c,
            thickness: w.thickness,
            outline: Face::new(vec![
                start.extend(f),
                end.extend(f),
                end.extend(c),
                start.extend(c),
            ]),
            storey: s.storey,
            openings: Vec::new(),
            balconies: Vec::new(),
            party: 0.0,
        };
        Ok(Some((wall, id, placement)))
    }

    /// The stair of storey `s`: one extruded block per step; `None` when it has no step.
    fn stair(
        &mut self,
        s: &StoreyInterior,
        st: &crate::model::Stair,
        frame: &ElementFrame,
        key: &str,
        path: &str,
    ) -> Result<Option<Id>, ExportError> {
        let steps = lod4geom::stair_steps(s, st);
        if steps.is_empty() {
            return Ok(None);
        }
        let up = self.g.dir_z;
        let mut items = Vec::with_capacity(steps.len());
        for step in &steps {
            let profile = self.plan_profile(frame, &step.ring, &[])?;
            items.push(self.w.entity("IFCEXTRUDEDAREASOLID", |a| {
                a.id(profile)
                    .opt_id(self.g.position)
                    .id(up)
                    .positive(step.z1 - step.z0);
            })?);
        }
        for &item in &items {
            self.styled(item, lod4geom::STAIR_COLOR)?;
        }
        let body_ctx = self.g.body_ctx;
        let rep = self.representation(body_ctx, "Body", "SweptSolid", &items)?;
        let shape = self.shape(&[rep])?;
        let pl = self.level_placement(frame, s.floor_z)?;
        Ok(Some(self.w.entity("IFCSTAIR", |a| {
            a.guid(key, path)
                .opt_id(self.g.owner)
                .string("Stair")
                .null()
                .null()
                .id(pl)
                .id(shape)
                .null()
                .enumeration("STRAIGHT_RUN_STAIR");
        })?))
    }

    /// The floor slab of storey `s` above `below` ([`lod4geom::floor_slab`]); `None` for the
    /// ground storey or an empty slab.
    fn floor(
        &mut self,
        below: Option<&StoreyInterior>,
        s: &StoreyInterior,
        frame: &ElementFrame,
        key: &str,
        path: &str,
    ) -> Result<Option<Id>, ExportError> {
        let (pieces, thickness) = lod4geom::floor_slab(below, s);
        if pieces.is_empty() {
            return Ok(None);
        }
        let down = self.g.dir_neg_z;
        let mut items = Vec::with_capacity(pieces.len());
        for p in &pieces {
            let profile = self.plan_profile(frame, &p.outer, &p.holes)?;
            items.push(self.w.entity("IFCEXTRUDEDAREASOLID", |a| {
                a.id(profile)
                    .opt_id(self.g.position)
                    .id(down)
                    .positive(thickness);
            })?);
        }
        for &item in &items {
            self.styled(item, lod4geom::SLAB_COLOR)?;
        }
        let body_ctx = self.g.body_ctx;
        let rep = self.representation(body_ctx, "Body", "SweptSolid", &items)?;
        let shape = self.shape(&[rep])?;
        let pl = self.level_placement(frame, s.floor_z)?;
        let name = format!("Floor {}", s.storey);
        Ok(Some(self.w.entity("IFCSLAB", |a| {
            a.guid(key, path)
                .opt_id(self.g.owner)
                .string(&name)
                .null()
                .null()
                .id(pl)
                .id(shape)
                .null()
                .enumeration("FLOOR");
        })?))
    }
}
