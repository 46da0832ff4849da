//! One volume, one owner: the plan (and the heights) each piece of a lot is drawn on, so that
//! no two of its pieces fill one volume.
//!
//! Where two pieces' plans overlap and their walls share more than
//! [`STACK_TOLERANCE`](super::STACK_TOLERANCE) of height (a tower mapped inside the part
//! around it, both from the ground), the smaller plan wins and is cut out of the larger (equal
//! plans: the later id wins). The cut applies only over the heights the winners fill (issue
//! 45): a part that the winners cover over its whole height range is drawn on what they leave
//! of its plan, or not at all (with a note naming it); a part they cover over some heights
//! only is drawn in bands, its whole plan where no winner stands and what the winners leave of
//! it where they do, so that a column under a deck or a ring on a column is never dropped for
//! a part that fills none of its heights. Pieces that only stand on each other keep their
//! plans.

use super::{boxes_meeting, Note, STACK_TOLERANCE};
use crate::geometry::Polygon;
use crate::input::BuildingTags;
use crate::kb::Style;
use crate::prepare::LotPiece;
use crate::report::Outcome;
use crate::rng::Rng;

/// What a piece is drawn on: polygons over its own heights, or over a band of them (a part
/// whose winners fill some of its heights only, [`resolve_overlaps`]).
#[derive(Clone, Debug, PartialEq)]
pub(super) struct Plan {
    /// The polygons, each drawn as the piece's footprint.
    pub(super) polygons: Vec<Polygon>,
    /// `Some((z0, z1))`: drawn from `z0` to `z1` (metres above the ground); the band at the top
    /// of the piece's walls keeps its roof, the others are flat.
    pub(super) band: Option<(f64, f64)>,
}

/// The plans each piece is drawn on, in piece order (module docs): one plan per piece, or one
/// per band of a piece drawn in bands, or none for a piece whose volume others fill.
pub(super) fn resolve_overlaps(
    styled: &[(&LotPiece, BuildingTags, Style, Rng)],
    notes: &mut Vec<Note>,
) -> Vec<Vec<Plan>> {
    let area = |p: &[Polygon]| p.iter().map(Polygon::area).sum::<f64>();
    let whole = |i: usize| Plan {
        polygons: styled[i].0.polygons.clone(),
        band: None,
    };
    if styled.len() < 2 {
        return (0..styled.len()).map(|i| vec![whole(i)]).collect();
    }
    let areas: Vec<f64> = styled.iter().map(|(p, ..)| area(&p.polygons)).collect();
    // Only a piece whose box meets this one's can cut it.
    let near = boxes_meeting(styled);
    let mut out = Vec::with_capacity(styled.len());
    for i in 0..styled.len() {
        let (piece, _, si, _) = &styled[i];
        let winners: Vec<usize> = near[i]
            .iter()
            .copied()
            .filter(|&j| j != i)
            .filter(|&j| {
                let (_, _, sj, _) = &styled[j];
                let shared = si.eave_height.min(sj.eave_height) - si.min_height.max(sj.min_height);
                shared > STACK_TOLERANCE && (areas[j] < areas[i] || (areas[j] == areas[i] && j > i))
            })
            .collect();
        if winners.is_empty() {
            out.push(vec![whole(i)]);
            continue;
        }
        // Only a real overlap changes the plan (a cut that removes nothing keeps the piece as
        // it was, bytes included): half a square metre, or a twentieth of a small part.
        let real = 0.5f64.min(0.05 * areas[i]);
        let cut_by = |js: &[usize]| {
            let cutters: Vec<Polygon> = js
                .iter()
                .flat_map(|&j| styled[j].0.polygons.iter().cloned())
                .collect();
            let cut = crate::prepare::cut_part(&piece.polygons, &cutters);
            (area(&cut) < areas[i] - real).then_some(cut)
        };
        let Some(cut) = cut_by(&winners) else {
            out.push(vec![whole(i)]);
            continue;
        };
        let bands = bands_of(
            si,
            &winners.iter().map(|&j| &styled[j].2).collect::<Vec<_>>(),
        );
        if let [(_, _, active)] = bands.as_slice() {
            if active.is_empty() {
                out.push(vec![whole(i)]);
                continue;
            }
            // The winners fill the piece's whole height range.
            if cut.is_empty() {
                notes.push((
                    Outcome::Note,
                    format!(
                        "{} lies inside other parts over its whole height range: their volumes are drawn, not its own",
                        piece.id
                    ),
                ));
            }
            out.push(vec![Plan {
                polygons: cut,
                band: None,
            }]);
            continue;
        }
        let plans = bands
            .into_iter()
            .filter_map(|(z0, z1, active)| {
                let js: Vec<usize> = active.iter().map(|&k| winners[k]).collect();
                let polygons = if js.is_empty() {
                    piece.polygons.clone()
                } else {
                    cut_by(&js).unwrap_or_else(|| piece.polygons.clone())
                };
                (!polygons.is_empty()).then_some(Plan {
                    polygons,
                    band: Some((z0, z1)),
                })
            })
            .collect();
        out.push(plans);
    }
    out
}

/// The bands of `piece`'s wall heights ([`Style::min_height`] to [`Style::eave_height`]) over
/// which the same `winners` stand (indices into `winners`), bottom up, neighbouring bands with
/// the same winners merged. A winner's base or top within [`STACK_TOLERANCE`] of the piece's
/// ends counts as the piece's end (no band thinner than the tolerance at either end). One band
/// with every winner: they fill the piece's whole height range. A winner with a pitched roof
/// counts up to the piece's top (its roof rises into the heights above its walls).
fn bands_of(piece: &Style, winners: &[&Style]) -> Vec<(f64, f64, Vec<usize>)> {
    let (lo, hi) = (piece.min_height, piece.eave_height);
    let snap = |z: f64| {
        if z <= lo + STACK_TOLERANCE {
            lo
        } else if z >= hi - STACK_TOLERANCE {
            hi
        } else {
            z
        }
    };
    // A winner with a pitched roof fills the heights over its walls too, as far as its roof
    // reaches: up to the piece's top, not knowing yet how high its roof will be.
    let ranges: Vec<(f64, f64)> = winners
        .iter()
        .map(|w| {
            let top = if w.roof == crate::model::RoofShape::Flat {
                snap(w.eave_height)
            } else {
                hi
            };
            (snap(w.min_height), top)
        })
        .collect();
    let mut cuts: Vec<f64> = vec![lo, hi];
    cuts.extend(ranges.iter().flat_map(|&(a, b)| [a, b]));
    cuts.sort_by(f64::total_cmp);
    cuts.dedup();
    let mut bands: Vec<(f64, f64, Vec<usize>)> = Vec::new();
    for w in cuts.windows(2) {
        let (z0, z1) = (w[0], w[1]);
        if z1 <= z0 {
            continue;
        }
        let active: Vec<usize> = (0..ranges.len())
            .filter(|&k| ranges[k].0 <= z0 && ranges[k].1 >= z1)
            .collect();
        match bands.last_mut() {
            Some(last) if last.2 == active => last.1 = z1,
            _ => bands.push((z0, z1, active)),
        }
    }
    bands
}

/// `style` drawn over the band `(z0, z1)` of its walls: its base raised to `z0`; below the
/// top band, a flat top at `z1`; the storeys shared out by height.
pub(super) fn banded(style: &Style, (z0, z1): (f64, f64)) -> Style {
    let mut s = style.clone();
    let walls = style.eave_height - style.min_height;
    if walls > 0.0 {
        let share = (z1 - z0) / walls;
        s.storeys = ((f64::from(style.storeys) * share).round() as u32).max(1);
    }
    s.min_height = z0;
    if z1 < style.eave_height {
        s.eave_height = z1;
        s.total_height = Some(z1);
        s.make_flat();
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    fn style(min: f64, eave: f64) -> Style {
        let kb = crate::kb::KnowledgeBase::earth_only();
        let mut s = kb
            .style_for(0, &BuildingTags::default(), &mut Rng::new(0, 0))
            .0;
        s.min_height = min;
        s.eave_height = eave;
        s.make_flat();
        s
    }

    #[test]
    fn a_winner_over_the_whole_range_is_one_band_and_one_over_a_part_of_it_makes_three() {
        let column = style(0.0, 6.0);
        assert_eq!(
            bands_of(&column, &[&style(0.0, 10.0)]),
            vec![(0.0, 6.0, vec![0])]
        );
        // Within the tolerance of the ends counts as the ends.
        assert_eq!(
            bands_of(&column, &[&style(0.3, 5.8)]),
            vec![(0.0, 6.0, vec![0])]
        );
        assert_eq!(
            bands_of(&column, &[&style(2.0, 3.0)]),
            vec![(0.0, 2.0, vec![]), (2.0, 3.0, vec![0]), (3.0, 6.0, vec![])]
        );
        // A winner with a pitched roof fills the heights over its walls up to the top.
        let mut pitched = style(2.0, 3.0);
        pitched.roof = crate::model::RoofShape::Hipped;
        assert_eq!(
            bands_of(&column, &[&pitched]),
            vec![(0.0, 2.0, vec![]), (2.0, 6.0, vec![0])]
        );
        assert_eq!(
            bands_of(&column, &[&style(2.0, 8.0), &style(0.0, 3.0)]),
            vec![
                (0.0, 2.0, vec![1]),
                (2.0, 3.0, vec![0, 1]),
                (3.0, 6.0, vec![0])
            ]
        );
    }

    #[test]
    fn a_lower_band_is_flat_and_the_top_band_keeps_the_roof() {
        let mut s = style(0.0, 12.0);
        s.storeys = 4;
        s.roof = crate::model::RoofShape::Gabled;
        let low = banded(&s, (0.0, 3.0));
        assert_eq!(low.roof, crate::model::RoofShape::Flat);
        assert_eq!(
            (low.min_height, low.eave_height, low.storeys),
            (0.0, 3.0, 1)
        );
        let top = banded(&s, (3.0, 12.0));
        assert_eq!(top.roof, crate::model::RoofShape::Gabled);
        assert_eq!(
            (top.min_height, top.eave_height, top.storeys),
            (3.0, 12.0, 3)
        );
    }
}
