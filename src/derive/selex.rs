//! SELEX facades in a city run (issue 23): an appearance that names a SELEX program
//! (`<selex file=...>`) has the facades of its buildings laid out by it at LOD3, in place of the
//! windows, doors and balconies its grammar rules found.
//!
//! Each mass's footprint edges become the program's `facade` faces
//! ([`crate::selex::eval::facade_specs`]), each with its side towards the street and the mass's
//! storeys (the levels the rules made), so one program serves every footprint; a program
//! written for the seed's box (`createShape`) finds them as `building_front`, ... too. The elements it
//! places become openings and balconies on their edge, cut at the storeys (a wall is one storey
//! high at LOD3: an element two storeys high becomes one opening on each). Labels decide what an
//! element is: `door…` and `entrance…` are doors, `balcony…` and `ledge…` balconies, `wall` and
//! covers nothing, anything else a window; framed elements (`addFacadeWithFrame`) are framed
//! windows; a rounded element keeps its rounding (its top corners on its top storey's piece, its
//! bottom corners on its bottom one's), a framed one its frame's size. Elements on bays
//! (`addVolume`) stand on no footprint edge and are counted as off the envelope. A door stands
//! on the floor of the storey its foot is in (moved down, its height kept: `addShape` centres
//! an element in its cell). The doors a program puts on the ground storey are the building's
//! entrances (`derive::facade::Facades::programmed`).

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use glam::DVec2;

use crate::derive::facade::{Facades, Level};
use crate::derive::selex_place::{self, element_on_edge, Placed};
use crate::geometry::Polygon;
use crate::kb::{KbError, KnowledgeBase};
use crate::selex::ast::Program;
use crate::selex::eval::{facade_specs, run_on_facades, Derivation, RunError, ShapeKind};
use crate::selex::parser::SelexError;

/// Why a SELEX program of the knowledge base was not loaded (`load_all`, [`load`]) or not
/// applied to a mass ([`apply`]).
#[derive(Debug, thiserror::Error)]
pub enum ProgramError {
    /// The KB's `<selex file>` is refused (e.g. outside its folder).
    #[error("{0}")]
    Path(#[from] KbError),
    /// The file could not be read.
    #[error("{file}: {source}")]
    Read {
        /// The file, as messages name it.
        file: String,
        /// The system's error.
        source: std::io::Error,
    },
    /// The program does not parse.
    #[error("{0}")]
    Parse(#[from] SelexError),
    /// The mass's facades are not one per footprint edge.
    #[error("the footprint's edges are not the facades'")]
    EdgesNotFacades,
    /// The program stopped with an error on the facades: the message is its first line.
    #[error("{}", .0.to_string().lines().next().unwrap_or_default())]
    Run(#[source] RunError),
}

/// A parsed SELEX program with its text and file name (for messages).
#[derive(Debug)]
pub struct SelexProgram {
    /// The file, as messages name it.
    pub file: String,
    /// Its text.
    pub source: String,
    /// The parsed program.
    pub program: Program,
}

/// Reads and parses every SELEX program the knowledge base's appearances name, once each.
/// An unreadable file, a path outside the KB's folder or a program that does not parse is an
/// error naming the file (and the place), so a run stops before any work.
pub(crate) fn load_all(
    kb: &KnowledgeBase,
) -> Result<HashMap<PathBuf, Arc<SelexProgram>>, ProgramError> {
    let mut out: HashMap<PathBuf, Arc<SelexProgram>> = HashMap::new();
    for (z, zone) in kb.zones().iter().enumerate() {
        for a in 0..zone.appearances.len() {
            let Some(path) = kb.selex_file(z, a)? else {
                continue;
            };
            if out.contains_key(&path) {
                continue;
            }
            // Read only inside the KB's folder, as it is when opened.
            let file = path.display().to_string();
            let program = match kb.read_appearance_file(&path) {
                Ok(source) => from_source(file, source)?,
                Err(source) => return Err(ProgramError::Read { file, source }),
            };
            out.insert(path, Arc::new(program));
        }
    }
    Ok(out)
}

/// Reads and parses one program.
pub fn load(path: &Path) -> Result<SelexProgram, ProgramError> {
    let file = path.display().to_string();
    let source = match crate::grammar::read_source(path) {
        Ok(s) => s,
        Err(source) => return Err(ProgramError::Read { file, source }),
    };
    from_source(file, source)
}

/// A program parsed from its text (`file` as messages name it).
fn from_source(file: String, source: String) -> Result<SelexProgram, ProgramError> {
    let program = crate::selex::parser::parse(&source, &file)?;
    Ok(SelexProgram {
        file,
        source,
        program,
    })
}

/// What [`apply`] made besides the facades it laid out.
#[derive(Debug, Default)]
pub struct Applied {
    /// The program's warnings, `file:line:col: message`.
    pub warnings: Vec<String>,
    /// The bays (`addVolume`) standing against the mass's walls, each to become a part of the
    /// building: a box from the wall out, as high as the cells it was pushed out of, with its
    /// own facades (the elements the program put on its faces).
    pub bays: Vec<Bay>,
}

/// A bay a program pushed out of a wall (`addVolume`), as a mass of its own.
#[derive(Debug)]
pub struct Bay {
    /// Its label in the program.
    pub label: String,
    /// Its footprint: front, right side, back (on the wall), left side; counter-clockwise.
    pub footprint: Polygon,
    /// Its bottom, metres.
    pub z0: f64,
    /// Its top, metres.
    pub z1: f64,
    /// Its openings and balconies per footprint edge, its levels those of the mass it stands
    /// against.
    pub facades: Facades,
    /// `roundShape` asked for a rounding this cannot draw (not the front, not about a vertical
    /// axis, or no valid arc): drawn square. A rounded front is an arc of chords in the
    /// footprint, each element on a flat facet of it.
    pub rounded: bool,
}

/// The edges of a footprint, outer ring then holes, in ring order.
fn edges_of(footprint: &Polygon) -> Vec<(DVec2, DVec2)> {
    footprint
        .rings()
        .flat_map(|r| (0..r.len()).map(move |i| (r[i], r[(i + 1) % r.len()])))
        .collect()
}

/// Lays out `facades` (found by the rules on a mass of `footprint` standing on `base_z`) with
/// `program`: its openings and balconies replace the rules'. Returns the program's warnings and
/// the bays it pushed out; an error of the program leaves `facades` as the rules made them and
/// is returned as the note.
pub fn apply(
    program: &SelexProgram,
    footprint: &Polygon,
    base_z: f64,
    front: Option<DVec2>,
    facades: &mut Facades,
) -> Result<Applied, ProgramError> {
    let storeys: Vec<f64> = facades
        .levels
        .iter()
        .map(|l| l.z1 - l.z0)
        .filter(|h| h.is_finite() && *h > 0.0)
        .collect();
    let base = facades.levels.first().map_or(base_z, |l| l.z0);
    let specs = facade_specs(footprint, base, &storeys, front);
    let edges = edges_of(footprint);
    if edges.len() != facades.openings.len() {
        return Err(ProgramError::EdgesNotFacades);
    }
    let d = run_on_facades(&program.program, &program.source, &program.file, &specs)
        .map_err(ProgramError::Run)?;
    let mut out = Applied {
        warnings: d
            .warnings
            .iter()
            .map(|n| format!("{}:{}:{}: {}", program.file, n.line, n.col, n.message))
            .collect(),
        bays: Vec::new(),
    };
    // Every face standing on a footprint edge: the `facade` faces, and their copies a
    // `createShape` made (`building_front`, ...). A bay's faces stand on the bay's.
    let mut laid = Facades {
        levels: facades.levels.clone(),
        openings: vec![Vec::new(); edges.len()],
        balconies: vec![Vec::new(); edges.len()],
        ..Facades::default()
    };
    let mut bays: Vec<usize> = Vec::new();
    for (face, shape) in d.shapes.iter().enumerate() {
        if place(&d, face, &edges, &mut laid) {
            bays.extend(
                shape
                    .children
                    .iter()
                    .copied()
                    .filter(|&c| matches!(d.shapes[c].kind, ShapeKind::Volume { .. })),
            );
        }
    }
    for v in bays {
        match bay(&d, v, &facades.levels) {
            Some(b) => out.bays.push(b),
            None => laid.off_envelope += 1,
        }
    }
    facades.openings = laid.openings;
    facades.balconies = laid.balconies;
    facades.off_envelope += laid.off_envelope;
    facades.programmed = true;
    Ok(out)
}

/// The bay volume `v` of `d` (standing on a face of the mass) as a [`Bay`], with the elements
/// on its faces; `None` when it is too small to build (under 0.3 m deep, wide or high).
fn bay(d: &Derivation, v: usize, levels: &[Level]) -> Option<Bay> {
    let shape = &d.shapes[v];
    let ShapeKind::Volume { rounding, .. } = &shape.kind else {
        return None;
    };
    let frames: Vec<_> = shape.children.iter().filter_map(|&c| d.frame(c)).collect();
    let (front, left) = (frames.first()?, frames.get(1)?);
    let (w, depth, h) = (front.width, left.width, front.height);
    if !(w >= 0.3 && depth >= 0.3 && h >= 0.3) {
        return None;
    }
    let p1 = front.origin.truncate();
    let p0 = left.origin.truncate();
    let u = front.u.truncate();
    let mut footprint = Polygon::new(vec![p1, p1 + u * w, p0 + u * w, p0], vec![]);
    // A front rounded about a vertical axis: an arc of chords (as `selex derive` draws it), each
    // element on a flat facet of its own.
    let front_id = shape
        .children
        .iter()
        .copied()
        .find(|&c| d.frame(c).is_some());
    let mut arc = None;
    if let (Some(r), Some(front_id)) = (rounding, front_id) {
        let vertical = r.axis.as_deref().is_none_or(|a| a == "vertical");
        let spans = selex_place::element_spans(d, front_id);
        let outside = r.direction != "inside";
        let drawn = (r.face == "front" && vertical)
            .then(|| selex_place::rounded_front(w, depth, r.degree, r.segments, outside, &spans))
            .flatten();
        if let Some((local, facets, _)) = drawn {
            let n = front.normal().truncate();
            let world = |p: DVec2| p0 + u * p.x + n * p.y;
            let round = Polygon::new(local.iter().map(|&p| world(p)).collect(), vec![]);
            let valid = crate::geometry::is_simple(&round.outer)
                && edges_of(&round)
                    .iter()
                    .all(|(a, b)| a.distance(*b) >= selex_place::MIN_EDGE - 1e-6);
            if valid {
                footprint = round;
                let facets: Vec<selex_place::Facet> = facets
                    .into_iter()
                    .map(|f| selex_place::Facet {
                        a: world(f.a),
                        b: world(f.b),
                        ..f
                    })
                    .collect();
                arc = Some((front_id, facets));
            }
        }
    }
    let (z0, z1) = (front.origin.z, front.origin.z + h);
    // The mass's storeys, cut to the bay.
    let levels: Vec<Level> = levels
        .iter()
        .map(|l| Level {
            z0: l.z0.max(z0),
            z1: l.z1.min(z1),
        })
        .filter(|l| l.z1 - l.z0 > 1e-6)
        .collect();
    let levels = if levels.is_empty() {
        vec![Level { z0, z1 }]
    } else {
        levels
    };
    let edges = edges_of(&footprint);
    let mut facades = Facades {
        levels,
        openings: vec![Vec::new(); edges.len()],
        balconies: vec![Vec::new(); edges.len()],
        programmed: true,
        ..Facades::default()
    };
    let mut unplaced = Vec::new();
    for &c in &shape.children {
        if arc.as_ref().is_some_and(|a| a.0 == c) {
            continue;
        }
        if !place(d, c, &edges, &mut facades) {
            // A side the rounding shortened: its elements stand on no wall.
            unplaced.extend(selex_place::element_spans(d, c));
        }
    }
    if let Some((f, facets)) = &arc {
        let mut lost = Vec::new();
        for (k, label, e, u, z) in selex_place::on_facets(d, *f, facets, &edges, z0, &mut lost) {
            match element_on_edge(label, e, u, z, &facades.levels) {
                Placed::Nothing => {}
                Placed::Balcony(b) => facades.balconies[k].push(b),
                Placed::Openings(o) => facades.openings[k].extend(o),
            }
        }
        facades.off_envelope += lost.len();
    }
    facades.off_envelope += unplaced.len();
    for v in &mut facades.openings {
        v.sort_by(|a, b| a.z0.total_cmp(&b.z0).then(a.u0.total_cmp(&b.u0)));
    }
    Some(Bay {
        label: shape.label.clone(),
        footprint,
        z0,
        z1,
        facades,
        rounded: rounding.is_some() && arc.is_none(),
    })
}

/// Places the elements of `face` (if it is a face standing on one of `edges` at the bottom of
/// `facades`' levels) as openings and balconies of that edge; returns whether it stood on one.
fn place(d: &Derivation, face: usize, edges: &[(DVec2, DVec2)], facades: &mut Facades) -> bool {
    let ShapeKind::Face { frame, .. } = &d.shapes[face].kind else {
        return false;
    };
    let start = frame.origin.truncate();
    let end = start + frame.u.truncate() * frame.width;
    let near = |p: DVec2, q: DVec2| p.distance(q) < 1e-6;
    let Some(k) = edges
        .iter()
        .position(|&(a, b)| near(a, start) && near(b, end))
    else {
        return false;
    };
    let base = facades.levels.first().map_or(frame.origin.z, |l| l.z0);
    if (frame.origin.z - base).abs() > 1e-6 {
        return false;
    }
    for &c in &d.shapes[face].children {
        let ShapeKind::Element(e) = &d.shapes[c].kind else {
            continue;
        };
        let (u0, u1) = (e.rect.x, e.rect.x + e.rect.w);
        let (z0, z1) = (base + e.rect.y, base + e.rect.y + e.rect.h);
        match element_on_edge(&d.shapes[c].label, e, (u0, u1), (z0, z1), &facades.levels) {
            Placed::Nothing => {}
            Placed::Balcony(b) => facades.balconies[k].push(b),
            Placed::Openings(o) => facades.openings[k].extend(o),
        }
    }
    facades.openings[k].sort_by(|a, b| a.z0.total_cmp(&b.z0).then(a.u0.total_cmp(&b.u0)));
    true
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::OpeningKind;

    /// The lots of Monaco with a street in front, largest first.
    fn monaco_lots() -> Vec<crate::prepare::Lot> {
        let mut report = crate::report::Report::default();
        let pbf = Path::new(env!("CARGO_MANIFEST_DIR")).join("data/monaco/monaco.osm.pbf");
        let read = crate::input::osm::read_osm(&pbf, &mut report).unwrap();
        let mut site = crate::prepare::prepare(read.footprints, None, None, &mut report);
        crate::prepare::assign_fronts(&mut site, &read.streets, None);
        let mut lots: Vec<_> = site
            .lots
            .into_iter()
            .filter(|l| l.front.is_some())
            .collect();
        lots.sort_by(|a, b| {
            let area = |l: &crate::prepare::Lot| l.polygons.iter().map(|p| p.area()).sum::<f64>();
            area(b)
                .total_cmp(&area(a))
                .then(a.id.to_string().cmp(&b.id.to_string()))
        });
        lots
    }

    /// The seed's printed programs, unchanged: their `createShape` box becomes the real building's
    /// mass, its `<label>_front` the facades facing the street, so each front facade of Monaco's
    /// largest buildings gets what the box's front got (golden counts of src/selex/eval_tests.rs).
    #[test]
    fn the_seeds_printed_programs_run_unchanged_on_real_monaco_footprints() {
        use crate::derive::facade::{Facades, Level};
        use crate::selex::eval::Side;
        use crate::selex::parser::parse;
        // (file, per front facade: (label, count), ...)
        let cases: [(&str, &[(&str, usize)]); 5] = [
            ("brito.slx", &[("entrance", 1)]),
            ("rounded_door.slx", &[("entrance", 1), ("door", 1)]),
            ("update_grid.slx", &[("door", 1), ("window", 2)]),
            ("framed.slx", &[("entrance", 1), ("windows", 2)]),
            ("clock_tower.slx", &[("clock", 1), ("windows", 6)]),
        ];
        let lots = monaco_lots();
        let storeys = [3.5, 3.0, 3.0, 3.0];
        for (file, expect) in cases {
            let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
                .join("tests/data/selex")
                .join(file);
            let source = std::fs::read_to_string(&path).unwrap();
            let program = parse(&source, file).unwrap_or_else(|e| panic!("{e}"));
            let selex = SelexProgram {
                file: file.into(),
                source: source.clone(),
                program: program.clone(),
            };
            let (mut fronts_seen, mut bays) = (0, 0);
            for lot in lots.iter().take(20) {
                for polygon in &lot.polygons {
                    let specs = facade_specs(polygon, 0.0, &storeys, lot.front);
                    let fronts = specs.iter().filter(|s| s.side == Side::Front).count();
                    fronts_seen += fronts;
                    let d = run_on_facades(&program, &source, file, &specs)
                        .unwrap_or_else(|e| panic!("{}: {e}", lot.id));
                    for (label, n) in expect {
                        let found = d.find(label).len();
                        assert_eq!(
                            found,
                            n * fronts,
                            "{file} on {}: {label} {:?}",
                            lot.id,
                            d.warnings.first()
                        );
                    }
                    // Into a city run's facades: the clock and the windows on the front facades
                    // are openings of their walls, rounded (the clock also framed).
                    let edges = polygon.rings().map(Vec::len).sum::<usize>();
                    let mut levels = Vec::new();
                    let mut z = 0.0;
                    for h in storeys {
                        levels.push(Level { z0: z, z1: z + h });
                        z += h;
                    }
                    let mut f = Facades {
                        levels,
                        openings: vec![Vec::new(); edges],
                        balconies: vec![Vec::new(); edges],
                        ..Facades::default()
                    };
                    let applied = apply(&selex, polygon, 0.0, lot.front, &mut f)
                        .unwrap_or_else(|e| panic!("{file} on {}: {e}", lot.id));
                    if file == "clock_tower.slx" {
                        let all: Vec<_> = f.openings.iter().flatten().collect();
                        let clocks = all
                            .iter()
                            .filter(|o| o.framed && o.rounding.is_some() && o.frame_size.is_some())
                            .count();
                        let rounded = all
                            .iter()
                            .filter(|o| !o.framed && o.rounding.is_some())
                            .count();
                        assert!(clocks >= fronts, "{}: {clocks} clock pieces", lot.id);
                        assert!(rounded >= 6 * fronts, "{}: {rounded} windows", lot.id);
                    }
                    if file == "rounded_door.slx" {
                        // The door stands on its bay, not in a wall of the mass; every bay is a
                        // mass of its own with the door on its front (edge 0), or too small.
                        assert!(f.openings.iter().flatten().next().is_none());
                        assert_eq!(applied.bays.len() + f.off_envelope, fronts, "{}", lot.id);
                        bays += applied.bays.len();
                        for b in &applied.bays {
                            // The front an arc of chords (roundShape, 30 segments).
                            assert!(!b.rounded && b.footprint.outer.len() > 8, "{b:?}");
                            assert!(crate::geometry::is_simple(&b.footprint.outer));
                            assert!(b.footprint.area() > 0.09);
                            assert!((b.z0, b.z1) == (0.0, 12.5 * 3.0 / 4.0), "{b:?}");
                            // 6.25 m high (two of the bay's three rows): cut at the 3.5 m
                            // floor, on one facet of the arc.
                            let with: Vec<_> = b
                                .facades
                                .openings
                                .iter()
                                .filter(|o| !o.is_empty())
                                .collect();
                            assert_eq!(with.len(), 1, "{}: one facet", lot.id);
                            let door = with[0];
                            assert_eq!(door.len(), 2, "{}: the door cut at a floor", lot.id);
                            // The door on the ground storey, its fanlight above, rounded.
                            assert_eq!(door[0].kind, OpeningKind::Door);
                            assert!(door[0].rounding.is_none());
                            assert_eq!(door[1].kind, OpeningKind::Window);
                            assert!(door[1].glazed && door[1].rounding.is_some());
                        }
                    }
                }
            }
            assert!(fronts_seen >= 20, "{file}: {fronts_seen} front facades");
            if file == "rounded_door.slx" {
                assert!(bays >= 20, "{bays} bays drawn");
            }
        }
    }

    #[test]
    fn a_door_centred_in_its_cell_stands_on_its_floor() {
        use crate::derive::facade::{Facades, Level};
        let src = r#"{< descendant() [label == "facade"] > -> createStoreyGrid("g", 3.0)};
{< descendant() [label == "facade"] [side == "front"] / [label == "g"] / [rowIdx == 1] [colIdx == 1] > -> addShape("door", 1.2, 2.2)};
{< descendant() [label == "facade"] [side == "front"] / [label == "g"] / [rowIdx == 2] > -> addShape("window", 1.0, 1.4)};
"#;
        let program = SelexProgram {
            file: "door.slx".into(),
            source: src.into(),
            program: crate::selex::parser::parse(src, "door.slx").unwrap(),
        };
        // A 9 x 6 m box whose first edge (south) faces the street.
        let fp = Polygon::new(
            vec![
                glam::DVec2::new(0.0, 0.0),
                glam::DVec2::new(9.0, 0.0),
                glam::DVec2::new(9.0, 6.0),
                glam::DVec2::new(0.0, 6.0),
            ],
            vec![],
        );
        let mut f = Facades {
            levels: vec![Level { z0: 0.0, z1: 4.0 }, Level { z0: 4.0, z1: 7.0 }],
            openings: vec![Vec::new(); 4],
            balconies: vec![Vec::new(); 4],
            ..Facades::default()
        };
        apply(&program, &fp, 0.0, Some(glam::DVec2::NEG_Y), &mut f).unwrap();
        assert!(f.programmed);
        let front = &f.openings[0];
        let door = front.iter().find(|o| o.kind == OpeningKind::Door).unwrap();
        // Centred in its 4 m cell the door's foot was 0.9 m up; it stands on the floor now.
        assert!(
            door.z0.abs() < 1e-9 && (door.z1 - 2.2).abs() < 1e-9,
            "{door:?}"
        );
        assert!((door.u1 - door.u0 - 1.2).abs() < 1e-9);
        // Windows stay where the program put them: centred in their cells.
        let w = front
            .iter()
            .find(|o| o.kind == OpeningKind::Window)
            .unwrap();
        assert!((w.z0 - (4.0 + 0.8)).abs() < 1e-9, "{w:?}");
    }
}
