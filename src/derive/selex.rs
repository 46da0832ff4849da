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

use crate::derive::facade::{Facades, FoundBalcony, FoundOpening, OpeningKind};
use crate::geometry::Polygon;
use crate::kb::KnowledgeBase;
use crate::model::{FrameSize, Rounding};
use crate::selex::ast::Program;
use crate::selex::eval::{facade_specs, run_on_facades, ShapeKind};

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
            let label = d.shapes[c].label.to_ascii_lowercase();
            let (u0, u1) = (e.rect.x, e.rect.x + e.rect.w);
            let (z0, z1) = (base + e.rect.y, base + e.rect.y + e.rect.h);
            if label == "wall" {
                continue;
            }
            if label.starts_with("balcony") || label.starts_with("ledge") {
                balconies[k].push(FoundBalcony {
                    u0,
                    u1,
                    z0,
                    z1,
                    color: None,
                });
                continue;
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
            // One opening per storey the element spans; the top corners' rounding goes to the
            // top piece, the bottom corners' to the bottom one.
            for l in &facades.levels {
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
                openings[k].push(FoundOpening {
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
