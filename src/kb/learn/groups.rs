//! The groups samples are learned in: the cells of a grid, or the zones of a KB.

use super::LearnError;
use std::collections::BTreeMap;

use super::format::{designation, num};
use super::{round7, Group, Sample, Shape, MAX_CELLS, MAX_GRID_LATITUDE};
use crate::kb::{KnowledgeBase, ZoneKind, KM_PER_DEG};

/// The grid's cells as zones under one town: group 0 earth, 1 the town, then the cells by row
/// (south to north) and column (west to east).
pub(super) fn grid_groups(
    samples: &[&Sample],
    metres: f64,
    name: &str,
) -> Result<Vec<Group>, LearnError> {
    if !(metres.is_finite() && metres >= 1.0) {
        return Err(LearnError::GridCell { metres });
    }
    let lat_min = samples
        .iter()
        .map(|s| s.lonlat.1)
        .fold(f64::INFINITY, f64::min);
    let lat_max = samples
        .iter()
        .map(|s| s.lonlat.1)
        .fold(f64::NEG_INFINITY, f64::max);
    let lon_min = samples
        .iter()
        .map(|s| s.lonlat.0)
        .fold(f64::INFINITY, f64::min);
    if lat_min < -MAX_GRID_LATITUDE || lat_max > MAX_GRID_LATITUDE {
        return Err(LearnError::GridLatitude {
            latitude: if lat_max > MAX_GRID_LATITUDE {
                lat_max
            } else {
                lat_min
            },
        });
    }
    // Anchored on the south-west corner of the data, floored to the written precision.
    let lat0 = (lat_min * 1e7).floor() / 1e7;
    let lon0 = (lon_min * 1e7).floor() / 1e7;
    let dlat = metres / (KM_PER_DEG * 1000.0);
    let lat_edge = |j: i64| round7(lat0 + j as f64 * dlat);
    let dlon = |j: i64| {
        let mid = (lat0 + (j as f64 + 0.5) * dlat).clamp(-89.0, 89.0);
        dlat / mid.to_radians().cos()
    };
    let lon_edge = |j: i64, i: i64| round7(lon0 + i as f64 * dlon(j));
    // Half-open cells on the written (rounded) edges, so that binning and the polygons agree.
    let bin = |v: f64, start: i64, edge: &dyn Fn(i64) -> f64| {
        let mut k = start;
        while v < edge(k) {
            k -= 1;
        }
        while v >= edge(k + 1) {
            k += 1;
        }
        k
    };
    let mut cells: BTreeMap<(i64, i64), Vec<usize>> = BTreeMap::new();
    for (k, s) in samples.iter().enumerate() {
        let (lon, lat) = s.lonlat;
        let j = bin(lat, ((lat - lat0) / dlat).floor() as i64, &lat_edge);
        let i = bin(lon, ((lon - lon0) / dlon(j)).floor() as i64, &|i| {
            lon_edge(j, i)
        });
        cells.entry((j, i)).or_default().push(k);
    }
    if cells.len() > MAX_CELLS {
        return Err(LearnError::GridCells {
            metres: num(metres, 3),
            cells: cells.len(),
        });
    }
    let rect = |j: i64, i: i64| {
        [
            lon_edge(j, i),
            lat_edge(j),
            lon_edge(j, i + 1),
            lat_edge(j + 1),
        ]
    };
    let mut bounds = [
        f64::INFINITY,
        f64::INFINITY,
        f64::NEG_INFINITY,
        f64::NEG_INFINITY,
    ];
    for &(j, i) in cells.keys() {
        let r = rect(j, i);
        bounds = [
            bounds[0].min(r[0]),
            bounds[1].min(r[1]),
            bounds[2].max(r[2]),
            bounds[3].max(r[3]),
        ];
    }
    if bounds[0] < -180.0 || bounds[2] > 180.0 || bounds[2] - bounds[0] > 180.0 {
        return Err(LearnError::GridLongitudes {
            west: bounds[0],
            east: bounds[2],
        });
    }
    let mut groups = vec![
        // Earth holds no sample: the extract (the town) is the top of the statistics, and
        // earth's are the built-in defaults.
        Group {
            element: "earth",
            name: "earth".into(),
            parent: None,
            shape: Shape::Earth,
            members: Vec::new(),
        },
        Group {
            element: "town",
            name: designation(name),
            parent: Some(0),
            shape: Shape::Rect(bounds),
            members: (0..samples.len()).collect(),
        },
    ];
    for ((j, i), members) in cells {
        groups.push(Group {
            element: "district",
            name: format!("row {} col {}", j, i),
            parent: Some(1),
            shape: Shape::Rect(rect(j, i)),
            members,
        });
    }
    Ok(groups)
}

/// The zones of `kb` that hold buildings, with their ancestors, in document order (earth
/// first).
pub(super) fn zone_groups(samples: &[&Sample], kb: &KnowledgeBase) -> Vec<Group> {
    let zones = kb.zones();
    let mut members: Vec<Vec<usize>> = vec![Vec::new(); zones.len().max(1)];
    for (k, s) in samples.iter().enumerate() {
        for z in kb.lineage(kb.locate(s.lonlat.0, s.lonlat.1)) {
            if let Some(m) = members.get_mut(z) {
                m.push(k);
            }
        }
    }
    let mut index: Vec<Option<usize>> = vec![None; zones.len()];
    let mut groups: Vec<Group> = Vec::new();
    for (z, zone) in zones.iter().enumerate() {
        if z > 0 && members[z].is_empty() {
            continue;
        }
        index[z] = Some(groups.len());
        let parent = zone.parent.and_then(|p| index.get(p).copied().flatten());
        groups.push(Group {
            element: match zone.kind {
                ZoneKind::Earth => "earth",
                ZoneKind::Country => "country",
                ZoneKind::Region => "region",
                ZoneKind::Town => "town",
                ZoneKind::District => "district",
                ZoneKind::Other(_) => "zone",
            },
            name: if z == 0 {
                "earth".into()
            } else {
                designation(&zone.name)
            },
            parent: if z == 0 { None } else { parent.or(Some(0)) },
            shape: if z == 0 {
                Shape::Earth
            } else {
                Shape::Kept {
                    circle: zone.circle.map(|c| (c.lat, c.lon, c.radius_km)),
                    polygons: zone.polygons.iter().map(|p| p.ring.clone()).collect(),
                }
            },
            members: std::mem::take(&mut members[z]),
        });
    }
    groups
}
