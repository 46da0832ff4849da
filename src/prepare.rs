//! From source footprints to lots in the local frame: projection, ring clean-up and repair,
//! and `building:part` grouping under their outlines.
//!
//! Every footprint comes out either as (part of) a [`Lot`] or as a report entry with its reason.

use geo::BooleanOps;
use glam::DVec2;
use rayon::prelude::*;
use rstar::{RTree, RTreeObject, AABB};

pub mod infer;

use crate::crs::Crs;
use crate::geometry::{ring, ring_signed_area, Polygon};
use crate::input::{Footprint, FootprintKind, SharedTags, SourcePolygon, Streets};
use crate::model::SourceId;
use crate::report::{Outcome, Report};

/// Vertices closer than this (metres) are merged.
const MERGE_TOLERANCE: f64 = 1e-3;
/// A vertex where a footprint bends by less than [`STRAIGHTEN_MAX_TURN_DEG`] and that lies
/// within this distance (metres) of the line through its neighbours is dropped
/// (`straighten_lot`): a straight wall drawn with a node a few centimetres off (most often a
/// neighbour's corner), which would give the roof a crease along the whole building and cost
/// a gable its end.
pub const STRAIGHTEN_TOLERANCE: f64 = 0.05;
/// See [`STRAIGHTEN_TOLERANCE`] (degrees).
pub const STRAIGHTEN_MAX_TURN_DEG: f64 = 1.0;
/// Footprint polygons smaller than this (square metres) are dropped.
const MIN_AREA: f64 = 0.5;
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
    /// outline's ([`crate::derive::merged_tags`]).
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
    /// the part itself.
    pub drawn_outline: Vec<Polygon>,
    /// Representative point in WGS84 (lon, lat) degrees, for the knowledge-base zone.
    pub lonlat: (f64, f64),
    /// Where the building's front faces, set by [`assign_fronts`]: the unit outward normal (local
    /// frame) of the outline edge that faces the nearest street. `None` without a street
    /// within [`FRONT_MAX_DISTANCE`] (and for shapefile input, which has no streets): the
    /// grammar then keeps the thesis front.
    pub front: Option<DVec2>,
}

impl Lot {
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
}

/// The most a projection chosen by citygen may stretch a building's lengths: 0.25 % (2.5 mm
/// per metre), 2.5 times the worst of UTM within its own zone (0.1 % at the zone's edge on the
/// equator). It lets a city overhang its zone by a degree or more (London across 0°, any
/// town on a zone boundary) and refuses a file of places hundreds of kilometres apart.
pub const MAX_SCALE_ERROR: f64 = 0.0025;

/// The output CRS [`choose_output_crs`] picked, and how well it fits the data.
#[derive(Clone, Debug, PartialEq)]
pub struct CrsChoice {
    /// The WGS84 UTM zone of the centre of the data.
    pub crs: Crs,
    /// The data's longitudes, west to east (west > east when they cross the antimeridian).
    pub west_east: (f64, f64),
    /// The largest scale error of the zone at a vertex of the data ([`Crs::utm_scale_error`]),
    /// with that vertex's footprint and lon/lat; `None` when no vertex is finite.
    pub worst: Option<(f64, SourceId, (f64, f64))>,
}

/// The UTM zone for data without `--crs`: the zone of the centre of the footprints' lon/lat
/// bounds, where the bounds take the shorter way round the globe (data on both sides of the
/// antimeridian is centred on it, not on Greenwich). With `bbox` (lon/lat), only the vertices
/// inside it count when some are, so that a region cut from a larger file gets its own zone.
/// Also finds the vertex the zone stretches most (see [`MAX_SCALE_ERROR`]).
pub fn choose_output_crs(
    footprints: &[Footprint],
    source_crs: Option<Crs>,
    bbox: Option<[f64; 4]>,
) -> CrsChoice {
    let to_lonlat = |x: f64, y: f64| match source_crs {
        None | Some(Crs::Wgs84) => (x, y),
        Some(c) => c.to_lonlat(x, y),
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
    let crs = Crs::utm_for(wrap(0.5 * (west + east)), 0.5 * (lat.0 + lat.1));
    let mut worst: Option<(f64, SourceId, (f64, f64))> = None;
    for (id, (lon, la)) in counted() {
        let e = crs.utm_scale_error(lon, la).unwrap_or(0.0);
        if worst.as_ref().is_none_or(|w| e > w.0) {
            worst = Some((e, id, (lon, la)));
        }
    }
    CrsChoice {
        crs,
        west_east: (wrap(west), wrap(east)),
        worst,
    }
}

/// Projects and cleans every footprint, then groups parts under outlines.
///
/// `source_crs` `None` means WGS84 degrees. `out_crs` `None` picks the UTM zone of the data's
/// centre. The origin is the centre of the data's bounds, rounded to the metre.
pub fn prepare(
    footprints: Vec<Footprint>,
    source_crs: Option<Crs>,
    out_crs: Option<Crs>,
    report: &mut Report,
) -> Site {
    let to_lonlat = |x: f64, y: f64| match source_crs {
        None | Some(Crs::Wgs84) => (x, y),
        Some(c) => c.to_lonlat(x, y),
    };
    // Output CRS: the UTM zone of the centre of the data.
    let crs = out_crs.unwrap_or_else(|| choose_output_crs(&footprints, source_crs, None).crs);
    let same = source_crs == Some(crs);
    let project = |x: f64, y: f64| -> (DVec2, (f64, f64)) {
        if same {
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
    let origin = if lo.x.is_finite() {
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
            (p, clean_polygons_quietly(local))
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
                drawn_outline: polygons.clone(),
                polygons,
                parts: Vec::new(),
                lonlat: p.lonlat,
                front: None,
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
    Site {
        crs,
        origin,
        origin_lonlat,
        lots,
    }
}

/// Straightens the rings of a lot ([`ring::straighten`] within [`STRAIGHTEN_TOLERANCE`]): the
/// outline, its drawn rest and its parts. A vertex within 1 cm of another of the lot's rings
/// stays (a part's corner on the outline, an outline's corner on a part), so that what shares a
/// boundary still does; the outline and its drawn rest, which share theirs by construction, are
/// not each other's keepers. A polygon that straightening would make touch itself stays as it
/// was.
fn straighten_lot(lot: &mut Lot) {
    const NEAR: f64 = 0.01;
    let rings_of = |ps: &[Polygon]| -> Vec<Vec<DVec2>> {
        ps.iter().flat_map(|p| p.rings().cloned()).collect()
    };
    let outline = rings_of(&lot.polygons);
    let drawn = rings_of(&lot.drawn_outline);
    let parts: Vec<Vec<Vec<DVec2>>> = lot.parts.iter().map(|p| rings_of(&p.polygons)).collect();
    let near = |q: DVec2, rings: &[&Vec<DVec2>]| {
        rings.iter().any(|r| {
            (0..r.len())
                .any(|i| nearest_on_segment(r[i], r[(i + 1) % r.len()], q).distance(q) <= NEAR)
        })
    };
    let fix = |ps: &mut Vec<Polygon>, keepers: &[&Vec<DVec2>]| {
        for p in ps.iter_mut() {
            let straight = |r: &Vec<DVec2>| {
                ring::straighten(r, STRAIGHTEN_TOLERANCE, STRAIGHTEN_MAX_TURN_DEG, |q| {
                    !keepers.is_empty() && near(q, keepers)
                })
            };
            let candidate =
                Polygon::new(straight(&p.outer), p.holes.iter().map(straight).collect());
            if candidate != *p && candidate.outer.len() >= 3 && is_valid(&candidate) {
                *p = candidate;
            }
        }
    };
    let all_parts: Vec<&Vec<DVec2>> = parts.iter().flatten().collect();
    fix(&mut lot.polygons, &all_parts);
    fix(&mut lot.drawn_outline, &all_parts);
    for (k, part) in lot.parts.iter_mut().enumerate() {
        let keepers: Vec<&Vec<DVec2>> = outline
            .iter()
            .chain(&drawn)
            .chain(
                parts
                    .iter()
                    .enumerate()
                    .filter(|(j, _)| *j != k)
                    .flat_map(|(_, r)| r),
            )
            .collect();
        fix(&mut part.polygons, &keepers);
    }
    share_vertices(lot);
}

/// How far (metres) a vertex of one of a lot's drawn rings may lie from another ring's edge
/// and be put into that edge: two rings that share a boundary then have the same vertices along
/// it, and their walls meet edge to edge (a vertex on one side only leaves a sliver between the
/// two solids, a volume overlap to a solid validator, and a T-junction in the shell).
const SHARED_VERTEX_TOLERANCE: f64 = 0.002;

/// Puts every vertex of the lot's drawn rings (the outline's rest and the parts) into the
/// edges of the others that pass within [`SHARED_VERTEX_TOLERANCE`] of it, strictly between
/// their ends (at least [`crate::model::MIN_VERTEX_GAP`] from each). A polygon that the
/// insertion would make invalid stays as it was.
fn share_vertices(lot: &mut Lot) {
    if lot.parts.is_empty() {
        return;
    }
    let gap = crate::model::MIN_VERTEX_GAP;
    // Every vertex of each piece, with the piece it belongs to.
    let mut verts: Vec<(usize, DVec2)> = Vec::new();
    let pieces = std::iter::once(&lot.drawn_outline).chain(lot.parts.iter().map(|p| &p.polygons));
    for (k, ps) in pieces.enumerate() {
        for p in ps {
            verts.extend(p.rings().flatten().map(|&v| (k, v)));
        }
    }
    let insert = |k: usize, r: &Vec<DVec2>| -> Vec<DVec2> {
        let n = r.len();
        let mut out = Vec::with_capacity(n);
        for i in 0..n {
            let (a, b) = (r[i], r[(i + 1) % n]);
            out.push(a);
            let (lo, hi) = (a.min(b), a.max(b));
            let d = b - a;
            let l2 = d.length_squared();
            let mut on: Vec<(f64, DVec2)> = verts
                .iter()
                .filter(|(j, v)| {
                    *j != k
                        && v.x >= lo.x - SHARED_VERTEX_TOLERANCE
                        && v.x <= hi.x + SHARED_VERTEX_TOLERANCE
                        && v.y >= lo.y - SHARED_VERTEX_TOLERANCE
                        && v.y <= hi.y + SHARED_VERTEX_TOLERANCE
                })
                .filter(|&&(_, v)| {
                    v.distance(a) >= gap
                        && v.distance(b) >= gap
                        && nearest_on_segment(a, b, v).distance(v) <= SHARED_VERTEX_TOLERANCE
                })
                // Along the edge; a vertex at least `gap` from both ends of an edge it lies
                // within 2 mm of is strictly inside it, so the edge has a length.
                .map(|&(_, v)| ((v - a).dot(d) / l2, v))
                .collect();
            on.sort_by(|x, y| {
                x.0.total_cmp(&y.0)
                    .then(x.1.x.total_cmp(&y.1.x))
                    .then(x.1.y.total_cmp(&y.1.y))
            });
            on.dedup_by(|x, y| x.1.distance(y.1) < gap);
            out.extend(on.into_iter().map(|x| x.1));
        }
        out
    };
    let fix = |k: usize, ps: &mut Vec<Polygon>| {
        for p in ps.iter_mut() {
            let candidate = Polygon::new(
                insert(k, &p.outer),
                p.holes.iter().map(|h| insert(k, h)).collect(),
            );
            if candidate != *p && is_valid(&candidate) {
                *p = candidate;
            }
        }
    };
    fix(0, &mut lot.drawn_outline);
    for (i, part) in lot.parts.iter_mut().enumerate() {
        fix(i + 1, &mut part.polygons);
    }
}

/// An outline's bounding box in the part-assignment index.
struct OutlineBox {
    index: usize,
    aabb: AABB<[f64; 2]>,
}

impl RTreeObject for OutlineBox {
    type Envelope = AABB<[f64; 2]>;
    fn envelope(&self) -> Self::Envelope {
        self.aabb
    }
}

/// The smallest piece of an outline left over by its parts that is still drawn (m²), and the
/// least mean width (area / half perimeter, metres): what the parts leave of an outline is
/// mostly the slivers between nearly shared edges.
const MIN_REST_AREA: f64 = 2.0;
const MIN_REST_WIDTH: f64 = 0.25;

/// Groups parts under outlines (Simple 3D Buildings). Each part goes under the smallest
/// outline containing its representative point. A part that lies in no outline but is tagged
/// `building=*` too (a church mapped as its nave with `building=church` + `building:part=yes`,
/// domes and towers as parts inside it) holds the unowned parts inside it, the largest such
/// part first, and is drawn as a part of itself; any other part that lies in no outline is a
/// building of its own (with a note). An outline with parts is a container: only what its
/// parts leave uncovered is drawn with its own tags ([`Lot::drawn_outline`]), so that outline
/// and parts never both fill one volume.
fn group_parts(
    mut outlines: Vec<Lot>,
    pieces: Vec<(LotPiece, (f64, f64))>,
    report: &mut Report,
) -> Vec<Lot> {
    let tree = outline_index(&outlines);
    let area = |polys: &[Polygon]| polys.iter().map(Polygon::area).sum::<f64>();
    let owner_in =
        |lots: &[Lot], tree: &RTree<OutlineBox>, piece: &LotPiece, skip: Option<SourceId>| {
            let probe = interior_point(&piece.polygons[0]);
            tree.locate_in_envelope_intersecting(AABB::from_point([probe.x, probe.y]))
                .filter(|b| Some(lots[b.index].id) != skip)
                .filter(|b| lots[b.index].polygons.iter().any(|p| p.contains(probe)))
                .min_by(|a, b| {
                    area(&lots[a.index].polygons)
                        .total_cmp(&area(&lots[b.index].polygons))
                        .then(a.index.cmp(&b.index))
                })
                .map(|b| b.index)
        };
    let mut unowned = Vec::new();
    for (piece, lonlat) in pieces {
        match owner_in(&outlines, &tree, &piece, None) {
            Some(i) => outlines[i].parts.push(piece),
            None => unowned.push((piece, lonlat)),
        }
    }
    // Unowned parts tagged building=* too are candidate containers; each unowned part goes into
    // the largest candidate containing it (a dome into the nave, not into a tower).
    let is_building = |p: &LotPiece| p.tags.has_building;
    let mut containers: Vec<Lot> = unowned
        .iter()
        .filter(|(p, _)| is_building(p))
        .map(|(p, lonlat)| Lot {
            id: p.id,
            tags: p.tags.clone(),
            polygons: p.polygons.clone(),
            parts: Vec::new(),
            drawn_outline: p.polygons.clone(),
            lonlat: *lonlat,
            front: None,
        })
        .collect();
    let ctree = outline_index(&containers);
    let largest_container = |piece: &LotPiece| {
        let probe = interior_point(&piece.polygons[0]);
        ctree
            .locate_in_envelope_intersecting(AABB::from_point([probe.x, probe.y]))
            .filter(|b| containers[b.index].id != piece.id)
            .filter(|b| {
                containers[b.index]
                    .polygons
                    .iter()
                    .any(|p| p.contains(probe))
            })
            .filter(|b| area(&containers[b.index].polygons) > area(&piece.polygons))
            .max_by(|a, b| {
                area(&containers[a.index].polygons)
                    .total_cmp(&area(&containers[b.index].polygons))
                    .then(b.index.cmp(&a.index))
            })
            .map(|b| b.index)
    };
    let homes: Vec<Option<usize>> = unowned.iter().map(|(p, _)| largest_container(p)).collect();
    let mut orphans = Vec::new();
    let mut contained = vec![false; containers.len()];
    for ((piece, lonlat), home) in unowned.into_iter().zip(homes) {
        match home {
            Some(c) => {
                if let Some(k) = containers.iter().position(|l| l.id == piece.id) {
                    contained[k] = true;
                }
                containers[c].parts.push(piece);
            }
            None if is_building(&piece) => {}
            None => {
                report.add(
                    Some(piece.id),
                    Outcome::Note,
                    "building:part lies in no building outline; generated as a building of its own",
                );
                orphans.push(Lot {
                    id: piece.id,
                    tags: piece.tags.clone(),
                    polygons: piece.polygons.clone(),
                    parts: Vec::new(),
                    drawn_outline: piece.polygons,
                    lonlat,
                    front: None,
                });
            }
        }
    }
    // A container inside a larger one is one of its parts, not a building of its own.
    let containers: Vec<Lot> = containers
        .into_iter()
        .zip(contained)
        .filter(|(_, inside)| !inside)
        .map(|(l, _)| l)
        .collect();
    for lot in &mut outlines {
        if lot.parts.is_empty() {
            continue;
        }
        let parts: Vec<Polygon> = lot
            .parts
            .iter()
            .flat_map(|p| p.polygons.iter().cloned())
            .collect();
        let outline_area = area(&lot.polygons);
        lot.drawn_outline = cut_out(&lot.polygons, &parts);
        if !lot.drawn_outline.is_empty() {
            report.add(
                Some(lot.id),
                Outcome::Note,
                format!(
                    "building:parts cover {:.0} % of the outline; the rest ({:.0} m²) is drawn with the outline's tags",
                    100.0 * (1.0 - area(&lot.drawn_outline) / outline_area.max(1e-9)),
                    area(&lot.drawn_outline)
                ),
            );
        }
    }
    outlines.extend(containers);
    outlines.extend(orphans);
    for lot in &mut outlines {
        lot.parts.sort_by_key(|p| p.id);
    }
    outlines.sort_by_key(|l| l.id);
    outlines
}

/// What of `polygons` lies outside every polygon of `cutters`, cleaned as footprints are, and
/// without the slivers that nearly shared edges leave (pieces under 2 m² or 0.25 m of mean
/// width).
pub fn cut_out(polygons: &[Polygon], cutters: &[Polygon]) -> Vec<Polygon> {
    let rest: Vec<Polygon> = crate::geometry::clip::difference(polygons, cutters)
        .into_iter()
        .filter(|p| {
            let perimeter: f64 = p.rings().map(|r| ring_perimeter(r)).sum();
            p.area() >= MIN_REST_AREA && p.area() >= MIN_REST_WIDTH * 0.5 * perimeter
        })
        .collect();
    clean_polygons_quietly(rest).0.unwrap_or_default()
}

/// The bounding boxes of lots' outlines, for finding the outlines around a point.
fn outline_index(lots: &[Lot]) -> RTree<OutlineBox> {
    let boxes: Vec<OutlineBox> = lots
        .iter()
        .enumerate()
        .map(|(index, l)| {
            let (mut lo, mut hi) = (DVec2::splat(f64::INFINITY), DVec2::splat(f64::NEG_INFINITY));
            for p in &l.polygons {
                let (a, b) = p.bounds();
                lo = lo.min(a);
                hi = hi.max(b);
            }
            OutlineBox {
                index,
                aabb: AABB::from_corners([lo.x, lo.y], [hi.x, hi.y]),
            }
        })
        .collect();
    RTree::bulk_load(boxes)
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
pub fn ring_centroid(r: &[DVec2]) -> DVec2 {
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

/// Cleans polygons: merges near-duplicate vertices, drops spikes and degenerate rings,
/// repairs self-intersections and stray holes with a boolean union, drops slivers.
/// `None` (with a report entry) when nothing usable is left.
fn clean_polygons(id: SourceId, polys: Vec<Polygon>, report: &mut Report) -> Option<Vec<Polygon>> {
    let (polygons, entry) = clean_polygons_quietly(polys);
    if let Some((outcome, text)) = entry {
        report.add(Some(id), outcome, text);
    }
    polygons
}

/// What [`clean_polygons_quietly`] gives: the cleaned polygons (`None`: skipped) and the report
/// entry for the footprint, if any.
type Cleaned = (Option<Vec<Polygon>>, Option<(Outcome, String)>);

/// [`clean_polygons`] without a report: the cleaned polygons (`None`: the footprint is
/// skipped) and the report entry to add for it, if any.
fn clean_polygons_quietly(
    polys: Vec<Polygon>,
) -> (Option<Vec<Polygon>>, Option<(Outcome, String)>) {
    let mut out = Vec::with_capacity(polys.len());
    let mut repaired = Vec::new();
    for p in polys {
        let Some((outer, spikes)) = merge_ring(&p.outer) else {
            repaired.push("dropped an outer ring with fewer than 3 distinct vertices".to_string());
            continue;
        };
        let mut spikes_removed = spikes;
        let mut holes = Vec::with_capacity(p.holes.len());
        for h in &p.holes {
            match merge_ring(h) {
                Some((r, spikes)) => {
                    spikes_removed += spikes;
                    holes.push(r);
                }
                None => repaired.push("dropped a degenerate inner ring".to_string()),
            }
        }
        if spikes_removed > 0 {
            repaired.push(format!(
                "removed {spikes_removed} spike(s) (an edge going out and straight back)"
            ));
        }
        let poly = Polygon::new(outer, holes);
        if is_valid(&poly) {
            out.push(poly);
        } else {
            let fixed = repair(&poly);
            repaired.push(format!(
                "self-intersecting or inconsistent rings resolved into {} polygon(s)",
                fixed.len()
            ));
            out.extend(fixed);
        }
    }
    let before = out.len();
    out.retain(|p| p.area() >= MIN_AREA);
    if out.len() < before {
        repaired.push(format!(
            "dropped {} polygon(s) smaller than {MIN_AREA} m²",
            before - out.len()
        ));
    }
    if out.is_empty() {
        let why = if repaired.is_empty() {
            "no usable polygon".to_string()
        } else {
            repaired.join("; ")
        };
        return (
            None,
            Some((Outcome::Skipped, format!("degenerate footprint: {why}"))),
        );
    }
    let entry = (!repaired.is_empty()).then(|| (Outcome::Repaired, repaired.join("; ")));
    (Some(out), entry)
}

/// Merges vertices closer than the tolerance and removes zero-width spikes (a, b, a)
/// ([`ring::dedup_within`], [`ring::remove_spikes_by`]); returns the ring and the number of
/// spikes. `None` when fewer than 3 vertices are left. (A ring can still have zero area, e.g. a
/// bow-tie: the validity check and the repair handle that.)
fn merge_ring(r: &[DVec2]) -> Option<(Vec<DVec2>, usize)> {
    let mut v = r.to_vec();
    ring::dedup_within(&mut v, MERGE_TOLERANCE);
    let spikes = ring::remove_spikes_by(&mut v, |a, b| a.distance(b) <= MERGE_TOLERANCE);
    (v.len() >= 3).then_some((v, spikes))
}

/// Whether rings are simple, do not cross each other, and holes lie inside the outer ring.
fn is_valid(p: &Polygon) -> bool {
    let total: usize = p.rings().map(Vec::len).sum();
    if total > MAX_CHECKED_VERTICES {
        return true; // too large to check pairwise; the writers cope with it
    }
    let segs: Vec<(DVec2, DVec2, usize, usize)> = p
        .rings()
        .enumerate()
        .flat_map(|(ri, r)| (0..r.len()).map(move |i| (r[i], r[(i + 1) % r.len()], ri, i)))
        .collect();
    for (i, a) in segs.iter().enumerate() {
        for b in &segs[i + 1..] {
            let adjacent = a.2 == b.2 && {
                let n = p.rings().nth(a.2).map_or(0, Vec::len);
                b.3 == a.3 + 1 || (a.3 == 0 && b.3 == n - 1)
            };
            if adjacent {
                continue;
            }
            if segments_touch(a.0, a.1, b.0, b.1) {
                return false;
            }
        }
    }
    p.holes.iter().all(|h| {
        h.iter()
            .all(|q| crate::geometry::ring_contains(&p.outer, *q))
    })
}

fn segments_touch(a: DVec2, b: DVec2, c: DVec2, d: DVec2) -> bool {
    let orient = |p: DVec2, q: DVec2, r: DVec2| (q - p).perp_dot(r - p);
    let (d1, d2, d3, d4) = (
        orient(c, d, a),
        orient(c, d, b),
        orient(a, b, c),
        orient(a, b, d),
    );
    if ((d1 > 0.0 && d2 < 0.0) || (d1 < 0.0 && d2 > 0.0))
        && ((d3 > 0.0 && d4 < 0.0) || (d3 < 0.0 && d4 > 0.0))
    {
        return true;
    }
    let on = |p: DVec2, q: DVec2, r: DVec2, o: f64| {
        o.abs() <= 1e-12 * (1.0 + (q - p).length_squared())
            && r.x >= p.x.min(q.x)
            && r.x <= p.x.max(q.x)
            && r.y >= p.y.min(q.y)
            && r.y <= p.y.max(q.y)
    };
    on(c, d, a, d1) || on(c, d, b, d2) || on(a, b, c, d3) || on(a, b, d, d4)
}

/// Resolves self-intersections with a boolean union of the polygon with nothing.
fn repair(p: &Polygon) -> Vec<Polygon> {
    let to_ring =
        |r: &Vec<DVec2>| geo::LineString::from(r.iter().map(|q| (q.x, q.y)).collect::<Vec<_>>());
    let g = geo::Polygon::new(to_ring(&p.outer), p.holes.iter().map(to_ring).collect());
    let fixed = g.union(&geo::MultiPolygon::<f64>::new(Vec::new()));
    fixed
        .0
        .into_iter()
        .filter_map(|gp| {
            let ring = |ls: &geo::LineString<f64>| -> Vec<DVec2> {
                ls.0.iter().map(|c| DVec2::new(c.x, c.y)).collect()
            };
            let (outer, _) = merge_ring(&ring(gp.exterior()))?;
            let holes = gp
                .interiors()
                .iter()
                .filter_map(|h| merge_ring(&ring(h)).map(|(r, _)| r))
                .collect();
            Some(Polygon::new(outer, holes))
        })
        .collect()
}

/// Keeps the lots whose representative point lies in `bbox` = [min lon, min lat, max lon,
/// max lat] (degrees), so a region can be split across runs or machines: every footprint lies in
/// exactly one of several boxes that tile the region (min inclusive, max exclusive). The lots
/// left out are counted in one report note. A box that holds none of the lots (when there are
/// some) leaves none and is an `Err` naming the data's extent, and saying so when the box with
/// its longitudes and latitudes swapped would hold some: the caller decides whether an empty
/// run is an error (`--allow-empty`).
pub fn retain_in_bbox(site: &mut Site, bbox: [f64; 4], report: &mut Report) -> Result<(), String> {
    let inside = in_bbox;
    let before = site.lots.len();
    if before > 0 && !site.lots.iter().any(|l| inside(l.lonlat, bbox)) {
        let (mut lo, mut hi) = (
            (f64::INFINITY, f64::INFINITY),
            (f64::NEG_INFINITY, f64::NEG_INFINITY),
        );
        for l in &site.lots {
            lo = (lo.0.min(l.lonlat.0), lo.1.min(l.lonlat.1));
            hi = (hi.0.max(l.lonlat.0), hi.1.max(l.lonlat.1));
        }
        let swapped = [bbox[1], bbox[0], bbox[3], bbox[2]];
        let hint = if site.lots.iter().any(|l| inside(l.lonlat, swapped)) {
            format!(
                "; its corners look swapped: --bbox {},{},{},{} (longitude first) holds some",
                swapped[0], swapped[1], swapped[2], swapped[3]
            )
        } else {
            String::new()
        };
        let why = format!(
            "--bbox {},{},{},{} holds none of the {before} buildings, which lie in longitude {:.5} to {:.5}, latitude {:.5} to {:.5}{hint}",
            bbox[0], bbox[1], bbox[2], bbox[3], lo.0, hi.0, lo.1, hi.1
        );
        site.lots.clear();
        report.add(None, Outcome::Note, why.clone());
        return Err(why);
    }
    site.lots.retain(|l| inside(l.lonlat, bbox));
    let out = before - site.lots.len();
    if out > 0 {
        report.add(
            None,
            Outcome::Note,
            format!(
                "{out} of {before} building(s) outside --bbox {},{},{},{} were not generated",
                bbox[0], bbox[1], bbox[2], bbox[3]
            ),
        );
    }
    Ok(())
}

/// One square tile of a tiled run: the lots whose representative point lies in it.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Tile {
    /// Output-CRS coordinates of the tile's lower-left corner, in whole metres.
    pub corner: (i64, i64),
    /// The tile's lots: `site.lots[range]` after [`group_into_tiles`].
    pub range: std::ops::Range<usize>,
}

impl Tile {
    /// The file-name suffix of the tile, `{easting}_{northing}` of its lower-left corner, so
    /// that the same grid gives the same names night after night.
    pub fn suffix(&self) -> String {
        format!("{}_{}", self.corner.0, self.corner.1)
    }
}

/// The grid cell (easting, northing divided by `size`, rounded down) of the `size`-metre tile
/// holding the lot's representative point in `crs`: its tile's corner is the cell times `size`.
pub fn tile_cell(crs: Crs, lot: &Lot, size: u32) -> (i64, i64) {
    let size = f64::from(size.max(1));
    let (x, y) = crs.from_lonlat(lot.lonlat.0, lot.lonlat.1);
    // A non-finite point (cannot happen for a prepared lot) goes to the origin's tile rather
    // than being lost.
    let cell = |v: f64| {
        if v.is_finite() {
            (v / size).floor() as i64
        } else {
            0
        }
    };
    (cell(x), cell(y))
}

/// Groups the lots by the `size`-metre square of the output CRS grid holding their
/// representative point, and reorders `site.lots` so that each tile's lots are contiguous.
/// Tiles come in (easting, northing) order of their corners; inside a tile the lots keep their
/// input order, so the outputs stay deterministic. Every lot is in exactly one tile.
pub fn group_into_tiles(site: &mut Site, size: u32) -> Vec<Tile> {
    let key = |lot: &Lot| tile_cell(site.crs, lot, size);
    let size = i64::from(size.max(1));
    let mut keyed: Vec<((i64, i64), Lot)> = std::mem::take(&mut site.lots)
        .into_iter()
        .map(|l| (key(&l), l))
        .collect();
    // Stable: lots of one tile keep their input order.
    keyed.sort_by_key(|(k, _)| *k);
    let mut tiles: Vec<Tile> = Vec::new();
    for (i, (k, lot)) in keyed.into_iter().enumerate() {
        let corner = (k.0 * size, k.1 * size);
        match tiles.last_mut() {
            Some(t) if t.corner == corner => t.range.end = i + 1,
            _ => tiles.push(Tile {
                corner,
                range: i..i + 1,
            }),
        }
        site.lots.push(lot);
    }
    tiles
}

/// A site holding one lot given in local metres, placed at `lonlat` (the local origin), for
/// trying a ruleset without a city (`citygen rules derive`).
pub fn single_lot(
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
        drawn_outline: polygons.clone(),
        polygons,
        parts: Vec::new(),
        lonlat,
        front: None,
    };
    straighten_lot(&mut lot);
    Some(Site {
        crs,
        origin,
        origin_lonlat: crs.to_lonlat(origin.x, origin.y),
        lots: vec![lot],
    })
}

/// A street farther than this (metres) from every facing outline edge does not make a front:
/// beyond it a building stands in a park, a compound or behind other buildings, and the nearest
/// street says little about where its door is.
pub const FRONT_MAX_DISTANCE: f64 = 50.0;
/// Outline edges shorter than this (metres) are passed over for the front when the outline has
/// longer ones: a chamfered corner or a small recess would get the door otherwise, and a door
/// bay does not fit on it.
const FRONT_MIN_EDGE: f64 = 2.0;
/// Edges whose distance to the street is within this (metres) of the nearest one count as
/// equally near; the longest of them is the front (the main facade over a slightly closer
/// recess).
const FRONT_TIE: f64 = 1.0;
/// An edge faces a street when the direction from its midpoint to the street's nearest point is
/// within 60° of its outward normal.
const FRONT_COS_CONE: f64 = 0.5;

/// A street segment in the front index, local metres.
struct StreetSegment([f64; 2], [f64; 2]);

impl RTreeObject for StreetSegment {
    type Envelope = AABB<[f64; 2]>;
    fn envelope(&self) -> Self::Envelope {
        AABB::from_corners(self.0, self.1)
    }
}

/// Sets [`Lot::front`] of every lot from the street centre lines the reader gave (in the same
/// source coordinates as the footprints, `source_crs` as for [`prepare`]).
///
/// For each outer edge of the outline (edges shorter than 2 m are passed over when longer ones
/// exist) and each street segment near the lot (an rstar index over the segments), the edge
/// *faces* the segment when the segment's point nearest to the edge's midpoint lies within 60°
/// of the edge's outward normal; its distance is that of the midpoint (so the long side of a
/// building whose corner touches a street does not win over the end wall that faces it). The
/// nearest facing edge within [`FRONT_MAX_DISTANCE`] — the longest of those within 1 m of the
/// nearest — gives the front: its outward normal. Pure per lot, so it runs in parallel and the
/// result does not depend on the thread count. Street vertices that cannot be projected break
/// their line.
///
/// An edge whose outside is another building's (probes a quarter, half and three quarters
/// along it, [`FRONT_PARTY_PROBE`] out, all inside another lot's outline) is no front: a
/// party wall does not face the street beyond its neighbour.
///
/// Not handled: a street hidden behind another building still counts (no visibility test).
pub fn assign_fronts(site: &mut Site, streets: &Streets, source_crs: Option<Crs>) {
    if streets.is_empty() {
        return;
    }
    let crs = site.crs;
    let origin = site.origin;
    let local = |x: f64, y: f64| -> Option<DVec2> {
        let (lon, lat) = match source_crs {
            None | Some(Crs::Wgs84) => (x, y),
            Some(c) if c == crs => return finite(DVec2::new(x, y) - origin),
            Some(c) => c.to_lonlat(x, y),
        };
        let (px, py) = crs.from_lonlat(lon, lat);
        finite(DVec2::new(px, py) - origin)
    };
    let mut segments = Vec::new();
    for line in streets.lines() {
        let pts: Vec<Option<DVec2>> = line.iter().map(|&(x, y)| local(x, y)).collect();
        for w in pts.windows(2) {
            if let [Some(a), Some(b)] = *w {
                if a.distance(b) > MERGE_TOLERANCE {
                    segments.push(StreetSegment([a.x, a.y], [b.x, b.y]));
                }
            }
        }
    }
    let tree = RTree::bulk_load(segments);
    let outlines: Vec<OutlineEntry> = site
        .lots
        .iter()
        .enumerate()
        .flat_map(|(i, l)| {
            l.polygons.iter().enumerate().map(move |(j, p)| {
                let (lo, hi) = p.bounds();
                OutlineEntry::new(
                    rstar::primitives::Rectangle::from_corners(lo.to_array(), hi.to_array()),
                    (i, j),
                )
            })
        })
        .collect();
    let outlines = RTree::bulk_load(outlines);
    let lots = &site.lots;
    let fronts: Vec<Option<DVec2>> = lots
        .par_iter()
        .enumerate()
        .map(|(i, lot)| {
            let others = |p: DVec2| {
                outlines
                    .locate_all_at_point(p.to_array())
                    .any(|e| e.data.0 != i && lots[e.data.0].polygons[e.data.1].contains(p))
            };
            front_of(&lot.polygons, &tree, &others)
        })
        .collect();
    for (lot, f) in site.lots.iter_mut().zip(fronts) {
        lot.front = f;
    }
}

/// How far outside an edge [`assign_fronts`] looks for another building (metres).
pub const FRONT_PARTY_PROBE: f64 = 0.25;

/// A lot's outline polygon in the index of [`assign_fronts`]: (lot, polygon).
type OutlineEntry =
    rstar::primitives::GeomWithData<rstar::primitives::Rectangle<[f64; 2]>, (usize, usize)>;

fn finite(p: DVec2) -> Option<DVec2> {
    p.is_finite().then_some(p)
}

/// The point of segment `a`-`b` nearest to `p`.
fn nearest_on_segment(a: DVec2, b: DVec2, p: DVec2) -> DVec2 {
    let d = b - a;
    let l2 = d.length_squared();
    if l2 <= 0.0 {
        return a;
    }
    a + d * ((p - a).dot(d) / l2).clamp(0.0, 1.0)
}

/// Whether a representative point (lon, lat) is in `--bbox` b (west, south, east, north), as
/// [`retain_in_bbox`] decides.
pub fn in_bbox((lon, lat): (f64, f64), b: [f64; 4]) -> bool {
    lon >= b[0] && lon < b[2] && lat >= b[1] && lat < b[3]
}

/// Which lots `--bbox` keeps or whose outline comes within `margin` metres of one it keeps: the
/// lots a run in the box needs as neighbours.
pub fn near_bbox(lots: &[Lot], bbox: [f64; 4], margin: f64) -> Vec<bool> {
    let kept: Vec<bool> = lots.iter().map(|l| in_bbox(l.lonlat, bbox)).collect();
    near_selected(lots, &kept, margin)
}

/// Which lots are `selected` or have an outline within `margin` metres of a selected one's (the
/// lots a run writing the selected ones needs as neighbours: a `--bbox`, a shard's tiles).
/// `selected` has one flag per lot.
pub fn near_selected(lots: &[Lot], selected: &[bool], margin: f64) -> Vec<bool> {
    let bounds = |l: &Lot| {
        let (mut lo, mut hi) = (DVec2::splat(f64::INFINITY), DVec2::splat(f64::NEG_INFINITY));
        for p in l
            .polygons
            .iter()
            .chain(l.parts.iter().flat_map(|p| &p.polygons))
        {
            let (a, b) = p.bounds();
            lo = lo.min(a);
            hi = hi.max(b);
        }
        (lo.is_finite() && hi.is_finite())
            .then(|| AABB::from_corners((lo - margin).to_array(), (hi + margin).to_array()))
    };
    let is_selected = |i: usize| selected.get(i).copied().unwrap_or(false);
    let kept: Vec<rstar::primitives::Rectangle<[f64; 2]>> = lots
        .iter()
        .enumerate()
        .filter(|(i, _)| is_selected(*i))
        .filter_map(|(_, l)| bounds(l))
        .map(|b| rstar::primitives::Rectangle::from_corners(b.lower(), b.upper()))
        .collect();
    let tree = RTree::bulk_load(kept);
    lots.iter()
        .enumerate()
        .map(|(i, l)| {
            is_selected(i)
                || bounds(l)
                    .is_some_and(|b| tree.locate_in_envelope_intersecting(b).next().is_some())
        })
        .collect()
}

/// The front of one outline (see [`assign_fronts`]).
fn front_of(
    polygons: &[Polygon],
    tree: &RTree<StreetSegment>,
    in_another: &dyn Fn(DVec2) -> bool,
) -> Option<DVec2> {
    let (mut lo, mut hi) = (DVec2::splat(f64::INFINITY), DVec2::splat(f64::NEG_INFINITY));
    for p in polygons {
        let (a, b) = p.bounds();
        lo = lo.min(a);
        hi = hi.max(b);
    }
    if !(lo.is_finite() && hi.is_finite()) {
        return None;
    }
    let m = DVec2::splat(FRONT_MAX_DISTANCE);
    let near: Vec<(DVec2, DVec2)> = tree
        .locate_in_envelope_intersecting(AABB::from_corners(
            (lo - m).to_array(),
            (hi + m).to_array(),
        ))
        .map(|s| (DVec2::from(s.0), DVec2::from(s.1)))
        .collect();
    if near.is_empty() {
        return None;
    }
    // (distance, length, outward normal) of every edge that faces a street.
    let edges = || {
        polygons.iter().flat_map(|p| {
            let r = &p.outer;
            (0..r.len()).map(move |i| (r[i], r[(i + 1) % r.len()]))
        })
    };
    let long_exists = edges().any(|(a, b)| a.distance(b) >= FRONT_MIN_EDGE);
    let mut facing: Vec<(f64, f64, DVec2)> = Vec::new();
    for (a, b) in edges() {
        let len = a.distance(b);
        if len <= MERGE_TOLERANCE || (long_exists && len < FRONT_MIN_EDGE) {
            continue;
        }
        let d = (b - a) / len;
        // Outer rings are counter-clockwise: the outside is on the right.
        let normal = DVec2::new(d.y, -d.x);
        let mid = (a + b) * 0.5;
        let party = [0.25, 0.5, 0.75]
            .iter()
            .all(|t| in_another(a + (b - a) * *t + normal * FRONT_PARTY_PROBE));
        if party {
            continue;
        }
        let best = near
            .iter()
            .filter_map(|&(s0, s1)| {
                let v = nearest_on_segment(s0, s1, mid) - mid;
                let dist = v.length();
                let faces = dist <= MERGE_TOLERANCE || normal.dot(v) >= FRONT_COS_CONE * dist;
                (faces && dist <= FRONT_MAX_DISTANCE).then_some(dist)
            })
            .min_by(f64::total_cmp);
        if let Some(dist) = best {
            facing.push((dist, len, normal));
        }
    }
    let nearest = facing.iter().map(|f| f.0).min_by(f64::total_cmp)?;
    facing
        .iter()
        .filter(|f| f.0 <= nearest + FRONT_TIE)
        // The longest; on equal lengths the first in ring order (max_by keeps the last).
        .rev()
        .max_by(|x, y| x.1.total_cmp(&y.1))
        .map(|f| f.2)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sq(x0: f64, y0: f64, s: f64) -> Vec<DVec2> {
        vec![
            DVec2::new(x0, y0),
            DVec2::new(x0 + s, y0),
            DVec2::new(x0 + s, y0 + s),
            DVec2::new(x0, y0 + s),
        ]
    }

    #[test]
    fn bow_tie_is_repaired_into_two_triangles() {
        let bow = vec![
            DVec2::new(0.0, 0.0),
            DVec2::new(10.0, 10.0),
            DVec2::new(10.0, 0.0),
            DVec2::new(0.0, 10.0),
        ];
        let p = Polygon {
            outer: bow,
            holes: vec![],
        };
        assert!(!is_valid(&p));
        let mut report = Report::default();
        let out = clean_polygons(SourceId::Way(1), vec![p], &mut report).unwrap();
        assert_eq!(out.len(), 2);
        let area: f64 = out.iter().map(Polygon::area).sum();
        assert!((area - 50.0).abs() < 1e-6, "{area}");
        assert_eq!(report.entries[0].outcome, Outcome::Repaired);
    }

    #[test]
    fn duplicates_and_spikes_are_removed() {
        let mut r = sq(0.0, 0.0, 10.0);
        r.insert(1, DVec2::new(0.0, 0.0));
        r.insert(3, DVec2::new(15.0, 0.0)); // spike out of (10,0) and back
        r.insert(4, DVec2::new(10.0, 0.0));
        let (c, spikes) = merge_ring(&r).unwrap();
        assert_eq!(spikes, 1);
        assert_eq!(c.len(), 4, "{c:?}");
    }

    #[test]
    fn sliver_is_skipped_with_a_reason() {
        let sliver = vec![
            DVec2::new(0.0, 0.0),
            DVec2::new(10.0, 0.0),
            DVec2::new(10.0, 0.01),
        ];
        let mut report = Report::default();
        let out = clean_polygons(
            SourceId::Way(2),
            vec![Polygon::new(sliver, vec![])],
            &mut report,
        );
        assert!(out.is_none());
        assert_eq!(report.entries[0].outcome, Outcome::Skipped);
        assert!(report.entries[0].reason.contains("smaller than"));
    }

    #[test]
    fn courtyard_stays_a_hole() {
        let p = Polygon::new(sq(0.0, 0.0, 20.0), vec![sq(5.0, 5.0, 10.0)]);
        let mut report = Report::default();
        let out = clean_polygons(SourceId::Relation(3), vec![p], &mut report).unwrap();
        assert_eq!(out[0].holes.len(), 1);
        assert!((out[0].area() - 300.0).abs() < 1e-9);
        assert!(report.entries.is_empty());
    }

    /// The front of a 20 m × 10 m block at the origin with one street from `a` to `b`.
    fn front_with_street(a: DVec2, b: DVec2) -> Option<DVec2> {
        let tree = RTree::bulk_load(vec![StreetSegment(a.to_array(), b.to_array())]);
        let block = Polygon::new(
            vec![
                DVec2::new(0.0, 0.0),
                DVec2::new(20.0, 0.0),
                DVec2::new(20.0, 10.0),
                DVec2::new(0.0, 10.0),
            ],
            vec![],
        );
        front_of(&[block], &tree, &|_| false)
    }

    #[test]
    fn the_front_is_the_normal_of_the_edge_that_faces_the_nearest_street() {
        let v = DVec2::new;
        // Along the north side.
        assert_eq!(
            front_with_street(v(-50.0, 15.0), v(70.0, 15.0)),
            Some(DVec2::Y)
        );
        // A north-south street past the east end: the end wall faces it, not the long south
        // side, although both touch the corner nearest to the street.
        assert_eq!(
            front_with_street(v(25.0, -40.0), v(25.0, 50.0)),
            Some(DVec2::X)
        );
        // A street along the wall itself (a mapped sidewalk) counts.
        assert_eq!(
            front_with_street(v(-5.0, 0.0), v(25.0, 0.0)),
            Some(-DVec2::Y)
        );
        // Too far.
        assert_eq!(front_with_street(v(-50.0, 70.0), v(70.0, 70.0)), None);
    }

    /// A wall against another building does not face the street beyond it: the block's north
    /// side touches a neighbour 0.2 m away, so its front is the east end, which faces the street
    /// 30 m off, not the north side 20 m from the street behind the neighbour.
    #[test]
    fn a_wall_against_a_neighbour_is_no_front() {
        let v = DVec2::new;
        let tree = RTree::bulk_load(vec![StreetSegment([-10.0, 30.0], [50.0, 30.0])]);
        let block = Polygon::new(
            vec![v(0.0, 0.0), v(20.0, 0.0), v(20.0, 10.0), v(0.0, 10.0)],
            vec![],
        );
        let neighbour = Polygon::new(
            vec![v(-5.0, 10.2), v(25.0, 10.2), v(25.0, 20.0), v(-5.0, 20.0)],
            vec![],
        );
        let free = front_of(std::slice::from_ref(&block), &tree, &|_| false);
        assert_eq!(free, Some(DVec2::Y));
        let against = |p: DVec2| neighbour.contains(p);
        assert_eq!(
            front_of(std::slice::from_ref(&block), &tree, &against),
            None
        );
        let both: Vec<StreetSegment> = vec![
            StreetSegment([-10.0, 30.0], [50.0, 30.0]),
            StreetSegment([50.0, -20.0], [50.0, 40.0]),
        ];
        let both = RTree::bulk_load(both);
        assert_eq!(front_of(&[block], &both, &against), Some(DVec2::X));
    }

    #[test]
    fn fronts_need_streets_and_do_not_move_the_lots() {
        let mut report = Report::default();
        let block = Polygon::new(sq(0.0, 0.0, 10.0), vec![]);
        let mut site = single_lot(block, (7.42, 43.73), None, &mut report).unwrap();
        let before = site.lots[0].polygons.clone();
        let crs = site.crs;
        assign_fronts(&mut site, &Streets::default(), Some(crs));
        assert_eq!(site.lots[0].front, None);
        // A west street in lon/lat (source CRS None = WGS84), projected like the footprints.
        let (x, y) = (site.origin.x - 12.0, site.origin.y);
        let a = crs.to_lonlat(x, y - 50.0);
        let b = crs.to_lonlat(x, y + 50.0);
        let mut streets = Streets::default();
        streets.push(&[a, b]);
        assign_fronts(&mut site, &streets, None);
        let f = site.lots[0].front.unwrap();
        assert!(f.dot(-DVec2::X) > 0.999, "{f}");
        assert_eq!(site.lots[0].polygons, before);
    }

    #[test]
    fn interior_point_of_a_u_shape_is_inside() {
        let u = vec![
            DVec2::new(0.0, 0.0),
            DVec2::new(30.0, 0.0),
            DVec2::new(30.0, 20.0),
            DVec2::new(20.0, 20.0),
            DVec2::new(20.0, 5.0),
            DVec2::new(10.0, 5.0),
            DVec2::new(10.0, 20.0),
            DVec2::new(0.0, 20.0),
        ];
        let p = Polygon::new(u, vec![]);
        assert!(p.contains(interior_point(&p)));
    }

    #[test]
    fn tiles_hold_every_lot_once_in_input_order_and_name_their_corner() {
        let crs = Crs::utm_for(7.42, 43.73);
        let lot = |i: i64, x: f64, y: f64| {
            let (lon, lat) = crs.to_lonlat(x, y);
            Lot {
                id: SourceId::Way(i),
                tags: Default::default(),
                polygons: vec![Polygon::new(sq(0.0, 0.0, 10.0), vec![])],
                parts: Vec::new(),
                drawn_outline: vec![Polygon::new(sq(0.0, 0.0, 10.0), vec![])],
                lonlat: (lon, lat),
                front: None,
            }
        };
        // Input order mixes the tiles; 5 and 2 share a tile with 1, in that input order.
        let mut site = Site {
            crs,
            origin: DVec2::new(370_000.0, 4_842_000.0),
            origin_lonlat: crs.to_lonlat(370_000.0, 4_842_000.0),
            lots: vec![
                lot(1, 370_010.0, 4_842_010.0),
                lot(3, 370_260.0, 4_842_010.0),
                lot(4, 370_010.0, 4_842_260.0),
                lot(2, 370_240.0, 4_842_240.0),
                lot(5, 370_100.0, 4_842_100.0),
            ],
        };
        let tiles = group_into_tiles(&mut site, 250);
        let ids: Vec<SourceId> = site.lots.iter().map(|l| l.id).collect();
        let way = SourceId::Way;
        assert_eq!(ids, vec![way(1), way(2), way(5), way(4), way(3)]);
        let names: Vec<(String, std::ops::Range<usize>)> = tiles
            .iter()
            .map(|t| (t.suffix(), t.range.clone()))
            .collect();
        assert_eq!(
            names,
            vec![
                ("370000_4842000".to_string(), 0..3),
                ("370000_4842250".to_string(), 3..4),
                ("370250_4842000".to_string(), 4..5),
            ]
        );
    }
}

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
