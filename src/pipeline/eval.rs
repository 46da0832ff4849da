//! `citygen eval`: the truth benchmark of the height and roof estimator (issue 42, step 6),
//! and the offline fit of its shipped models.
//!
//! A case is an input (OSM or shapefile) and, optionally, a truth file (`id,height_m,roof`,
//! as `scripts/truth_corpus.py` writes it: measured city models, footprints only). With a
//! truth file every tag of height, storeys and roof is removed and the estimates are compared
//! with the truth; the baseline draws every building at the city's own median height and the
//! majority roof family. Without one, the input's own tags are hidden fold by fold (a
//! `1/folds` share at a time, chosen by a hash of the id and the seed) and the estimates of
//! the hidden buildings, made from the rest, are compared with their tags; the baseline is the
//! median (and majority) of the tags left visible.
//!
//! `--save-model DIR` fits the shipped models on every case's rows (truth, or tags), at most
//! [`ROWS_PER_CASE`] a case so that one large city does not outweigh the others;
//! `--loco` first measures each case with models fitted on the others only (what a city
//! nobody fitted on sees).

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use rayon::prelude::*;

use super::{read_source, RunError, Source};
use crate::kb::KnowledgeBase;
use crate::model::{Inference, RoofShape, SourceId};
use crate::prepare::{self, estimate, gbt, morph, Lot};
use crate::report::Report;

/// The most rows one case gives the shipped models' fit.
pub const ROWS_PER_CASE: usize = 1500;

/// One input of the benchmark.
#[derive(Clone, Debug)]
pub struct Case {
    /// The footprints.
    pub source: Source,
    /// Measured truth (`id,height_m,roof,...` CSV), or `None` to hide the input's own tags.
    pub truth: Option<PathBuf>,
}

/// One measure of one case.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct Score {
    /// Buildings compared.
    pub n: usize,
    /// Mean absolute error of the estimates (metres, storeys, or share of roofs wrong).
    pub error: f64,
    /// The same for the baseline (a constant at the median; the majority roof family).
    pub baseline: f64,
    /// Share of storey counts exactly right (storeys only).
    pub exact: Option<f64>,
    /// Spearman rank correlation of estimates and truth (heights and storeys).
    pub rank: Option<f64>,
    /// Median of the estimates and of the truth (heights and storeys).
    pub medians: Option<(f64, f64)>,
}

impl Score {
    /// `error / baseline` (1 when the baseline makes no error).
    pub fn ratio(&self) -> f64 {
        if self.baseline > 0.0 {
            self.error / self.baseline
        } else {
            1.0
        }
    }
}

/// What one case measured.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct CaseScore {
    /// The input's path.
    pub name: String,
    /// `truth` or `hidden tags`.
    pub mode: String,
    /// Heights (metres).
    pub height: Option<Score>,
    /// Storeys.
    pub storeys: Option<Score>,
    /// Flat versus pitched.
    pub roof: Option<Score>,
    /// What a run draws for the buildings it estimates (nothing hidden): their plausibility.
    pub form: Option<Form>,
    /// How the compared attached footprints' roofs are drawn (issue 42's terraces).
    pub attached_roofs: Option<AttachedRoofs>,
    /// One CSV line per building compared ([`dump_header`]), for offline analysis.
    #[serde(skip)]
    pub rows: Vec<String>,
}

/// The header of `citygen eval --dump`: the case, the building, its features
/// (the estimator's feature names), its zone's prior, the estimate and the truth (empty when
/// unknown).
pub fn dump_header() -> String {
    let mut h = vec!["case".to_string(), "id".to_string()];
    h.extend(morph::FEATURE_NAMES.iter().map(|s| (*s).to_string()));
    h.extend(
        [
            "zone_storeys",
            "zone_pitched",
            "zone_floor_height",
            "est_height",
            "est_storeys",
            "est_pitched",
            "height",
            "storeys",
            "pitched",
        ]
        .map(String::from),
    );
    h.join(",")
}

/// The plausibility of a run's estimates (issue 42's village checks).
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct Form {
    /// Buildings whose height was estimated (no height or storeys tag).
    pub estimated: usize,
    /// Share of them at 5 storeys or more.
    pub five_plus: f64,
    /// Share of those under 60 m² above 2 storeys.
    pub small_above_two: f64,
    /// Spearman rank correlation of their storeys and footprint areas.
    pub storey_area_rank: f64,
    /// Touching pairs (2 m of wall shared or more) with both roofs estimated.
    pub touching_pairs: usize,
    /// Share of them whose roof families (flat, pitched) differ.
    pub pairs_differing: f64,
    /// Of those pairs, the ones of like size (at most `ROW_AREA_RATIO` of the estimator
    /// apart: members of a row, not a house and its outbuilding).
    pub row_pairs: usize,
    /// Share of the like-sized pairs whose roof families differ (issue 42's terraces).
    pub row_pairs_differing: f64,
}

/// The least share of its walls a footprint shares with touching neighbours to count as attached
/// in [`AttachedRoofs`] (as `prepare::estimate::prior_storeys` counts a row member).
pub const ATTACHED_SHARE: f32 = 0.1;
/// The smallest attached footprint (m²) [`AttachedRoofs`] counts: a row member, not a shed.
pub const ATTACHED_MIN_M2: f64 = 30.0;

/// The compared footprints that are attached ([`ATTACHED_SHARE`] of their walls shared or more)
/// and of [`ATTACHED_MIN_M2`] or more, by their measured (or hidden tagged) roof family: how
/// many, and the share drawn in the other family. Issue 42's terraces: "at most 10 % drawn
/// pitched where the rows are flat" is `flat_drawn_pitched` where the rows are flat.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct AttachedRoofs {
    /// Attached footprints whose roof is flat.
    pub flat: usize,
    /// Share of them drawn pitched.
    pub flat_drawn_pitched: f64,
    /// Attached footprints whose roof is pitched.
    pub pitched: usize,
    /// Share of them drawn flat.
    pub pitched_drawn_flat: f64,
}

impl AttachedRoofs {
    /// From `(truth pitched, drawn pitched)` pairs of attached footprints; `None` without any.
    pub fn of(pairs: &[(bool, bool)]) -> Option<AttachedRoofs> {
        if pairs.is_empty() {
            return None;
        }
        let share = |truth: bool| {
            let of: Vec<bool> = pairs.iter().filter(|p| p.0 == truth).map(|p| p.1).collect();
            let other = of.iter().filter(|&&drawn| drawn != truth).count();
            (of.len(), other as f64 / of.len().max(1) as f64)
        };
        let (flat, flat_drawn_pitched) = share(false);
        let (pitched, pitched_drawn_flat) = share(true);
        Some(AttachedRoofs {
            flat,
            flat_drawn_pitched,
            pitched,
            pitched_drawn_flat,
        })
    }
}

/// [`Form`] of one run's estimates.
fn form(out: &estimate::Outcome) -> Option<Form> {
    let rows: Vec<(f64, f64)> = out
        .estimates
        .iter()
        .zip(&out.features)
        .filter_map(|(e, f)| {
            e.filter(|e| e.height_source != crate::model::ValueSource::Tag)
                .map(|e| (e.storeys, f64::from(f[0]).exp()))
        })
        .collect();
    if rows.is_empty() {
        return None;
    }
    let n = rows.len() as f64;
    let small: Vec<&(f64, f64)> = rows.iter().filter(|r| r.1 < 60.0).collect();
    let area = |i: u32| {
        out.features
            .get(i as usize)
            .map_or(0.0, |f| f64::from(f[0]).exp())
    };
    // (roofs differ, the pair is of like size)
    let pairs: Vec<(bool, bool)> = out
        .touching
        .iter()
        .filter(|p| p.2 >= estimate::ROW_SHARED_M)
        .filter_map(|&(a, b, _)| {
            let roof = |i: u32| {
                out.estimates
                    .get(i as usize)
                    .copied()
                    .flatten()
                    .filter(|e| e.roof_source != crate::model::ValueSource::Tag)
                    .map(|e| e.pitched >= 0.5)
            };
            let (x, y) = (area(a), area(b));
            let like = x.max(y) / x.min(y).max(1.0) <= estimate::ROW_AREA_RATIO;
            Some((roof(a)? != roof(b)?, like))
        })
        .collect();
    let row_roofs: Vec<bool> = pairs.iter().filter(|p| p.1).map(|p| p.0).collect();
    Some(Form {
        touching_pairs: pairs.len(),
        pairs_differing: pairs.iter().filter(|d| d.0).count() as f64 / pairs.len().max(1) as f64,
        row_pairs: row_roofs.len(),
        row_pairs_differing: row_roofs.iter().filter(|d| **d).count() as f64
            / row_roofs.len().max(1) as f64,
        estimated: rows.len(),
        five_plus: rows.iter().filter(|r| r.0 >= 5.0).count() as f64 / n,
        small_above_two: small.iter().filter(|r| r.0 > 2.0).count() as f64
            / small.len().max(1) as f64,
        storey_area_rank: spearman(&rows),
    })
}

/// The benchmark's options.
#[derive(Clone, Debug)]
pub struct EvalOptions {
    /// The cases.
    pub cases: Vec<Case>,
    /// The knowledge base (regional roof priors, storey heights).
    pub kb: Option<PathBuf>,
    /// Folds for hidden tags.
    pub folds: usize,
    /// Chooses the folds.
    pub seed: u64,
    /// Models to use instead of the shipped ones (a folder with `height.gbt`, `roof.gbt`).
    pub model: Option<PathBuf>,
    /// Fit the shipped models on all cases and write them here.
    pub save_model: Option<PathBuf>,
    /// Measure each case with models fitted on the others.
    pub loco: bool,
    /// Fit a model on each input's visible tags, as `prepare::estimate` can (runs do not).
    pub fit: bool,
}

/// One case read and measured once.
struct Loaded {
    name: String,
    kb_zones: Vec<usize>,
    lots: Vec<Lot>,
    truth: Option<HashMap<SourceId, (f64, Option<bool>)>>,
}

/// Runs the benchmark: the scores of every case (with the models given, shipped, or with
/// `loco` fitted on the other cases), having written the models when `save_model` asks.
pub fn run(o: &EvalOptions) -> Result<Vec<CaseScore>, RunError> {
    let mut report = Report::default();
    let kb = super::load_kb(o.kb.as_deref(), &mut report)?;
    let cases: Vec<Loaded> = o
        .cases
        .iter()
        .map(|c| load(&kb, c))
        .collect::<Result<_, _>>()?;
    let given = match &o.model {
        Some(dir) => read_models(dir)?,
        None => estimate::Models::shipped(),
    };
    let mut scores = Vec::new();
    for (k, case) in cases.iter().enumerate() {
        let models = if o.loco {
            let others: Vec<&Loaded> = cases
                .iter()
                .enumerate()
                .filter(|(j, _)| *j != k)
                .map(|(_, c)| c)
                .collect();
            fit_models(&kb, &others)
        } else {
            given.clone()
        };
        scores.push(score(&kb, case, &models, o));
    }
    if let Some(dir) = &o.save_model {
        let all: Vec<&Loaded> = cases.iter().collect();
        let models = fit_models(&kb, &all);
        write_models(dir, &models)?;
    }
    Ok(scores)
}

fn load(kb: &KnowledgeBase, case: &Case) -> Result<Loaded, RunError> {
    let mut report = Report::default();
    let read = read_source(&case.source, None, None, &mut report)?;
    let streets = read.streets.clone();
    let source_crs = read.source_crs;
    // The zones as a run finds them: the input's admin boundaries first.
    let boundaries = crate::kb::BoundaryZones::new(kb, &read.boundaries);
    let mut site = prepare::prepare(read.footprints, source_crs, None, &mut report);
    prepare::assign_fronts(&mut site, &streets, source_crs);
    let name = match &case.source {
        Source::Osm(p) | Source::Shp { path: p, .. } => p.display().to_string(),
    };
    let truth = match &case.truth {
        Some(t) => Some(read_truth(t)?),
        None => None,
    };
    let kb_zones = site
        .lots
        .par_iter()
        .map(|l| kb.locate_with(&boundaries, l.lonlat.0, l.lonlat.1).zone)
        .collect();
    Ok(Loaded {
        name,
        kb_zones,
        lots: site.lots,
        truth,
    })
}

/// Reads a truth CSV: a header naming `id` and `height_m` (and optionally `roof`: `flat` or
/// `pitched`, and `source_id`), one building a line. A building is found by its `id` and,
/// failing that, by its `source_id`: a shapefile whose id column names its records
/// (`feature/N` rather than `shp/<index>`, or a text id such as a GUID, see `input::shp`)
/// still meets its truth rows.
fn read_truth(path: &Path) -> Result<HashMap<SourceId, (f64, Option<bool>)>, RunError> {
    let text = std::fs::read_to_string(path)
        .map_err(|e| RunError::Input(format!("{}: {e}", path.display())))?;
    let mut lines = text.lines();
    let head: Vec<&str> = lines
        .next()
        .unwrap_or("")
        .split(',')
        .map(str::trim)
        .collect();
    let col = |name: &str| head.iter().position(|h| *h == name);
    let (Some(id_col), Some(h_col)) = (col("id"), col("height_m")) else {
        return Err(RunError::Input(format!(
            "{}: the header must name `id` and `height_m`",
            path.display()
        )));
    };
    let roof_col = col("roof");
    let source_col = col("source_id");
    let mut out = HashMap::new();
    let mut aliases = Vec::new();
    for (n, line) in lines.enumerate() {
        let f: Vec<&str> = line.split(',').map(str::trim).collect();
        let bad = || RunError::Input(format!("{}:{}: bad line", path.display(), n + 2));
        let id = f
            .get(id_col)
            .and_then(|s| SourceId::parse(s))
            .ok_or_else(bad)?;
        let Some(h) = f.get(h_col).and_then(|s| s.parse::<f64>().ok()) else {
            continue;
        };
        let roof = roof_col.and_then(|c| match f.get(c).copied() {
            Some("flat") => Some(false),
            Some("pitched") => Some(true),
            _ => None,
        });
        if h.is_finite() && h > 0.0 {
            out.insert(id, (h, roof));
            let source = source_col
                .and_then(|c| f.get(c))
                .filter(|s| !s.is_empty())
                .map(|s| {
                    SourceId::parse(s)
                        .or_else(|| s.parse().ok().map(SourceId::Feature))
                        .unwrap_or_else(|| SourceId::text(s))
                });
            if let Some(s) = source {
                aliases.push((s, (h, roof)));
            }
        }
    }
    // Ids first: a source id never hides another building's id.
    for (s, v) in aliases {
        out.entry(s).or_insert(v);
    }
    Ok(out)
}

/// The lots with their height, storeys and roof tags removed where `hide(i)`.
fn hidden(lots: &[Lot], hide: impl Fn(usize) -> bool) -> Vec<Lot> {
    lots.iter()
        .enumerate()
        .map(|(i, l)| {
            let mut l = l.clone();
            if hide(i) {
                let mut t = (*l.tags).clone();
                t.height = None;
                t.levels = None;
                t.roof_shape = None;
                t.roof_height = None;
                t.roof_levels = None;
                t.provenance = None;
                l.tags = std::sync::Arc::new(t);
            }
            l
        })
        .collect()
}

/// What the truth or the tags say of lot `l`: (height, storeys, pitched).
fn truth_of(case: &Loaded, l: &Lot) -> (Option<f64>, Option<f64>, Option<bool>) {
    match &case.truth {
        Some(t) => match t.get(&l.id) {
            Some((h, r)) => (Some(*h), None, *r),
            None => (None, None, None),
        },
        None => (
            l.tags.height,
            l.tags.levels,
            l.tags.roof_shape.map(|r| r != RoofShape::Flat),
        ),
    }
}

fn fold_of(id: SourceId, seed: u64, folds: usize) -> usize {
    let mut h = seed ^ 0x9E37_79B9_7F4A_7C15;
    h ^= id.seed_value();
    h = h.wrapping_mul(0xBF58_476D_1CE4_E5B9);
    h ^= h >> 31;
    (h % folds.max(1) as u64) as usize
}

/// Pairs (estimate, truth) per measure, and the visible values for the baselines.
#[derive(Default)]
struct Pairs {
    height: Vec<(f64, f64)>,
    storeys: Vec<(f64, f64)>,
    roof: Vec<(bool, bool)>,
    baseline_height: Vec<f64>,
    baseline_storeys: Vec<f64>,
    baseline_roof: Vec<f64>,
}

fn score(
    kb: &KnowledgeBase,
    case: &Loaded,
    models: &estimate::Models,
    o: &EvalOptions,
) -> CaseScore {
    let want = vec![Inference::ALL; case.lots.len()];
    let truths: Vec<_> = case.lots.iter().map(|l| truth_of(case, l)).collect();
    let mut pairs = Pairs::default();
    let mut rows = Vec::new();
    // (truth pitched, drawn pitched) of the compared attached footprints.
    let mut attached = Vec::new();
    let folds = if case.truth.is_some() {
        1
    } else {
        o.folds.max(2)
    };
    for fold in 0..folds {
        let hide =
            |i: usize| case.truth.is_some() || fold_of(case.lots[i].id, o.seed, folds) == fold;
        let lots = hidden(&case.lots, hide);
        let mixes = super::roof_mixes(kb, &lots, &case.kb_zones);
        let out = estimate::estimate(&lots, &mixes, &want, models, o.fit);
        let mut base = (Vec::new(), Vec::new(), Vec::new());
        for (i, (h, s, r)) in truths.iter().enumerate() {
            if hide(i) {
                let Some(e) = out.estimates[i] else { continue };
                if h.is_some() || s.is_some() || r.is_some() {
                    let opt = |v: Option<f64>| v.map_or(String::new(), |v| format!("{v:.3}"));
                    let mut line = vec![case.name.clone(), case.lots[i].id.to_string()];
                    line.extend(out.features[i].iter().map(|v| format!("{v:.4}")));
                    let mix = mixes
                        .get(i)
                        .copied()
                        .unwrap_or(crate::model::RoofMix::DEFAULT);
                    line.extend([
                        format!("{}", mix.storeys),
                        format!("{:.3}", mix.pitched),
                        format!("{}", mix.floor_height),
                        format!("{:.3}", e.height),
                        format!("{}", e.storeys),
                        format!("{:.3}", e.pitched),
                        opt(*h),
                        opt(*s),
                        opt(r.map(|p| f64::from(u8::from(p)))),
                    ]);
                    rows.push(line.join(","));
                }
                if let Some(h) = h {
                    pairs.height.push((e.height, *h));
                }
                if let Some(s) = s {
                    pairs.storeys.push((e.storeys, *s));
                }
                if let Some(r) = r {
                    pairs.roof.push((e.pitched >= 0.5, *r));
                    let f = &out.features[i];
                    if f[6] >= ATTACHED_SHARE && f64::from(f[0]).exp() >= ATTACHED_MIN_M2 {
                        attached.push((*r, e.pitched >= 0.5));
                    }
                }
            }
            if case.truth.is_some() || !hide(i) {
                base.0.extend(*h);
                base.1.extend(*s);
                base.2.extend(r.map(|p| f64::from(u8::from(p))));
            }
        }
        // One baseline per fold, applied to that fold's hidden buildings.
        let (bh, bs, br) = (median(&base.0), median(&base.1), mean(&base.2));
        let nh = pairs.height.len() - pairs.baseline_height.len();
        let ns = pairs.storeys.len() - pairs.baseline_storeys.len();
        let nr = pairs.roof.len() - pairs.baseline_roof.len();
        pairs.baseline_height.extend(std::iter::repeat_n(bh, nh));
        pairs.baseline_storeys.extend(std::iter::repeat_n(bs, ns));
        pairs.baseline_roof.extend(std::iter::repeat_n(br, nr));
    }
    let mixes = super::roof_mixes(kb, &case.lots, &case.kb_zones);
    let as_run = if case.truth.is_some() {
        let lots = hidden(&case.lots, |_| true);
        estimate::estimate(&lots, &mixes, &want, models, o.fit)
    } else {
        estimate::estimate(&case.lots, &mixes, &want, models, o.fit)
    };
    CaseScore {
        form: form(&as_run),
        attached_roofs: AttachedRoofs::of(&attached),
        name: case.name.clone(),
        mode: if case.truth.is_some() {
            "truth"
        } else {
            "hidden tags"
        }
        .to_string(),
        height: numeric(&pairs.height, &pairs.baseline_height, false),
        storeys: numeric(&pairs.storeys, &pairs.baseline_storeys, true),
        roof: roofs(&pairs.roof, &pairs.baseline_roof),
        rows,
    }
}

fn median(v: &[f64]) -> f64 {
    let mut v = v.to_vec();
    v.sort_by(f64::total_cmp);
    v.get(v.len() / 2).copied().unwrap_or(0.0)
}

fn mean(v: &[f64]) -> f64 {
    if v.is_empty() {
        0.5
    } else {
        v.iter().sum::<f64>() / v.len() as f64
    }
}

fn numeric(pairs: &[(f64, f64)], baseline: &[f64], whole: bool) -> Option<Score> {
    if pairs.is_empty() {
        return None;
    }
    let n = pairs.len() as f64;
    let error = pairs.iter().map(|(e, t)| (e - t).abs()).sum::<f64>() / n;
    let base = pairs
        .iter()
        .zip(baseline)
        .map(|((_, t), b)| (b - t).abs())
        .sum::<f64>()
        / n;
    let exact = whole.then(|| pairs.iter().filter(|(e, t)| (e - t).abs() < 0.5).count() as f64 / n);
    Some(Score {
        n: pairs.len(),
        error,
        baseline: base,
        exact,
        rank: Some(spearman(pairs)),
        medians: Some((
            median(&pairs.iter().map(|p| p.0).collect::<Vec<_>>()),
            median(&pairs.iter().map(|p| p.1).collect::<Vec<_>>()),
        )),
    })
}

fn roofs(pairs: &[(bool, bool)], baseline: &[f64]) -> Option<Score> {
    if pairs.is_empty() {
        return None;
    }
    let n = pairs.len() as f64;
    let wrong = pairs.iter().filter(|(e, t)| e != t).count() as f64 / n;
    let base = pairs
        .iter()
        .zip(baseline)
        .filter(|((_, t), b)| (**b >= 0.5) != *t)
        .count() as f64
        / n;
    Some(Score {
        n: pairs.len(),
        error: wrong,
        baseline: base,
        exact: None,
        rank: None,
        medians: None,
    })
}

/// Spearman's rank correlation (average ranks for ties).
fn spearman(pairs: &[(f64, f64)]) -> f64 {
    fn ranks(v: &[f64]) -> Vec<f64> {
        let mut idx: Vec<usize> = (0..v.len()).collect();
        idx.sort_by(|a, b| v[*a].total_cmp(&v[*b]));
        let mut r = vec![0.0; v.len()];
        let mut i = 0;
        while i < idx.len() {
            let mut j = i;
            while j + 1 < idx.len() && v[idx[j + 1]] == v[idx[i]] {
                j += 1;
            }
            for k in i..=j {
                r[idx[k]] = (i + j) as f64 / 2.0;
            }
            i = j + 1;
        }
        r
    }
    let a = ranks(&pairs.iter().map(|p| p.0).collect::<Vec<_>>());
    let b = ranks(&pairs.iter().map(|p| p.1).collect::<Vec<_>>());
    let n = a.len() as f64;
    let (ma, mb) = (a.iter().sum::<f64>() / n, b.iter().sum::<f64>() / n);
    let (mut sab, mut saa, mut sbb) = (0.0, 0.0, 0.0);
    for (x, y) in a.iter().zip(&b) {
        sab += (x - ma) * (y - mb);
        saa += (x - ma) * (x - ma);
        sbb += (y - mb) * (y - mb);
    }
    if saa > 0.0 && sbb > 0.0 {
        sab / (saa * sbb).sqrt()
    } else {
        0.0
    }
}

/// Fits the shipped models on the cases' rows (module docs).
fn fit_models(kb: &KnowledgeBase, cases: &[&Loaded]) -> estimate::Models {
    let (mut hx, mut hy, mut hp) = (Vec::new(), Vec::new(), Vec::new());
    let (mut rx, mut ry, mut rp) = (Vec::new(), Vec::new(), Vec::new());
    for case in cases {
        let m = morph::measure(&case.lots);
        let mut rows_h = Vec::new();
        let mut rows_r = Vec::new();
        for (i, l) in case.lots.iter().enumerate() {
            let zone = case.kb_zones.get(i).copied().unwrap_or(0);
            let mix = kb.roof_mix(zone, l.tags.building.as_deref());
            let (h, s, r) = truth_of(case, l);
            let known = estimate::known(&l.tags, m.width[i], mix);
            let log_h = match (&case.truth, h) {
                (Some(_), Some(h)) => Some(h.ln()),
                (Some(_), None) => None,
                (None, _) => known.log_height.filter(|_| h.is_some() || s.is_some()),
            };
            if let Some(y) = log_h {
                rows_h.push((
                    m.features[i],
                    y,
                    estimate::prior_log_height(&m.features[i], &mix),
                ));
            }
            if let Some(r) = r {
                rows_r.push((
                    m.features[i],
                    f64::from(u8::from(r)),
                    estimate::prior_roof(&mix, &m.features[i]),
                ));
            }
        }
        let step = |n: usize| n.div_ceil(ROWS_PER_CASE).max(1);
        let sh = step(rows_h.len());
        for (f, y, p) in rows_h.into_iter().step_by(sh) {
            hp.push(p);
            hx.push(f);
            hy.push(y);
        }
        let sr = step(rows_r.len());
        for (f, y, p) in rows_r.into_iter().step_by(sr) {
            rx.push(f);
            ry.push(y);
            rp.push(p);
        }
    }
    let params = gbt::Params {
        rounds: 150,
        depth: 3,
        rate: 0.06,
        min_leaf: 30,
        lambda: 10.0,
        bins: 32,
    };
    estimate::Models {
        height: gbt::fit(&hx, &hy, &hp, gbt::Loss::Squared, &params),
        roof: gbt::fit(&rx, &ry, &rp, gbt::Loss::Logistic, &params),
    }
}

fn read_models(dir: &Path) -> Result<estimate::Models, RunError> {
    let read = |name: &str| -> Result<gbt::Model, RunError> {
        let p = dir.join(name);
        let text = std::fs::read_to_string(&p)
            .map_err(|e| RunError::Input(format!("{}: {e}", p.display())))?;
        gbt::Model::from_text(&text).map_err(|e| RunError::Input(format!("{}: {e}", p.display())))
    };
    Ok(estimate::Models {
        height: read("height.gbt")?,
        roof: read("roof.gbt")?,
    })
}

fn write_models(dir: &Path, m: &estimate::Models) -> Result<(), RunError> {
    for (name, model) in [("height.gbt", &m.height), ("roof.gbt", &m.roof)] {
        let p = dir.join(name);
        crate::fsio::write_atomic(&p, model.to_text().as_bytes())
            .map_err(|e| RunError::Input(format!("{}: {e}", p.display())))?;
    }
    Ok(())
}

/// Writes the scores as JSON (atomically).
pub fn write_scores(path: &Path, scores: &[CaseScore]) -> Result<(), RunError> {
    let text = serde_json::to_string_pretty(scores).unwrap_or_default();
    crate::fsio::write_atomic(path, text.as_bytes())
        .map_err(|e| RunError::Input(format!("{}: {e}", path.display())))
}

/// Writes every case's compared buildings as one CSV ([`dump_header`]).
pub fn write_dump(path: &Path, scores: &[CaseScore]) -> Result<(), RunError> {
    let mut text = dump_header();
    text.push('\n');
    for line in scores.iter().flat_map(|s| &s.rows) {
        text.push_str(line);
        text.push('\n');
    }
    crate::fsio::write_atomic(path, text.as_bytes())
        .map_err(|e| RunError::Input(format!("{}: {e}", path.display())))
}

#[cfg(test)]
mod tests {
    use super::AttachedRoofs;

    #[test]
    fn attached_roofs_count_each_family_drawn_in_the_other() {
        // (truth pitched, drawn pitched): 4 flat of which 1 drawn pitched, 2 pitched of which
        // 1 drawn flat.
        let pairs = [
            (false, false),
            (false, true),
            (false, false),
            (false, false),
            (true, true),
            (true, false),
        ];
        let a = AttachedRoofs::of(&pairs).unwrap();
        assert_eq!((a.flat, a.pitched), (4, 2));
        assert!((a.flat_drawn_pitched - 0.25).abs() < 1e-12, "{a:?}");
        assert!((a.pitched_drawn_flat - 0.5).abs() < 1e-12, "{a:?}");
        assert_eq!(AttachedRoofs::of(&[]), None);
        // One family only: the other's share is 0 of 0.
        let a = AttachedRoofs::of(&[(false, true)]).unwrap();
        assert_eq!((a.flat, a.pitched, a.pitched_drawn_flat), (1, 0, 0.0));
        assert_eq!(a.flat_drawn_pitched, 1.0);
    }
}
