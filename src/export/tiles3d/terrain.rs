//! The terrain content of a tile ([`super::Detail::Terrain`]): the file's TIN in the tile's
//! east-north-up frame (the frame of its other two contents, so the three share the tile's
//! `transform`), one mesh of one triangle primitive with smooth normals in a matte ground
//! material. Each vertex goes to ECEF exactly, raised by the geoid undulation at it when the
//! heights are orthometric ([`ModelFrame::lift_at`]), and then into the frame: the terrain
//! spans the whole tile, where a building's second-order map would not do.

use glam::{DVec3, Vec3};
use serde_json::{json, Value};

use super::frame::{EnuFrame, ModelFrame};
use super::glb::Bin;
use crate::model::Terrain;

/// glTF component types and buffer view targets.
const FLOAT: u32 = 5126;
const UNSIGNED_INT: u32 = 5125;
const ARRAY_BUFFER: u32 = 34962;
const ELEMENT_ARRAY_BUFFER: u32 = 34963;

/// The ground's colour (linear RGB): the glTF writer's terrain green.
const GROUND_LINEAR: [f32; 3] = [0.266, 0.319, 0.147];

/// The terrain laid out in `frame`: the glTF document's mesh parts (`nodes`, `meshes`,
/// `materials`, `accessors`) into `bin`, and the bounds of its positions in the frame (east,
/// north, up).
pub(super) fn lay_out(
    t: &Terrain,
    model: &ModelFrame,
    frame: &EnuFrame,
    bin: &mut Bin,
) -> (Value, DVec3, DVec3) {
    let enu: Vec<DVec3> = t
        .vertices
        .iter()
        .map(|v| frame.to_enu(model.to_ecef_lifted(*v, model.lift_at(*v))))
        .collect();
    let mut normals = vec![DVec3::ZERO; enu.len()];
    for tri in &t.triangles {
        let p = tri.map(|k| enu[k as usize]);
        let n = (p[1] - p[0]).cross(p[2] - p[0]);
        for &k in tri {
            normals[k as usize] += n;
        }
    }
    // glTF's y-up axes: x east, y up, z south.
    let gl = |v: DVec3| Vec3::new(v.x as f32, v.z as f32, -v.y as f32);
    let (mut lo, mut hi) = (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY));
    let (mut glo, mut ghi) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
    let mut pos = Vec::with_capacity(12 * enu.len());
    for p in &enu {
        let g = gl(*p);
        // The bounds of the positions as stored (f32), so the box holds them exactly.
        let back = DVec3::new(f64::from(g.x), -f64::from(g.z), f64::from(g.y));
        (lo, hi) = (lo.min(back), hi.max(back));
        (glo, ghi) = (glo.min(g), ghi.max(g));
        g.to_array()
            .iter()
            .for_each(|c| pos.extend_from_slice(&c.to_le_bytes()));
    }
    let mut nrm = Vec::with_capacity(12 * enu.len());
    for n in &normals {
        gl(n.try_normalize().unwrap_or(DVec3::Z))
            .to_array()
            .iter()
            .for_each(|c| nrm.extend_from_slice(&c.to_le_bytes()));
    }
    let idx: Vec<u8> = t
        .triangles
        .iter()
        .flatten()
        .flat_map(|k| k.to_le_bytes())
        .collect();
    let pv = bin.view(&pos, Some(ARRAY_BUFFER));
    let nv = bin.view(&nrm, Some(ARRAY_BUFFER));
    let iv = bin.view(&idx, Some(ELEMENT_ARRAY_BUFFER));
    let count = enu.len();
    let parts = json!({
        "nodes": [{"name": "terrain", "mesh": 0}],
        "meshes": [{"name": "terrain", "primitives": [{
            "attributes": {"POSITION": 0, "NORMAL": 1},
            "indices": 2,
            "material": 0
        }]}],
        "materials": [{
            "name": "terrain",
            "pbrMetallicRoughness": {
                "baseColorFactor": [GROUND_LINEAR[0], GROUND_LINEAR[1], GROUND_LINEAR[2], 1.0],
                "metallicFactor": 0.0,
                "roughnessFactor": 0.9
            }
        }],
        "accessors": [
            {"bufferView": pv, "componentType": FLOAT, "count": count, "type": "VEC3",
             "min": glo.to_array(), "max": ghi.to_array()},
            {"bufferView": nv, "componentType": FLOAT, "count": count, "type": "VEC3"},
            {"bufferView": iv, "componentType": UNSIGNED_INT, "count": 3 * t.triangles.len(),
             "type": "SCALAR"}
        ]
    });
    (parts, lo, hi)
}
