//! From source footprints to lots in the local frame: projection, ring clean-up and repair,
//! and `building:part` grouping under their outlines.
//!
//! Every footprint comes out either as (part of) a [`Lot`] or as a report entry with its reason.

use glam::DVec2;
use rayon::prelude::*;

mod clean;
pub(crate) mod estimate;
mod fronts;
pub(crate) mod gbt;
pub mod ground;
pub mod infer;
pub(crate) mod morph;
mod parts;
pub(crate) mod structure;
mod tiles;

use clean::{clean_polygons, clean_polygons_quietly, Cleaned};
pub use fronts::{assign_fronts, FRONT_MAX_DISTANCE, FRONT_PARTY_PROBE};
pub(crate) use parts::cut_part;
use parts::{group_parts, straighten_lot};
pub(crate) use tiles::full_bounds;
pub use tiles::{
    group_into_tiles, in_bbox, near_bbox, near_selected, retain_in_bbox, tile_cell, EmptyBox, Tile,
};

use crate::crs::Crs;
use crate::geometry::{ring_signed_area, Polygon};
use crate::input::{Footprint, FootprintKind, SharedTags, SourcePolygon};
use crate::model::SourceId;
use crate::report::{Outcome, Report};

/// Vertices closer than this (metres) are merged.
const MERGE_TOLERANCE: f64 = 1e-3;
/// A vertex where a footprint bends by less than `STRAIGHTEN_MAX_TURN_DEG` and that lies
/// within this distance (metres) of the line through its neighbours is dropped
/// (`straighten_lot`): a straight wall drawn with a node a few centimetres off (most often a
/// neighbour's corner), which would give the roof a crease along the whole building and cost
/// a gable its end.
pub const STRAIGHTEN_TOLERANCE: f64 = 0.05;
/// See [`STRAIGHTEN_TOLERANCE`] (degrees).
pub(crate) const STRAIGHTEN_MAX_TURN_DEG: f64 = 1.0;
/// Outline polygons smaller than this (square metres) are dropped.
const MIN_AREA: f64 = 0.5;
/// A tagged `building:part` is drawn at any size (issue 45: the rings of a column are
/// 0.02-0.5 m²): only a polygon with no area is dropped, under this many square metres (a
/// square centimetre) or ...
const MIN_PART_AREA: f64 = 1e-4;
/// ... under this mean width (metres, twice the area over the perimeter: a line on the
/// output's millimetre grid, not a footprint).
const MIN_PART_WIDTH: f64 = 0.01;
/// Rings with more vertices than this are not checked for self-intersection pair by pair.
const MAX_CHECKED_VERTICES: usize = 20_000;

/// A piece of a building with its own tags (a `building:part`, or the outline itself).
#[derive(Clone, Debug)]
pub struct LotPiece {
    /// The piece's own id: the `building:part`'s, or the outline's when the piece is the outline
    /// itself.
    pub id: SourceId,
    /// Its polygons in the local frame (metres), cleaned and repaired, outer rings
    /// counter-clockwise.
    pub polygons: Vec<Polygon>,
    /// The piece's own tags; when it is derived, a part without colours or material takes its
    /// outline's (`crate::derive::merged_tags`).
    pub tags: SharedTags,
}

/// One building to generate, in the local frame.
#[derive(Clone, Debug)]
pub struct Lot {
    /// The outline's id (`way/123`, `relation/45`, `shp/7`; a `building:part` that lies in no
    /// outline keeps its own): the building's id in every output and in the report.
    pub id: SourceId,
    /// The outline's tags (the part's own for a `building:part` that lies in no outline).
    pub tags: SharedTags,
    /// The outline polygons (several for a multipolygon with several outer rings).
    pub polygons: Vec<Polygon>,
    /// `building:part`s found inside the outline, in id order.
    pub parts: Vec<LotPiece>,
    /// What of the outline is drawn with its own tags: all of it without parts; with parts,
    /// what they leave uncovered (the outline minus their union, slivers dropped), often
    /// nothing; for a part that holds other parts (tagged `building=*` too, in no outline),
    /// the part itself. `None` when it is the outline polygons themselves, as it is for every
    /// lot without parts (issue 46: one copy of the geometry, not two); read it with
    /// [`Lot::drawn_outline`].
    pub drawn: Option<Vec<Polygon>>,
    /// For an outline with parts, its own tags as read (issue 45): what its uncovered rest
    /// ([`Lot::drawn_outline`]) is drawn with, never the values the estimator or the
    /// neighbours lend [`Lot::tags`]. `None` for a lot without parts and for a part that holds
    /// others (whose drawn outline is itself).
    pub rest_tags: Option<SharedTags>,
    /// Representative point in WGS84 (lon, lat) degrees, for the knowledge-base zone.
    pub lonlat: (f64, f64),
    /// Where the building's front faces, set by [`assign_fronts`]: the unit outward normal (local
    /// frame) of the outline edge that faces the nearest street. `None` without a street
    /// within [`FRONT_MAX_DISTANCE`] (and for shapefile input, which has no streets): the
    /// grammar then keeps the thesis front.
    pub front: Option<DVec2>,
    /// The ground the building stands on, metres (issue 44): the lowest DEM height under its
    /// footprint (`--dem`, [`ground::sample_all`]) or `--ground-height`; 0 without terrain. The
    /// derived building is raised by it whole.
    pub ground: f64,
    /// The terrain around the footprint (issue 44, `--dem` at LOD3 and above,
    /// [`ground::sample_all`]): what its facades look at to put the entrance at the terrain and
    /// keep every opening above it. `None` without a DEM, below LOD3, and for the neighbours a
    /// run does not write.
    pub terrain: Option<std::sync::Arc<crate::model::ElevationGrid>>,
}

impl Lot {
    /// What of the outline is drawn with its own tags ([`Lot::drawn`]): its own polygons
    /// when it has some, else the outline's.
    pub fn drawn_outline(&self) -> &[Polygon] {
        self.drawn.as_deref().unwrap_or(&self.polygons)
    }

    /// Lower-left and upper-right corners of the outline polygons (local metres), `None`
    /// when there is none or a coordinate is not finite.
    pub fn bounds(&self) -> Option<(DVec2, DVec2)> {
        let (mut lo, mut hi) = (DVec2::splat(f64::INFINITY), DVec2::splat(f64::NEG_INFINITY));
        for p in &self.polygons {
            let (a, b) = p.bounds();
            lo = lo.min(a);
            hi = hi.max(b);
        }
        (lo.is_finite() && hi.is_finite()).then_some((lo, hi))
    }
}

/// All lots of a run and the frame they are in.
#[derive(Debug)]
pub struct Site {
    /// The output CRS: `--crs`, else the WGS84 UTM zone of the centre of the data's lon/lat bounds.
    pub crs: Crs,
    /// Output-CRS coordinates of the local origin.
    pub origin: DVec2,
    /// The origin as WGS84 (longitude, latitude) in degrees; the IFC writer's `IfcSite`
    /// reference point.
    pub origin_lonlat: (f64, f64),
    /// The buildings to generate, sorted by id (ways, then relations, then shapefile records, each
    /// by number). [`group_into_tiles`] reorders them tile by tile and [`retain_in_bbox`] drops
    /// those outside `--bbox` (counted in one report note).
    pub lots: Vec<Lot>,
    /// The input's admin boundaries as read (lon/lat; OSM only), for the knowledge base's zone
    /// lookup; set by the caller from [`crate::input::ReadResult::boundaries`].
    pub boundaries: Vec<crate::input::AdminBoundary>,
    /// The ground under the run's extent in the local frame (issue 44), when `--dem` gave
    /// one: what the terrain written beside the buildings is made from. `None` without terrain.
    pub elevation: Option<crate::model::ElevationGrid>,
    /// What the run's heights are measured from (issue 44): set with `--dem` or
    /// `--ground-height`, `None` without terrain (buildings on z = 0). The writers get it as
    /// [`crate::export::OutputContext::vertical_datum`].
    pub vertical_datum: Option<crate::model::VerticalDatum>,
    /// The input file's other attributes by footprint id (issue 47), for the writers: set by
    /// the caller from [`crate::input::ReadResult::attributes`]; empty for OSM input.
    pub attributes: std::collections::HashMap<crate::model::SourceId, crate::model::Attributes>,
}

/// The most a projection chosen by citygen may stretch a building's lengths: 0.25 % (2.5 mm
/// per metre), 2.5 times the worst of UTM within its own zone (0.1 % at the zone's edge on the
/// equator). It lets a city overhang its zone by a degree or more (London across 0°, any
/// town on a zone boundary) and refuses a file of places hundreds of kilometres apart.
pub(crate) const MAX_SCALE_ERROR: f64 = 0.0025;

/// The output CRS `choose_output_crs` picked, and how well it fits the data.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct CrsChoice {
    /// The input's projected CRS, or the WGS84 UTM zone of the centre of the data.
    pub crs: Crs,
    /// The data's longitudes, west to east (west > east when they cross the antimeridian).
    pub west_east: (f64, f64),
    /// The largest scale error of the zone at a vertex of the data ([`Crs::utm_scale_error`]),
    /// with that vertex's footprint and lon/lat; `None` when no vertex is finite.
    pub worst: Option<(f64, SourceId, (f64, f64))>,
}

/// The output CRS for data without `--crs`: the input's projected CRS (a `.prj`, a
/// GeoPackage's SRS, GeoJSON's `crs`, `--src-crs`) when it stretches no vertex by more than
/// [`MAX_SCALE_ERROR`], else the UTM zone of the centre of the footprints' lon/lat
/// bounds, where the bounds take the shorter way round the globe (data on both sides of the
/// antimeridian is centred on it, not on Greenwich). With `bbox` (lon/lat), only the vertices
/// inside it count when some are, so that a region cut from a larger file gets its own zone.
/// Also finds the vertex the zone stretches most (see [`MAX_SCALE_ERROR`]).
pub(crate) fn choose_output_crs(
    footprints: &[Footprint],
    source_crs: Option<Crs>,
    bbox: Option<[f64; 4]>,
) -> CrsChoice {
    let to_lonlat = |x: f64, y: f64| match source_crs {
        None | Some(Crs::Wgs84) => (x, y),
        Some(c) => c.file_to_lonlat(x, y),
    };
    let vertices = || {
        footprints.iter().flat_map(move |f| {
            f.polygons
                .iter()
                .flat_map(|p| p.outer.iter())
                .map(move |p| (f.id, to_lonlat(p.0, p.1)))
                .filter(|(_, (lon, lat))| lon.is_finite() && lat.is_finite())
        })
    };
    let in_box = |(lon, lat): (f64, f64)| match bbox {
        Some(b) => lon >= b[0] && lon < b[2] && lat >= b[1] && lat < b[3],
        None => true,
    };
    let use_box = bbox.is_some() && vertices().any(|(_, ll)| in_box(ll));
    let counted = || vertices().filter(move |(_, ll)| !use_box || in_box(*ll));
    // Longitude bounds as given, and with the western hemisphere moved east by 360°: the
    // narrower of the two is the data's extent.
    let mut plain = (f64::INFINITY, f64::NEG_INFINITY);
    let mut shifted = plain;
    let mut lat = plain;
    for (_, (lon, la)) in counted() {
        plain = (plain.0.min(lon), plain.1.max(lon));
        let e = if lon < 0.0 { lon + 360.0 } else { lon };
        shifted = (shifted.0.min(e), shifted.1.max(e));
        lat = (lat.0.min(la), lat.1.max(la));
    }
    if !plain.0.is_finite() {
        return CrsChoice {
            crs: Crs::utm_for(0.0, 0.0),
            west_east: (0.0, 0.0),
            worst: None,
        };
    }
    let wrap = |l: f64| (l + 180.0).rem_euclid(360.0) - 180.0;
    let (west, east) = if shifted.1 - shifted.0 < plain.1 - plain.0 {
        shifted
    } else {
        plain
    };
    let worst_in = |crs: Crs| {
        let mut worst: Option<(f64, SourceId, (f64, f64))> = None;
        for (id, (lon, la)) in counted() {
            let e = crs.scale_error(lon, la).unwrap_or(f64::INFINITY);
            if worst.as_ref().is_none_or(|w| e > w.0) {
                worst = Some((e, id, (lon, la)));
            }
        }
        worst
    };
    // The input's own projected CRS when it fits the data (a national grid far outside its
    // country does not, nor does a file spanning a continent); else the UTM zone.
    // A CRS in feet gives its metre twin (State Plane ftUS -> the same zone in metres):
    // citygen's outputs are in metres.
    if let Some(c) = source_crs
        .filter(|c| !c.is_geographic())
        .and_then(|c| c.in_metres())
    {
        let worst = worst_in(c);
        if worst.as_ref().is_some_and(|w| w.0 <= MAX_SCALE_ERROR) {
            return CrsChoice {
                crs: c,
                west_east: (wrap(west), wrap(east)),
                worst,
            };
        }
    }
    let crs = Crs::utm_for(wrap(0.5 * (west + east)), 0.5 * (lat.0 + lat.1));
    let worst = worst_in(crs);
    CrsChoice {
        crs,
        west_east: (wrap(west), wrap(east)),
        worst,
    }
}

/// Projects and cleans every footprint, then groups parts under outlines.
///
/// `source_crs` `None` means WGS84 degrees. `out_crs` `None` picks `choose_output_crs`'s CRS
/// (the input's projected CRS, or the UTM zone of the data's centre). The origin is the centre of the data's bounds, rounded to the metre.
pub fn prepare(
    footprints: Vec<Footprint>,
    source_crs: Option<Crs>,
    out_crs: Option<Crs>,
    report: &mut Report,
) -> Site {
    prepare_at(footprints, source_crs, out_crs, None, report)
}

/// [`prepare`] around `origin` (output CRS) when given, instead of the centre of the data's
/// bounds: a shard reading its part of a split input takes the whole input's origin, so that
/// its buildings' local coordinates are those of a run on the whole input, bit for bit.
pub fn prepare_at(
    footprints: Vec<Footprint>,
    source_crs: Option<Crs>,
    out_crs: Option<Crs>,
    origin: Option<DVec2>,
    report: &mut Report,
) -> Site {
    let to_lonlat = |x: f64, y: f64| match source_crs {
        None | Some(Crs::Wgs84) => (x, y),
        Some(c) => c.file_to_lonlat(x, y),
    };
    // Output CRS: the input's projected CRS or the UTM zone of the centre of the data.
    let crs = out_crs.unwrap_or_else(|| choose_output_crs(&footprints, source_crs, None).crs);
    let same = source_crs == Some(crs);
    let unit = crs.unit().metres;
    let project = |x: f64, y: f64| -> (DVec2, (f64, f64)) {
        if same {
            // The file's unit (feet for a State Plane file) to the model's metres.
            let (x, y) = (x * unit, y * unit);
            (DVec2::new(x, y), crs.to_lonlat(x, y))
        } else {
            let ll = to_lonlat(x, y);
            let (px, py) = crs.from_lonlat(ll.0, ll.1);
            (DVec2::new(px, py), ll)
        }
    };

    // Project everything in absolute output-CRS coordinates first (in parallel; the report
    // entries and the bounds follow the input order).
    struct Projected {
        id: SourceId,
        kind: FootprintKind,
        tags: SharedTags,
        polygons: Vec<Polygon>,
        lonlat: (f64, f64),
    }
    const UNPROJECTABLE: &str = "coordinates cannot be projected to the output CRS";
    let projected: Vec<Result<Projected, SourceId>> = footprints
        .into_par_iter()
        .map(|f| {
            let mut lonlat_sum = (0.0, 0.0, 0usize);
            let mut polys = Vec::with_capacity(f.polygons.len());
            let ring = |r: &[(f64, f64)], acc: &mut (f64, f64, usize)| -> Option<Vec<DVec2>> {
                let mut out = Vec::with_capacity(r.len());
                for &(x, y) in r {
                    let (p, ll) = project(x, y);
                    if !(p.x.is_finite() && p.y.is_finite()) {
                        return None;
                    }
                    acc.0 += ll.0;
                    acc.1 += ll.1;
                    acc.2 += 1;
                    out.push(p);
                }
                Some(out)
            };
            for sp in &f.polygons {
                let SourcePolygon { outer, holes } = sp;
                let o = ring(outer, &mut lonlat_sum).ok_or(f.id)?;
                let mut hs = Vec::with_capacity(holes.len());
                for h in holes {
                    let mut dummy = (0.0, 0.0, 0);
                    hs.push(ring(h, &mut dummy).ok_or(f.id)?);
                }
                polys.push(Polygon {
                    outer: o,
                    holes: hs,
                });
            }
            let n = lonlat_sum.2.max(1) as f64;
            Ok(Projected {
                id: f.id,
                kind: f.kind,
                tags: f.tags,
                polygons: polys,
                lonlat: (lonlat_sum.0 / n, lonlat_sum.1 / n),
            })
        })
        .collect();
    let (mut lo, mut hi) = (DVec2::splat(f64::INFINITY), DVec2::splat(f64::NEG_INFINITY));
    let projected: Vec<Projected> = projected
        .into_iter()
        .filter_map(|p| match p {
            Ok(p) => {
                for q in p.polygons.iter().flat_map(|p| &p.outer) {
                    lo = lo.min(*q);
                    hi = hi.max(*q);
                }
                Some(p)
            }
            Err(id) => {
                report.add(Some(id), Outcome::Skipped, UNPROJECTABLE);
                None
            }
        })
        .collect();
    let origin = if let Some(o) = origin {
        o
    } else if lo.x.is_finite() {
        ((lo + hi) * 0.5).round()
    } else {
        DVec2::ZERO
    };
    let origin_lonlat = crs.to_lonlat(origin.x, origin.y);

    // Clean the rings in the local frame (in parallel; entries in input order).
    let cleaned: Vec<(Projected, Cleaned)> = projected
        .into_par_iter()
        .map(|mut p| {
            let local = std::mem::take(&mut p.polygons)
                .into_iter()
                .map(|q| q.translated(-origin))
                .collect();
            let least = match p.kind {
                FootprintKind::Building => clean::Least::OUTLINE,
                FootprintKind::Part => clean::Least::PART,
            };
            (p, clean_polygons_quietly(local, least))
        })
        .collect();
    let mut outlines = Vec::new();
    let mut pieces = Vec::new();
    for (p, (polygons, entry)) in cleaned {
        if let Some((outcome, text)) = entry {
            report.add(Some(p.id), outcome, text);
        }
        let Some(polygons) = polygons else {
            continue;
        };
        match p.kind {
            FootprintKind::Building => outlines.push(Lot {
                id: p.id,
                tags: p.tags,
                drawn: None,
                rest_tags: None,
                polygons,
                parts: Vec::new(),
                lonlat: p.lonlat,
                front: None,
                ground: 0.0,
                terrain: None,
            }),
            FootprintKind::Part => pieces.push((
                LotPiece {
                    id: p.id,
                    polygons,
                    tags: p.tags,
                },
                p.lonlat,
            )),
        }
    }
    let mut lots = group_parts(outlines, pieces, report);
    lots.par_iter_mut().for_each(straighten_lot);
    // What is not a house, once: its tags carry the class (issue 45).
    structure::classify(&mut lots);
    Site {
        crs,
        origin,
        origin_lonlat,
        lots,
        boundaries: Vec::new(),
        elevation: None,
        vertical_datum: None,
        attributes: Default::default(),
    }
}

/// Length of a closed ring.
fn ring_perimeter(r: &[DVec2]) -> f64 {
    (0..r.len())
        .map(|i| r[i].distance(r[(i + 1) % r.len()]))
        .sum()
}

/// A point inside the polygon: the centroid when it is inside, else the midpoint of the widest
/// horizontal chord through the middle of the bounds.
pub fn interior_point(p: &Polygon) -> DVec2 {
    let c = ring_centroid(&p.outer);
    if p.contains(c) {
        return c;
    }
    let (lo, hi) = p.bounds();
    for k in 1..8 {
        let y = lo.y + (hi.y - lo.y) * (k as f64 / 8.0);
        let mut xs: Vec<f64> = Vec::new();
        for ring in p.rings() {
            let n = ring.len();
            for i in 0..n {
                let (a, b) = (ring[i], ring[(i + 1) % n]);
                if (a.y > y) != (b.y > y) {
                    xs.push(a.x + (y - a.y) * (b.x - a.x) / (b.y - a.y));
                }
            }
        }
        xs.sort_by(f64::total_cmp);
        let best = xs
            .chunks_exact(2)
            .max_by(|u, v| (u[1] - u[0]).total_cmp(&(v[1] - v[0])));
        if let Some(seg) = best {
            let q = DVec2::new(0.5 * (seg[0] + seg[1]), y);
            if p.contains(q) {
                return q;
            }
        }
    }
    p.outer[0]
}

/// Area centroid of a ring (vertex mean for a degenerate ring).
pub(crate) fn ring_centroid(r: &[DVec2]) -> DVec2 {
    let a = ring_signed_area(r);
    if a.abs() < 1e-12 {
        return r.iter().copied().sum::<DVec2>() / r.len().max(1) as f64;
    }
    let o = r[0];
    let mut c = DVec2::ZERO;
    for i in 0..r.len() {
        let (p, q) = (r[i] - o, r[(i + 1) % r.len()] - o);
        let cross = p.perp_dot(q);
        c += (p + q) * cross;
    }
    o + c / (6.0 * a)
}

/// A site holding one lot given in local metres, placed at `lonlat` (the local origin), for
/// trying a ruleset without a city (`citygen rules derive`).
pub(crate) fn single_lot(
    polygon: Polygon,
    lonlat: (f64, f64),
    crs: Option<Crs>,
    report: &mut Report,
) -> Option<Site> {
    let crs = crs.unwrap_or_else(|| Crs::utm_for(lonlat.0, lonlat.1));
    let (x, y) = crs.from_lonlat(lonlat.0, lonlat.1);
    let origin = DVec2::new(x, y).round();
    let id = SourceId::Lot(0);
    let polygons = clean_polygons(id, vec![polygon], report)?;
    report.read += 1;
    let mut lot = Lot {
        id,
        tags: SharedTags::default(),
        drawn: None,
        rest_tags: None,
        polygons,
        parts: Vec::new(),
        lonlat,
        front: None,
        ground: 0.0,
        terrain: None,
    };
    straighten_lot(&mut lot);
    Some(Site {
        crs,
        origin,
        origin_lonlat: crs.to_lonlat(origin.x, origin.y),
        lots: vec![lot],
        boundaries: Vec::new(),
        elevation: None,
        vertical_datum: None,
        attributes: Default::default(),
    })
}

#[cfg(test)]
mod tests;

#[cfg(test)]
mod crs_choice_tests {
    use super::*;

    /// A 10 m square building (as lon/lat degrees) at each point.
    fn at(points: &[(f64, f64)]) -> Vec<Footprint> {
        points
            .iter()
            .enumerate()
            .map(|(i, &(lon, lat))| {
                let d = 1e-4;
                Footprint {
                    id: SourceId::Way(i as i64 + 1),
                    kind: FootprintKind::Building,
                    polygons: vec![SourcePolygon {
                        outer: vec![
                            (lon, lat),
                            (lon + d, lat),
                            (lon + d, lat + d),
                            (lon, lat + d),
                            (lon, lat),
                        ],
                        holes: vec![],
                    }],
                    tags: SharedTags::default(),
                }
            })
            .collect()
    }

    fn zone(c: &CrsChoice) -> u8 {
        match c.crs {
            Crs::Utm { zone, .. } => zone,
            _ => 0,
        }
    }

    fn worst(c: &CrsChoice) -> f64 {
        c.worst.as_ref().map_or(f64::NAN, |w| w.0)
    }

    #[test]
    fn one_town_gets_its_zone_and_fits_it() {
        let c = choose_output_crs(&at(&[(7.41, 43.73), (7.43, 43.74)]), None, None);
        assert_eq!(
            c.crs,
            Crs::Utm {
                zone: 32,
                north: true
            }
        );
        assert!(worst(&c) < 1e-3, "{c:?}");
        let south = choose_output_crs(&at(&[(-58.4, -34.6)]), None, None);
        assert_eq!(
            south.crs,
            Crs::Utm {
                zone: 21,
                north: false
            }
        );
    }

    #[test]
    fn data_across_the_antimeridian_is_centred_on_it() {
        // Taveuni, Fiji, on both sides of 180°: the plain bounds' centre would be Greenwich.
        let c = choose_output_crs(&at(&[(179.95, -16.8), (-179.95, -16.8)]), None, None);
        assert!(zone(&c) == 60 || zone(&c) == 1, "{c:?}");
        assert!(worst(&c) < MAX_SCALE_ERROR, "{c:?}");
        assert!(c.west_east.0 > 179.0 && c.west_east.1 < -179.0, "{c:?}");
    }

    #[test]
    fn a_city_across_a_zone_boundary_fits_but_two_distant_cities_do_not() {
        // Greater London spans 0° (zones 30 and 31).
        let london = choose_output_crs(&at(&[(-0.5, 51.3), (0.3, 51.7)]), None, None);
        assert!(worst(&london) < MAX_SCALE_ERROR, "{london:?}");
        // Monaco and Lisbon in one file: 16° apart.
        let two = at(&[(7.42, 43.73), (-9.14, 38.72)]);
        let c = choose_output_crs(&two, None, None);
        assert!(worst(&c) > MAX_SCALE_ERROR, "{c:?}");
        // A box around one of them: that city's zone, and it fits.
        let lisbon = choose_output_crs(&two, None, Some([-9.5, 38.5, -9.0, 39.0]));
        assert_eq!(
            lisbon.crs,
            Crs::Utm {
                zone: 29,
                north: true
            }
        );
        assert!(worst(&lisbon) < 1e-3, "{lisbon:?}");
        // A box that holds nothing: the whole data decides (the box's own check reports it).
        let none = choose_output_crs(&two, None, Some([100.0, 0.0, 101.0, 1.0]));
        assert_eq!(none, c);
    }

    #[test]
    fn no_finite_vertex_gives_a_zone_and_no_worst() {
        let c = choose_output_crs(&at(&[(f64::NAN, 1.0)]), None, None);
        assert!(c.worst.is_none());
    }
}
