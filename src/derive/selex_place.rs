//! How SELEX elements become openings and balconies of a wall, shared by the city path
//! (`derive::selex`) and `selex derive`'s lots (`derive::selex_lot`): an element's label decides
//! what it is and a wall's storeys cut it (`element_on_edge`); a bay's front rounded by
//! `roundShape` is an arc of chords (`rounded_front`) whose elements stand each on a flat
//! facet of their own (`on_facets`).

use glam::DVec2;

use crate::derive::facade::{FoundBalcony, FoundOpening, Level, OpeningKind};
use crate::model::{FrameSize, Rounding};
use crate::selex::eval::{Derivation, Element, ShapeId, ShapeKind};

/// The shortest edge of a rounded bay's footprint, metres.
pub(crate) const MIN_EDGE: f64 = 0.05;

/// A flat facet of a rounded front: the span `u0..u1` of the flat front it replaces, and its
/// ends (left, right seen from outside) in plan.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Facet {
    pub(crate) u0: f64,
    pub(crate) u1: f64,
    pub(crate) a: DVec2,
    pub(crate) b: DVec2,
}

/// Whether an element's label is the cover's (nothing is drawn for it).
pub(crate) fn is_cover(label: &str) -> bool {
    label.eq_ignore_ascii_case("wall")
}

/// The block behind a free-standing face.
/// A bay's footprint with a rounded front, in the bay's own axes (x along the wall from the
/// bay's left end seen from outside, y outwards; the wall at y = 0): the path from (0, 0) round
/// the front to (w, 0), the facets carrying the elements whose flat spans are `spans`, and the
/// segments drawn. `None` when there is nothing to round.
#[allow(clippy::type_complexity)]
pub(crate) fn rounded_front(
    w: f64,
    depth: f64,
    degree: f64,
    segments: u32,
    outside: bool,
    spans: &[(f64, f64)],
) -> Option<(Vec<DVec2>, Vec<Facet>, u32)> {
    let degree = if degree.is_finite() {
        degree.clamp(0.0, 1.0)
    } else {
        0.0
    };
    let most = if outside {
        depth.min(w / 2.0)
    } else {
        (depth - MIN_EDGE).min(w / 2.0)
    };
    let mut rise = degree * most;
    if rise < MIN_EDGE / 2.0 || w < 2.0 * MIN_EDGE {
        return None;
    }
    // Sides shorter than an edge may be: the arc starts on the wall.
    if outside && depth - rise < MIN_EDGE {
        rise = depth;
    }
    let r = (w * w / 4.0 + rise * rise) / (2.0 * rise);
    let phi = (w / 2.0).atan2(r - rise);
    let at = |t: f64| {
        let alpha = phi * (2.0 * t - 1.0);
        let x = w / 2.0 + r * alpha.sin();
        let y_out = depth - r + r * alpha.cos();
        let y = if outside {
            y_out
        } else {
            depth - rise + (depth - y_out)
        };
        DVec2::new(x, y)
    };
    let length = 2.0 * phi * r;
    let most_segments = ((length / MIN_EDGE).floor() as u32).max(1);
    let n = segments.clamp(1, most_segments);
    // The elements' spans on the arc, merged, as shares of the front's width.
    let mut sp: Vec<(f64, f64)> = spans
        .iter()
        .filter(|(a, b)| a.is_finite() && b.is_finite() && b > a)
        .map(|&(a, b)| ((a / w).clamp(0.0, 1.0), (b / w).clamp(0.0, 1.0)))
        .filter(|(a, b)| b > a)
        .collect();
    sp.sort_by(|a, b| a.0.total_cmp(&b.0));
    let mut merged: Vec<(f64, f64)> = Vec::new();
    for (a, b) in sp {
        match merged.last_mut() {
            Some(last) if a <= last.1 => last.1 = last.1.max(b),
            _ => merged.push((a, b)),
        }
    }
    // A span's end within a short chord of the arc's end goes to the end.
    let near = MIN_EDGE / length;
    for s in &mut merged {
        if s.0 < near {
            s.0 = 0.0;
        }
        if s.1 > 1.0 - near {
            s.1 = 1.0;
        }
    }
    let mut ts: Vec<f64> = (0..=n)
        .map(|k| f64::from(k) / f64::from(n))
        .filter(|&t| {
            !merged
                .iter()
                .any(|&(a, b)| t > a - near && t < b + near && t != 0.0 && t != 1.0)
        })
        .collect();
    for &(a, b) in &merged {
        ts.push(a);
        ts.push(b);
    }
    ts.sort_by(f64::total_cmp);
    ts.dedup_by(|a, b| (*a - *b).abs() < 1e-12);
    let mut path = vec![DVec2::ZERO];
    for &t in &ts {
        let p = at(t);
        if path.last().is_none_or(|q| q.distance(p) > 1e-9) {
            path.push(p);
        }
    }
    let end = DVec2::new(w, 0.0);
    if path.last().is_some_and(|q| q.distance(end) > 1e-9) {
        path.push(end);
    }
    // The last point repeats the first when the arc ends on the wall.
    if path.len() > 1 && path[path.len() - 1].distance(path[0]) < 1e-9 {
        path.pop();
    }
    let facets = merged
        .iter()
        .map(|&(a, b)| Facet {
            u0: a * w,
            u1: b * w,
            a: at(a),
            b: at(b),
        })
        .collect();
    Some((path, facets, n))
}

/// An element on a facet: (edge, label, the element, its span along the edge, its heights).
pub(crate) type OnFacet<'d> = (usize, &'d str, &'d Element, (f64, f64), (f64, f64));

/// Where the elements of the rounded front `f` stand: each on the facet of `facets` holding its
/// middle, as (edge of `edges`, its label, the element, its span along the edge, its heights
/// from `z0`), centred on the facet at the share of the facet's span its centre is at, its
/// width kept (at most the facet's). Elements on no facet (and covers: nothing) are added to
/// `unplaced`.
pub(crate) fn on_facets<'d>(
    d: &'d Derivation,
    f: ShapeId,
    facets: &[Facet],
    edges: &[(DVec2, DVec2)],
    z0: f64,
    unplaced: &mut Vec<String>,
) -> Vec<OnFacet<'d>> {
    let mut out = Vec::new();
    for &c in &d.shapes[f].children {
        let ShapeKind::Element(e) = &d.shapes[c].kind else {
            continue;
        };
        let label = d.shapes[c].label.as_str();
        if is_cover(label) {
            continue;
        }
        let mid = e.rect.x + e.rect.w / 2.0;
        let facet = facets
            .iter()
            .find(|ft| mid >= ft.u0 - 1e-9 && mid <= ft.u1 + 1e-9);
        let k = facet.and_then(|ft| {
            edges
                .iter()
                .position(|&(s, t)| s.distance(ft.a) < 0.005 && t.distance(ft.b) < 0.005)
        });
        let (Some(ft), Some(k)) = (facet, k) else {
            unplaced.push(format!(
                "{label} at ({:.2}, {:.2}) on the rounded `{}`: on no facet of the arc",
                e.rect.x, e.rect.y, d.shapes[f].label
            ));
            continue;
        };
        let len = edges[k].0.distance(edges[k].1);
        let share = if ft.u1 - ft.u0 > 1e-9 {
            (mid - ft.u0) / (ft.u1 - ft.u0)
        } else {
            0.5
        };
        let half = (e.rect.w / 2.0).min(len / 2.0);
        let centre = (share * len).clamp(half, len - half);
        let z = (z0 + e.rect.y, z0 + e.rect.y + e.rect.h);
        out.push((k, label, e, (centre - half, centre + half), z));
    }
    out
}

/// The flat spans `(x0, x1)` of the elements on face `f` (covers left out).
pub(crate) fn element_spans(d: &Derivation, f: ShapeId) -> Vec<(f64, f64)> {
    d.shapes[f]
        .children
        .iter()
        .filter_map(|&c| match &d.shapes[c].kind {
            ShapeKind::Element(e) if !is_cover(&d.shapes[c].label) => {
                Some((e.rect.x, e.rect.x + e.rect.w))
            }
            _ => None,
        })
        .collect()
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
/// `ledge…` balconies, `wall` nothing, anything else a window (case does not matter). A door
/// stands on the floor of the storey its foot is in (moved down, its height kept); above its
/// first storey a door is its fanlight, a window. An
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
    let (mut z0, mut z1) = (z0, z1);
    if kind == OpeningKind::Door {
        // A door stands on the floor of the storey its foot is in (an `addShape` centres it
        // in its cell): moved down, its height kept.
        if let Some(l) = levels.iter().find(|l| z0 >= l.z0 && z0 < l.z1) {
            (z0, z1) = (l.z0, z1 - (z0 - l.z0));
        }
    }
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
        // A door taller than its storey: above its first storey it is its fanlight, glass.
        let kind = if out.is_empty() {
            kind
        } else {
            OpeningKind::Window
        };
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
