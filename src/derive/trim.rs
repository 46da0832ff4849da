//! Cornices and eaves (issue 49, LOD3 and above): where the knowledge base asks for them, which
//! footprint edges of a part carry them.
//!
//! A flat-roofed part whose style has a `cornice` gets a [`Cornice`] along the top of its walls;
//! a pitched one whose style has `eaves` gets [`Eaves`]. An edge carries either only where the
//! strip in front of it, out to twice the trim's reach and a margin (so that two buildings'
//! cornices or eaves facing each other never meet), and over the trim's heights, meets no
//! footprint: not a neighbour's, not another part's of the building, not the part's own
//! wings (a narrow court). So no cornice or eaves runs on a party wall. Where two carrying
//! edges meet at a corner that turns outward, the strip's ends are tested past the corner too,
//! for the mitred corner the writers draw. A cornice is lowered to stay clear of the top
//! storey's openings and balconies on the edges it runs along; below [`MIN_CORNICE`] it is not
//! drawn. The geometry itself is the writers' (`export::lod3geom::cornice_solids`,
//! `eaves_solids`).

use glam::DVec2;

use crate::color::Color;
use crate::kb::Style;
use crate::model::{Cornice, Eaves, Part, RoofShape, SourceId, RAILING_HEIGHT};

use super::surroundings::{strip_spans, Neighbour, Span, Surroundings};

/// The lowest cornice drawn (metres): one the top storey's windows leave less room for is left
/// out.
pub(crate) const MIN_CORNICE: f64 = 0.1;
/// How far above the top storey's openings and balcony railings a cornice's bottom stays
/// (metres).
const CORNICE_CLEARANCE: f64 = 0.05;
/// Thickness of the eaves' board under the roof's surface, vertical (metres).
pub(crate) const EAVES_THICKNESS: f64 = 0.12;
/// The margin past the trim's reach that the strip in front of an edge must keep free
/// (metres).
const MARGIN: f64 = 0.1;

/// Sets the cornice and eaves of `parts` (one building, `owner` on `ground`, derived on z = 0;
/// `around` at its neighbours' own grounds) from their styles (`styles[i]` is part `i`'s).
pub(crate) fn apply(
    parts: &mut [Part],
    styles: &[&Style],
    (owner, ground): (SourceId, f64),
    around: &Surroundings,
) {
    let asks = |p: &Part, s: &Style| {
        p.structure.is_none()
            && match p.roof_shape {
                RoofShape::Flat => s.cornice.is_some(),
                _ => s.eaves.is_some(),
            }
    };
    if !parts.iter().zip(styles).any(|(p, s)| asks(p, s)) {
        return;
    }
    let own = Surroundings::new(parts.iter().map(|p| Neighbour::of_part(owner, p)).collect());
    for i in 0..parts.len() {
        let style = styles[i];
        if !asks(&parts[i], style) {
            continue;
        }
        let p = &parts[i];
        if p.roof_shape == RoofShape::Flat {
            let Some((depth, height)) = style.cornice else {
                continue;
            };
            let Some(height) = cornice_height(p, height) else {
                continue;
            };
            let (z0, z1) = (p.eave_z - height, p.eave_z);
            let edges = free_edges(p, &own, around, (owner, ground), 2.0 * depth, (z0, z1));
            if edges.iter().any(|&e| e) {
                let color = lighter(p.wall_color);
                parts[i].cornice = Some(Cornice {
                    depth,
                    height,
                    edges,
                    color,
                });
            }
        } else {
            let Some(overhang) = style.eaves else {
                continue;
            };
            // The board's lowest point: a steep roof drops fast past the wall.
            let z0 = p.eave_z - 2.0 * overhang - EAVES_THICKNESS;
            let reach = 2.0 * overhang;
            let edges = free_edges(p, &own, around, (owner, ground), reach, (z0, p.top_z));
            if edges.iter().any(|&e| e) {
                let soffit = p.wall_color;
                parts[i].eaves = Some(Eaves {
                    overhang,
                    thickness: EAVES_THICKNESS,
                    edges,
                    soffit,
                });
            }
        }
    }
}

/// The cornice's height on `p`: `wanted`, lowered so that its bottom stays
/// [`CORNICE_CLEARANCE`] above every opening and balcony railing of the walls that reach the
/// eave; `None` below [`MIN_CORNICE`].
fn cornice_height(p: &Part, wanted: f64) -> Option<f64> {
    let mut room = wanted;
    for w in p.walls.iter().filter(|w| w.top_z >= p.eave_z - 1e-6) {
        let tops = w
            .openings
            .iter()
            .map(|o| o.z1)
            .chain(w.balconies.iter().map(|b| b.z + RAILING_HEIGHT));
        for top in tops {
            room = room.min(p.eave_z - top - CORNICE_CLEARANCE);
        }
    }
    (room.is_finite() && room >= MIN_CORNICE).then_some(room)
}

/// A moulding's colour: the wall's, lightened a fifth of the way to white (stone or stucco).
fn lighter(c: Color) -> Color {
    let l = |x: f32| x + (1.0 - x) * 0.2;
    Color {
        r: l(c.r),
        g: l(c.g),
        b: l(c.b),
        a: c.a,
    }
}

/// Per footprint edge of `p` (rings in order): whether the strip `reach` + [`MARGIN`] out in
/// front of it, over `z0..z1` (on z = 0), meets no footprint; past a corner where the next or
/// previous edge turns outward, the strip is tested [`MARGIN`] + `reach` further along.
fn free_edges(
    p: &Part,
    own: &Surroundings,
    around: &Surroundings,
    (owner, ground): (SourceId, f64),
    reach: f64,
    (z0, z1): (f64, f64),
) -> Vec<bool> {
    let reach = reach + MARGIN;
    let (lo, hi) = p.footprint.bounds();
    let m = DVec2::splat(2.0 * reach + 0.1);
    let others = around.near(owner, lo - m, hi + m);
    let mine = own.indices_near(lo - m, hi + m);
    let mut out = Vec::new();
    for ring in p.footprint.rings() {
        let n = ring.len();
        for i in 0..n {
            let (a, b) = (ring[i], ring[(i + 1) % n]);
            let len = a.distance(b);
            if !(len.is_finite() && len > 1e-6) {
                out.push(false);
                continue;
            }
            let d = (b - a) / len;
            // Outward corners: the next edge turns left (a convex corner of the solid), as
            // does the previous one into this.
            let turn = |u: DVec2, v: DVec2| u.perp_dot(v) > 1e-9;
            let prev = ring[(i + n - 1) % n];
            let next = ring[(i + 2) % n];
            let ext_a = if turn(a - prev, d) { reach } else { 0.0 };
            let ext_b = if turn(d, next - b) { reach } else { 0.0 };
            let (sa, sb) = (a - d * ext_a, b + d * ext_b);
            let mut s: Vec<Span> = Vec::new();
            for &q in &mine {
                strip_spans(sa, sb, own.part(q), reach, &mut s);
            }
            let first = s.len();
            for nb in &others {
                strip_spans(sa, sb, nb, reach, &mut s);
            }
            for span in &mut s[first..] {
                span.z0 -= ground;
                span.z1 -= ground;
            }
            let whole = len + ext_a + ext_b;
            out.push(!s.iter().any(|sp| sp.meets(0.0, whole, z0, z1)));
        }
    }
    out
}
