//! Base quantities (IFC4 `Qto_*BaseQuantities`): what a planner tabulates first, on every
//! building (`Qto_BuildingBaseQuantities`: Height, EavesHeight, FootprintArea,
//! GrossFloorArea, GrossVolume) and storey (`Qto_BuildingStoreyBaseQuantities`: GrossHeight,
//! GrossPerimeter, GrossFloorArea, GrossVolume). Spaces get theirs in `lod4`.
//!
//! Measured on the model: a part's footprint area is its ground polygon's (holes out), its
//! volume the closed solid of its ground, walls and roof (the divergence theorem over the
//! faces; wall openings do not count, they are filled); a storey's floor area is its part's
//! footprint, its height the distance to the next storey's floor (the top storey's to the
//! eaves). The building's footprint area counts its parts standing on its base (parts lifted
//! by `min_height` are over another's ground); its gross floor area is every part's storeys
//! times its footprint.

use glam::DVec3;

use crate::export::step::{global_id, Id};
use crate::export::ExportError;
use crate::geometry::ring_signed_area;
use crate::model::{Building, Face, Part};

use super::Render;

/// A quantity's IFC entity.
#[derive(Clone, Copy)]
pub(super) enum Q {
    Length,
    Area,
    Volume,
}

impl Q {
    fn entity(self) -> &'static str {
        match self {
            Q::Length => "IFCQUANTITYLENGTH",
            Q::Area => "IFCQUANTITYAREA",
            Q::Volume => "IFCQUANTITYVOLUME",
        }
    }
}

/// The area of a part's footprint (outer ring less its holes), square metres.
pub(crate) fn footprint_area(part: &Part) -> f64 {
    let fp = &part.footprint;
    let holes: f64 = fp.holes.iter().map(|h| ring_signed_area(h).abs()).sum();
    (ring_signed_area(&fp.outer).abs() - holes).max(0.0)
}

/// The outer ring's perimeter of a part's footprint, metres.
fn footprint_perimeter(part: &Part) -> f64 {
    let r = &part.footprint.outer;
    (0..r.len())
        .map(|i| r[i].distance(r[(i + 1) % r.len()]))
        .sum()
}

/// The volume a part's ground, walls and roof enclose (cubic metres, 0 when they do not close
/// to a positive volume): the divergence theorem over the faces, each fanned from its first
/// vertex, relative to the ground's first point. Wall holes (openings) are left out, the
/// ground's and roofs' holes (courtyards) counted.
pub(crate) fn part_volume(part: &Part) -> f64 {
    let o = part.ground.outer.first().copied().unwrap_or(DVec3::ZERO);
    let fan = |ring: &[DVec3]| -> f64 {
        if ring.len() < 3 {
            return 0.0;
        }
        let p0 = ring[0] - o;
        (1..ring.len() - 1)
            .map(|i| p0.dot((ring[i] - o).cross(ring[i + 1] - o)))
            .sum()
    };
    let face = |f: &Face, holes: bool| -> f64 {
        let h: f64 = if holes {
            f.holes.iter().map(|h| fan(h)).sum()
        } else {
            0.0
        };
        fan(&f.outer) + h
    };
    let six: f64 = face(&part.ground, true)
        + part
            .walls
            .iter()
            .map(|w| face(&w.outline, false))
            .sum::<f64>()
        + part.roof.iter().map(|f| face(f, true)).sum::<f64>();
    let v = six / 6.0;
    if v.is_finite() && v > 0.0 {
        v
    } else {
        0.0
    }
}

impl Render<'_> {
    /// An `IfcElementQuantity` `name` of the finite, non-negative `values` (GlobalId path
    /// `path`) and the `IfcRelDefinesByProperties` that puts it on `object`.
    fn element_quantity(
        &mut self,
        key: &str,
        path: &str,
        name: &str,
        values: &[(&str, Q, f64)],
        object: Id,
    ) -> Result<(), ExportError> {
        let mut ids = Vec::with_capacity(values.len());
        for &(qname, q, v) in values {
            if !(v.is_finite() && v >= 0.0) {
                continue;
            }
            ids.push(self.w.entity(q.entity(), |a| {
                a.string(qname).null().null().real(v);
                // Formula (IFC4).
                if self.g.schema.ifc4_attributes() {
                    a.null();
                }
            })?);
        }
        if ids.is_empty() {
            return Ok(());
        }
        let qto = self.w.entity("IFCELEMENTQUANTITY", |a| {
            a.guid(key, path)
                .opt_id(self.g.owner)
                .string(name)
                .null()
                .null()
                .ids(&ids);
        })?;
        let rel = global_id(key, &format!("{path}/rel"));
        self.w.entity("IFCRELDEFINESBYPROPERTIES", |a| {
            a.string(&rel)
                .opt_id(self.g.owner)
                .null()
                .null()
                .ids(&[object])
                .id(qto);
        })?;
        Ok(())
    }

    /// `Qto_BuildingBaseQuantities` of building `b` on its `IfcBuilding`.
    pub(super) fn building_quantities(
        &mut self,
        b: &Building,
        key: &str,
        building: Id,
    ) -> Result<(), ExportError> {
        let on_base = |p: &&Part| (p.base_z - b.base_z).abs() < 0.01;
        let footprint: f64 = b.parts.iter().filter(on_base).map(footprint_area).sum();
        let floors: f64 = b
            .parts
            .iter()
            .map(|p| footprint_area(p) * f64::from(p.storeys.max(1)))
            .sum();
        let volume: f64 = b.parts.iter().map(part_volume).sum();
        let eaves = b
            .parts
            .iter()
            .map(|p| p.eave_z - b.base_z)
            .fold(0.0_f64, f64::max);
        self.element_quantity(
            key,
            "qto",
            "Qto_BuildingBaseQuantities",
            &[
                ("Height", Q::Length, b.measured_height),
                ("EavesHeight", Q::Length, eaves),
                ("FootprintArea", Q::Area, footprint),
                ("GrossFloorArea", Q::Area, floors),
                ("GrossVolume", Q::Volume, volume),
            ],
            building,
        )
    }

    /// `Qto_BuildingBaseQuantities` of one part of a building of several, on its `.PARTIAL.`
    /// `IfcBuilding`: the part's own height (top above its base), eaves, footprint, floors and
    /// closed volume.
    pub(super) fn part_quantities(
        &mut self,
        part: &Part,
        key: &str,
        partial: Id,
    ) -> Result<(), ExportError> {
        self.element_quantity(
            key,
            &format!("{}/qto", part.key),
            "Qto_BuildingBaseQuantities",
            &[
                ("Height", Q::Length, part.top_z - part.base_z),
                ("EavesHeight", Q::Length, part.eave_z - part.base_z),
                ("FootprintArea", Q::Area, footprint_area(part)),
                (
                    "GrossFloorArea",
                    Q::Area,
                    footprint_area(part) * f64::from(part.storeys.max(1)),
                ),
                ("GrossVolume", Q::Volume, part_volume(part)),
            ],
            partial,
        )
    }

    /// `Qto_BuildingStoreyBaseQuantities` of storey `i` of `part` (floor at `floor_z`, `height`
    /// to the next floor or the eaves) on its `IfcBuildingStorey`.
    pub(super) fn storey_quantities(
        &mut self,
        key: &str,
        part: &Part,
        i: usize,
        storey: Id,
        height: f64,
    ) -> Result<(), ExportError> {
        let area = footprint_area(part);
        self.element_quantity(
            key,
            &format!("{}/storey/{i}/qto", part.key),
            "Qto_BuildingStoreyBaseQuantities",
            &[
                ("GrossHeight", Q::Length, height),
                ("GrossPerimeter", Q::Length, footprint_perimeter(part)),
                ("GrossFloorArea", Q::Area, area),
                ("GrossVolume", Q::Volume, area * height.max(0.0)),
            ],
            storey,
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::export::lod3geom::samples;

    #[test]
    fn a_part_volume_is_its_closed_solids_and_its_footprint_area_its_grounds() {
        for b in samples::all() {
            for p in &b.parts {
                let a = footprint_area(p);
                let v = part_volume(p);
                // Between the footprint times the eaves and times the top: walls up to the
                // eaves, a roof of at most the top.
                let (lo, hi) = (a * (p.eave_z - p.base_z), a * (p.top_z - p.base_z));
                assert!(
                    v >= lo * 0.999 - 1e-6 && v <= hi * 1.001 + 1e-6,
                    "{}: {v} not in [{lo}, {hi}]",
                    p.key
                );
                assert!(a > 0.0 && v > 0.0, "{}", p.key);
            }
        }
    }
}
