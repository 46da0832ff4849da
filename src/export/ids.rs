//! The id scheme of the city-model writers: a building's source key made safe for an XML id
//! (`id_fragment`) and its parts' ids (`part_ids`). CityGML and CityJSON name buildings and
//! parts alike, so that a part is found by the same id in both.

use crate::model::Part;

/// Keeps ASCII letters, digits, `_`, `-` and `.` (NCName-safe after a letter prefix), replacing
/// anything else by `_`.
pub(crate) fn id_fragment(s: &str) -> String {
    s.chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || matches!(c, '_' | '-' | '.') {
                c
            } else {
                '_'
            }
        })
        .collect()
}

/// The id prefixes of the parts: `<building id>_<part key>`, or `<building id>_p<index>` for all
/// parts when the keys are empty or not unique (ids must be unique in the file).
pub(crate) fn part_ids(building_id: &str, parts: &[Part]) -> Vec<String> {
    let keys: Vec<String> = parts.iter().map(|p| id_fragment(&p.key)).collect();
    let usable = keys
        .iter()
        .enumerate()
        .all(|(i, k)| !k.is_empty() && !keys[..i].contains(k));
    keys.iter()
        .enumerate()
        .map(|(i, k)| {
            if usable {
                format!("{building_id}_{k}")
            } else {
                format!("{building_id}_p{i}")
            }
        })
        .collect()
}

/// The id of a file's terrain (CityGML `dem:ReliefFeature`, CityJSON `TINRelief`):
/// `TIN_<easting>_<northing>` of its south-west corner in whole metres of the output CRS
/// (`origin + local`), so that the terrains of a run's tiles, merged, keep distinct ids.
pub(crate) fn terrain_id(t: &crate::model::Terrain, origin: glam::DVec3) -> String {
    let (x, y) = t
        .vertices
        .iter()
        .fold((f64::INFINITY, f64::INFINITY), |(x, y), v| {
            (x.min(v.x), y.min(v.y))
        });
    let m = |v: f64| if v.is_finite() { v.floor() as i64 } else { 0 };
    format!("TIN_{}_{}", m(x + origin.x), m(y + origin.y))
}
