//! SELEX facades in a city run (issue 23): an appearance that names a SELEX program
//! (`<selex file=...>`) has the facades of its buildings laid out by it at LOD3, in place of the
//! windows, doors and balconies its grammar rules found.
//!
//! Each mass's footprint edges become the program's `facade` faces
//! ([`crate::selex::eval::facade_specs`]), each with its side towards the street and the mass's
//! storeys (the levels the rules made), so one program serves every footprint. The elements it
//! places become openings and balconies on their edge, cut at the storeys (a wall is one storey
//! high at LOD3: an element two storeys high becomes one opening on each). Labels decide what an
//! element is: `door…` and `entrance…` are doors, `balcony…` and `ledge…` balconies, `wall` and
//! covers nothing, anything else a window; framed elements (`addFacadeWithFrame`) are framed
//! windows. Elements on bays (`addVolume`) stand on no footprint edge and are counted as off the
//! envelope.

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use crate::derive::facade::{Facades, FoundBalcony, FoundOpening, Level, OpeningKind};
use crate::geometry::Polygon;
use crate::kb::KnowledgeBase;
use crate::model::{FrameSize, Rounding};
use crate::selex::ast::Program;
use crate::selex::eval::{facade_specs, run_on_facades, Element, ShapeKind};

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
pub fn load_all(kb: &KnowledgeBase) -> Result<HashMap<PathBuf, Arc<SelexProgram>>, String> {
    let mut out: HashMap<PathBuf, Arc<SelexProgram>> = HashMap::new();
    for (z, zone) in kb.zones().iter().enumerate() {
        for a in 0..zone.appearances.len() {
            let Some(path) = kb.selex_path(z, a).map_err(|e| e.to_string())? else {
                continue;
            };
            if out.contains_key(&path) {
                continue;
            }
            let program = load(&path)?;
            out.insert(path, Arc::new(program));
        }
    }
    Ok(out)
}

/// Reads and parses one program.
pub fn load(path: &Path) -> Result<SelexProgram, String> {
    let file = path.display().to_string();
    let source = crate::grammar::read_source(path).map_err(|e| format!("{file}: {e}"))?;
    let program = crate::selex::parser::parse(&source, &file).map_err(|e| e.to_string())?;
    Ok(SelexProgram {
        file,
        source,
        program,
    })
}

/// Lays out `facades` (found by the rules on a mass of `footprint` standing on `base_z`) with
/// `program`: its openings and balconies replace the rules'. Returns the program's warnings
/// (`file:line:col: message`); an error of the program leaves `facades` as the rules made them
/// and is returned as the note.
pub fn apply(
    program: &SelexProgram,
    footprint: &Polygon,
    base_z: f64,
    front: Option<glam::DVec2>,
    facades: &mut Facades,
) -> Result<Vec<String>, String> {
    let storeys: Vec<f64> = facades
        .levels
        .iter()
        .map(|l| l.z1 - l.z0)
        .filter(|h| h.is_finite() && *h > 0.0)
        .collect();
    let base = facades.levels.first().map_or(base_z, |l| l.z0);
    let specs = facade_specs(footprint, base, &storeys, front);
    // Edge k of the footprint is facade_specs' k-th face, unless an edge was too short.
    let edges: Vec<(glam::DVec2, glam::DVec2)> = footprint
        .rings()
        .flat_map(|r| (0..r.len()).map(move |i| (r[i], r[(i + 1) % r.len()])))
        .collect();
    if edges.len() != facades.openings.len() {
        return Err("the footprint's edges are not the facades'".into());
    }
    let d = run_on_facades(&program.program, &program.source, &program.file, &specs)
        .map_err(|e| e.to_string().lines().next().unwrap_or_default().to_string())?;
    let faces = d.find("facade");
    let mut openings: Vec<Vec<FoundOpening>> = vec![Vec::new(); edges.len()];
    let mut balconies: Vec<Vec<FoundBalcony>> = vec![Vec::new(); edges.len()];
    let mut off = 0usize;
    for (face, spec) in faces.iter().zip(&specs) {
        let Some(k) = edges
            .iter()
            .position(|&(a, b)| a == spec.start && b == spec.end)
        else {
            continue;
        };
        for &c in &d.shapes[*face].children {
            let ShapeKind::Element(e) = &d.shapes[c].kind else {
                if matches!(d.shapes[c].kind, ShapeKind::Volume { .. }) {
                    off += 1;
                }
                continue;
            };
            let (u0, u1) = (e.rect.x, e.rect.x + e.rect.w);
            let (z0, z1) = (base + e.rect.y, base + e.rect.y + e.rect.h);
            match element_on_edge(&d.shapes[c].label, e, (u0, u1), (z0, z1), &facades.levels) {
                Placed::Nothing => {}
                Placed::Balcony(b) => balconies[k].push(b),
                Placed::Openings(o) => openings[k].extend(o),
            }
        }
    }
    for v in &mut openings {
        v.sort_by(|a, b| a.z0.total_cmp(&b.z0).then(a.u0.total_cmp(&b.u0)));
    }
    facades.openings = openings;
    facades.balconies = balconies;
    facades.off_envelope += off;
    Ok(d.warnings
        .iter()
        .map(|n| format!("{}:{}:{}: {}", program.file, n.line, n.col, n.message))
        .collect())
}

/// What one SELEX element becomes on a footprint edge ([`element_on_edge`]).
#[derive(Clone, Debug, PartialEq)]
pub(crate) enum Placed {
    /// Nothing: the cover (`wall`).
    Nothing,
    /// A balcony (`balcony…`, `ledge…`).
    Balcony(FoundBalcony),
    /// A door or a window, one opening per storey it spans (none where it spans less than
    /// 0.3 m of every storey).
    Openings(Vec<FoundOpening>),
}

/// The opening(s) or balcony an element labelled `label` becomes where it stands at `u0..u1`
/// along its footprint edge (metres from the edge's start) and `z0..z1` (absolute heights),
/// on a wall cut at `levels`. Labels decide: `door…` and `entrance…` are doors, `balcony…` and
/// `ledge…` balconies, `wall` nothing, anything else a window (case does not matter). An
/// opening spanning several storeys is cut at them, the top corners' rounding going to the top
/// piece and the bottom corners' to the bottom one; a frame (`addFacadeWithFrame`) makes it
/// framed, with its size.
pub(crate) fn element_on_edge(
    label: &str,
    e: &Element,
    (u0, u1): (f64, f64),
    (z0, z1): (f64, f64),
    levels: &[Level],
) -> Placed {
    let label = label.to_ascii_lowercase();
    if label == "wall" {
        return Placed::Nothing;
    }
    if label.starts_with("balcony") || label.starts_with("ledge") {
        return Placed::Balcony(FoundBalcony {
            u0,
            u1,
            z0,
            z1,
            color: None,
        });
    }
    let kind = if label.starts_with("door") || label.starts_with("entrance") {
        OpeningKind::Door
    } else {
        OpeningKind::Window
    };
    let frame_size = e.frame.map(|f| FrameSize {
        width: f.thickness,
        protrusion: f.width,
    });
    let mut out = Vec::new();
    for l in levels {
        let (lo, hi) = (z0.max(l.z0), z1.min(l.z1));
        if hi - lo < 0.3 {
            continue;
        }
        let rounding = e.rounding.map(|r| {
            let (top, bottom) = (hi >= z1 - 1e-9, lo <= z0 + 1e-9);
            let c = r.corners;
            Rounding {
                corners: [c[0] && top, c[1] && top, c[2] && bottom, c[3] && bottom],
                radius: r.offset,
                segments: r.segments,
                profile: r.profile,
            }
        });
        out.push(FoundOpening {
            kind,
            u0,
            u1,
            z0: lo,
            z1: hi,
            color: None,
            frame_color: None,
            glazed: kind == OpeningKind::Window,
            framed: e.frame.is_some(),
            frame_size,
            rounding: rounding.filter(Rounding::is_rounded),
        });
    }
    Placed::Openings(out)
}
