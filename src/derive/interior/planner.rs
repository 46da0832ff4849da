//! The storey planner: stair core, corridor and units, each unit's programme laid out by a
//! weighted treemap, and the clean-up of the pieces into simple rooms (steps 3-6 of the
//! algorithm in [`super`]).

use super::*;

/// A corridor along `axis` between `lo` and `hi` on the other axis.
#[derive(Clone, Copy, Debug)]
pub(super) struct Spine {
    pub(super) axis: Axis,
    pub(super) lo: f64,
    pub(super) hi: f64,
}

/// A room in the making (frame coordinates).
#[derive(Clone, Debug)]
pub(super) struct Proto {
    pub(super) kind: RoomKind,
    pub(super) name: String,
    pub(super) unit: Option<usize>,
    pub(super) min_area: Option<f64>,
    pub(super) poly: Polygon,
}

pub(super) struct Planner {
    pub(super) usable: Polygon,
    pub(super) region: GMulti,
    pub(super) programme: Programme,
    pub(super) stair: Option<StairCore>,
    pub(super) spine: Option<Spine>,
}

pub(super) use crate::geometry::ring_perimeter as perimeter;

/// Ring bounds (min, max).
pub(super) fn ring_bounds(r: &[DVec2]) -> (DVec2, DVec2) {
    r.iter().fold(
        (DVec2::splat(f64::INFINITY), DVec2::splat(f64::NEG_INFINITY)),
        |(lo, hi), p| (lo.min(*p), hi.max(*p)),
    )
}

impl Planner {
    /// A corridor for large storeys of multi-unit programmes.
    pub(super) fn spine_for(&self) -> Option<Spine> {
        if !matches!(
            self.programme,
            Programme::Apartments | Programme::Office | Programme::Retail
        ) {
            return None;
        }
        let (lo, hi) = self.usable.bounds();
        let ext = hi - lo;
        if self.usable.area() < 150.0 || ext.x < 9.0 || ext.y < 9.0 {
            return None;
        }
        // The corridor runs along the longer extent; it sits on the line that halves the area.
        let (axis, across) = if ext.x >= ext.y {
            (Axis::X, Axis::Y)
        } else {
            (Axis::Y, Axis::X)
        };
        let c = geom::cut_at_fraction(&self.region, across, 0.5);
        let w = if self.programme == Programme::Office {
            1.6
        } else {
            1.4
        };
        Some(Spine {
            axis,
            lo: c - 0.5 * w,
            hi: c + 0.5 * w,
        })
    }

    /// Finds the stair core: the first form that fits, nearest to the target point.
    pub(super) fn place_stair(&self, height: f64) -> Option<StairCore> {
        let risers = ((height / 0.18).ceil() as u32).clamp(3, 120);
        let going = 0.27;
        let fw = if self.programme == Programme::House {
            0.9
        } else {
            1.2
        };
        let half = risers.div_ceil(2) as f64;
        let forms = [
            (
                StairForm::DogLeg,
                DVec2::new(2.0 * fw + 0.1, half * going + fw),
            ),
            (
                StairForm::Straight,
                DVec2::new(fw, risers as f64 * going + 0.3),
            ),
            (StairForm::Spiral, DVec2::new(1.6, 1.6)),
        ];
        let (lo, hi) = self.usable.bounds();
        let centroid = {
            let c = geo::Centroid::centroid(&self.region);
            c.map_or(0.5 * (lo + hi), |p| DVec2::new(p.x(), p.y()))
        };
        for (form, size) in forms {
            let mut best: Option<(f64, DVec2, DVec2)> = None;
            for dims in [size, DVec2::new(size.y, size.x)] {
                // Target: beside the corridor (on its far side), else the centroid.
                let target_lo = match self.spine {
                    Some(s) if s.axis == Axis::X => DVec2::new(centroid.x - 0.5 * dims.x, s.hi),
                    Some(s) => DVec2::new(s.hi, centroid.y - 0.5 * dims.y),
                    None => centroid - 0.5 * dims,
                };
                if let Some(p) = self.nearest_fit(target_lo, dims, lo, hi) {
                    let d = p.distance(target_lo);
                    if best.is_none_or(|b| d < b.0) {
                        best = Some((d, p, dims));
                    }
                }
            }
            if let Some((_, p, dims)) = best {
                let q = p + dims;
                let polygon = Polygon::new(
                    vec![p, DVec2::new(q.x, p.y), q, DVec2::new(p.x, q.y)],
                    vec![],
                );
                let up = if dims.y >= dims.x { DVec2::Y } else { DVec2::X };
                return Some(StairCore {
                    polygon,
                    form,
                    flight_width: if form == StairForm::Spiral { 0.7 } else { fw },
                    risers,
                    riser_height: height / risers as f64,
                    going,
                    up,
                });
            }
        }
        None
    }

    /// The grid position (lower corner) nearest `target` where a `dims` rectangle fits.
    pub(super) fn nearest_fit(
        &self,
        target: DVec2,
        dims: DVec2,
        lo: DVec2,
        hi: DVec2,
    ) -> Option<DVec2> {
        if dims.x > hi.x - lo.x || dims.y > hi.y - lo.y {
            return None;
        }
        let ext = (hi - lo).max_element();
        let step = (ext / 60.0).max(0.25);
        let axis_positions = |t: f64, a: f64, b: f64| -> Vec<f64> {
            // Positions t + k*step within [a, b], plus the two ends.
            let mut v = vec![a, b];
            let k0 = ((a - t) / step).ceil() as i64;
            let k1 = ((b - t) / step).floor() as i64;
            for k in k0.max(-400)..=k1.min(400) {
                v.push(t + k as f64 * step);
            }
            v
        };
        let xs = axis_positions(target.x, lo.x, hi.x - dims.x);
        let ys = axis_positions(target.y, lo.y, hi.y - dims.y);
        let mut cand: Vec<(f64, DVec2)> = Vec::with_capacity(xs.len() * ys.len());
        for &x in &xs {
            for &y in &ys {
                let p = DVec2::new(x, y);
                cand.push((p.distance_squared(target), p));
            }
        }
        cand.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.x.total_cmp(&b.1.x)));
        cand.into_iter()
            .map(|c| c.1)
            .find(|p| geom::rect_inside(&self.usable, *p, *p + dims))
    }

    /// The room list of a single-unit storey (or of a house storey).
    pub(super) fn storey_items(
        &self,
        level: usize,
        levels: usize,
        house_t: Option<usize>,
    ) -> Vec<Item> {
        match self.programme {
            Programme::House => {
                let t = house_t;
                let part = if levels == 1 {
                    DwellingPart::Whole
                } else if level == 0 {
                    DwellingPart::Ground
                } else {
                    let x = t.unwrap_or(0);
                    let uppers = levels - 1;
                    let per = x.div_ceil(uppers.max(1));
                    let first = ((level - 1) * per).min(x);
                    DwellingPart::Upper {
                        first,
                        count: per.min(x - first),
                    }
                };
                programme::dwelling(t, part, "")
            }
            _ => Vec::new(),
        }
    }

    /// The storey's usable region without the stair.
    pub(super) fn free_region(&self) -> GMulti {
        match &self.stair {
            Some(s) => self
                .region
                .difference(&GMulti::new(vec![geom::to_geo(&s.polygon)])),
            None => self.region.clone(),
        }
    }

    /// Lays out one storey; `None` when the result fails its own checks.
    pub(super) fn layout(
        &self,
        level: usize,
        house_items: &[Item],
        rng: &mut Rng,
    ) -> Option<StoreyPlan> {
        let free = self.free_region();
        let free_area = geom::garea(&free);
        let mut leaves: Vec<(Item, Option<usize>, GMulti)> = Vec::new();
        if let Some(sp) = self.spine {
            self.spine_layout(level, sp, &free, rng, &mut leaves);
        } else {
            let mut items: Vec<Item> = match self.programme {
                Programme::House => house_items.to_vec(),
                _ => self.unit_items(free_area, "", rng),
            };
            programme::distribute(&mut items, free_area, rng);
            let areas: Vec<f64> = items.iter().map(|i| i.area).collect();
            let parts = treemap(&free, &areas, None);
            for (it, g) in items.into_iter().zip(parts) {
                leaves.push((it, None, g));
            }
        }
        let mut protos = explode(leaves);
        if let Some(s) = &self.stair {
            protos.push(Proto {
                kind: RoomKind::Stair,
                name: "Stair".into(),
                unit: None,
                min_area: None,
                poly: s.polygon.clone(),
            });
        }
        finish(&self.usable, protos, level == 0)
    }

    /// Items for one unit (or a single-unit storey) of the non-house programmes.
    pub(super) fn unit_items(&self, area: f64, unit: &str, _rng: &mut Rng) -> Vec<Item> {
        let mk = |kind: RoomKind, name: String, w: f64| programme::item(kind, name, w);
        let pre = |s: &str| {
            if unit.is_empty() {
                s.to_string()
            } else {
                format!("{unit} {s}")
            }
        };
        if area < 12.0 {
            let kind = match self.programme {
                Programme::Office => RoomKind::Office,
                Programme::Retail => RoomKind::Shop,
                Programme::Apartments | Programme::House => RoomKind::Living,
                Programme::OpenPlan => RoomKind::OpenPlan,
            };
            return vec![mk(kind, pre(kind.label()), 1.0)];
        }
        match self.programme {
            Programme::Apartments | Programme::House => {
                programme::dwelling(typology(area), DwellingPart::Whole, unit)
            }
            Programme::Office => {
                let n = ((area / 16.0).round() as usize).clamp(1, 8);
                let mut v = vec![mk(RoomKind::Hall, pre("Reception"), 1.0)];
                for i in 0..n {
                    v.push(mk(RoomKind::Office, pre(&format!("Office {}", i + 1)), 1.5));
                }
                v.push(mk(RoomKind::Wc, pre("WC"), 0.2));
                v
            }
            Programme::Retail => {
                let mut v = vec![
                    mk(RoomKind::Shop, pre("Shop"), 5.0),
                    mk(RoomKind::Storage, pre("Storage"), 0.8),
                ];
                if area >= 40.0 {
                    v.push(mk(RoomKind::Wc, pre("WC"), 0.2));
                }
                v
            }
            Programme::OpenPlan => vec![mk(RoomKind::OpenPlan, pre("Open plan"), 1.0)],
        }
    }

    /// Corridor, entrance hall and units cut across the corridor.
    pub(super) fn spine_layout(
        &self,
        level: usize,
        sp: Spine,
        free: &GMulti,
        rng: &mut Rng,
        leaves: &mut Vec<(Item, Option<usize>, GMulti)>,
    ) {
        let across = match sp.axis {
            Axis::X => Axis::Y,
            Axis::Y => Axis::X,
        };
        let corridor = geom::band(free, across, sp.lo, sp.hi);
        let (low, _) = geom::split(free, across, sp.lo);
        let (_, high) = geom::split(free, across, sp.hi);
        let mut low = low;
        if level == 0 && sp.axis == Axis::X {
            // An entrance hall from the front to the corridor, in line with the stair.
            let (blo, _) = self.usable.bounds();
            let cx = self.stair.as_ref().map_or_else(
                || {
                    let (a, b) = geom::gbounds(free);
                    0.5 * (a.x + b.x)
                },
                |s| {
                    let (a, b) = ring_bounds(&s.polygon.outer);
                    0.5 * (a.x + b.x)
                },
            );
            let r = geom::rect(
                DVec2::new(cx - 1.0, blo.y - 1.0),
                DVec2::new(cx + 1.0, sp.lo),
            );
            let hall = low.intersection(&GMulti::new(vec![r]));
            if geom::garea(&hall) > 1.0 {
                low = low.difference(&hall);
                leaves.push((
                    programme::item(RoomKind::Hall, "Entrance hall".into(), 1.0),
                    None,
                    hall,
                ));
            }
        }
        leaves.push((
            programme::item(RoomKind::Corridor, "Corridor".into(), 1.0),
            None,
            corridor,
        ));
        let target = match self.programme {
            Programme::Office => 18.0,
            Programme::Retail => 60.0,
            _ => 85.0,
        };
        let mut unit_no = 0usize;
        let mut cells: Vec<(Item, Option<usize>, GMulti)> = Vec::new();
        for side in [low, high] {
            for piece in side.0 {
                let piece = GMulti::new(vec![piece]);
                let a = geom::garea(&piece);
                if a < 1e-6 {
                    continue;
                }
                let n = ((a / target).round() as usize).max(1);
                let weights: Vec<f64> = (0..n).map(|_| rng.range(0.85, 1.15)).collect();
                let units = treemap(&piece, &weights, Some(sp.axis));
                for u in units {
                    let ua = geom::garea(&u);
                    if ua < 1e-6 {
                        continue;
                    }
                    unit_no += 1;
                    match self.programme {
                        Programme::Apartments | Programme::House => {
                            let label = format!("Flat {unit_no}");
                            let mut items = self.unit_items(ua, &label, rng);
                            programme::distribute(&mut items, ua, rng);
                            let areas: Vec<f64> = items.iter().map(|i| i.area).collect();
                            let parts = treemap(&u, &areas, None);
                            for (it, g) in items.into_iter().zip(parts) {
                                leaves.push((it, Some(unit_no), g));
                            }
                        }
                        Programme::Office => cells.push((
                            programme::item(RoomKind::Office, format!("Office {unit_no}"), 1.0),
                            Some(unit_no),
                            u,
                        )),
                        _ => {
                            let kind = if self.programme == Programme::Retail {
                                RoomKind::Shop
                            } else {
                                RoomKind::OpenPlan
                            };
                            leaves.push((
                                programme::item(kind, format!("{} {unit_no}", kind.label()), 1.0),
                                Some(unit_no),
                                u,
                            ))
                        }
                    }
                }
            }
        }
        // The smallest office cell is the storey's WC.
        if let Some(i) = (0..cells.len())
            .min_by(|a, b| geom::garea(&cells[*a].2).total_cmp(&geom::garea(&cells[*b].2)))
        {
            if cells.len() > 2 {
                cells[i].0 = programme::item(RoomKind::Wc, "WC".into(), 1.0);
                cells[i].1 = None;
            }
        }
        leaves.extend(cells);
    }

    /// The fallback storey: the usable polygon (minus the stair) cut at its holes into open
    /// rooms, with doors.
    pub(super) fn simple_storey(&self, ground: bool) -> StoreyPlan {
        let free = self.free_region();
        let kind = match self.programme {
            Programme::Apartments | Programme::House => RoomKind::Living,
            Programme::Office => RoomKind::Office,
            Programme::Retail => RoomKind::Shop,
            Programme::OpenPlan => RoomKind::OpenPlan,
        };
        let mut protos = explode(vec![(
            programme::item(kind, kind.label().into(), 1.0),
            None,
            free,
        )]);
        if let Some(s) = &self.stair {
            protos.push(Proto {
                kind: RoomKind::Stair,
                name: "Stair".into(),
                unit: None,
                min_area: None,
                poly: s.polygon.clone(),
            });
        }
        finish(&self.usable, protos.clone(), ground).unwrap_or_else(|| {
            // Even the graph failed: rooms without doors (reported by the checks).
            let (rooms, stair_room) = to_rooms(protos);
            StoreyPlan {
                rooms,
                walls: Vec::new(),
                doors: Vec::new(),
                entrance: None,
                stair_room,
            }
        })
    }
}

/// Weighted treemap of `region` into one piece per weight, in order (seeds 002/004 §3.3, with
/// bisection): the list is split where its weight halves, the region is cut perpendicular to
/// its longer extent (or across `fixed`'s lines) so that the area below the cut matches the
/// first group's share, and both sides recurse.
pub(super) fn treemap(region: &GMulti, weights: &[f64], fixed: Option<Axis>) -> Vec<GMulti> {
    let n = weights.len();
    if n == 0 {
        return Vec::new();
    }
    if n == 1 {
        return vec![region.clone()];
    }
    let w: Vec<f64> = weights
        .iter()
        .map(|x| if x.is_finite() && *x > 0.0 { *x } else { 1e-6 })
        .collect();
    let total: f64 = w.iter().sum();
    let mut k = 1;
    let mut acc = w[0];
    let mut best = ((acc - 0.5 * total).abs(), 1);
    for (i, x) in w.iter().enumerate().take(n - 1).skip(1) {
        acc += x;
        let d = (acc - 0.5 * total).abs();
        if d < best.0 {
            best = (d, i + 1);
        }
    }
    k = k.max(best.1);
    let frac = w[..k].iter().sum::<f64>() / total;
    let (lo, hi) = geom::gbounds(region);
    if !(lo.is_finite() && hi.is_finite()) {
        return vec![GMulti::new(Vec::new()); n];
    }
    let axis = fixed.unwrap_or(if hi.x - lo.x >= hi.y - lo.y {
        Axis::X
    } else {
        Axis::Y
    });
    let t = geom::cut_at_fraction(region, axis, frac);
    let (a, b) = geom::split(region, axis, t);
    let mut out = treemap(&a, &w[..k], fixed);
    out.extend(treemap(&b, &w[k..], fixed));
    out
}

/// Each leaf's pieces become rooms (the largest keeps the name; the others are named as parts),
/// cleaned and cut at their holes until simple.
pub(super) fn explode(leaves: Vec<(Item, Option<usize>, GMulti)>) -> Vec<Proto> {
    let mut out = Vec::new();
    for (it, unit, g) in leaves {
        let mut pieces: Vec<Polygon> =
            g.0.iter()
                .map(geom::from_geo)
                .filter(|p| p.outer.len() >= 3 && p.area() > 1e-6)
                .flat_map(|p| simple_pieces(p, 0))
                .filter(|p| p.outer.len() >= 3 && p.area() > 1e-6)
                .collect();
        pieces.sort_by(|a, b| b.area().total_cmp(&a.area()));
        for (i, p) in pieces.into_iter().enumerate() {
            out.push(Proto {
                kind: it.kind,
                name: if i == 0 {
                    it.name.clone()
                } else {
                    format!("{} ({})", it.name, i + 1)
                },
                unit,
                min_area: if i == 0 { it.min_area } else { None },
                poly: p,
            });
        }
    }
    out
}

/// The simple pieces of a polygon: cut through its holes ([`split_holes`]), then each piece's
/// ring cut where it touches itself ([`geom::simple_parts`]); a hole pinched onto the ring
/// becomes a hole of the piece around it and is cut through in turn.
pub(super) fn simple_pieces(p: Polygon, depth: usize) -> Vec<Polygon> {
    let mut out = Vec::new();
    for q in split_holes(p, 0) {
        let (outers, pinched) = geom::simple_parts(&q.outer);
        for o in outers {
            let holes: Vec<Vec<DVec2>> = pinched
                .iter()
                .filter(|h| {
                    let c = h.iter().copied().sum::<DVec2>() / h.len() as f64;
                    crate::geometry::ring_contains(&o, c)
                })
                .map(|h| h.iter().rev().copied().collect())
                .collect();
            if holes.is_empty() || depth >= 4 {
                out.push(Polygon::new(o, Vec::new()));
            } else {
                out.extend(simple_pieces(Polygon::new(o, holes), depth + 1));
            }
        }
    }
    out
}

/// Cuts a polygon through the middle of its first hole (across the hole's longer extent) until
/// no piece has a hole.
pub(super) fn split_holes(p: Polygon, depth: usize) -> Vec<Polygon> {
    if p.holes.is_empty() || depth > 12 {
        return vec![p];
    }
    let (lo, hi) = ring_bounds(&p.holes[0]);
    let (axis, t) = if hi.x - lo.x >= hi.y - lo.y {
        (Axis::X, 0.5 * (lo.x + hi.x))
    } else {
        (Axis::Y, 0.5 * (lo.y + hi.y))
    };
    let (a, b) = geom::split(&GMulti::new(vec![geom::to_geo(&p)]), axis, t);
    a.0.iter()
        .chain(b.0.iter())
        .map(geom::from_geo)
        .filter(|q| q.outer.len() >= 3 && q.area() > 1e-6)
        .flat_map(|q| split_holes(q, depth + 1))
        .collect()
}
