#!/usr/bin/env python3
"""Leave-one-city-out scores of flat-vs-pitched roof rules (issue 42; docs/truth.md, "Roofs").

Reads the CSV that `citygen eval ... --dump FILE.csv` writes (every compared building: the
estimator's features, its zone's prior, the estimate and the truth) and, for the context
features, the truth folders' footprints (`tests/data/truth/<city>/footprints.shp` and
`truth.csv`). For each of the six places with measured roofs it fits a rule on the other
five (cities weighted equally) and scores it on the one left out; it prints the share of
roofs right per left-out city and pooled, beside the estimator as shipped (`est_pitched`).

    citygen eval <the cases of docs/truth.md> --seed 1 --dump dump.csv
    python3 scripts/roof_loco.py dump.csv [tests/data/truth]

Needs numpy, pandas, scipy, scikit-learn and pyshp. Deterministic (fixed model seeds).
"""

import sys
import warnings

import numpy as np
import pandas as pd

warnings.filterwarnings("ignore")

SIX = ["denhaag", "rotterdam_delfshaven", "zurich", "delft", "matsumoto", "ina"]
# The features of src/prepare/morph.rs as `--dump` names them.
FEATURES = [
    "log_area", "compactness", "elongation", "log_width", "log_vertices", "convexity",
    "shared_wall_share", "touching", "log_count_150m", "log_count_250m",
    "built_share_150m", "built_share_250m", "built_share_750m", "log_mean_area_250m",
    "kind_storeys", "street_front",
]
# The size steps of `prior_roof` (src/prepare/estimate.rs): under 30, 60, 120, 250, 600 m².
EDGES = [30, 60, 120, 250, 600]
STEPS = [-1.5, 0.8, -0.3, 0.0, -1.0, -1.5]


def logit(p):
    p = np.clip(p, 0.05, 0.95)
    return np.log(p / (1 - p))


def load(dump, truth_dir):
    d = pd.read_csv(dump)
    d["city"] = d.case.str.split("/").str[-2]
    d = d[d.city.isin(SIX) & d.pitched.notna()].copy()
    d["zl"] = logit(d.zone_pitched)
    d["cur"] = np.log(d.est_pitched.clip(1e-6, 1 - 1e-6) / (1 - d.est_pitched.clip(1e-6, 1 - 1e-6)))
    d["cls"] = np.digitize(np.exp(d.log_area), EDGES)
    if truth_dir:
        d = context(d, truth_dir)
    return d.reset_index(drop=True)


def context(d, truth_dir):
    """The 15 nearest footprints' mean forms (nb_*) and mean distance (nb_dist)."""
    import shapefile
    from scipy.spatial import cKDTree

    parts = []
    for c in SIX:
        g = d[d.city == c].copy()
        shapes = shapefile.Reader(f"{truth_dir}/{c}/footprints.shp").shapes()
        cen = {f"shp/{k}": np.array(s.points).mean(0) for k, s in enumerate(shapes)}
        t = pd.read_csv(f"{truth_dir}/{c}/truth.csv", dtype=str)
        ids = dict(zip(t.source_id, t.id))
        ids.update({i: i for i in t.id})
        g = g[[str(i) in ids for i in g.id]].copy()
        xy = np.array([cen[ids[str(i)]] for i in g.id])
        lat = np.radians(xy[:, 1].mean())
        xy = xy * np.array([111320 * np.cos(lat), 110540])
        dist, idx = cKDTree(xy).query(xy, k=16)
        for f in ["log_area", "shared_wall_share", "compactness", "elongation",
                  "log_vertices", "convexity", "log_width"]:
            g["nb_" + f] = g[f].values[idx[:, 1:]].mean(1)
        g["nb_dist"] = np.log(dist[:, 1:].mean(1) + 1)
        parts.append(g)
    return pd.concat(parts)


def weights(d, mask):
    return (1.0 / d[mask].groupby("city").city.transform("size")).values


def loco_sklearn(d, make, feats):
    y = (d.pitched >= 0.5).astype(int).values
    p = np.zeros(len(d))
    for c in SIX:
        tr = (d.city != c).values
        m = make()
        m.fit(d.loc[tr, feats].values, y[tr], sample_weight=weights(d, tr))
        p[~tr] = m.predict_proba(d.loc[~tr, feats].values)[:, 1]
    return p


def prior(d, w, steps, extra):
    z = w * d.zl.values + np.asarray(steps)[d.cls.values]
    for coef, (col, pivot) in extra:
        z = z + coef * (d[col].values - pivot)
    return z


def loco_prior(d, extra_cols):
    """The prior's zone weight and size steps (and a term per extra column) chosen by
    coordinate search on the other cities' mean accuracy."""
    y = (d.pitched >= 0.5).values
    grid_w = [0.25, 0.5, 0.75, 1.0, 1.25]
    grid_s = list(np.round(np.arange(-2, 2.01, 0.25), 2))
    grid_e = [-2, -1, -0.5, 0, 0.5, 1, 2]
    out = np.zeros(len(d), bool)
    for c in SIX:
        train = [x for x in SIX if x != c]
        masks = [(d.city == x).values for x in train]

        def score(p):
            z = prior(d, p[0], p[1:7], list(zip(p[7:], extra_cols)))
            return np.mean([((z >= 0) == y)[m].mean() for m in masks])

        p = [0.5, *STEPS] + [0.0] * len(extra_cols)
        best = score(p)
        for _ in range(3):
            for k in range(len(p)):
                grid = grid_w if k == 0 else grid_s if k < 7 else grid_e
                for v in grid:
                    q = list(p)
                    q[k] = v
                    s = score(q)
                    if s > best + 1e-9:
                        best, p = s, q
        z = prior(d, p[0], p[1:7], list(zip(p[7:], extra_cols)))
        m = (d.city == c).values
        out[m] = (z >= 0)[m]
    return out.astype(float)


def report(d, name, p):
    ok = (p >= 0.5) == (d.pitched >= 0.5).values
    cities = " ".join(f"{c[:9]} {100 * ok[(d.city == c).values].mean():.0f}" for c in SIX)
    print(f"{name:34s} pooled {100 * ok.mean():5.1f} | {cities}")


def main():
    from sklearn.ensemble import HistGradientBoostingClassifier
    from sklearn.linear_model import LogisticRegression

    dump = sys.argv[1]
    truth_dir = sys.argv[2] if len(sys.argv) > 2 else "tests/data/truth"
    d = load(dump, truth_dir)
    nb = [c for c in d.columns if c.startswith("nb_")]

    def gbt():
        return HistGradientBoostingClassifier(max_depth=3, max_iter=100, learning_rate=0.1,
                                              random_state=0)

    def lr():
        return LogisticRegression(C=1.0, max_iter=5000)

    print(f"{len(d)} roofs; share of roofs right, each city scored by a rule fitted on the others")
    report(d, "as shipped (the prior, rows)", d.est_pitched.values)
    report(d, "each city's majority (oracle)", d.groupby("city").pitched.transform("mean").values)
    report(d, "prior re-chosen (weight, steps)", loco_prior(d, []))
    for col, pivot in [("built_share_150m", 0.3), ("log_mean_area_250m", 4.5),
                       ("shared_wall_share", 0.2), ("compactness", 0.65)]:
        report(d, f"  + {col}", loco_prior(d, [(col, pivot)]))
    report(d, "logistic: features, zone", loco_sklearn(d, lr, FEATURES + ["zl"]))
    report(d, "trees: features, zone", loco_sklearn(d, gbt, FEATURES + ["zl"]))
    report(d, "trees: features, zone, context", loco_sklearn(d, gbt, FEATURES + ["zl"] + nb))
    report(d, "trees: shipped log-odds, context", loco_sklearn(d, gbt, ["cur"] + nb))
    report(d, "logistic: shipped log-odds, context", loco_sklearn(d, lr, ["cur"] + nb))


if __name__ == "__main__":
    main()
