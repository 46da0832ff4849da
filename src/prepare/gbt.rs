//! Gradient-boosted regression trees, small and deterministic: the estimator's model
//! ([`super::estimate`]).
//!
//! Why hand-written: the model must be a pure function of its training rows (same bytes at any
//! thread count), boost from a prior (the shipped model's prediction, so that a run with few
//! tagged buildings stays near it), serialise to a few kilobytes of text in `assets/`, and cost
//! nothing to evaluate a million times. The crates that fit (linfa's trees, smartcore,
//! gbdt-rs) bring a heavy dependency tree or no prior offset and no stable text format.
//!
//! The method is the usual second-order boosting (as XGBoost/LightGBM): features cut into at
//! most [`Params::bins`] quantile bins on the training rows, trees grown level by level to
//! [`Params::depth`], each split the one of largest gain `G_L²/(H_L+λ) + G_R²/(H_R+λ) -
//! G²/(H+λ)` with at least [`Params::min_leaf`] rows a side, leaves `-G/(H+λ)` times the
//! learning rate. Squared loss for log heights, logistic loss for pitched roofs.

use std::fmt::Write as _;

use super::morph::{Features, FEATURES, FEATURE_NAMES};

/// The loss a model is fitted with.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Loss {
    /// Squared error: the prediction is a value (a log height).
    Squared,
    /// Logistic: the prediction is a log-odds (of a pitched roof).
    Logistic,
}

/// How a model is fitted.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Params {
    /// Trees.
    pub rounds: usize,
    /// Levels of splits per tree.
    pub depth: usize,
    /// Each tree's leaves are scaled by this.
    pub rate: f64,
    /// The fewest rows on either side of a split.
    pub min_leaf: usize,
    /// L2 regularisation of the leaf values.
    pub lambda: f64,
    /// The most bins a feature is cut into.
    pub bins: usize,
}

impl Default for Params {
    fn default() -> Params {
        Params {
            rounds: 120,
            depth: 4,
            rate: 0.08,
            min_leaf: 20,
            lambda: 5.0,
            bins: 48,
        }
    }
}

/// One node: a split (`feature < FEATURES`) sends `x[feature] <= threshold` left, else right;
/// a leaf holds `value`.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Node {
    feature: usize,
    threshold: f32,
    left: u32,
    right: u32,
    value: f64,
}

const LEAF: usize = usize::MAX;

/// A fitted model: `base + Σ trees`, added to the row's prior.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct Model {
    loss: Loss,
    base: f64,
    trees: Vec<Vec<Node>>,
}

/// Why a model file could not be read.
#[derive(Debug, thiserror::Error, PartialEq)]
#[error("model line {line}: {what}")]
pub(crate) struct ModelError {
    line: usize,
    what: String,
}

impl Model {
    /// A model that adds nothing to the prior.
    pub(crate) fn zero(loss: Loss) -> Model {
        Model {
            loss,
            base: 0.0,
            trees: Vec::new(),
        }
    }

    /// What the model adds to a row's prior.
    pub(crate) fn predict(&self, x: &Features) -> f64 {
        self.trees
            .iter()
            .fold(self.base, |s, t| s + tree_value(t, x))
    }

    /// What the base and the first `rounds` trees add (0 for none: the prior alone).
    pub(crate) fn predict_first(&self, x: &Features, rounds: usize) -> f64 {
        if rounds == 0 {
            return 0.0;
        }
        self.trees
            .iter()
            .take(rounds)
            .fold(self.base, |s, t| s + tree_value(t, x))
    }

    /// The model as text (module docs of [`Model::from_text`]).
    pub(crate) fn to_text(&self) -> String {
        let mut s = String::new();
        let loss = match self.loss {
            Loss::Squared => "squared",
            Loss::Logistic => "logistic",
        };
        let _ = writeln!(s, "citygen-gbt 1 {loss} base {:e}", self.base);
        let _ = writeln!(s, "features {}", FEATURE_NAMES.join(","));
        for t in &self.trees {
            let _ = write!(s, "tree");
            for n in t {
                if n.feature == LEAF {
                    let _ = write!(s, " L{:e}", n.value);
                } else {
                    let _ = write!(s, " {}:{:e}:{}:{}", n.feature, n.threshold, n.left, n.right);
                }
            }
            s.push('\n');
        }
        s
    }

    /// Reads what [`Model::to_text`] wrote: a head line `citygen-gbt 1 LOSS base B`, a
    /// `features` line that must name this build's features in order, then one `tree` line per
    /// tree: nodes `F:THRESHOLD:LEFT:RIGHT` or leaves `LVALUE`, children after their parent.
    pub(crate) fn from_text(text: &str) -> Result<Model, ModelError> {
        let err = |line: usize, what: &str| ModelError {
            line,
            what: what.to_string(),
        };
        let mut lines = text.lines().enumerate().map(|(i, l)| (i + 1, l.trim()));
        let (n, head) = lines.next().ok_or_else(|| err(1, "empty"))?;
        let w: Vec<&str> = head.split_whitespace().collect();
        let loss = match w.as_slice() {
            ["citygen-gbt", "1", "squared", "base", _] => Loss::Squared,
            ["citygen-gbt", "1", "logistic", "base", _] => Loss::Logistic,
            _ => return Err(err(n, "not a citygen-gbt 1 model")),
        };
        let base: f64 = w[4].parse().map_err(|_| err(n, "bad base"))?;
        let (n, feats) = lines.next().ok_or_else(|| err(2, "no features line"))?;
        if feats != format!("features {}", FEATURE_NAMES.join(",")) {
            return Err(err(n, "its features are not this build's"));
        }
        let mut trees = Vec::new();
        for (n, l) in lines.filter(|(_, l)| !l.is_empty()) {
            let mut words = l.split_whitespace();
            if words.next() != Some("tree") {
                return Err(err(n, "expected `tree`"));
            }
            let nodes: Vec<Node> = words
                .map(|w| parse_node(w).ok_or_else(|| err(n, &format!("bad node {w:?}"))))
                .collect::<Result<_, _>>()?;
            let ok = !nodes.is_empty()
                && nodes.iter().enumerate().all(|(k, node)| {
                    node.feature == LEAF
                        || (node.left as usize > k
                            && node.right as usize > k
                            && (node.left as usize) < nodes.len()
                            && (node.right as usize) < nodes.len())
                });
            if !ok {
                return Err(err(n, "a child before its parent or out of the tree"));
            }
            trees.push(nodes);
        }
        Ok(Model { loss, base, trees })
    }
}

/// The leaf value row `x` reaches in one tree (0 for a malformed tree).
fn tree_value(t: &[Node], x: &Features) -> f64 {
    let mut k = 0usize;
    while let Some(n) = t.get(k) {
        if n.feature == LEAF {
            return n.value;
        }
        let next = if x[n.feature] <= n.threshold {
            n.left as usize
        } else {
            n.right as usize
        };
        if next <= k {
            return 0.0;
        }
        k = next;
    }
    0.0
}

fn parse_node(w: &str) -> Option<Node> {
    if let Some(v) = w.strip_prefix('L') {
        let value: f64 = v.parse().ok().filter(|v: &f64| v.is_finite())?;
        return Some(Node {
            feature: LEAF,
            threshold: 0.0,
            left: 0,
            right: 0,
            value,
        });
    }
    let mut p = w.split(':');
    let feature: usize = p.next()?.parse().ok().filter(|f| *f < FEATURES)?;
    let threshold: f32 = p.next()?.parse().ok()?;
    let left: u32 = p.next()?.parse().ok()?;
    let right: u32 = p.next()?.parse().ok()?;
    p.next().is_none().then_some(Node {
        feature,
        threshold,
        left,
        right,
        value: 0.0,
    })
}

/// The logistic function.
pub(crate) fn sigmoid(z: f64) -> f64 {
    1.0 / (1.0 + (-z).exp())
}

/// Per feature, the cut points of its bins (ascending): quantiles of the rows' values.
fn cuts(x: &[Features], bins: usize) -> Vec<Vec<f32>> {
    (0..FEATURES)
        .map(|f| {
            let mut v: Vec<f32> = x.iter().map(|r| r[f]).collect();
            v.sort_by(f32::total_cmp);
            v.dedup();
            if v.len() <= bins {
                // Midpoints would move a cut off the values the rows have; the lower value of
                // each pair is the threshold (x <= t goes left).
                return v.iter().take(v.len().saturating_sub(1)).copied().collect();
            }
            let mut c: Vec<f32> = (1..bins).map(|k| v[k * v.len() / bins]).collect();
            c.dedup();
            c
        })
        .collect()
}

fn bin_of(cuts: &[f32], v: f32) -> u8 {
    cuts.partition_point(|c| *c < v).min(255) as u8
}

/// Fits a model to rows `x` with targets `y` (a log height, or 1/0 for a pitched roof) over
/// each row's `prior` (module docs). Deterministic; rows are used in the order given.
pub(crate) fn fit(x: &[Features], y: &[f64], prior: &[f64], loss: Loss, p: &Params) -> Model {
    let n = x.len().min(y.len()).min(prior.len());
    if n == 0 {
        return Model::zero(loss);
    }
    let bins = p.bins.clamp(2, 255);
    let cuts = cuts(&x[..n], bins);
    let binned: Vec<[u8; FEATURES]> = x[..n]
        .iter()
        .map(|r| std::array::from_fn(|f| bin_of(&cuts[f], r[f])))
        .collect();
    let mut score: Vec<f64> = prior[..n].to_vec();
    let grad = |s: f64, t: f64| match loss {
        Loss::Squared => (s - t, 1.0),
        Loss::Logistic => {
            let q = sigmoid(s);
            (q - t, (q * (1.0 - q)).max(1e-6))
        }
    };
    // The base: one Newton step from the prior.
    let (g, h) = (0..n).fold((0.0, 0.0), |(g, h), i| {
        let (a, b) = grad(score[i], y[i]);
        (g + a, h + b)
    });
    let base = -g / (h + 1e-9);
    score.iter_mut().for_each(|s| *s += base);
    let mut trees = Vec::with_capacity(p.rounds);
    let mut gh = vec![(0.0, 0.0); n];
    for _ in 0..p.rounds {
        for i in 0..n {
            gh[i] = grad(score[i], y[i]);
        }
        let tree = grow(&binned, &cuts, &gh, p);
        let model = Model {
            loss,
            base: 0.0,
            trees: vec![tree],
        };
        for i in 0..n {
            score[i] += model.predict(&x[i]);
        }
        trees.extend(model.trees);
    }
    Model { loss, base, trees }
}

/// One tree on the gradients `gh` (module docs).
fn grow(binned: &[[u8; FEATURES]], cuts: &[Vec<f32>], gh: &[(f64, f64)], p: &Params) -> Vec<Node> {
    let mut nodes: Vec<Node> = Vec::new();
    // (node index, rows) to split, level by level.
    let all: Vec<u32> = (0..binned.len() as u32).collect();
    let leaf = |rows: &[u32]| {
        let (g, h) = rows.iter().fold((0.0, 0.0), |(g, h), &i| {
            (g + gh[i as usize].0, h + gh[i as usize].1)
        });
        Node {
            feature: LEAF,
            threshold: 0.0,
            left: 0,
            right: 0,
            value: -p.rate * g / (h + p.lambda),
        }
    };
    nodes.push(leaf(&all));
    let mut level = vec![(0usize, all)];
    for _ in 0..p.depth {
        let mut next = Vec::new();
        for (k, rows) in level {
            let Some((f, bin)) = best_split(binned, cuts, gh, &rows, p) else {
                continue;
            };
            let (l, r): (Vec<u32>, Vec<u32>) =
                rows.iter().partition(|&&i| binned[i as usize][f] <= bin);
            let (li, ri) = (nodes.len(), nodes.len() + 1);
            nodes.push(leaf(&l));
            nodes.push(leaf(&r));
            nodes[k] = Node {
                feature: f,
                threshold: cuts[f][bin as usize],
                left: li as u32,
                right: ri as u32,
                value: 0.0,
            };
            next.push((li, l));
            next.push((ri, r));
        }
        level = next;
    }
    nodes
}

/// The best (feature, bin) to split `rows` at (rows with bin <= it go left), if any gains.
fn best_split(
    binned: &[[u8; FEATURES]],
    cuts: &[Vec<f32>],
    gh: &[(f64, f64)],
    rows: &[u32],
    p: &Params,
) -> Option<(usize, u8)> {
    if rows.len() < 2 * p.min_leaf {
        return None;
    }
    let mut hist = vec![[(0.0f64, 0.0f64, 0u32); 256]; FEATURES];
    let (mut g_all, mut h_all) = (0.0, 0.0);
    for &i in rows {
        let (g, h) = gh[i as usize];
        g_all += g;
        h_all += h;
        for (f, b) in binned[i as usize].iter().enumerate() {
            let e = &mut hist[f][*b as usize];
            e.0 += g;
            e.1 += h;
            e.2 += 1;
        }
    }
    let score = |g: f64, h: f64| g * g / (h + p.lambda);
    let parent = score(g_all, h_all);
    let mut best: Option<(f64, usize, u8)> = None;
    for (f, c) in cuts.iter().enumerate() {
        let (mut g, mut h, mut count) = (0.0, 0.0, 0usize);
        for (bin, e) in hist[f].iter().take(c.len()).enumerate() {
            g += e.0;
            h += e.1;
            count += e.2 as usize;
            if count < p.min_leaf || rows.len() - count < p.min_leaf {
                continue;
            }
            let gain = score(g, h) + score(g_all - g, h_all - h) - parent;
            if gain > 1e-9 && best.is_none_or(|b| gain > b.0) {
                best = Some((gain, f, bin as u8));
            }
        }
    }
    best.map(|(_, f, b)| (f, b))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rows(n: usize) -> (Vec<Features>, Vec<f64>) {
        let mut x = Vec::new();
        let mut y = Vec::new();
        for i in 0..n {
            let mut r = [0.0f32; FEATURES];
            r[0] = (i % 17) as f32;
            r[3] = (i % 5) as f32;
            x.push(r);
            y.push(if r[0] > 8.0 { 3.0 } else { 1.0 } + 0.1 * f64::from(r[3]));
        }
        (x, y)
    }

    #[test]
    fn boosting_learns_a_step_and_reads_back_what_it_wrote() {
        let (x, y) = rows(600);
        let prior = vec![0.0; x.len()];
        let m = fit(&x, &y, &prior, Loss::Squared, &Params::default());
        let err: f64 = x
            .iter()
            .zip(&y)
            .map(|(r, t)| (m.predict(r) - t).abs())
            .sum::<f64>()
            / x.len() as f64;
        assert!(err < 0.05, "mean error {err}");
        let back = Model::from_text(&m.to_text()).expect("reads");
        for r in &x {
            assert_eq!(back.predict(r).to_bits(), m.predict(r).to_bits());
        }
        assert_eq!(m, fit(&x, &y, &prior, Loss::Squared, &Params::default()));
    }

    #[test]
    fn a_prior_that_is_right_is_left_alone_and_logistic_separates() {
        let (x, y) = rows(300);
        let m = fit(&x, &y, &y, Loss::Squared, &Params::default());
        assert!(x.iter().all(|r| m.predict(r).abs() < 1e-9));
        let t: Vec<f64> = x.iter().map(|r| f64::from(u8::from(r[0] > 8.0))).collect();
        let m = fit(
            &x,
            &t,
            &vec![0.0; x.len()],
            Loss::Logistic,
            &Params::default(),
        );
        let right = x
            .iter()
            .zip(&t)
            .filter(|(r, t)| (sigmoid(m.predict(r)) > 0.5) == (**t > 0.5))
            .count();
        assert_eq!(right, x.len());
    }

    #[test]
    fn bad_model_text_is_refused_with_its_line() {
        assert!(Model::from_text("").is_err());
        let head = format!(
            "citygen-gbt 1 squared base 0\nfeatures {}\n",
            FEATURE_NAMES.join(",")
        );
        assert!(Model::from_text(&format!("{head}tree 0:1:5:6 L1 L2\n")).is_err());
        assert!(Model::from_text(&format!("{head}tree 0:1:1:2 L1 L2\n")).is_ok());
        let e = Model::from_text(&format!("{head}tree 99:1:1:2 L1 L2\n")).unwrap_err();
        assert_eq!(e.line, 3);
        assert!(Model::from_text("citygen-gbt 1 squared base 0\nfeatures a,b\n").is_err());
    }
}
