//! The joint distribution of roof shapes and storeys: fitted to the marginals, merged into at
//! most so many bins, rounded to probabilities.

use std::collections::BTreeMap;

use super::format::num;
use super::Joint;
use crate::model::RoofShape;

/// A roof shape as a key: its OSM name; `""` for none.
pub(super) fn roof_key(r: Option<RoofShape>) -> &'static str {
    r.map_or("", RoofShape::osm_name)
}

/// Fits `seed` (rows: storeys, columns: roofs; counts) to the two marginals by iterative
/// proportional fitting. A thousandth of a sample's worth of the product of the marginals is
/// added to the seed first, so that every combination is possible and the fit exists (a
/// storeys value seen only on buildings without a roof tag still gets the roof distribution);
/// combinations left under [`MIN_MASS`] are dropped.
pub(super) fn fit_joint(
    seed: &BTreeMap<(u32, &'static str), f64>,
    rows: &BTreeMap<u32, f64>,
    cols: &BTreeMap<&'static str, f64>,
) -> Joint {
    let r: Vec<(u32, f64)> = rows.iter().map(|(k, v)| (*k, *v)).collect();
    let c: Vec<(&'static str, f64)> = cols.iter().map(|(k, v)| (*k, *v)).collect();
    let mut m: Vec<Vec<f64>> = r
        .iter()
        .map(|(s, ps)| {
            c.iter()
                .map(|(roof, pr)| seed.get(&(*s, *roof)).copied().unwrap_or(0.0) + 1e-3 * ps * pr)
                .collect()
        })
        .collect();
    for _ in 0..1000 {
        for (row, (_, p)) in m.iter_mut().zip(&r) {
            let sum: f64 = row.iter().sum();
            if sum > 0.0 {
                row.iter_mut().for_each(|x| *x *= p / sum);
            }
        }
        let mut worst: f64 = 0.0;
        for (j, (_, p)) in c.iter().enumerate() {
            let sum: f64 = m.iter().map(|row| row[j]).sum();
            if sum > 0.0 {
                m.iter_mut().for_each(|row| row[j] *= p / sum);
            }
            worst = worst.max((sum - p).abs());
        }
        if worst < 1e-12 {
            break;
        }
    }
    let mut out = Joint::new();
    let total: f64 = m.iter().flatten().sum();
    for (row, (s, _)) in m.iter().zip(&r) {
        for (x, (roof, _)) in row.iter().zip(&c) {
            if total > 0.0 && x / total >= MIN_MASS {
                out.insert((*roof, *s), x / total);
            }
        }
    }
    normalise(out)
}

/// The least mass of a fitted combination: half the smallest proba written (0.0001).
const MIN_MASS: f64 = 5e-5;

/// One appearance before writing: a roof key, a storeys range (0..=0 for none) and its mass.
#[derive(Clone, Debug, PartialEq)]
pub(super) struct Bin {
    pub(super) roof: &'static str,
    pub(super) lo: u32,
    pub(super) hi: u32,
    pub(super) mass: f64,
}

/// The L1 error of a bin drawn uniformly over its range against the joint.
fn bin_cost(b: &Bin, joint: &Joint) -> f64 {
    let w = f64::from(b.hi - b.lo + 1);
    (b.lo..=b.hi)
        .map(|s| (joint.get(&(b.roof, s)).copied().unwrap_or(0.0) - b.mass / w).abs())
        .sum()
}

/// At most `max` bins for `joint`: one per combination, then greedily the cheapest step (in
/// added L1 error) of merging two neighbouring storeys bins of one roof, or folding a roof that
/// has one bin into the nearest bin of the most common other roof. Returns the bins (by roof,
/// then storeys) and what was merged, for the comment.
pub(super) fn merge_bins(joint: &Joint, max: usize) -> (Vec<Bin>, Vec<String>) {
    let mut bins: Vec<Bin> = joint
        .iter()
        .map(|(&(roof, s), &mass)| Bin {
            roof,
            lo: s,
            hi: s,
            mass,
        })
        .collect();
    let combinations = bins.len();
    let mut folded: Vec<String> = Vec::new();
    // Each bin's error, and the error a merge of bins k and k + 1 (same roof) would add: only
    // the neighbours of a merge change, so a step costs a scan of the bins.
    let merge_delta = |bins: &[Bin], cost: &[f64], k: usize| -> Option<f64> {
        let (a, b) = (bins.get(k)?, bins.get(k + 1)?);
        if a.roof != b.roof {
            return None;
        }
        let m = Bin {
            roof: a.roof,
            lo: a.lo,
            hi: b.hi,
            mass: a.mass + b.mass,
        };
        Some(bin_cost(&m, joint) - cost[k] - cost[k + 1])
    };
    let mut cost: Vec<f64> = bins.iter().map(|b| bin_cost(b, joint)).collect();
    let all_deltas = |bins: &[Bin], cost: &[f64]| -> Vec<Option<f64>> {
        (0..bins.len().saturating_sub(1))
            .map(|k| merge_delta(bins, cost, k))
            .collect()
    };
    let mut delta = all_deltas(&bins, &cost);
    while bins.len() > max.max(1) {
        // (added error, merge k with k + 1 | fold k)
        let mut best: Option<(f64, usize, bool)> = None;
        for (k, d) in delta.iter().enumerate() {
            if let Some(d) = *d {
                if best.is_none_or(|(e, _, _)| d < e) {
                    best = Some((d, k, false));
                }
            }
        }
        let roofs: BTreeMap<&str, (usize, f64)> =
            bins.iter().fold(BTreeMap::new(), |mut acc, b| {
                let e = acc.entry(b.roof).or_insert((0, 0.0));
                e.0 += 1;
                e.1 += b.mass;
                acc
            });
        if roofs.len() > 1 {
            for (k, b) in bins.iter().enumerate() {
                if roofs.get(b.roof).is_some_and(|r| r.0 == 1) {
                    let d = 2.0 * b.mass - cost[k];
                    if best.is_none_or(|(e, _, _)| d < e) {
                        best = Some((d, k, true));
                    }
                }
            }
        }
        let Some((_, k, fold)) = best else { break };
        if !fold {
            let b = bins.remove(k + 1);
            cost.remove(k + 1);
            delta.remove(k);
            bins[k].hi = b.hi;
            bins[k].mass += b.mass;
            cost[k] = bin_cost(&bins[k], joint);
            if k > 0 {
                delta[k - 1] = merge_delta(&bins, &cost, k - 1);
            }
            if k < delta.len() {
                delta[k] = merge_delta(&bins, &cost, k);
            }
            continue;
        }
        let gone = bins.remove(k);
        // The most common other roof (ties: the first by name), its bin nearest in storeys.
        let mut target_roof: Option<(&str, f64)> = None;
        for (r, (_, m)) in &roofs {
            if *r != gone.roof && target_roof.is_none_or(|(_, tm)| *m > tm) {
                target_roof = Some((r, *m));
            }
        }
        let Some((tr, _)) = target_roof else { break };
        let gap = |b: &Bin| {
            if b.hi < gone.lo {
                gone.lo - b.hi
            } else {
                b.lo.saturating_sub(gone.hi)
            }
        };
        let Some(t) = (0..bins.len())
            .filter(|&i| bins[i].roof == tr)
            .min_by_key(|&i| (gap(&bins[i]), i))
        else {
            break;
        };
        bins[t].mass += gone.mass;
        folded.push(format!(
            "roof {} ({} %) folded into {}",
            if gone.roof.is_empty() {
                "untagged"
            } else {
                gone.roof
            },
            num(100.0 * gone.mass, 1),
            tr
        ));
        // Rare: everything again.
        cost = bins.iter().map(|b| bin_cost(b, joint)).collect();
        delta = all_deltas(&bins, &cost);
    }
    let mut notes = Vec::new();
    if bins.len() < combinations {
        let ranges = bins.iter().filter(|b| b.hi > b.lo).count();
        notes.push(format!(
            "{} appearances from {combinations} (storeys, roof) combinations: {ranges} merge \
             neighbouring storeys into a range drawn uniformly{}",
            bins.len(),
            if folded.is_empty() {
                String::new()
            } else {
                format!("; {}", folded.join("; "))
            }
        ));
    }
    (bins, notes)
}

/// Probabilities in units of 1/10,000 summing to exactly 10,000 (largest remainders; ties to
/// the first).
pub(super) fn round_probas(masses: &[f64]) -> Vec<u32> {
    const UNITS: f64 = 10_000.0;
    let total: f64 = masses.iter().sum();
    if masses.is_empty() || total <= 0.0 {
        return vec![0; masses.len()];
    }
    let exact: Vec<f64> = masses.iter().map(|m| m / total * UNITS).collect();
    let mut units: Vec<u32> = exact.iter().map(|x| x.floor() as u32).collect();
    let short = 10_000u32.saturating_sub(units.iter().sum());
    let mut order: Vec<usize> = (0..masses.len()).collect();
    order.sort_by(|&a, &b| {
        let fa = exact[a] - exact[a].floor();
        let fb = exact[b] - exact[b].floor();
        fb.total_cmp(&fa).then(a.cmp(&b))
    });
    for &i in order.iter().cycle().take(short as usize) {
        units[i] += 1;
    }
    units
}

pub(super) fn normalise<K: Ord>(m: BTreeMap<K, f64>) -> BTreeMap<K, f64> {
    let total: f64 = m.values().sum();
    if total <= 0.0 {
        return m;
    }
    m.into_iter().map(|(k, v)| (k, v / total)).collect()
}
