//! From masses to the semantic model: walls, ground and roof of each building part.
//!
//! A [`Mass`] is one vertical extrusion of one footprint with its roof and colours: what the
//! derived shape tree says a building part is (see [`crate::derive`]). [`build_part`] turns it
//! into a [`Part`] cut at the run's LOD: at LOD1 a block with a flat top at the overall height,
//! from LOD2 the real roof on walls that stop at the eave.

use glam::{DVec2, DVec3};

use crate::color::Color;
use crate::geometry::roof::{self, RoofGeometry};
use crate::geometry::Polygon;
use crate::model::{Face, Lod, Part, RoofShape, Wall};

/// Default exterior wall thickness in metres.
pub const WALL_THICKNESS: f64 = 0.3;

/// Roofs lower than this are drawn flat (a pitched roof of a few centimetres is noise).
const MIN_ROOF_HEIGHT: f64 = 0.05;

/// One building part before it becomes geometry.
#[derive(Clone, Debug, PartialEq)]
pub struct Mass {
    pub footprint: Polygon,
    pub base_z: f64,
    /// Top of the walls.
    pub eave_z: f64,
    pub storeys: u32,
    pub roof: RoofShape,
    /// Pitch in degrees, used when `roof_height` is not given.
    pub roof_angle_deg: f64,
    /// Height of the roof above the eave, when known (OSM `roof:height`).
    pub roof_height: Option<f64>,
    pub wall_color: Color,
    pub roof_color: Color,
}

/// A roof that could not be built as asked and fell back to flat.
#[derive(Clone, Debug, PartialEq)]
pub struct RoofFallback {
    pub asked: RoofShape,
    pub reason: String,
}

/// Computes the roof surfaces of a mass at z = 0 (the eave), or the reason it must be flat.
pub fn roof_geometry(mass: &Mass) -> Result<RoofGeometry, RoofFallback> {
    let fallback = |reason: String| RoofFallback {
        asked: mass.roof,
        reason,
    };
    let pitched = match mass.roof {
        RoofShape::Flat => return Ok(roof::flat(&mass.footprint)),
        RoofShape::Hipped
        | RoofShape::HalfHipped
        | RoofShape::SideHipped
        | RoofShape::Mansard
        | RoofShape::Gambrel => roof::hipped(&mass.footprint, mass.roof_angle_deg)
            .map_err(|e| fallback(e.to_string()))?,
        RoofShape::Gabled | RoofShape::Saltbox => {
            match roof::gabled(&mass.footprint, mass.roof_angle_deg) {
                Ok(g) => g,
                Err(e) => return Err(fallback(e.to_string())),
            }
        }
        RoofShape::Pyramidal | RoofShape::Cone | RoofShape::Dome | RoofShape::Onion => {
            let h = mass.roof_height.unwrap_or_else(|| {
                let (lo, hi) = mass.footprint.bounds();
                0.5 * (hi - lo).min_element() * mass.roof_angle_deg.to_radians().tan()
            });
            roof::pyramidal(&mass.footprint, h).map_err(|e| fallback(e.to_string()))?
        }
        other => {
            return Err(fallback(format!(
                "roof shape {} is not built yet",
                other.osm_name()
            )))
        }
    };
    let pitched = match mass.roof_height {
        Some(h) if h > MIN_ROOF_HEIGHT => pitched.scaled_to_height(h),
        _ => pitched,
    };
    if pitched.height.is_nan() || pitched.height <= MIN_ROOF_HEIGHT {
        return Err(fallback(format!(
            "roof would be {:.3} m high",
            pitched.height
        )));
    }
    Ok(pitched)
}

/// Builds the walls, ground and roof of one part at the given LOD.
///
/// `roof` is the result of [`roof_geometry`] for this mass (computed by the caller, which may
/// need the roof height first). At LOD1 the part is a block up to its overall top.
pub fn build_part(key: String, mass: &Mass, roof: &RoofGeometry, lod: Lod) -> Part {
    let flat = roof.faces.is_empty() || roof.height <= MIN_ROOF_HEIGHT;
    let top_z = if flat {
        mass.eave_z
    } else {
        mass.eave_z + roof.height
    };
    let wall_top = if lod == Lod::Lod1 { top_z } else { mass.eave_z };
    let walls = walls(&mass.footprint, mass.base_z, wall_top);
    let roof_faces = if lod == Lod::Lod1 || flat {
        vec![horizontal_face(&mass.footprint, wall_top, true)]
    } else {
        roof.faces
            .iter()
            .map(|f| translate_face(f, mass.eave_z))
            .collect()
    };
    Part {
        key,
        footprint: mass.footprint.clone(),
        base_z: mass.base_z,
        eave_z: if lod == Lod::Lod1 { top_z } else { mass.eave_z },
        top_z,
        storeys: mass.storeys.max(1),
        levels: even_levels(mass.base_z, mass.eave_z, mass.storeys.max(1)),
        wall_color: mass.wall_color,
        roof_color: mass.roof_color,
        roof_shape: if flat { RoofShape::Flat } else { mass.roof },
        walls,
        roof: roof_faces,
        ground: horizontal_face(&mass.footprint, mass.base_z, false),
    }
}

/// One wall per ring edge, outer ring first, rectangles from `base` to `top`.
///
/// The outer ring is counter-clockwise and holes clockwise, so the outside of the building is
/// always on the right of start->end and the outline (start, end, end-up, start-up) faces out.
pub fn walls(footprint: &Polygon, base: f64, top: f64) -> Vec<Wall> {
    let mut out = Vec::with_capacity(footprint.outer.len());
    for ring in footprint.rings() {
        let n = ring.len();
        for i in 0..n {
            let (s, e) = (ring[i], ring[(i + 1) % n]);
            out.push(Wall {
                start: s,
                end: e,
                base_z: base,
                top_z: top,
                thickness: WALL_THICKNESS,
                outline: Face::new(vec![at(s, base), at(e, base), at(e, top), at(s, top)]),
                storey: 0,
                openings: Vec::new(),
                balconies: Vec::new(),
            });
        }
    }
    out
}

/// Floor elevations of `n` equal storeys between `base` and `eave`.
pub fn even_levels(base: f64, eave: f64, n: u32) -> Vec<f64> {
    let n = n.max(1);
    let h = (eave - base) / f64::from(n);
    (0..n).map(|i| base + h * f64::from(i)).collect()
}

/// The footprint as a horizontal face at `z`, facing up (a roof) or down (a ground).
pub fn horizontal_face(footprint: &Polygon, z: f64, up: bool) -> Face {
    let ring = |r: &Vec<DVec2>, reverse: bool| {
        let mut v: Vec<DVec3> = r.iter().map(|p| at(*p, z)).collect();
        if reverse {
            v.reverse();
        }
        v
    };
    Face {
        outer: ring(&footprint.outer, !up),
        holes: footprint.holes.iter().map(|h| ring(h, !up)).collect(),
    }
}

fn translate_face(f: &Face, dz: f64) -> Face {
    let t = |r: &Vec<DVec3>| r.iter().map(|p| DVec3::new(p.x, p.y, p.z + dz)).collect();
    Face {
        outer: t(&f.outer),
        holes: f.holes.iter().map(t).collect(),
    }
}

fn at(p: DVec2, z: f64) -> DVec3 {
    DVec3::new(p.x, p.y, z)
}
