#!/usr/bin/env python3
"""Generate the shipped world knowledge base knowledge_base/kb.xml from its hand-edited source.

  python3 scripts/world_kb.py [--src knowledge_base/world/kb.src.xml] [--out knowledge_base/kb.xml]
                              [--tolerance 0.01] [--decimals 3] [--min-island-km2 1] [--coast-km 3]

The source is a normal knowledge base in which each country zone holds a placeholder
`<boundary ne="NNN"/>` (NNN: the feature id of world-atlas, ISO 3166-1 numeric as a string, e.g.
"250"; it matches every feature with that id: "036" is Australia and the Ashmore and Cartier
Islands) or `<boundary name="Kosovo"/>` (a feature's name, for features without an id). Each
placeholder is replaced by one `<polygon points="lon lat, ..."/>` per ring, on its own line at
the placeholder's indentation; everything else of the source is kept byte for byte, and a header
comment saying the file is generated is added after the XML declaration.

Boundaries: Natural Earth 1:50m admin-0 countries (public domain) as packaged by the npm package
world-atlas@2.0.2 (ISC), file countries-50m.json (TopoJSON). The package is fetched once with
`npm pack` into target/world-atlas/ (git-ignored). The TopoJSON arcs (quantized, delta-encoded)
are decoded and each shared arc is simplified once (Douglas-Peucker, endpoints kept), so that two
neighbours' borders stay identical; each feature's outer rings are assembled from its arcs (holes
are dropped: an enclave is its own, smaller, zone and wins the tie at equal depth), rings below
--min-island-km2 are dropped unless they are the feature's largest, rings spanning more than 180
degrees of longitude (Antarctica) are split, and every ring is checked against the reader's rules
(src/kb/polygon.rs: at least 3 distinct points, at most 4096, no self-intersection, non-zero area,
lon span <= 180). The arcs of a ring that fails are simplified again at half the tolerance (down
to none) until every ring passes.

Coast buffer: the arcs used by one feature only border the sea; their vertices are pushed out by
--coast-km along the outward bisector (local km frame, miter at most twice the offset), tapered
to 0 towards the points where a coast meets a land border, which stay exact. The offset of the
vertices of edges where a ring crosses itself, or crosses another feature's ring, is halved
(down to 0) until it does not; a ring still failing the reader's rules is retried at half the
offset as a whole, then none.

Python 3 standard library only. Exit status 1 when a placeholder matches no feature or a ring
cannot be made valid; features the source does not reference are listed as warnings.
"""
import argparse
import json
import math
import os
import re
import subprocess
import sys
import tarfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
PACKAGE = "world-atlas@2.0.2"
TARBALL = "world-atlas-2.0.2.tgz"
MEMBER = "package/countries-50m.json"
CACHE = os.path.join(ROOT, "target", "world-atlas")
MAX_POINTS = 4096  # src/kb/dom.rs MAX_POLYGON_POINTS
EARTH_RADIUS_KM = 6371.0088
KM_PER_DEG = EARTH_RADIUS_KM * math.pi / 180.0
PLACEHOLDER = re.compile(
    r'^([ \t]*)<boundary\s+(ne|name)\s*=\s*"([^"]*)"\s*/>[ \t]*\r?\n', re.M
)


def load_topology():
    path = os.path.join(CACHE, TARBALL)
    if not os.path.exists(path):
        os.makedirs(CACHE, exist_ok=True)
        print(f"fetching {PACKAGE} with npm pack into {os.path.relpath(CACHE, ROOT)}", file=sys.stderr)
        subprocess.run(["npm", "pack", PACKAGE], cwd=CACHE, check=True, stdout=subprocess.DEVNULL)
    with tarfile.open(path) as t:
        return json.load(t.extractfile(MEMBER))


def decode_arcs(topo):
    (sx, sy), (tx, ty) = topo["transform"]["scale"], topo["transform"]["translate"]
    arcs = []
    for arc in topo["arcs"]:
        x = y = 0
        pts = []
        for dx, dy in arc:
            x += dx
            y += dy
            pts.append((x * sx + tx, y * sy + ty))
        arcs.append(pts)
    return arcs


# ---------------------------------------------------------------- simplification


def seg_dist2(p, a, b, k):
    """Squared distance from p to segment ab, x scaled by k (cos of the latitude)."""
    ax, ay, bx, by, px, py = a[0] * k, a[1], b[0] * k, b[1], p[0] * k, p[1]
    dx, dy = bx - ax, by - ay
    l2 = dx * dx + dy * dy
    if l2 == 0.0:
        return (px - ax) ** 2 + (py - ay) ** 2
    t = max(0.0, min(1.0, ((px - ax) * dx + (py - ay) * dy) / l2))
    return (px - ax - t * dx) ** 2 + (py - ay - t * dy) ** 2


def douglas_peucker(pts, tol, keep=()):
    """Indices kept by Douglas-Peucker (first and last always, and those in `keep`)."""
    n = len(pts)
    if n <= 2 or tol <= 0.0:
        return list(range(n))
    k = math.cos(math.radians(sum(p[1] for p in pts) / n))
    tol2 = tol * tol
    kept = [False] * n
    kept[0] = kept[-1] = True
    for i in keep:
        kept[i] = True
    anchors = [i for i in range(n) if kept[i]]
    stack = list(zip(anchors, anchors[1:]))
    while stack:
        i, j = stack.pop()
        if j <= i + 1:
            continue
        best, far = -1.0, -1
        for m in range(i + 1, j):
            d = seg_dist2(pts[m], pts[i], pts[j], k)
            if d > best:
                best, far = d, m
        if best > tol2:
            kept[far] = True
            stack.append((i, far))
            stack.append((far, j))
    return [i for i in range(n) if kept[i]]


def simplify_arc(pts, tol):
    if tol <= 0.0 or len(pts) <= 3:
        return list(pts)
    keep = ()
    if pts[0] == pts[-1]:
        # A closed arc (an island): keep the point farthest from the start and the one farthest
        # from that chord, so that it stays a ring.
        d = [(p[0] - pts[0][0]) ** 2 + (p[1] - pts[0][1]) ** 2 for p in pts]
        f1 = max(range(len(pts)), key=d.__getitem__)
        k = math.cos(math.radians(pts[0][1]))
        f2 = max(range(len(pts)), key=lambda m: seg_dist2(pts[m], pts[0], pts[f1], k))
        keep = (f1, f2)
    return [pts[i] for i in douglas_peucker(pts, tol, keep)]


# ---------------------------------------------------------------- ring checks (as polygon.rs)


def ring_area_km2(ring):
    n = len(ring)
    lat0 = sum(p[1] for p in ring) / n
    kx = KM_PER_DEG * math.cos(math.radians(lat0))
    twice = 0.0
    for i in range(n):
        a, b = ring[i], ring[(i + 1) % n]
        twice += (a[0] * kx) * (b[1] * KM_PER_DEG) - (b[0] * kx) * (a[1] * KM_PER_DEG)
    return abs(twice / 2.0)


def orient(a, b, c):
    return (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])


def on_segment(a, b, p):
    return min(a[0], b[0]) <= p[0] <= max(a[0], b[0]) and min(a[1], b[1]) <= p[1] <= max(a[1], b[1])


def segments_touch(a, b, c, d):
    o1, o2, o3, o4 = orient(a, b, c), orient(a, b, d), orient(c, d, a), orient(c, d, b)
    if ((o1 > 0 > o2) or (o1 < 0 < o2)) and ((o3 > 0 > o4) or (o3 < 0 < o4)):
        return True
    return (
        (o1 == 0 and on_segment(a, b, c))
        or (o2 == 0 and on_segment(a, b, d))
        or (o3 == 0 and on_segment(c, d, a))
        or (o4 == 0 and on_segment(c, d, b))
    )


def crossings(ring):
    """Yields the pairs of edges that break polygon.rs's rule, each once: adjacent edges that
    fold back, then other edges that touch. Edges are bucketed by latitude bands so only edges
    sharing a band are compared."""
    n = len(ring)
    for i in range(n):
        a, s, b = ring[i - 1], ring[i], ring[(i + 1) % n]
        u = (a[0] - s[0], a[1] - s[1])
        v = (b[0] - s[0], b[1] - s[1])
        if u[0] * v[1] - u[1] * v[0] == 0.0 and u[0] * v[0] + u[1] * v[1] > 0.0:
            yield (i - 1) % n, i
    lo = min(p[1] for p in ring)
    hi = max(p[1] for p in ring)
    nb = max(1, n // 4)
    h = (hi - lo) / nb or 1.0
    bands = [[] for _ in range(nb)]
    for i in range(n):
        a, b = ring[i], ring[(i + 1) % n]
        b0 = min(nb - 1, int((min(a[1], b[1]) - lo) / h))
        b1 = min(nb - 1, int((max(a[1], b[1]) - lo) / h))
        for k in range(b0, b1 + 1):
            bands[k].append(i)
    seen = set()
    for band in bands:
        m = len(band)
        for x in range(m):
            i = band[x]
            a, b = ring[i], ring[(i + 1) % n]
            ax0, ax1 = min(a[0], b[0]), max(a[0], b[0])
            ay0, ay1 = min(a[1], b[1]), max(a[1], b[1])
            for y in range(x + 1, m):
                j = band[y]
                if j == i + 1 or i == j + 1 or (i == 0 and j == n - 1) or (j == 0 and i == n - 1):
                    continue
                c, d = ring[j], ring[(j + 1) % n]
                if max(c[0], d[0]) < ax0 or min(c[0], d[0]) > ax1:
                    continue
                if max(c[1], d[1]) < ay0 or min(c[1], d[1]) > ay1:
                    continue
                key = (min(i, j), max(i, j))
                if key not in seen and segments_touch(a, b, c, d):
                    seen.add(key)
                    yield key


def first_crossing(ring):
    """polygon.rs's rule: the first pair of edges that breaks it, or None."""
    return next(crossings(ring), None)


def clean(ring):
    """The ring as polygon.rs stores it: consecutive repeats and the closing vertex removed."""
    out = []
    for p in ring:
        if not out or out[-1] != p:
            out.append(p)
    if len(out) > 1 and out[0] == out[-1]:
        out.pop()
    return out


def problem(ring):
    """None when the reader accepts the (cleaned) ring, else the reason."""
    if len(ring) < 3:
        return "fewer than 3 distinct points"
    if len(ring) > MAX_POINTS:
        return f"{len(ring)} points (more than {MAX_POINTS})"
    lons = [p[0] for p in ring]
    if max(lons) - min(lons) > 180.0:
        return "spans more than 180 degrees of longitude"
    if first_crossing(ring):
        return "crosses itself"
    if not ring_area_km2(ring) > 0.0:
        return "no area"
    return None


# ---------------------------------------------------------------- antimeridian


def continuous_lon(ring):
    """The ring with each longitude moved by whole turns to within 180° of the one before."""
    out = [ring[0]]
    for x, y in ring[1:]:
        px = out[-1][0]
        while x - px > 180.0:
            x -= 360.0
        while px - x > 180.0:
            x += 360.0
        out.append((x, y))
    return out


def unwrap(ring):
    """Longitudes made continuous (TopoJSON rings jump from 180 to -180 where they cross the
    antimeridian); a ring that goes round a pole (Antarctica) is closed along the pole."""
    out = continuous_lon(ring)
    shift = out[-1][0] - out[0][0]
    if abs(shift) > 180.0:
        pole = -90.0 if sum(p[1] for p in out) < 0 else 90.0
        out += [(out[-1][0], pole), (out[0][0], pole)]
    return out


def cut_along(ring, m):
    """The parts of a simple ring on each side of the meridian m (x < m, x >= m). The ring is
    cut into chains at its crossings; the crossings sorted by latitude pair up into the
    intervals of the meridian inside the ring (even-odd), which link the chains into rings."""
    n = len(ring)
    east = [p[0] >= m for p in ring]
    if all(east) or not any(east):
        return [ring]
    start = next(i for i in range(n) if east[i - 1] != east[i])
    r, s = ring[start:] + ring[:start], east[start:] + east[:start]

    def cross(a, b):
        return (m, a[1] + (m - a[0]) * (b[1] - a[1]) / (b[0] - a[0]))

    first = cross(r[-1], r[0])
    chains, sides, cur = [], [], [first]
    for i in range(n):
        cur.append(r[i])
        j = (i + 1) % n
        if s[j] != s[i]:
            c = first if j == 0 else cross(r[i], r[j])
            cur.append(c)
            chains.append(cur)
            sides.append(s[i])
            cur = [c]
    k = len(chains)  # chain t ends at crossing t and chain t + 1 starts there
    order = sorted(range(k), key=lambda t: chains[t][-1][1])
    partner = {}
    for a, b in zip(order[0::2], order[1::2]):
        partner[a], partner[b] = b, a
    out, seen = [], set()
    for t in range(k):
        if t in seen:
            continue
        loop, u = [], t
        while u not in seen:
            seen.add(u)
            loop.extend(chains[u])
            u = (partner[u] + 1) % k
            if sides[u] != sides[t]:
                raise SystemExit("a ring could not be cut along a meridian (not simple?)")
        out.append(loop)
    return out


def split_wide(ring):
    """A ring in [-180, 180] spanning at most 180 degrees, or its parts cut along the
    antimeridian (and the Greenwich meridian for a ring round a pole)."""
    ring = unwrap(ring)
    out = []
    todo = [ring]
    while todo:
        r = todo.pop()
        lons = [p[0] for p in r]
        lo, hi = min(lons), max(lons)
        if hi - lo <= 180.0 and lo >= -180.0 and hi <= 180.0:
            out.append(r)
            continue
        if lo >= 180.0 or hi <= -180.0:
            d = -360.0 if lo >= 180.0 else 360.0
            todo.append([(x + d, y) for x, y in r])
            continue
        cuts = [m for m in (-180.0, 180.0, 0.0, -360.0, 360.0) if lo < m < hi]
        parts = cut_along(r, cuts[0])
        if len(parts) < 2:
            raise SystemExit("a ring could not be cut along a meridian")
        todo.extend(parts)
    return out


def split_pinches(ring):
    """A ring that passes twice through one vertex, cut there into two loops."""
    seen = {}
    for i, p in enumerate(ring):
        if p in seen:
            j = seen[p]
            return split_pinches(ring[j:i]) + split_pinches(ring[i:] + ring[:j])
        seen[p] = i
    return [ring]


# ---------------------------------------------------------------- coast buffer


def arc_uses(features):
    """How many times each arc is used by all rings (outer rings and holes) of all features: an
    arc used once borders the sea (a coast), one used twice is a land border."""
    uses = {}

    def walk(x):
        if isinstance(x, int):
            i = x if x >= 0 else ~x
            uses[i] = uses.get(i, 0) + 1
        else:
            for y in x:
                walk(y)

    for g in features:
        if g.get("arcs") is not None:
            walk(g["arcs"])
    return uses


def flagged_ring(simple, arc_ids, coastal):
    """The ring of arcs (no closing vertex, no consecutive repeats) and, per vertex, whether it
    stays fixed: on a land-border arc or where a coast meets a land border."""
    pts, fixed = [], []
    for a in arc_ids:
        i = a if a >= 0 else ~a
        p = arc_points(simple, a)
        coast = coastal[i]
        if pts:
            fixed[-1] = fixed[-1] or not coast  # the junction with the previous arc
            p = p[1:]
        pts.extend(p)
        fixed.extend([not coast] * len(p))
    if len(pts) > 1 and pts[0] == pts[-1]:
        fixed[0] = fixed[0] or fixed[-1]
        pts.pop()
        fixed.pop()
        last = arc_ids[-1] if arc_ids[-1] >= 0 else ~arc_ids[-1]
        fixed[0] = fixed[0] or not coastal[last]
    out, ofix = [], []
    for p, f in zip(pts, fixed):
        if out and out[-1] == p:
            ofix[-1] = ofix[-1] or f
        else:
            out.append(p)
            ofix.append(f)
    while len(out) > 1 and out[0] == out[-1]:
        ofix[0] = ofix[0] or ofix[-1]
        out.pop()
        ofix.pop()
    # Continuous longitudes (as unwrap, without closing a ring round a pole along the pole: the
    # two ends of such a ring stay fixed, and split_wide closes it later).
    u = continuous_lon(out)
    if abs(u[-1][0] - u[0][0]) > 180.0:
        ofix[0] = ofix[-1] = True
    return u, ofix


class Coast:
    """One ring to push out to sea: its points, fixed flags, the offset cap per vertex (km,
    tapered to 0 towards the fixed points: the offset line leaves a land border at 45 degrees)
    and the reduction factor per vertex (1 = full offset)."""

    def __init__(self, pts, fixed, km):
        n = len(pts)
        self.pts, self.fixed, self.km = pts, fixed, km
        twice = sum(pts[i][0] * pts[(i + 1) % n][1] - pts[(i + 1) % n][0] * pts[i][1] for i in range(n))
        self.ccw = twice > 0
        seg = []
        for i in range(n):
            a, b = pts[i], pts[(i + 1) % n]
            kx = KM_PER_DEG * math.cos(math.radians((a[1] + b[1]) / 2))
            seg.append(math.hypot((b[0] - a[0]) * kx, (b[1] - a[1]) * KM_PER_DEG))
        cap = [0.0 if f else km for f in fixed]
        if any(fixed):
            # Distance along the ring to the nearest fixed vertex, both ways (two passes round).
            d = [0.0 if f else math.inf for f in fixed]
            for _ in range(2):
                for i in range(n):
                    j = (i + 1) % n
                    d[j] = min(d[j], d[i] + seg[i])
            for _ in range(2):
                for i in range(n - 1, -1, -1):
                    j = (i + 1) % n
                    d[i] = min(d[i], d[j] + seg[i])
            cap = [min(km, x) for x in d]
        self.cap = cap
        self.factor = [1.0] * n
        self.moves = [c > 0.0 for c in cap]

    def offset(self, decimals):
        pts, n = self.pts, len(self.pts)
        out = []
        for i in range(n):
            c = pts[i]
            off = self.cap[i] * self.factor[i]
            if off <= 0.0:
                out.append(c)
                continue
            p, q = pts[i - 1], pts[(i + 1) % n]
            kx = KM_PER_DEG * max(0.05, math.cos(math.radians(c[1])))
            ux, uy = (c[0] - p[0]) * kx, (c[1] - p[1]) * KM_PER_DEG
            wx, wy = (q[0] - c[0]) * kx, (q[1] - c[1]) * KM_PER_DEG
            lu, lw = math.hypot(ux, uy), math.hypot(wx, wy)
            if lu == 0.0 or lw == 0.0:
                out.append(c)
                continue
            ux, uy, wx, wy = ux / lu, uy / lu, wx / lw, wy / lw
            # Outward normals: the interior is on the left of a counter-clockwise ring.
            if self.ccw:
                n1, n2 = (uy, -ux), (wy, -wx)
            else:
                n1, n2 = (-uy, ux), (-wy, wx)
            bx, by = n1[0] + n2[0], n1[1] + n2[1]
            lb = math.hypot(bx, by)
            if lb < 1e-9:  # a spike: out along it
                bx, by, cos_half = ux, uy, 1.0
            else:
                bx, by = bx / lb, by / lb
                cos_half = bx * n1[0] + by * n1[1]
            miter = off / max(cos_half, 0.5)  # the miter at most twice the offset
            x = c[0] + bx * miter / kx
            y = max(-90.0, min(90.0, c[1] + by * miter / KM_PER_DEG))
            out.append((round(x, decimals), round(y, decimals)))
        return out

    def reduce(self, i, spread=2):
        n = len(self.pts)
        hit = False
        for k in range(i - spread, i + spread + 1):
            k %= n
            if self.factor[k] > 0.0 and self.cap[k] > 0.0:
                self.factor[k] = self.factor[k] / 2 if self.factor[k] > 1 / 16 else 0.0
                hit = True
        return hit


def all_crossings(ring):
    """The pairs of edges (i, j) that break polygon.rs's rule (first_crossing, all of them)."""
    return list(crossings(ring))


def proper_cross(a, b, c, d):
    o1, o2, o3, o4 = orient(a, b, c), orient(a, b, d), orient(c, d, a), orient(c, d, b)
    return ((o1 > 0 > o2) or (o1 < 0 < o2)) and ((o3 > 0 > o4) or (o3 < 0 < o4))


def country_crossings(coasts, rings):
    """Edges of a ring that properly cross an edge of another feature's ring, as (job, vertex)
    pairs to reduce (the moved endpoints of both edges), and the set of feature pairs that
    overlap. `coasts` and `rings` are per job: (feature, Coast) and the offset points."""
    cell = 0.5
    grid = {}
    for jb, ((f, c), r) in enumerate(zip(coasts, rings)):
        n = len(r)
        for i in range(n):
            a, b = r[i], r[(i + 1) % n]
            for gx in range(int(math.floor(min(a[0], b[0]) / cell)), int(math.floor(max(a[0], b[0]) / cell)) + 1):
                for gy in range(int(math.floor(min(a[1], b[1]) / cell)), int(math.floor(max(a[1], b[1]) / cell)) + 1):
                    grid.setdefault((gx, gy), []).append((jb, i))
    hits, pairs, done = set(), set(), set()
    for edges in grid.values():
        if len(edges) < 2:
            continue
        for x in range(len(edges)):
            j1, i1 = edges[x]
            f1, c1 = coasts[j1]
            r1 = rings[j1]
            n1 = len(r1)
            m1 = c1.moves[i1] or c1.moves[(i1 + 1) % n1]
            a, b = r1[i1], r1[(i1 + 1) % n1]
            for y in range(x + 1, len(edges)):
                j2, i2 = edges[y]
                f2, c2 = coasts[j2]
                if f1 == f2:
                    continue
                r2 = rings[j2]
                n2 = len(r2)
                m2 = c2.moves[i2] or c2.moves[(i2 + 1) % n2]
                if not (m1 or m2):
                    continue
                key = (j1, i1, j2, i2)
                if key in done:
                    continue
                done.add(key)
                if proper_cross(a, b, r2[i2], r2[(i2 + 1) % n2]):
                    pairs.add((min(f1, f2), max(f1, f2)))
                    for jb, i, cc, n in ((j1, i1, c1, n1), (j2, i2, c2, n2)):
                        for k in (i, (i + 1) % n):
                            if cc.moves[k]:
                                hits.add((jb, k))
    return hits, pairs


# ---------------------------------------------------------------- assembly


def arc_points(simple, index):
    return simple[index] if index >= 0 else simple[~index][::-1]


def ring_from(simple, arc_ids):
    pts = []
    for a in arc_ids:
        p = arc_points(simple, a)
        pts.extend(p if not pts else p[1:])
    return pts


def jumps(ring):
    return sum(1 for i in range(1, len(ring)) if abs(ring[i][0] - ring[i - 1][0]) > 180.0)


def outer_rings(geometry, raw):
    """Each polygon's outer ring, and the rings that go round a pole (an odd number of jumps
    across the antimeridian): TopoJSON gives Antarctica as a degenerate ring along -89.999
    with the coast, round the pole, as its "hole"; unwrapped and closed along the pole, the
    coast is the outer ring (the degenerate ring is left to the island threshold)."""
    polys = {"Polygon": [geometry["arcs"]], "MultiPolygon": geometry["arcs"]}.get(geometry["type"], [])
    out = []
    for poly in polys:
        out.append(poly[0])
        out.extend(r for r in poly[1:] if jumps(ring_from(raw, r)) % 2 == 1)
    return out


def fmt(x, decimals):
    s = f"{x:.{decimals}f}"
    if "." in s:
        s = s.rstrip("0").rstrip(".")
    return "0" if s in ("-0", "") else s


def pieces_of(ring, decimals):
    """The rings the reader gets from one assembled ring: cut along the antimeridian, at the
    given decimals, split at pinches, loops with no area dropped."""
    pieces = []
    for p in split_wide(clean(ring)):
        p = [(float(fmt(x, decimals)), float(fmt(y, decimals))) for x, y in p]
        for q in split_pinches(clean(p)):
            q = clean(q)
            # A pinch can leave a loop with no area (a spike): nothing to keep.
            if len(q) >= 3 and ring_area_km2(q) > 0.0:
                pieces.append(q)
    return pieces


def buffer_coasts(coasts, decimals, log):
    """Offset rings: each Coast pushed out to sea; where the offset ring crosses itself (fjords,
    narrow straits) the offset is halved around the crossing (down to 0), and where it crosses
    another feature's ring likewise for both, for a few rounds."""
    def unself(c):
        if not any(c.moves):
            return c.pts
        for _ in range(40):
            o = c.offset(decimals)
            x = all_crossings(o)
            if not x:
                return o
            cut = False
            for i, j in x:
                n = len(o)
                for k in {i, (i + 1) % n, j, (j + 1) % n}:
                    cut = c.reduce(k, spread=0) or cut
            if not cut:
                return o
            c.self_cut = True
        return c.offset(decimals)

    rings = [unself(c) for f, c in coasts]
    pairs = set()
    first = None
    for rnd in range(8):
        hits, pairs = country_crossings(coasts, rings)
        if first is None:
            first = pairs
        log(f"coast buffer, round {rnd + 1}: {len(hits)} vertices where rings of two countries cross, {len(pairs)} pairs")
        if not hits:
            break
        touched = set()
        for jb, k in hits:
            c = coasts[jb][1]
            if c.reduce(k, spread=1):
                c.country_cut = True
                touched.add(jb)
        if not touched:
            break
        for jb in touched:
            rings[jb] = unself(coasts[jb][1])
    return rings, pairs, first or set()


def build(topo, tol, decimals, min_island, coast_km, log):
    raw = decode_arcs(topo)
    features = topo["objects"]["countries"]["geometries"]
    uses = arc_uses(features)
    coastal = [uses.get(i, 0) == 1 for i in range(len(raw))]
    # Which outer rings of each feature are kept (island threshold on the unsimplified ring).
    jobs = []  # (feature index, arc ids)
    for f, g in enumerate(features):
        rings = outer_rings(g, raw)
        if not rings:
            continue
        areas = [ring_area_km2(unwrap(clean(ring_from(raw, r)))) for r in rings]
        largest = max(range(len(rings)), key=areas.__getitem__)
        for k, r in enumerate(rings):
            if k == largest or areas[k] >= min_island:
                jobs.append((f, r))
    arc_tol = [tol] * len(raw)
    while True:
        simple = [
            [(round(x, decimals), round(y, decimals)) for x, y in simplify_arc(a, arc_tol[i])]
            for i, a in enumerate(raw)
        ]
        coasts = []
        for f, r in jobs:
            pts, fixed = flagged_ring(simple, r, coastal)
            c = Coast(pts, fixed, coast_km)
            c.self_cut = c.country_cut = False
            c.halved = 0
            coasts.append((f, c))
        offset, pairs, first = (
            buffer_coasts(coasts, decimals, log) if coast_km > 0 else ([c.pts for f, c in coasts], set(), set())
        )
        failing = []
        out = {}
        for jb, (f, r) in enumerate(jobs):
            c = coasts[jb][1]
            ring = offset[jb]
            while True:
                pieces = pieces_of(ring, decimals)
                bad = [problem(q) for q in pieces if problem(q)]
                if (not bad and pieces) or not any(x > 0 for x in c.factor):
                    break
                # The whole ring at half the offset (down to none).
                c.halved += 1
                c.factor = [x / 2 if c.halved < 5 else 0.0 for x in c.factor]
                ring = c.offset(decimals)
            if bad or not pieces:
                failing.append((f, r, bad[0] if bad else "nothing left"))
            else:
                out.setdefault(f, []).extend(pieces)
        if not failing:
            info = {
                "self_cut": sum(1 for f, c in coasts if c.self_cut),
                "country_cut": sum(1 for f, c in coasts if c.country_cut),
                "halved": sum(1 for f, c in coasts if c.halved),
                "smaller": sum(1 for f, c in coasts if c.self_cut or c.country_cut or c.halved),
                "buffered": sum(1 for f, c in coasts if any(c.moves)),
                "limited": sorted(
                    (features[a]["properties"]["name"], features[b]["properties"]["name"]) for a, b in first
                ),
                "overlaps": sorted(
                    (features[a]["properties"]["name"], features[b]["properties"]["name"]) for a, b in pairs
                ),
            }
            return features, out, arc_tol, info
        refined = False
        for f, r, why in failing:
            for a in r:
                i = a if a >= 0 else ~a
                if arc_tol[i] > 0:
                    arc_tol[i] = arc_tol[i] / 2 if arc_tol[i] > tol / 64 else 0.0
                    refined = True
        if not refined:
            for f, r, why in failing:
                print(f"error: a ring of {features[f]['properties']['name']}: {why}", file=sys.stderr)
            raise SystemExit(1)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--src", default=os.path.join(ROOT, "knowledge_base", "world", "kb.src.xml"))
    ap.add_argument("--out", default=os.path.join(ROOT, "knowledge_base", "kb.xml"))
    ap.add_argument("--tolerance", type=float, default=0.01, help="Douglas-Peucker tolerance, degrees of latitude (default 0.01, about 1.1 km)")
    ap.add_argument("--decimals", type=int, default=3, help="decimals of the written coordinates (default 3)")
    ap.add_argument("--min-island-km2", type=float, default=1.0, help="rings smaller than this are dropped unless a feature's largest (default 1)")
    ap.add_argument("--coast-km", type=float, default=3.0, help="coasts pushed out to sea by this distance, km (default 3; 0: none)")
    a = ap.parse_args()

    topo = load_topology()

    def log(msg):
        print(msg, file=sys.stderr)

    features, rings, arc_tol, info = build(topo, a.tolerance, a.decimals, a.min_island_km2, a.coast_km, log)
    by_id, by_name = {}, {}
    for f, g in enumerate(features):
        if g.get("id") is not None:
            by_id.setdefault(g["id"], []).append(f)
        by_name.setdefault(g["properties"]["name"], []).append(f)

    with open(a.src, encoding="utf-8", newline="") as fh:
        src = fh.read()
    used = set()
    errors = []
    stats = {"rings": 0, "points": 0}

    def replace(m):
        indent, key, value = m.group(1), m.group(2), m.group(3)
        eol = "\r\n" if m.group(0).endswith("\r\n") else "\n"
        found = (by_id if key == "ne" else by_name).get(value, [])
        if not found:
            line = src.count("\n", 0, m.start()) + 1
            errors.append(f"{a.src}:{line}: <boundary {key}=\"{value}\"/> matches no feature")
            return m.group(0)
        lines = []
        for f in found:
            used.add(f)
            for ring in rings.get(f, []):
                stats["rings"] += 1
                stats["points"] += len(ring)
                pts = ", ".join(f"{fmt(x, a.decimals)} {fmt(y, a.decimals)}" for x, y in ring)
                lines.append(f'{indent}<polygon points="{pts}"/>{eol}')
        return "".join(lines)

    body = PLACEHOLDER.sub(replace, src)
    # Left-over placeholders outside comments (a comment may mention <boundary .../>).
    bare = re.sub(r"<!--.*?-->", lambda c: re.sub(r"[^\n]", " ", c.group(0)), body, flags=re.S)
    if "<boundary" in bare:
        line = bare.count("\n", 0, bare.index("<boundary")) + 1
        errors.append(f"a <boundary> placeholder not alone on its line or malformed (near output line {line})")
    for e in errors:
        print(f"error: {e}", file=sys.stderr)
    for f, g in enumerate(features):
        if f not in used:
            print(
                f"warning: feature {g.get('id') or '-'} \"{g['properties']['name']}\" is not referenced by the source",
                file=sys.stderr,
            )
    if errors:
        return 1
    refined = sum(1 for t in arc_tol if t < a.tolerance)
    header = (
        "<!--\n"
        "  GENERATED FILE, do not edit: regenerate with `python3 scripts/world_kb.py`.\n"
        f"  Source: {os.path.relpath(a.src, ROOT)} with each <boundary/> placeholder replaced by the\n"
        "  country's outer rings from Natural Earth 1:50m admin-0 countries (public domain), as\n"
        f"  packaged by the npm package {PACKAGE} (ISC), countries-50m.json. Shared borders\n"
        f"  simplified once per arc (Douglas-Peucker, {a.tolerance} degrees; {refined} arcs finer so that\n"
        f"  every ring is simple), coordinates at {a.decimals} decimals, islands under {a.min_island_km2:g} km2\n"
        f"  dropped (a country's largest ring is always kept), holes dropped. Coasts (arcs of one\n"
        f"  feature only) pushed out to sea by {a.coast_km:g} km, land borders exact; {info['smaller']} of\n"
        f"  {info['buffered']} coastal rings with a smaller offset somewhere (self-crossing or another\n"
        f"  country's ring), {len(info['overlaps'])} pairs of countries overlapping: {stats['rings']} rings,\n"
        f"  {stats['points']} points.\n"
        "-->\n"
    )
    decl = re.match(r"<\?xml[^>]*\?>\r?\n", body)
    cut = decl.end() if decl else 0
    out = body[:cut] + header + body[cut:]
    tmp = a.out + ".tmp"
    with open(tmp, "w", encoding="utf-8", newline="") as fh:
        fh.write(out)
    os.replace(tmp, a.out)
    print(
        f"{os.path.relpath(a.out, ROOT)}: {len(out.encode('utf-8'))} bytes, {stats['rings']} rings, "
        f"{stats['points']} points, {len(used)} of {len(features)} features, {refined} arcs refined",
        file=sys.stderr,
    )
    print(
        f"coast buffer {a.coast_km:g} km: {info['buffered']} coastal rings, {info['smaller']} with a smaller offset "
        f"somewhere ({info['self_cut']} self-crossing, {info['country_cut']} another country, {info['halved']} "
        f"halved as a whole); offsets limited where rings of {len(info['limited'])} pairs of countries crossed: "
        f"{info['limited']}; {len(info['overlaps'])} overlapping pairs left {info['overlaps']}",
        file=sys.stderr,
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
