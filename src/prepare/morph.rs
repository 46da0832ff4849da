//! The form and the context of every footprint (issue 42, step 1): what the height and roof
//! estimator ([`super::estimate`]) reads where the map is silent.
//!
//! Per lot, from its outline: area, compactness (`4πA/P²`), elongation and width (the extents
//! along the outline's principal axes), vertex count, convexity (area over the convex hull's);
//! from its neighbours: the length of wall it shares with touching lots (edges within
//! [`TOUCH_M`] of another lot's, nearly parallel) and how many it touches; the density around
//! it (buildings and built-up share in square windows of about 150, 250 and 750 m, from cell
//! sums: no per-pair work), the mean footprint size there (geometric mean); and its kind's
//! usual storeys ([`kind_storeys`]) and whether a street runs past it.
//!
//! Cost: one R-tree of outline bounds for the touching pairs, two hash grids of cell sums for
//! the densities; linear in the lots, in parallel. Pure and deterministic.

use std::collections::HashMap;
use std::hash::{BuildHasherDefault, Hasher};

use glam::DVec2;
use rayon::prelude::*;
use rstar::primitives::{GeomWithData, Rectangle};
use rstar::{RTree, AABB};

use super::Lot;

/// How close two edges of different lots must lie to count as one shared wall (metres).
pub(crate) const TOUCH_M: f64 = 0.5;
/// Edges sharing a wall differ in direction by less than this (the sine of about 10°).
const PARALLEL_SIN: f64 = 0.17;
/// The fine density grid's cell (metres).
const FINE_CELL_M: f64 = 50.0;
/// The coarse density grid's cell (metres).
const COARSE_CELL_M: f64 = 250.0;
/// The farthest a lot's features look from its point (metres): the widest window is the
/// 3 x 3 coarse cells around the point's cell, whose far corner lies up to two cells away
/// on each axis. (`citygen split` sizes its halo from it.)
pub(crate) const WINDOW_REACH_M: f64 = 2.0 * COARSE_CELL_M * std::f64::consts::SQRT_2;

/// The number of features of one lot.
pub(crate) const FEATURES: usize = 16;

/// The features' names, in order (the model file's header names them).
pub(crate) const FEATURE_NAMES: [&str; FEATURES] = [
    "log_area",
    "compactness",
    "elongation",
    "log_width",
    "log_vertices",
    "convexity",
    "shared_wall_share",
    "touching",
    "log_count_150m",
    "log_count_250m",
    "built_share_150m",
    "built_share_250m",
    "built_share_750m",
    "log_mean_area_250m",
    "kind_storeys",
    "street_front",
];

/// One lot's features, in [`FEATURE_NAMES`] order.
pub(crate) type Features = [f32; FEATURES];

/// What [`measure`] finds.
#[derive(Clone, Debug, Default)]
pub(crate) struct Morphology {
    /// Per lot, its features.
    pub features: Vec<Features>,
    /// Touching pairs `(i, j, shared metres)` with `i < j`, sorted.
    pub touching: Vec<(u32, u32, f32)>,
    /// Per lot, the short extent of its outline (metres): what a pitched roof spans.
    pub width: Vec<f64>,
    /// Per lot, its footprint area (square metres).
    pub area: Vec<f64>,
}

/// The usual storeys of a `building=*` kind, 0 for an unknown or generic one (`yes`). A
/// kind's own plausible range is [`kind_cap`].
pub(crate) fn kind_storeys(kind: Option<&str>) -> f32 {
    match kind.unwrap_or("yes") {
        "house" | "detached" | "semidetached_house" | "terrace" | "farm" | "villa"
        | "residential_house" | "dwelling_house" => 2.0,
        "bungalow" | "cabin" | "hut" | "shed" | "garage" | "garages" | "carport" | "stable"
        | "barn" | "cowshed" | "farm_auxiliary" | "greenhouse" | "kiosk" | "roof" | "canopy"
        | "toilets" | "allotment_house" | "boathouse" | "sty" | "shelter" | "service"
        | "transformer_tower" | "bunker" | "container" | "storage_tank" | "static_caravan"
        | "ruins" | "retail" | "supermarket" | "parking_entrance" | "gatehouse" => 1.0,
        "apartments" | "office" | "hotel" | "dormitory" | "hospital" => 5.0,
        "commercial" | "public" | "civic" | "government" | "university" | "college"
        | "mixed_use" => 3.5,
        "school" | "kindergarten" | "church" | "chapel" | "mosque" | "temple" | "synagogue"
        | "industrial" | "warehouse" | "manufacture" | "train_station" | "sports_hall"
        | "hangar" => 1.5,
        _ => 0.0,
    }
}

/// The most storeys a kind plausibly has when untagged (structures and sheds stay low), `None`
/// for no limit of its own.
pub(crate) fn kind_cap(kind: Option<&str>) -> Option<f64> {
    match kind.unwrap_or("yes") {
        "shed" | "garage" | "garages" | "carport" | "kiosk" | "roof" | "canopy" | "toilets"
        | "hut" | "sty" | "shelter" | "container" | "greenhouse" | "allotment_house"
        | "parking_entrance" | "transformer_tower" | "service" | "bunker" | "ruins"
        | "static_caravan" | "boathouse" | "gatehouse" => Some(1.0),
        "stable" | "barn" | "cowshed" | "farm_auxiliary" | "cabin" | "bungalow" => Some(2.0),
        "house" | "detached" | "semidetached_house" | "farm" | "villa" => Some(4.0),
        "terrace" => Some(5.0),
        _ => None,
    }
}

/// The most storeys an untagged footprint of `area` m² is given whatever its neighbours say: a
/// storey needs room for a stair and a room (narrow old-town houses of 40-60 m² do have 3).
pub(crate) fn area_cap(area: f64) -> f64 {
    match area {
        a if a < 15.0 => 1.0,
        a if a < 30.0 => 2.0,
        a if a < 60.0 => 3.0,
        a if a < 100.0 => 6.0,
        _ => f64::INFINITY,
    }
}

/// A cheap deterministic hasher for cell keys (multiply-rotate, as rustc's FxHash).
#[derive(Default)]
struct CellHasher(u64);

impl Hasher for CellHasher {
    fn finish(&self) -> u64 {
        self.0
    }
    fn write(&mut self, bytes: &[u8]) {
        for b in bytes {
            self.write_u64(u64::from(*b));
        }
    }
    fn write_u64(&mut self, x: u64) {
        self.0 = (self.0.rotate_left(5) ^ x).wrapping_mul(0x51_7c_c1_b7_27_22_0a_95);
    }
}

type Cells = HashMap<(i32, i32), Cell, BuildHasherDefault<CellHasher>>;

/// Sums over the lots whose point falls in one cell.
#[derive(Clone, Copy, Default)]
struct Cell {
    count: f64,
    area: f64,
    log_area: f64,
}

fn cell_of(p: DVec2, size: f64) -> (i32, i32) {
    let c = |v: f64| (v / size).floor().clamp(i32::MIN as f64, i32::MAX as f64) as i32;
    (c(p.x), c(p.y))
}

fn cells(points: &[Option<DVec2>], area: &[f64], size: f64) -> Cells {
    let mut out = Cells::default();
    for (p, a) in points.iter().zip(area) {
        if let Some(p) = p {
            let c = out.entry(cell_of(*p, size)).or_default();
            c.count += 1.0;
            c.area += a;
            c.log_area += a.max(1.0).ln();
        }
    }
    out
}

/// The sums of the `(2r + 1)²` cells around `p`'s.
fn window(cells: &Cells, p: DVec2, size: f64, r: i32) -> Cell {
    let (cx, cy) = cell_of(p, size);
    let mut s = Cell::default();
    for dx in -r..=r {
        for dy in -r..=r {
            if let Some(c) = cells.get(&(cx.saturating_add(dx), cy.saturating_add(dy))) {
                s.count += c.count;
                s.area += c.area;
                s.log_area += c.log_area;
            }
        }
    }
    s
}

/// The outline's shape: (area, perimeter, vertices, hull area, short extent, long extent).
fn shape(lot: &Lot) -> (f64, f64, usize, f64, f64, f64) {
    let mut area = 0.0;
    let mut perimeter = 0.0;
    let mut vertices = 0;
    let mut all: Vec<DVec2> = Vec::new();
    for p in &lot.polygons {
        area += p.area().abs();
        for r in p.rings() {
            vertices += r.len();
            perimeter += ring_edges(r).map(|(a, b)| a.distance(b)).sum::<f64>();
        }
        all.extend_from_slice(&p.outer);
    }
    let (short, long) = extents(&all);
    (area, perimeter, vertices, hull_area(&mut all), short, long)
}

fn ring_edges(r: &[DVec2]) -> impl Iterator<Item = (DVec2, DVec2)> + '_ {
    (0..r.len()).map(move |i| (r[i], r[(i + 1) % r.len()]))
}

/// Extents along the principal axes of the points (short, long).
pub(crate) fn extents(pts: &[DVec2]) -> (f64, f64) {
    if pts.len() < 2 {
        return (0.0, 0.0);
    }
    let n = pts.len() as f64;
    let mean = pts.iter().fold(DVec2::ZERO, |s, p| s + *p) / n;
    let (mut sxx, mut syy, mut sxy) = (0.0, 0.0, 0.0);
    for p in pts {
        let d = *p - mean;
        sxx += d.x * d.x;
        syy += d.y * d.y;
        sxy += d.x * d.y;
    }
    let angle = 0.5 * (2.0 * sxy).atan2(sxx - syy);
    let u = DVec2::new(angle.cos(), angle.sin());
    let v = u.perp();
    let range = |axis: DVec2| {
        let (lo, hi) = pts
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), p| {
                let t = (*p - mean).dot(axis);
                (l.min(t), h.max(t))
            });
        (hi - lo).max(0.0)
    };
    let (a, b) = (range(u), range(v));
    (a.min(b), a.max(b))
}

/// The area of the convex hull (monotone chain); sorts `pts`.
fn hull_area(pts: &mut [DVec2]) -> f64 {
    if pts.len() < 3 {
        return 0.0;
    }
    pts.sort_by(|a, b| a.x.total_cmp(&b.x).then(a.y.total_cmp(&b.y)));
    let cross = |o: DVec2, a: DVec2, b: DVec2| (a - o).perp_dot(b - o);
    let mut hull: Vec<DVec2> = Vec::with_capacity(pts.len() + 1);
    for pass in 0..2 {
        let start = hull.len();
        let iter: Box<dyn Iterator<Item = &DVec2>> = if pass == 0 {
            Box::new(pts.iter())
        } else {
            Box::new(pts.iter().rev())
        };
        for &p in iter {
            while hull.len() >= start + 2
                && cross(hull[hull.len() - 2], hull[hull.len() - 1], p) <= 0.0
            {
                hull.pop();
            }
            hull.push(p);
        }
        hull.pop();
    }
    crate::geometry::ring_signed_area(&hull).abs()
}

/// The metres of `a`'s outline that run along `b`'s (module docs).
fn shared_length(a: &Lot, b: &Lot) -> f64 {
    let mut total = 0.0;
    for pa in &a.polygons {
        for (p, q) in ring_edges(&pa.outer) {
            let len = p.distance(q);
            if len < 1e-6 {
                continue;
            }
            let dir = (q - p) / len;
            let mut covered: Vec<(f64, f64)> = Vec::new();
            for pb in &b.polygons {
                for (r, s) in ring_edges(&pb.outer) {
                    let l2 = r.distance(s);
                    if l2 < 1e-6 || dir.perp_dot((s - r) / l2).abs() > PARALLEL_SIN {
                        continue;
                    }
                    let off = |x: DVec2| dir.perp_dot(x - p).abs();
                    if off(r) > TOUCH_M || off(s) > TOUCH_M {
                        continue;
                    }
                    let (t0, t1) = ((r - p).dot(dir), (s - p).dot(dir));
                    let (lo, hi) = (t0.min(t1).max(0.0), t0.max(t1).min(len));
                    if hi > lo {
                        covered.push((lo, hi));
                    }
                }
            }
            total += union_length(&mut covered);
        }
    }
    total
}

fn union_length(spans: &mut [(f64, f64)]) -> f64 {
    spans.sort_by(|a, b| a.0.total_cmp(&b.0));
    let mut total = 0.0;
    let mut cur: Option<(f64, f64)> = None;
    for &(lo, hi) in spans.iter() {
        match cur {
            Some((a, b)) if lo <= b => cur = Some((a, b.max(hi))),
            Some((a, b)) => {
                total += b - a;
                cur = Some((lo, hi));
            }
            None => cur = Some((lo, hi)),
        }
    }
    total + cur.map_or(0.0, |(a, b)| b - a)
}

/// Touching pairs `(i, j, shared metres)`, `i < j`, sorted.
fn touching_pairs(lots: &[Lot]) -> Vec<(u32, u32, f32)> {
    let boxes: Vec<GeomWithData<Rectangle<[f64; 2]>, u32>> = lots
        .iter()
        .enumerate()
        .filter_map(|(i, l)| {
            let (lo, hi) = l.bounds()?;
            let i = u32::try_from(i).ok()?;
            Some(GeomWithData::new(
                Rectangle::from_corners(lo.to_array(), hi.to_array()),
                i,
            ))
        })
        .collect();
    let tree = RTree::bulk_load(boxes);
    let mut pairs: Vec<(u32, u32, f32)> = (0..lots.len())
        .into_par_iter()
        .flat_map_iter(|i| {
            let found: Vec<(u32, u32, f32)> = match lots[i].bounds() {
                Some((lo, hi)) => {
                    let e = DVec2::splat(TOUCH_M);
                    let q = AABB::from_corners((lo - e).to_array(), (hi + e).to_array());
                    tree.locate_in_envelope_intersecting(q)
                        .map(|g| g.data as usize)
                        .filter(|&j| j > i)
                        .filter_map(|j| {
                            let s = shared_length(&lots[i], &lots[j])
                                .min(shared_length(&lots[j], &lots[i]));
                            (s > 1.0).then_some((i as u32, j as u32, s as f32))
                        })
                        .collect()
                }
                None => Vec::new(),
            };
            found
        })
        .collect();
    pairs.sort_by_key(|p| (p.0, p.1));
    pairs
}

/// A lot's point: the middle of its outline's bounds (what the density windows and the
/// estimator's neighbour distances are measured from).
pub(crate) fn point(lot: &Lot) -> Option<DVec2> {
    lot.bounds().map(|(lo, hi)| 0.5 * (lo + hi))
}

/// Measures every lot (module docs). The touching pairs come first, so that their index of
/// outline bounds is freed before the per-lot shapes are made (issue 46: this runs over every
/// lot at once).
pub(crate) fn measure(lots: &[Lot]) -> Morphology {
    let touching = touching_pairs(lots);
    let shapes: Vec<(f64, f64, usize, f64, f64, f64)> = lots.par_iter().map(shape).collect();
    let area: Vec<f64> = shapes.iter().map(|s| s.0.max(1.0)).collect();
    let points: Vec<Option<DVec2>> = lots.par_iter().map(point).collect();
    let mut shared = vec![(0.0f64, 0u32); lots.len()];
    for &(i, j, s) in &touching {
        for k in [i, j] {
            let e = &mut shared[k as usize];
            e.0 += f64::from(s);
            e.1 += 1;
        }
    }
    let fine = cells(&points, &area, FINE_CELL_M);
    let coarse = cells(&points, &area, COARSE_CELL_M);
    let features: Vec<Features> = (0..lots.len())
        .into_par_iter()
        .map(|i| {
            let (a, perimeter, vertices, hull, short, long) = shapes[i];
            let a = a.max(1.0);
            let Some(p) = points[i] else {
                return [0.0; FEATURES];
            };
            let w150 = window(&fine, p, FINE_CELL_M, 1);
            let w250 = window(&fine, p, FINE_CELL_M, 2);
            let w750 = window(&coarse, p, COARSE_CELL_M, 1);
            let share = |c: Cell, side: f64| (c.area / (side * side)).min(1.0);
            let (sh, n) = shared[i];
            let lot = &lots[i];
            [
                a.ln(),
                (4.0 * std::f64::consts::PI * a / (perimeter * perimeter).max(1e-9)).min(1.0),
                if short > 0.0 {
                    short / long.max(short)
                } else {
                    1.0
                },
                short.max(0.5).ln(),
                (vertices as f64).max(3.0).ln(),
                if hull > 0.0 { (a / hull).min(1.0) } else { 1.0 },
                (sh / perimeter.max(1e-9)).min(1.0),
                f64::from(n),
                (w150.count - 1.0).max(0.0).ln_1p(),
                (w250.count - 1.0).max(0.0).ln_1p(),
                share(w150, 3.0 * FINE_CELL_M),
                share(w250, 5.0 * FINE_CELL_M),
                share(w750, 3.0 * COARSE_CELL_M),
                (w250.log_area / w250.count.max(1.0)),
                f64::from(kind_storeys(lot.tags.building.as_deref())),
                if lot.front.is_some() { 1.0 } else { 0.0 },
            ]
            .map(|v| if v.is_finite() { v as f32 } else { 0.0 })
        })
        .collect();
    Morphology {
        features,
        touching,
        width: shapes.iter().map(|s| s.4).collect(),
        area,
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::geometry::Polygon;
    use crate::input::BuildingTags;
    use crate::model::SourceId;

    pub(crate) fn rect(i: i64, x: f64, y: f64, w: f64, d: f64, kind: &str) -> Lot {
        let v = DVec2::new;
        let p = Polygon::new(
            vec![v(x, y), v(x + w, y), v(x + w, y + d), v(x, y + d)],
            vec![],
        );
        Lot {
            id: SourceId::Way(i),
            tags: std::sync::Arc::new(BuildingTags {
                building: Some(kind.to_string()),
                ..Default::default()
            }),
            polygons: vec![p.clone()],
            parts: Vec::new(),
            drawn: None,
            rest_tags: None,
            lonlat: (0.0, 0.0),
            front: None,
            ground: 0.0,
            terrain: None,
        }
    }

    #[test]
    fn a_row_shares_its_party_walls_and_a_detached_house_none() {
        let lots = vec![
            rect(1, 0.0, 0.0, 6.0, 10.0, "terrace"),
            rect(2, 6.0, 0.0, 6.0, 10.0, "terrace"),
            rect(3, 12.0, 0.0, 6.0, 10.0, "terrace"),
            rect(4, 40.0, 0.0, 10.0, 10.0, "house"),
        ];
        let m = measure(&lots);
        assert_eq!(m.touching.len(), 2, "{:?}", m.touching);
        assert_eq!((m.touching[0].0, m.touching[0].1), (0, 1));
        assert!((m.touching[0].2 - 10.0).abs() < 1e-3);
        let f = |i: usize, k: usize| m.features[i][k];
        assert!(
            (f(1, 6) - 20.0 / 32.0).abs() < 1e-4,
            "middle house: 20 of 32 m"
        );
        assert_eq!(f(1, 7), 2.0);
        assert_eq!(f(3, 6), 0.0);
        assert!((f(0, 0) - 60f32.ln()).abs() < 1e-4);
        assert!((f(0, 2) - 0.6).abs() < 1e-4, "6 by 10: elongation 0.6");
        assert!((m.width[0] - 6.0).abs() < 1e-9);
        assert!(
            (f(3, 1) - std::f32::consts::PI / 4.0).abs() < 1e-4,
            "a square"
        );
        assert_eq!(f(3, 5), 1.0, "convex");
        assert_eq!(f(3, 14), 2.0, "a house's usual storeys");
    }

    #[test]
    fn an_l_shape_is_not_convex_and_density_counts_the_neighbours() {
        let v = DVec2::new;
        let l = Polygon::new(
            vec![
                v(0.0, 0.0),
                v(10.0, 0.0),
                v(10.0, 5.0),
                v(5.0, 5.0),
                v(5.0, 10.0),
                v(0.0, 10.0),
            ],
            vec![],
        );
        let mut lots = vec![rect(1, 0.0, 0.0, 1.0, 1.0, "yes")];
        lots[0].polygons = vec![l];
        for k in 0..10 {
            lots.push(rect(10 + k, 20.0 + 15.0 * k as f64, 20.0, 8.0, 8.0, "yes"));
        }
        let m = measure(&lots);
        assert!(
            (m.features[0][5] - 75.0 / 87.5).abs() < 1e-4,
            "75 of 87.5 m² hull"
        );
        assert!(m.features[0][9] > m.features[0][8] - 1e-6);
        assert!(m.features[0][11] > 0.0);
    }

    #[test]
    fn caps_keep_sheds_and_small_footprints_low() {
        assert_eq!(kind_cap(Some("stable")), Some(2.0));
        assert_eq!(kind_cap(Some("shed")), Some(1.0));
        assert_eq!(kind_cap(Some("apartments")), None);
        assert_eq!(area_cap(14.0), 1.0);
        assert_eq!(area_cap(59.0), 3.0);
        assert!(area_cap(500.0).is_infinite());
    }
}
