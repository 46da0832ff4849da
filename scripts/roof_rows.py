#!/usr/bin/env python3
"""Rows and annexes of the roof estimate (issue 42; docs/truth.md, "Roofs, fifth pass").

Reads `citygen eval ... --seed 1 --dump DUMP.csv` and the truth folders' footprints, finds the
touching pairs (2 m of wall or more, as `scripts/roof_levels.py`), rows of like size (at most
3 times apart) and blocks, and prints:

1. the measured truth's touching pairs: how often they differ in roof family, like-sized and
   unlike-sized, and for the smaller footprint of an unlike pair how often its own estimate,
   its larger neighbour's estimate, or its larger neighbour's measured family is right;
2. leave one place out (fitted on the other five places with measured roofs, places weighted
   equally): a logistic correction of the prior's log-odds (as an offset) by terms of the
   row as a unit (in a row, its member count, its median depth, its mean log area, the
   block's count), then the rows step; the share right per place and the share of attached
   flat roofs drawn pitched (Den Haag, Delfshaven, Delft);
3. what giving an annex (in no like-sized row, touching a footprint more than 3 times larger)
   its host's family does to the pairs differing and to the roofs right (`roof_annexes` in
   `src/prepare/estimate.rs`, ported over citygen's own estimates: run it on a dump of a
   build without that step).

    citygen eval <the cases of docs/truth.md> --seed 1 --dump dump.csv
    python3 scripts/roof_rows.py dump.csv [tests/data/truth]

Needs numpy, pandas, scipy, pyshp and shapely. Deterministic.
"""

import os
import sys

import numpy as np
import pandas as pd
from scipy.optimize import minimize

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import roof_levels as rl  # noqa: E402

SIX = ["denhaag", "rotterdam_delfshaven", "zurich", "delft", "matsumoto", "ina"]
PLACES = SIX + ["tatebayashi", "moroyama", "niiza"]
DUTCH = ["denhaag", "rotterdam_delfshaven", "delft"]


def logit(p):
    p = np.clip(p, 0.05, 0.95)
    return np.log(p / (1 - p))


def place(dump, truth_dir, c):
    g = dump[dump.city == c].copy()
    t = pd.read_csv(f"{truth_dir}/{c}/truth.csv", dtype=str)
    ids = dict(zip(t.source_id, t.id))
    ids.update({i: i for i in t.id})
    g["i"] = [int(ids[str(i)].split("/")[1]) for i in g.id]
    polys = rl.footprints(f"{truth_dir}/{c}/footprints.shp")
    n = len(polys)
    pairs = rl.touching_pairs(polys)
    area = np.array([p.area for p in polys])
    row = rl.components(n, pairs,
                        lambda i, j: max(area[i], area[j]) / max(min(area[i], area[j]), 1) <= 3)
    blk = rl.components(n, pairs, lambda i, j: True)
    d = pd.DataFrame({"i": np.arange(n), "area": area, "row": row, "blk": blk})
    d["row_n"] = d.groupby("row").i.transform("size")
    d["blk_n"] = d.groupby("blk").i.transform("size")
    d = d.merge(g[["i", "est_pitched", "pitched", "zone_pitched", "log_area", "log_width",
                   "elongation", "shared_wall_share"]], on="i", how="left")
    d["city"] = c
    return d, pairs


def truth_pairs(d, pairs, c):
    est, tru, area = d.est_pitched.values, d.pitched.values, d.area.values
    rows = []
    for i, j in pairs:
        a, b = (i, j) if area[i] <= area[j] else (j, i)
        rows.append((area[b] / max(area[a], 1), area[a], est[a], est[b], tru[a], tru[b]))
    p = pd.DataFrame(rows, columns="ratio small es el ts tl".split()).dropna()
    if p.empty:
        return
    u = p.ratio > 3
    differ = (p.ts >= 0.5) != (p.tl >= 0.5)
    line = (f"{c:22s} truth pairs differ: like-sized {100 * differ[~u].mean():4.1f} % of {(~u).sum()}, "
            f"3 times apart or more {100 * differ[u].mean():4.1f} % of {u.sum()}")
    for name, m in [("smaller under 30 m²", u & (p.small < 30)), ("smaller 30 m² and more", u & (p.small >= 30))]:
        q = p[m]
        if len(q):
            right = lambda col: ((q[col] >= 0.5) == (q.ts >= 0.5)).mean()  # noqa: E731
            line += (f" | {name} (n {len(q)}): pitched {q.ts.mean():.2f}, right by its own "
                     f"{right('es'):.2f}, its host's estimate {right('el'):.2f}, host's truth {right('tl'):.2f}")
    print(line)


def rows_step(a, z):
    p = 1 / (1 + np.exp(-z))
    key = (a.city + "/" + a.row.astype(str)).values
    w = a.area.values
    s = (pd.Series(p * w).groupby(key).transform("sum") / pd.Series(w).groupby(key).transform("sum")).values
    return np.where(a.row_n.values >= 2, s, p)


def score(a, p, name):
    m = a.pitched.notna().values
    ok = (p >= 0.5) == (a.pitched.values >= 0.5)
    per = {c: ok[m & (a.city == c).values].mean() for c in SIX}
    att = m & (a.shared_wall_share.values >= 0.1) & (a.area.values >= 30) & (a.pitched.values < 0.5)
    fdp = {c: (p[att & (a.city == c).values] >= 0.5).mean() for c in DUTCH}
    print(f"{name:44s} pooled {100 * ok[m].mean():5.1f} | "
          + " ".join(f"{c[:9]} {100 * v:4.1f}" for c, v in per.items())
          + " | flat attached drawn pitched " + " ".join(f"{c[:9]} {100 * v:4.1f}" for c, v in fdp.items()))


def fit(a, tr, x):
    y = (a.pitched.values[tr] >= 0.5).astype(float)
    off = a.prior.values[tr]
    w = 1 / a[tr].groupby("city").city.transform("size").values
    xt = x[tr]

    def f(b):
        p = 1 / (1 + np.exp(-(off + xt @ b)))
        loss = -(w * (y * np.log(p + 1e-9) + (1 - y) * np.log(1 - p + 1e-9))).sum() + 1e-3 * b @ b
        return loss, xt.T @ (w * (p - y)) + 2e-3 * b

    return minimize(f, np.zeros(x.shape[1]), jac=True).x


def main():
    truth_dir = sys.argv[2] if len(sys.argv) > 2 else "tests/data/truth"
    dump = pd.read_csv(sys.argv[1])
    dump["city"] = dump.case.str.split("/").str[-2]
    parts, all_pairs = [], {}
    print("1. the measured truth's touching pairs")
    for c in PLACES:
        d, pairs = place(dump, truth_dir, c)
        parts.append(d)
        all_pairs[c] = pairs
        truth_pairs(d, pairs, c)
    a = pd.concat(parts, ignore_index=True)
    a = a[a.log_area.notna() & a.city.isin(SIX)].reset_index(drop=True)
    a["area"] = np.exp(a.log_area)  # the estimator's own area (its size steps, the weights)
    size = np.select([a.area < 30, a.area < 60, a.area < 120, a.area < 250, a.area < 600],
                     [-1.5, 0.8, -0.3, 0.0, -1.0], -1.5)
    a["prior"] = 0.5 * logit(a.zone_pitched) + size
    a["inrow"] = (a.row_n >= 2).astype(float)
    a["log_row_n"] = np.log(a.row_n) * a.inrow
    depth = np.exp(a.log_width) / a.elongation.clip(0.05)
    a["row_depth"] = np.log(depth.groupby([a.city, a.row]).transform("median") / 10) * a.inrow
    a["row_log_area"] = a.groupby(["city", "row"]).log_area.transform("mean") * a.inrow
    a["log_blk_n"] = np.log(a.blk_n)
    print("2. leave one place out, the row as a unit (share right %)")
    score(a, a.est_pitched.values, "citygen (the dump)")
    score(a, rows_step(a, a.prior.values), "prior and rows (port)")
    m = a.pitched.notna().values
    for feats in [["inrow"], ["inrow", "log_row_n"], ["inrow", "row_depth"],
                  ["inrow", "log_row_n", "row_depth"], ["inrow", "row_log_area"],
                  ["inrow", "row_depth", "log_blk_n"]]:
        x = a[feats].values
        z = a.prior.values.copy()
        for c in SIX:
            te = (a.city == c).values
            z[te] += x[te] @ fit(a, m & ~te, x)
        score(a, rows_step(a, z), "left out: prior + " + " + ".join(feats))
    print("3. annexes take their host's family (over the dump's estimates)")
    for c in PLACES:
        d = [p for p in parts if p.city.iloc[0] == c][0]
        area, est, tru = d.area.values, d.est_pitched.values.copy(), d.pitched.values
        host = -np.ones(len(area), int)
        for i, j in all_pairs[c]:
            for s, l in [(i, j), (j, i)]:
                if area[l] > 3 * max(area[s], 1) and (host[s] < 0 or area[l] > area[host[s]]):
                    host[s] = l
        new = est.copy()
        for s in np.argsort(-area, kind="stable"):
            h = host[s]
            if h >= 0 and d.row_n.values[s] == 1 and not np.isnan(est[s]) and not np.isnan(new[h]):
                new[s] = new[h]
        differ = lambda p: np.mean([(p[i] >= 0.5) != (p[j] >= 0.5) for i, j in all_pairs[c]  # noqa: E731
                                    if not (np.isnan(p[i]) or np.isnan(p[j]))] or [0])
        mm = ~np.isnan(tru) & ~np.isnan(est)
        right = lambda p: ((p[mm] >= 0.5) == (tru[mm] >= 0.5)).sum()  # noqa: E731
        print(f"{c:22s} pairs differing {100 * differ(est):4.1f} -> {100 * differ(new):4.1f} %"
              + (f", roofs right {right(est)} -> {right(new)} of {mm.sum()}" if mm.sum() else ""))


if __name__ == "__main__":
    main()
