//! Values learned from the map itself (issue 21, step 2): a building without a tag takes what
//! its tagged neighbours say, where enough of them stand close by. Storeys (`building:levels`),
//! roof shape (`roof:shape`) and the wall and roof colours (`building:colour`, `roof:colour`),
//! each where the building's zone allows it (`<info infer="levels,roof,colour">`) or the run's
//! `--infer` says so.
//!
//! The rule, per lot and value: the lot must lack the value (for storeys: no
//! `building:levels` and no `height`). Its candidates are the [`InferOptions::k`] nearest lots
//! that carry it, within [`InferOptions::radius`] metres (representative points: the middle of
//! the outline's bounds); those of the same `building=*` kind when at least
//! [`InferOptions::min_neighbours`] of them are among the nearest, else all. Fewer than
//! `min_neighbours`: nothing inferred (the knowledge base decides). A roof shape or colour
//! needs [`InferOptions::min_votes`] neighbours within [`InferOptions::category_radius`]. Each neighbour weighs
//! `1 / (distance + 10 m)` times a footprint likeness `exp(-|ln(area / own area)|)` (a villa
//! beside a tower block is drawn like the villas around it). Storeys are the weighted median,
//! rounded; a neighbour with a `height` and no levels counts as `height / 3 m` storeys. Roof
//! shapes and colours are the weighted mode, kept only when it holds at least
//! [`InferOptions::majority`] of the weight.
//!
//! Pure function of the lots and the switches: deterministic, in parallel.

use glam::DVec2;
use rayon::prelude::*;
use rstar::primitives::GeomWithData;
use rstar::RTree;

use super::Lot;
use crate::color::Color;
use crate::model::Inference;
use crate::model::RoofShape;

/// The storey height a neighbour's `height` is divided by when it has no `building:levels`.
pub(crate) const STOREY_FROM_HEIGHT_M: f64 = 3.0;

/// How values are inferred.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct InferOptions {
    /// How many nearest tagged buildings are looked at.
    pub k: usize,
    /// The farthest a neighbour may be (metres).
    pub radius: f64,
    /// The fewest neighbours that make an inference.
    pub min_neighbours: usize,
    /// The least share of the weight a roof shape or colour must hold to be inferred.
    pub majority: f64,
    /// The fewest neighbours that make a roof shape or colour (a category: two domed
    /// neighbours must not turn a street domed).
    pub min_votes: usize,
    /// The farthest a neighbour may be for a roof shape or colour (metres): a category
    /// follows the street more than the district.
    pub category_radius: f64,
    /// How much a neighbour's footprint area unlike the building's lowers its weight: the
    /// weight is multiplied by `(smaller area / larger area) ^ likeness` (0: not at all).
    pub likeness: f64,
}

impl Default for InferOptions {
    fn default() -> InferOptions {
        InferOptions {
            k: 8,
            radius: 300.0,
            min_neighbours: 3,
            majority: 0.5,
            min_votes: 3,
            category_radius: 150.0,
            likeness: 1.0,
        }
    }
}

/// One inferred value and what it rests on.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Found<T> {
    /// The value.
    pub value: T,
    /// How many tagged neighbours were weighed.
    pub neighbours: usize,
    /// The distance of the farthest of them (metres).
    pub farthest: f64,
    /// The share of their weight that agrees with the value (1 for storeys: a median).
    pub agree: f64,
}

/// What was inferred for one lot (all `None`: nothing).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Inferred {
    /// Storeys (whole, at least 1).
    pub levels: Option<Found<f64>>,
    /// Roof shape.
    pub roof: Option<Found<RoofShape>>,
    /// Wall colour.
    pub wall: Option<Found<Color>>,
    /// Roof colour.
    pub roof_colour: Option<Found<Color>>,
}

impl Inferred {
    /// Whether anything was inferred.
    pub fn any(&self) -> bool {
        self.levels.is_some()
            || self.roof.is_some()
            || self.wall.is_some()
            || self.roof_colour.is_some()
    }
}

/// The middle of a lot's outline bounds (local metres), `None` when not finite.
fn point_of(lot: &Lot) -> Option<DVec2> {
    lot.bounds().map(|(lo, hi)| 0.5 * (lo + hi))
}

/// A lot's storeys from its own tags: `building:levels`, else `height` over 3 m.
fn storeys(lot: &Lot) -> Option<f64> {
    let t = &lot.tags;
    t.levels.filter(|l| l.is_finite() && *l >= 1.0).or_else(|| {
        t.height
            .filter(|h| h.is_finite() && *h > 0.0)
            .map(|h| (h / STOREY_FROM_HEIGHT_M).round().max(1.0))
    })
}

/// Whether a lot needs its storeys inferred: no levels and no height on its outline.
pub fn untagged(lot: &Lot) -> bool {
    storeys(lot).is_none()
}

/// The footprint area of a lot (outline polygons), at least 1 m².
fn area_of(lot: &Lot) -> f64 {
    lot.polygons
        .iter()
        .map(|p| p.area().abs())
        .sum::<f64>()
        .max(1.0)
}

/// Nearest tagged lots of one value.
struct Index {
    tree: RTree<GeomWithData<[f64; 2], usize>>,
}

impl Index {
    fn new(lots: &[Lot], points: &[Option<DVec2>], has: impl Fn(&Lot) -> bool) -> Index {
        let known: Vec<GeomWithData<[f64; 2], usize>> = lots
            .iter()
            .enumerate()
            .filter(|(_, l)| has(l))
            .filter_map(|(i, _)| points[i].map(|p| GeomWithData::new(p.to_array(), i)))
            .collect();
        Index {
            tree: RTree::bulk_load(known),
        }
    }

    /// The weighed neighbours of lot `me` at `p`: (index, weight, distance); empty when fewer
    /// than `min_neighbours`.
    fn near(
        &self,
        lots: &[Lot],
        areas: &[f64],
        me: usize,
        p: DVec2,
        o: &InferOptions,
    ) -> Vec<(usize, f64, f64)> {
        let near: Vec<(f64, usize)> = self
            .tree
            .nearest_neighbor_iter_with_distance_2(p.to_array())
            .filter(|(e, _)| e.data != me)
            .take(o.k)
            .map(|(e, d2)| (d2.sqrt(), e.data))
            .filter(|(d, _)| *d <= o.radius)
            .collect();
        let kind = |i: usize| lots[i].tags.building.as_deref();
        let own = kind(me);
        let same: Vec<(f64, usize)> = near
            .iter()
            .copied()
            .filter(|&(_, i)| kind(i) == own)
            .collect();
        let chosen = if same.len() >= o.min_neighbours {
            same
        } else {
            near
        };
        if chosen.len() < o.min_neighbours {
            return Vec::new();
        }
        chosen
            .into_iter()
            .map(|(d, i)| {
                let like = (-o.likeness * (areas[i] / areas[me]).ln().abs()).exp();
                (i, like / (d + 10.0), d)
            })
            .collect()
    }
}

/// The weighted median of `(value, weight)` pairs.
fn median(mut votes: Vec<(f64, f64)>) -> Option<f64> {
    votes.sort_by(|a, b| a.0.total_cmp(&b.0));
    let total: f64 = votes.iter().map(|v| v.1).sum();
    let mut acc = 0.0;
    votes.iter().find_map(|&(l, w)| {
        acc += w;
        (acc >= 0.5 * total).then_some(l)
    })
}

/// The weighted mode of `(value, weight)` pairs and its share of the weight; ties go to the
/// value met first (the nearest).
fn mode<T: PartialEq + Copy>(votes: &[(T, f64)]) -> Option<(T, f64)> {
    let mut tally: Vec<(T, f64)> = Vec::new();
    for &(v, w) in votes {
        match tally.iter_mut().find(|t| t.0 == v) {
            Some(t) => t.1 += w,
            None => tally.push((v, w)),
        }
    }
    let total: f64 = tally.iter().map(|t| t.1).sum();
    let best = tally
        .iter()
        .copied()
        .reduce(|a, b| if b.1 > a.1 { b } else { a })?;
    (total > 0.0).then_some((best.0, best.1 / total))
}

fn found<T>(value: T, near: &[(usize, f64, f64)], agree: f64) -> Found<T> {
    Found {
        value,
        neighbours: near.len(),
        farthest: near.iter().map(|n| n.2).fold(0.0, f64::max),
        agree,
    }
}

/// Per lot (in order): what its tagged neighbours say about the values `wanted(i)` allows and
/// its own tags lack (module docs).
pub fn infer(
    lots: &[Lot],
    wanted: impl Fn(usize) -> Inference + Sync,
    opts: InferOptions,
) -> Vec<Inferred> {
    let want: Vec<Inference> = (0..lots.len()).map(&wanted).collect();
    if !want.iter().any(|w| w.any()) {
        return vec![Inferred::default(); lots.len()];
    }
    let points: Vec<Option<DVec2>> = lots.par_iter().map(point_of).collect();
    let areas: Vec<f64> = lots.par_iter().map(area_of).collect();
    // An index only for what some lot wants (an empty one finds nothing).
    let index = |on: bool, has: fn(&Lot) -> bool| Index::new(lots, &points, |l| on && has(l));
    let (any_levels, any_roof, any_colour) = (
        want.iter().any(|w| w.levels),
        want.iter().any(|w| w.roof),
        want.iter().any(|w| w.colour),
    );
    let levels = index(any_levels, |l| storeys(l).is_some());
    let roofs = index(any_roof, |l| l.tags.roof_shape.is_some());
    let walls = index(any_colour, |l| l.tags.colour.is_some());
    let roof_colours = index(any_colour, |l| l.tags.roof_colour.is_some());
    let categorical = InferOptions {
        min_neighbours: opts.min_neighbours.max(opts.min_votes),
        radius: opts.radius.min(opts.category_radius),
        ..opts
    };
    (0..lots.len())
        .into_par_iter()
        .map(|i| {
            let mut out = Inferred::default();
            let (w, lot) = (want[i], &lots[i]);
            let Some(p) = points[i] else { return out };
            if w.levels && untagged(lot) {
                let near = levels.near(lots, &areas, i, p, &opts);
                let votes = near
                    .iter()
                    .filter_map(|&(j, wt, _)| storeys(&lots[j]).map(|s| (s, wt)))
                    .collect();
                out.levels = median(votes).map(|m| found(m.round().max(1.0), &near, 1.0));
            }
            if w.roof && lot.tags.roof_shape.is_none() && lot.tags.invalid_roof_shape.is_none() {
                let near = roofs.near(lots, &areas, i, p, &categorical);
                let votes: Vec<(RoofShape, f64)> = near
                    .iter()
                    .filter_map(|&(j, wt, _)| lots[j].tags.roof_shape.map(|r| (r, wt)))
                    .collect();
                out.roof = mode(&votes)
                    .filter(|m| m.1 >= opts.majority)
                    .map(|(r, a)| found(r, &near, a));
            }
            if w.colour {
                let colour = |index: &Index, get: fn(&Lot) -> Option<Color>| {
                    if get(lot).is_some() {
                        return None;
                    }
                    let near = index.near(lots, &areas, i, p, &categorical);
                    let votes: Vec<(Color, f64)> = near
                        .iter()
                        .filter_map(|&(j, wt, _)| get(&lots[j]).map(|c| (c, wt)))
                        .collect();
                    mode(&votes)
                        .filter(|m| m.1 >= opts.majority)
                        .map(|(c, a)| found(c, &near, a))
                };
                out.wall = colour(&walls, |l| l.tags.colour);
                out.roof_colour = colour(&roof_colours, |l| l.tags.roof_colour);
            }
            out
        })
        .collect()
}

/// Storeys alone, for every [`untagged`] lot (the `levels` of [`infer`] with levels wanted
/// everywhere).
pub fn infer_levels(lots: &[Lot], opts: InferOptions) -> Vec<Option<Found<f64>>> {
    let levels_only = Inference {
        levels: true,
        ..Inference::NONE
    };
    infer(lots, |_| levels_only, opts)
        .into_iter()
        .map(|f| f.levels)
        .collect()
}

/// What one lot's inference says, for the report and `kb explain`: one phrase per value, e.g.
/// `building:levels 5 from 8 tagged neighbours within 120 m`.
pub(crate) fn describe(inf: &Inferred) -> Vec<String> {
    fn phrase<T>(key: &str, shown: String, f: &Found<T>) -> String {
        let agree = if f.agree < 1.0 {
            format!(", {:.0} % agreeing", 100.0 * f.agree)
        } else {
            String::new()
        };
        format!(
            "{key} {shown} inferred from {} tagged neighbours within {:.0} m{agree}",
            f.neighbours, f.farthest
        )
    }
    let mut out = Vec::new();
    if let Some(f) = &inf.levels {
        out.push(phrase("building:levels", format!("{}", f.value), f));
    }
    if let Some(f) = &inf.roof {
        out.push(phrase("roof:shape", f.value.osm_name().to_string(), f));
    }
    if let Some(f) = &inf.wall {
        out.push(phrase(
            "building:colour",
            f.value
                .css_name()
                .map_or_else(|| f.value.to_hex(), str::to_string),
            f,
        ));
    }
    if let Some(f) = &inf.roof_colour {
        out.push(phrase(
            "roof:colour",
            f.value
                .css_name()
                .map_or_else(|| f.value.to_hex(), str::to_string),
            f,
        ));
    }
    out
}

/// Sets the inferred values as the lots' tags (a new shared tag set per lot changed) and
/// returns the report notes, one per lot changed: (lot index, text).
pub fn apply(lots: &mut [Lot], inferred: &[Inferred]) -> Vec<(usize, String)> {
    let mut notes = Vec::new();
    // Lots given the same values share one tag set (issue 46: a copy a lot was ~0.5 KB over
    // every lot the neighbours changed, held through the estimator's peak).
    let interner = crate::input::TagInterner::default();
    for (i, (lot, inf)) in lots.iter_mut().zip(inferred).enumerate() {
        if !inf.any() {
            continue;
        }
        let mut tags = (*lot.tags).clone();
        if let Some(f) = inf.levels {
            tags.levels = Some(f.value);
        }
        if let Some(f) = inf.roof {
            tags.roof_shape = Some(f.value);
        }
        if let Some(f) = inf.wall {
            tags.colour = Some(f.value);
        }
        if let Some(f) = inf.roof_colour {
            tags.roof_colour = Some(f.value);
        }
        lot.tags = interner.intern(tags);
        notes.push((i, describe(inf).join("; ")));
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
            drawn: None,
            rest_tags: None,
            lonlat: (0.0, 0.0),
            front: None,
            ground: 0.0,
            terrain: None,
        }
    }

    fn with(mut l: Lot, f: impl FnOnce(&mut BuildingTags)) -> Lot {
        let mut t = (*l.tags).clone();
        f(&mut t);
        l.tags = std::sync::Arc::new(t);
        l
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
        assert_eq!(got.value, 6.0);
        assert_eq!(got.neighbours, 3, "the house is another kind");
        assert_eq!(inf[5], None, "no tagged neighbour within the radius");
        let all = infer(&lots, |_| Inference::ALL, InferOptions::default());
        let notes = apply(&mut lots, &all);
        assert_eq!(notes.len(), 1);
        assert!(notes[0].1.starts_with("building:levels 6 inferred from 3"));
        assert_eq!(lots[2].tags.levels, Some(6.0));
        assert_eq!(lots[0].tags.levels, Some(5.0));
    }

    #[test]
    fn too_few_neighbours_infer_nothing() {
        let lots = vec![
            lot(1, 0.0, Some(5.0), "yes"),
            lot(2, 20.0, None, "yes"),
            lot(3, 40.0, Some(3.0), "yes"),
            lot(4, 60.0, Some(4.0), "yes"),
        ];
        let o = InferOptions::default();
        assert_eq!(infer_levels(&lots[..3], o)[1], None, "two neighbours");
        assert_eq!(
            infer_levels(&lots, o)[1].map(|f| f.value),
            Some(4.0),
            "the weighted median of three"
        );
    }

    #[test]
    fn a_height_counts_as_storeys_of_three_metres() {
        let lots = vec![
            with(lot(1, 0.0, None, "yes"), |t| t.height = Some(12.0)),
            with(lot(2, 10.0, None, "yes"), |t| t.height = Some(13.0)),
            with(lot(3, 30.0, None, "yes"), |t| t.height = Some(11.0)),
            lot(4, 20.0, None, "yes"),
        ];
        let inf = infer_levels(&lots, InferOptions::default());
        assert_eq!(inf[3].map(|f| f.value), Some(4.0));
        assert_eq!(inf[0], None, "a height is a tag");
    }

    #[test]
    fn roof_shapes_and_colours_follow_a_majority_and_only_where_wanted() {
        let red = Color::from_rgb24(0xaa0000);
        let roofed = |i, x, r: RoofShape| {
            with(lot(i, x, None, "yes"), move |t| {
                t.roof_shape = Some(r);
                t.roof_colour = Some(red);
            })
        };
        let lots = vec![
            roofed(1, 0.0, RoofShape::Hipped),
            roofed(2, 10.0, RoofShape::Hipped),
            roofed(3, 30.0, RoofShape::Flat),
            lot(4, 20.0, Some(2.0), "yes"),
            lot(5, 40.0, Some(2.0), "yes"),
        ];
        let roof_only = Inference {
            roof: true,
            ..Inference::NONE
        };
        let inf = infer(
            &lots,
            |i| if i == 3 { roof_only } else { Inference::NONE },
            InferOptions::default(),
        );
        let r = inf[3].roof.unwrap();
        assert_eq!(r.value, RoofShape::Hipped);
        assert!(r.agree > 0.5 && r.agree < 1.0, "{}", r.agree);
        assert_eq!(inf[3].roof_colour, None, "colours not wanted");
        assert!(!inf[4].any(), "nothing wanted for lot 5");
        let all = infer(&lots, |_| Inference::ALL, InferOptions::default());
        assert_eq!(all[4].roof_colour.map(|f| f.value), Some(red));
        // An even split is no majority at 0.5 + ε.
        let strict = InferOptions {
            majority: 0.99,
            ..Default::default()
        };
        assert_eq!(infer(&lots, |_| Inference::ALL, strict)[3].roof, None);
    }
}
