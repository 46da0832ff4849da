//! Storey counts learned from the map itself (issue 21, step 2, first part): a building with no
//! `building:levels` and no `height` takes the distance-weighted median of the levels of the
//! tagged buildings nearest to it, where enough of them stand close by.
//!
//! The rule, per untagged lot: the [`InferOptions::k`] nearest lots with `building:levels`
//! within [`InferOptions::radius`] metres (representative points: the middle of the outline's
//! bounds), those of the same `building=*` kind when at least
//! [`InferOptions::min_neighbours`] of them are among the nearest, else all; fewer than
//! `min_neighbours`: nothing inferred (the knowledge base decides). Each neighbour weighs
//! `1 / (distance + 10 m)`; the weighted median, rounded to whole storeys, is the result.
//! Pure function of the lots: deterministic, in parallel.

use glam::DVec2;
use rayon::prelude::*;
use rstar::primitives::GeomWithData;
use rstar::RTree;

use super::Lot;

/// How levels are inferred.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct InferOptions {
    /// How many nearest tagged buildings are looked at.
    pub k: usize,
    /// The farthest a neighbour may be (metres).
    pub radius: f64,
    /// The fewest neighbours that make an inference.
    pub min_neighbours: usize,
}

impl Default for InferOptions {
    fn default() -> InferOptions {
        InferOptions {
            k: 8,
            radius: 300.0,
            min_neighbours: 3,
        }
    }
}

/// A storey count inferred for one lot.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Inferred {
    /// The storeys (whole, at least 1).
    pub levels: f64,
    /// How many tagged neighbours gave it.
    pub neighbours: usize,
    /// The distance of the farthest of them (metres).
    pub farthest: f64,
}

/// The middle of a lot's outline bounds (local metres), `None` when not finite.
fn point_of(lot: &Lot) -> Option<DVec2> {
    let (mut lo, mut hi) = (DVec2::splat(f64::INFINITY), DVec2::splat(f64::NEG_INFINITY));
    for p in &lot.polygons {
        let (a, b) = p.bounds();
        lo = lo.min(a);
        hi = hi.max(b);
    }
    let m = 0.5 * (lo + hi);
    m.is_finite().then_some(m)
}

/// A lot's own tagged levels (outline tags), when usable.
fn tagged(lot: &Lot) -> Option<f64> {
    lot.tags.levels.filter(|l| l.is_finite() && *l >= 1.0)
}

/// Whether a lot needs an inference: no levels and no height on its outline.
pub fn untagged(lot: &Lot) -> bool {
    tagged(lot).is_none() && lot.tags.height.is_none()
}

/// Per lot (in order): the inferred storeys of every [`untagged`] lot that has enough tagged
/// neighbours (module docs), `None` for the others.
pub fn infer_levels(lots: &[Lot], opts: InferOptions) -> Vec<Option<Inferred>> {
    let known: Vec<GeomWithData<[f64; 2], usize>> = lots
        .iter()
        .enumerate()
        .filter(|(_, l)| tagged(l).is_some())
        .filter_map(|(i, l)| point_of(l).map(|p| GeomWithData::new(p.to_array(), i)))
        .collect();
    let tree = RTree::bulk_load(known);
    lots.par_iter()
        .map(|lot| {
            if !untagged(lot) {
                return None;
            }
            let p = point_of(lot)?;
            let near: Vec<(f64, usize)> = tree
                .nearest_neighbor_iter_with_distance_2(p.to_array())
                .take(opts.k)
                .map(|(e, d2)| (d2.sqrt(), e.data))
                .filter(|(d, _)| *d <= opts.radius)
                .collect();
            let kind = |i: usize| {
                lots[i]
                    .tags
                    .building
                    .as_deref()
                    .map(str::to_ascii_lowercase)
            };
            let own = lot.tags.building.as_deref().map(str::to_ascii_lowercase);
            let same: Vec<(f64, usize)> = near
                .iter()
                .copied()
                .filter(|&(_, i)| kind(i) == own)
                .collect();
            let chosen = if same.len() >= opts.min_neighbours {
                same
            } else {
                near
            };
            if chosen.len() < opts.min_neighbours {
                return None;
            }
            let mut votes: Vec<(f64, f64)> = chosen
                .iter()
                .filter_map(|&(d, i)| tagged(&lots[i]).map(|l| (l, 1.0 / (d + 10.0))))
                .collect();
            votes.sort_by(|a, b| a.0.total_cmp(&b.0));
            let total: f64 = votes.iter().map(|v| v.1).sum();
            let mut acc = 0.0;
            let median = votes.iter().find_map(|&(l, w)| {
                acc += w;
                (acc >= 0.5 * total).then_some(l)
            })?;
            Some(Inferred {
                levels: median.round().max(1.0),
                neighbours: chosen.len(),
                farthest: chosen.iter().map(|c| c.0).fold(0.0, f64::max),
            })
        })
        .collect()
}

/// Sets the inferred storeys as the lots' `building:levels` (a new shared tag set per lot) and
/// returns the report notes, one per lot changed: (lot index, text).
pub fn apply(lots: &mut [Lot], inferred: &[Option<Inferred>]) -> Vec<(usize, String)> {
    let mut notes = Vec::new();
    for (i, (lot, inf)) in lots.iter_mut().zip(inferred).enumerate() {
        let Some(inf) = inf else { continue };
        let mut tags = (*lot.tags).clone();
        tags.levels = Some(inf.levels);
        lot.tags = std::sync::Arc::new(tags);
        notes.push((
            i,
            format!(
                "building:levels {} inferred from {} tagged neighbours within {:.0} m",
                inf.levels, inf.neighbours, inf.farthest
            ),
        ));
    }
    notes
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::Polygon;
    use crate::input::BuildingTags;
    use crate::model::SourceId;

    fn lot(i: i64, x: f64, levels: Option<f64>, kind: &str) -> Lot {
        let v = DVec2::new;
        let ring = vec![v(x, 0.0), v(x + 8.0, 0.0), v(x + 8.0, 8.0), v(x, 8.0)];
        let p = Polygon::new(ring, vec![]);
        Lot {
            id: SourceId::Way(i),
            tags: std::sync::Arc::new(BuildingTags {
                levels,
                building: Some(kind.to_string()),
                ..Default::default()
            }),
            polygons: vec![p.clone()],
            parts: Vec::new(),
            drawn_outline: vec![p],
            lonlat: (0.0, 0.0),
            front: None,
        }
    }

    #[test]
    fn an_untagged_building_takes_the_weighted_median_of_its_tagged_neighbours() {
        let mut lots = vec![
            lot(1, 0.0, Some(5.0), "apartments"),
            lot(2, 10.0, Some(6.0), "apartments"),
            lot(3, 20.0, None, "apartments"),
            lot(4, 30.0, Some(6.0), "apartments"),
            lot(5, 40.0, Some(2.0), "house"),
            lot(6, 3000.0, None, "apartments"),
        ];
        let inf = infer_levels(&lots, InferOptions::default());
        assert_eq!(inf[0], None, "tagged lots keep their tags");
        let got = inf[2].unwrap();
        assert_eq!(got.levels, 6.0);
        assert_eq!(got.neighbours, 3, "the house is another kind");
        assert_eq!(inf[5], None, "no tagged neighbour within the radius");
        let notes = apply(&mut lots, &inf);
        assert_eq!(notes.len(), 1);
        assert_eq!(lots[2].tags.levels, Some(6.0));
        assert_eq!(lots[0].tags.levels, Some(5.0));
    }

    #[test]
    fn too_few_neighbours_infer_nothing() {
        let lots = vec![
            lot(1, 0.0, Some(5.0), "yes"),
            lot(2, 10.0, Some(6.0), "yes"),
            lot(3, 20.0, None, "yes"),
        ];
        assert_eq!(infer_levels(&lots, InferOptions::default())[2], None);
    }
}
