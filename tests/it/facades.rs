//! Facades a planner would sign (issue 20), through the whole generator on both samples:
//! no window, door or balcony opens into another footprint below its top; one main entrance per
//! building standing on the ground (on a part that is no structure, issue 45), on its street
//! side (within 25°), at the ground, of a door's size (0.8-2.5 by 2.0-2.6 m, balcony doors
//! too); no door in mid-air; round and many-edged towers (no structure) have windows on every
//! storey; no window, door or interior door narrower than the knowledge base's minimum
//! (issue 45).
//!
//! The neighbours are computed here from the buildings themselves (each lot near the district
//! derived at LOD2 through the public `generate`, its parts' footprints and height ranges), and
//! the openings are probed by points outside them, not by the generator's own spans.

use crate::common::*;

use citygen::derive::{Generator, Rules};
use citygen::geometry::Polygon;
use citygen::input::{osm::read_osm, shp::read_shp, shp::ShpOptions};
use citygen::model::{Building, Lod, OpeningKind, Part, SourceId, Wall};
use citygen::prepare::{assign_fronts, near_bbox, prepare, retain_in_bbox, Lot};
use glam::DVec2;

/// The shipped knowledge base's narrowest window or door (`minopeningwidth` unset: 0.4 m).
const MIN_OPENING_WIDTH: f64 = 0.4;

/// CI's LOD3 districts.
const MONACO_DISTRICT: [f64; 4] = [7.4180, 43.7290, 7.4240, 43.7330];
const CLIFTON_DISTRICT: [f64; 4] = [-1.1950, 52.9020, -1.1900, 52.9050];
/// CI's LOD4 corner of Monaco-Ville.
const MONACO_LOD4: [f64; 4] = [7.4225, 43.7300, 7.4240, 43.7312];

/// A footprint of a derived part with its height range.
struct Solid {
    owner: SourceId,
    key: String,
    footprint: Polygon,
    z0: f64,
    z1: f64,
}

/// The buildings of the area (with their lots) and every part around them.
struct Area {
    buildings: Vec<(Lot, Building)>,
    solids: Vec<Solid>,
    /// The solids whose bounds meet each [`CELL`]-metre grid cell.
    grid: std::collections::HashMap<(i64, i64), Vec<usize>>,
}

/// Cell size of [`Area::grid`] (metres).
const CELL: f64 = 20.0;

fn cell(p: DVec2) -> (i64, i64) {
    ((p.x / CELL).floor() as i64, (p.y / CELL).floor() as i64)
}

fn generator(lod: Lod) -> Generator {
    let (kb, _) = citygen::kb::KnowledgeBase::load(&root().join(KB)).unwrap();
    let caps = citygen::grammar::Caps {
        facades: lod >= Lod::Lod3,
        ..Default::default()
    };
    Generator::new(kb, Rules::Kb, lod, 0, caps)
}

fn area(osm: bool, bbox: Option<[f64; 4]>, lod: Lod) -> Area {
    let mut report = citygen::report::Report::default();
    let read = if osm {
        read_osm(&root().join(MONACO), &mut report).unwrap()
    } else {
        read_shp(&root().join(CLIFTON), &ShpOptions::default(), &mut report).unwrap()
    };
    let mut site = prepare(read.footprints, read.source_crs, None, &mut report);
    assign_fronts(&mut site, &read.streets, read.source_crs);
    let keep = match bbox {
        Some(b) => near_bbox(&site.lots, b, 1.0),
        None => vec![true; site.lots.len()],
    };
    // The neighbours, as this test sees them.
    let lod2 = generator(Lod::Lod2);
    let mut solids = Vec::new();
    for (lot, _) in site.lots.iter().zip(&keep).filter(|(_, k)| **k) {
        if let Ok((b, _)) = lod2.generate(lot) {
            for p in &b.parts {
                solids.push(Solid {
                    owner: b.id,
                    key: p.key.clone(),
                    footprint: p.footprint.clone(),
                    z0: p.base_z,
                    z1: p.top_z,
                });
            }
        }
    }
    let mut gen = generator(lod);
    gen.surroundings = gen.neighbours_of(&site.lots, |i| keep[i]);
    if let Some(b) = bbox {
        retain_in_bbox(&mut site, b, &mut report).unwrap();
    }
    let buildings = site
        .lots
        .into_iter()
        .filter_map(|lot| gen.generate(&lot).ok().map(|(b, _)| (lot, b)))
        .collect();
    let mut grid: std::collections::HashMap<(i64, i64), Vec<usize>> = Default::default();
    for (i, s) in solids.iter().enumerate() {
        let (lo, hi) = s.footprint.bounds();
        let ((x0, y0), (x1, y1)) = (cell(lo), cell(hi));
        for x in x0..=x1 {
            for y in y0..=y1 {
                grid.entry((x, y)).or_default().push(i);
            }
        }
    }
    Area {
        buildings,
        solids,
        grid,
    }
}

/// The unit vector along a wall and its outward normal.
fn frame(w: &Wall) -> (DVec2, DVec2) {
    let d = (w.end - w.start).normalize();
    (d, DVec2::new(d.y, -d.x))
}

/// Whether a door stands on one of its wall's balconies.
fn on_balcony(w: &Wall, u0: f64, u1: f64) -> bool {
    w.balconies.iter().any(|b| b.u0 < u1 && u0 < b.u1)
}

/// What of `u0..u1` by `z0..z1` on wall `w` of part `part` of building `b` lies in front of
/// another footprint below its top: probes every 10 cm across, 5, 25 and 45 cm out.
fn into_neighbour(
    area: &Area,
    b: &Building,
    part: &Part,
    w: &Wall,
    (u0, u1, z0, z1): (f64, f64, f64, f64),
) -> Option<String> {
    let (d, n) = frame(w);
    let steps = ((u1 - u0) / 0.1).ceil().max(1.0) as usize;
    for i in 0..=steps {
        let u = u0 + (u1 - u0) * (0.02 + 0.96 * i as f64 / steps as f64);
        for t in [0.05, 0.25, 0.45] {
            let p = w.start + d * u + n * t;
            let near = area.grid.get(&cell(p)).map_or(&[][..], Vec::as_slice);
            for s in near.iter().map(|&i| &area.solids[i]) {
                let own = s.owner == b.id && s.key == part.key;
                if !own && s.z0 < z1 && z0 < s.z1 && s.footprint.contains(p) {
                    return Some(format!(
                        "{} {}: {u0:.2}..{u1:.2} x {z0:.2}..{z1:.2} opens into {} {} ({:.1}..{:.1} m)",
                        b.id, part.key, s.owner, s.key, s.z0, s.z1
                    ));
                }
            }
        }
    }
    None
}

/// Every check of the module docs on one area; returns the figures printed.
fn check(name: &str, area: &Area) -> String {
    let mut faults: Vec<String> = Vec::new();
    let (mut windows, mut doors, mut balconies, mut entrances, mut fronted) = (0, 0, 0, 0, 0);
    let (mut square_on, mut towers) = (0, 0);
    for (lot, b) in &area.buildings {
        let mut main_doors = Vec::new();
        for part in &b.parts {
            let grounded = part.base_z <= 0.1;
            // No interior door narrower than the knowledge base's minimum (issue 45, LOD4).
            for s in &part.interior {
                for d in &s.doors {
                    if d.u1 - d.u0 < MIN_OPENING_WIDTH - 1e-9 {
                        faults.push(format!(
                            "{} {}: an interior door {:.2} m wide",
                            b.id,
                            part.key,
                            d.u1 - d.u0
                        ));
                    }
                }
            }
            for w in &part.walls {
                for o in &w.openings {
                    // No slit (issue 45): every window and door at least the minimum wide.
                    if o.u1 - o.u0 < MIN_OPENING_WIDTH - 1e-9 {
                        faults.push(format!(
                            "{} {}: a {:?} {:.2} m wide",
                            b.id,
                            part.key,
                            o.kind,
                            o.u1 - o.u0
                        ));
                    }
                    let r = (o.u0, o.u1, o.z0, o.z1);
                    if let Some(f) = into_neighbour(area, b, part, w, r) {
                        faults.push(f);
                    }
                    match o.kind {
                        OpeningKind::Window => windows += 1,
                        OpeningKind::Door => {
                            doors += 1;
                            let (wd, ht) = (o.u1 - o.u0, o.z1 - o.z0);
                            if !(0.8 - 1e-9..=2.5 + 1e-9).contains(&wd)
                                || !(2.0 - 1e-9..=2.6 + 1e-9).contains(&ht)
                            {
                                faults.push(format!(
                                    "{} {}: a door of {wd:.2} x {ht:.2} m",
                                    b.id, part.key
                                ));
                            }
                            if !on_balcony(w, o.u0, o.u1) {
                                main_doors.push((grounded, w.storey, w.clone()));
                            }
                        }
                    }
                }
                for bc in &w.balconies {
                    balconies += 1;
                    let r = (bc.u0, bc.u1, bc.z, bc.z + 1.0);
                    if let Some(f) = into_neighbour(area, b, part, w, r) {
                        faults.push(format!("balcony: {f}"));
                    }
                }
            }
        }
        for (grounded, storey, _) in &main_doors {
            if !grounded || *storey != 0 {
                faults.push(format!(
                    "{}: a door off the ground (storey {storey}, part on the ground: {grounded})",
                    b.id
                ));
            }
        }
        // A structure takes no entrance (issue 45): a building of structures only has none,
        // but for a tower's base door.
        let on_ground = b.parts.iter().any(|p| {
            p.base_z <= 0.1 && matches!(p.structure, None | Some(citygen::model::Structure::Tower))
        });
        if let (true, Some(front)) = (on_ground, lot.front) {
            fronted += 1;
            if main_doors.len() != 1 {
                faults.push(format!("{}: {} main entrances", b.id, main_doors.len()));
            } else {
                entrances += 1;
                let (_, n) = frame(&main_doors[0].2);
                // The street-facing wall: within 25° of the outline edge facing the street.
                if n.dot(front) < 25f64.to_radians().cos() {
                    faults.push(format!(
                        "{}: the entrance faces {:.0}° away from the street",
                        b.id,
                        n.dot(front).clamp(-1.0, 1.0).acos().to_degrees()
                    ));
                } else if n.dot(front) > 0.99 {
                    square_on += 1;
                }
            }
        } else if on_ground && main_doors.len() > 1 {
            faults.push(format!("{}: {} main entrances", b.id, main_doors.len()));
        }
        // Round and many-edged towers: windows on every storey.
        for part in &b.parts {
            // A tower has storeys a window fits in (not a ring of canopy 0.5 m deep).
            let storey = (part.eave_z - part.base_z) / part.levels.len().max(1) as f64;
            // A structure's tower keeps its top storey's windows only (issue 45).
            if !many_edged(&part.footprint.outer) || storey < 2.0 || part.structure.is_some() {
                continue;
            }
            towers += 1;
            for s in 0..part.levels.len() {
                let lit = part
                    .walls
                    .iter()
                    .filter(|w| w.storey == s)
                    .any(|w| w.openings.iter().any(|o| o.kind == OpeningKind::Window));
                if !lit {
                    faults.push(format!(
                        "{} {}: a tower of {} edges has no window on storey {s}",
                        b.id,
                        part.key,
                        part.footprint.outer.len()
                    ));
                }
            }
        }
    }
    let figures = format!(
        "{name}: {} buildings, {windows} windows, {doors} doors, {balconies} balconies; \
         {entrances}/{fronted} with a street have one entrance ({square_on} square on it); \
         {towers} round or many-edged parts",
        area.buildings.len()
    );
    assert!(
        faults.is_empty(),
        "{figures}\n{} faults:\n{}",
        faults.len(),
        faults[..faults.len().min(40)].join("\n")
    );
    figures
}

/// A footprint of at least 10 edges whose corners all lie within 15 % of one radius of their
/// centre, or of at least 16 edges each shorter than 3 m: a round or many-edged tower.
fn many_edged(r: &[DVec2]) -> bool {
    let n = r.len();
    if n < 10 {
        return false;
    }
    let c = r.iter().copied().sum::<DVec2>() / n as f64;
    let radius = r.iter().map(|p| p.distance(c)).sum::<f64>() / n as f64;
    let round = r
        .iter()
        .all(|p| (p.distance(c) - radius).abs() <= 0.15 * radius);
    let short = n >= 16 && (0..n).all(|i| r[i].distance(r[(i + 1) % n]) < 3.0);
    (round && radius > 3.0) || short
}

#[test]
fn lod3_districts_have_blank_party_walls_one_entrance_and_lit_towers() {
    let a = check("Monaco LOD3", &area(true, Some(MONACO_DISTRICT), Lod::Lod3));
    let b = check(
        "Clifton LOD3",
        &area(false, Some(CLIFTON_DISTRICT), Lod::Lod3),
    );
    eprintln!("{a}\n{b}");
}

#[test]
fn lod4_corners_have_blank_party_walls_and_one_entrance() {
    let a = check("Monaco LOD4", &area(true, Some(MONACO_LOD4), Lod::Lod4));
    eprintln!("{a}");
}

/// Both whole samples at LOD3 (CI runs it in release: `--ignored`).
#[test]
#[ignore = "whole samples: run in release by .ci/run"]
fn lod3_whole_samples_have_blank_party_walls_one_entrance_and_lit_towers() {
    let a = check("Monaco LOD3", &area(true, None, Lod::Lod3));
    let b = check("Clifton LOD3", &area(false, None, Lod::Lod3));
    eprintln!("{a}\n{b}");
}
