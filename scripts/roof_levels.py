#!/usr/bin/env python3
"""Where the roof estimate's accuracy is bounded (issue 42; docs/truth.md, "Roofs, fourth pass").

Reads `citygen eval ... --seed 1 --dump DUMP.csv` (the estimator's features, its zone's prior,
the estimate and the truth of every compared building) and the truth folders' footprints
(`tests/data/truth/<place>/footprints.shp`, `truth.csv`), computes context from the footprints
(touching pairs, rows of like size, density and size spread within 50/100/200 m, the nearest
15 footprints), and prints, for the six places with measured roofs, the share of roofs right
per place and pooled:

1. leave one place out (fitted on the other five, places weighted equally): boosted trees
   and logistic models on the estimator's features, the zone's log-odds and the context;
2. the within-place shape alone: models fitted with one intercept per training place (fixed
   effects), the left-out place drawn at its own measured pitched share (an oracle of the
   place's level) or at its zone's share in the knowledge base;
3. the rows step of `src/prepare/estimate.rs` (`roof_rows`) ported, over the prior, with
   other rules for a row's family, and the share of attached flat roofs drawn pitched.

    citygen eval <the cases of docs/truth.md> --seed 1 --dump dump.csv
    python3 scripts/roof_levels.py dump.csv [tests/data/truth]

Needs numpy, pandas, scipy, scikit-learn, pyshp and shapely. Deterministic (fixed seeds).
"""

import sys
import warnings

import numpy as np
import pandas as pd

warnings.filterwarnings("ignore")

SIX = ["denhaag", "rotterdam_delfshaven", "zurich", "delft", "matsumoto", "ina"]
FEATURES = [
    "log_area", "compactness", "elongation", "log_width", "log_vertices", "convexity",
    "shared_wall_share", "touching", "log_count_150m", "log_count_250m",
    "built_share_150m", "built_share_250m", "built_share_750m", "log_mean_area_250m",
]
CONTEXT = [
    "row_n", "block_n", "block_area", "cnt50", "built50", "medla50", "iqrla50", "att50",
    "cnt100", "built100", "medla100", "iqrla100", "att100", "cnt200", "built200", "medla200",
    "iqrla200", "att200", "nndist", "knn_dist", "knn_la", "knn_att",
]


def logit(p):
    p = np.clip(p, 0.05, 0.95)
    return np.log(p / (1 - p))


def prior(d):
    """`prior_roof` of src/prepare/estimate.rs."""
    a = np.exp(d.log_area)
    size = np.select([a < 30, a < 60, a < 120, a < 250, a < 600], [-1.5, 0.8, -0.3, 0.0, -1.0], -1.5)
    return 0.5 * logit(d.zone_pitched) + size


def footprints(path):
    import shapefile
    from shapely.geometry import MultiPolygon, Polygon

    shapes = shapefile.Reader(path).shapes()
    pts = np.concatenate([np.array(s.points) for s in shapes])
    lon0, lat0 = pts.mean(0)
    k = np.array([111320 * np.cos(np.radians(lat0)), 110540])
    out = []
    for s in shapes:
        xy = (np.array(s.points) - [lon0, lat0]) * k
        ends = list(s.parts) + [len(xy)]
        polys, cur = [], None
        for a, b in zip(ends[:-1], ends[1:]):
            r = xy[a:b]
            if len(r) < 4:
                continue
            signed = 0.5 * np.sum(r[:-1, 0] * r[1:, 1] - r[1:, 0] * r[:-1, 1])
            if signed < 0 or cur is None:  # ESRI: outer rings clockwise
                if cur is not None:
                    polys.append(cur)
                cur = [r, []]
            else:
                cur[1].append(r)
        if cur is not None:
            polys.append(cur)
        out.append(MultiPolygon([Polygon(o, h) for o, h in polys]).buffer(0))
    return out


def touching_pairs(polys):
    """Pairs (i, j), i < j, of footprints sharing 2 m of wall or more (0.5 m tolerance)."""
    from shapely import STRtree

    tree = STRtree(polys)
    pairs = []
    for i, p in enumerate(polys):
        b = p.buffer(0.5)
        for j in tree.query(b):
            if j > i and b.intersection(polys[j].boundary).length / 2 >= 2.0:
                pairs.append((i, j))
    return pairs


def components(n, pairs, join):
    """Per footprint, the smallest index of its group: pairs joined where join(i, j)."""
    parent = list(range(n))

    def find(i):
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    for i, j in pairs:
        if join(i, j):
            a, b = find(i), find(j)
            if a != b:
                parent[max(a, b)] = min(a, b)
    return np.array([find(i) for i in range(n)])


def context(path):
    """Per footprint (record order): rows and blocks (touching, 2 m of wall or more; rows of
    like size, at most 3 times apart, as `ROW_AREA_RATIO`), density, sizes around."""
    from scipy.spatial import cKDTree

    polys = footprints(path)
    n = len(polys)
    cen = np.array([[p.centroid.x, p.centroid.y] for p in polys])
    area = np.array([p.area for p in polys])
    pairs = touching_pairs(polys)
    row = components(n, pairs,
                     lambda i, j: max(area[i], area[j]) / max(min(area[i], area[j]), 1) <= 3)
    block = components(n, pairs, lambda i, j: True)
    d = pd.DataFrame({"gidx": np.arange(n), "row": row})
    d["row_n"] = np.log(pd.Series(row).map(pd.Series(row).value_counts()).values)
    d["block_n"] = np.log(pd.Series(block).map(pd.Series(block).value_counts()).values)
    d["block_area"] = np.log(pd.Series(area).groupby(block).transform("sum").values)
    attached = np.zeros(n)
    for i, j in pairs:
        attached[i] = attached[j] = 1
    la = np.log(np.maximum(area, 1))
    kd = cKDTree(cen)
    for r in [50, 100, 200]:
        near = kd.query_ball_point(cen, r)
        d[f"cnt{r}"] = [np.log1p(len(js) - 1) for js in near]
        d[f"built{r}"] = [area[js].sum() / (np.pi * r * r) for js in near]
        d[f"medla{r}"] = [np.median(la[js]) for js in near]
        d[f"iqrla{r}"] = [np.subtract(*np.percentile(la[js], [75, 25])) for js in near]
        d[f"att{r}"] = [attached[js].mean() for js in near]
    dist, idx = kd.query(cen, k=min(16, n))
    d["nndist"] = np.log1p(dist[:, 1])
    d["knn_dist"] = np.log1p(dist[:, 1:].mean(1))
    d["knn_la"] = la[idx[:, 1:]].mean(1)
    d["knn_att"] = attached[idx[:, 1:]].mean(1)
    return d


def load(dump, truth_dir):
    d = pd.read_csv(dump)
    d["city"] = d.case.str.split("/").str[-2]
    parts = []
    for c in SIX:
        g = d[d.city == c].copy()
        t = pd.read_csv(f"{truth_dir}/{c}/truth.csv", dtype=str)
        ids = dict(zip(t.source_id, t.id))
        ids.update({i: i for i in t.id})
        g["gidx"] = [int(ids[str(i)].split("/")[1]) for i in g.id]
        g = g.merge(context(f"{truth_dir}/{c}/footprints.shp"), on="gidx", how="left")
        parts.append(g)
    d = pd.concat(parts, ignore_index=True)
    d["zl"] = logit(d.zone_pitched)
    d["prior"] = prior(d)
    d["area"] = np.exp(d.log_area)
    return d


def report(d, name, p, flat_rows=False):
    m = d.pitched.notna().values
    ok = (p >= 0.5) == (d.pitched >= 0.5).values
    per = {c: ok[m & (d.city == c).values].mean() for c in SIX}
    line = (f"{name:46s} pooled {100 * ok[m].mean():5.1f} min {100 * min(per.values()):3.0f} | "
            + " ".join(f"{c[:9]} {100 * v:3.0f}" for c, v in per.items()))
    if flat_rows:
        att = (d.shared_wall_share >= 0.1).values & (d.area >= 30).values & (d.pitched == 0).values
        line += " | flat attached drawn pitched " + " ".join(
            f"{c[:9]} {100 * (p[att & (d.city == c).values] >= 0.5).mean():4.1f}"
            for c in ["denhaag", "rotterdam_delfshaven", "delft"])
    print(line, flush=True)


def weights(d, mask):
    return (1.0 / d[mask].groupby("city").city.transform("size")).values


def loco(d, make, feats):
    r = d[d.pitched.notna()]
    y = (r.pitched >= 0.5).astype(int).values
    p = np.full(len(d), np.nan)
    for c in SIX:
        tr = (r.city != c).values
        m = make()
        key = "logisticregression__sample_weight" if hasattr(m, "steps") else "sample_weight"
        m.fit(r.loc[tr, feats].values, y[tr], **{key: weights(r, tr)})
        p[r.index[~tr]] = m.predict_proba(r.loc[~tr, feats].values)[:, 1]
    return p


def within_shape(d, feats, level):
    """Trees with one intercept per training place (a one-hot column each); the left-out
    place's score averaged over the training places' intercepts, then drawn pitched for the
    top `level(place)` share of its roofs."""
    from sklearn.ensemble import HistGradientBoostingClassifier

    r = d[d.pitched.notna()]
    y = (r.pitched >= 0.5).astype(int).values
    dummies = pd.get_dummies(r.city).reindex(columns=SIX, fill_value=0).values.astype(float)
    x = np.hstack([r[feats].values, dummies])
    p = np.full(len(d), np.nan)
    for k, c in enumerate(SIX):
        tr = (r.city != c).values
        m = HistGradientBoostingClassifier(max_depth=3, max_iter=150, learning_rate=0.05,
                                           min_samples_leaf=30, random_state=0)
        m.fit(x[tr], y[tr], sample_weight=weights(r, tr))
        scores = []
        for j in range(len(SIX)):
            if j == k:
                continue
            xt = x[~tr].copy()
            xt[:, len(feats):] = 0
            xt[:, len(feats) + j] = 1
            q = m.predict_proba(xt)[:, 1]
            scores.append(np.log(q / (1 - q)))
        s = np.mean(scores, 0)
        share = level(r[~tr])
        p[r.index[~tr]] = (s >= np.quantile(s, 1 - share)).astype(float)
    return p


def rows(d, z, rule):
    """`roof_rows` over the prior's log-odds `z`: each row of like size one family."""
    p = 1 / (1 + np.exp(-z))
    out = p.copy()
    for _, g in d.groupby(["city", "row"]):
        if len(g) < 2:
            continue
        i = g.index.values
        w = d.area.values[i]
        if rule == "area-weighted mean probability (shipped)":
            v = np.average(p[i], weights=w)
        elif rule == "area-weighted mean log-odds":
            v = 1 / (1 + np.exp(-np.average(z[i], weights=w)))
        elif rule == "area-weighted vote":
            v = np.average((p[i] >= 0.5).astype(float), weights=w)
        else:  # "members' vote, ties pitched"
            v = np.mean(p[i] >= 0.5)
        out[i] = v
    return out


def main():
    from sklearn.ensemble import HistGradientBoostingClassifier
    from sklearn.linear_model import LogisticRegression
    from sklearn.pipeline import make_pipeline
    from sklearn.preprocessing import StandardScaler

    d = load(sys.argv[1], sys.argv[2] if len(sys.argv) > 2 else "tests/data/truth")
    trees = lambda: HistGradientBoostingClassifier(max_depth=3, max_iter=100, random_state=0)  # noqa: E731
    linear = lambda: make_pipeline(StandardScaler(), LogisticRegression(C=0.1, max_iter=3000))  # noqa: E731
    print("share of measured roofs right (%), each place scored by a rule fitted on the others")
    report(d, "as shipped (prior, rows; in sample)", d.est_pitched.values, True)
    report(d, "prior alone (no rows)", 1 / (1 + np.exp(-d.prior.values)), True)
    report(d, "each place's majority (oracle)", d.groupby("city").pitched.transform("mean").values)
    for name, make in [("trees", trees), ("logistic", linear)]:
        report(d, f"{name}: features", loco(d, make, FEATURES))
        report(d, f"{name}: features, zone", loco(d, make, FEATURES + ["zl"]))
        report(d, f"{name}: features, zone, context", loco(d, make, FEATURES + ["zl"] + CONTEXT))
    for feats, name in [(FEATURES, "features"), (FEATURES + CONTEXT, "features, context"),
                        (["log_area"], "area")]:
        report(d, f"within shape ({name}), place's own level",
               within_shape(d, feats, lambda g: (g.pitched >= 0.5).mean()))
        report(d, f"within shape ({name}), zone's level",
               within_shape(d, feats, lambda g: g.zone_pitched.mean()))
    for rule in ["area-weighted mean probability (shipped)", "area-weighted mean log-odds",
                 "area-weighted vote", "members' vote, ties pitched"]:
        report(d, f"prior, rows: {rule}", rows(d, d.prior.values, rule), True)


if __name__ == "__main__":
    main()
