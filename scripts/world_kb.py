#!/usr/bin/env python3
"""Generate the shipped world knowledge base knowledge_base/kb.xml from its hand-edited source.

  python3 scripts/world_kb.py [--src knowledge_base/world/kb.src.xml] [--out knowledge_base/kb.xml]
                              [--tolerance 0.01] [--decimals 3] [--min-island-km2 10]

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


def first_crossing(ring):
    """polygon.rs's rule: adjacent edges must not fold back, others must not touch. Edges are
    bucketed by latitude bands so only edges sharing a band are compared."""
    n = len(ring)
    for i in range(n):
        a, s, b = ring[i - 1], ring[i], ring[(i + 1) % n]
        u = (a[0] - s[0], a[1] - s[1])
        v = (b[0] - s[0], b[1] - s[1])
        if u[0] * v[1] - u[1] * v[0] == 0.0 and u[0] * v[0] + u[1] * v[1] > 0.0:
            return (i - 1) % n, i
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
                if segments_touch(a, b, c, d):
                    return min(i, j), max(i, j)
    return None


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


def unwrap(ring):
    """Longitudes made continuous (TopoJSON rings jump from 180 to -180 where they cross the
    antimeridian); a ring that goes round a pole (Antarctica) is closed along the pole."""
    out = [ring[0]]
    for x, y in ring[1:]:
        px = out[-1][0]
        while x - px > 180.0:
            x -= 360.0
        while px - x > 180.0:
            x += 360.0
        out.append((x, y))
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


def build(topo, tol, decimals, min_island):
    raw = decode_arcs(topo)
    features = topo["objects"]["countries"]["geometries"]
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
    done = {}
    while True:
        simple = [
            [(round(x, decimals), round(y, decimals)) for x, y in simplify_arc(a, arc_tol[i])]
            for i, a in enumerate(raw)
        ]
        failing = []
        out = {}
        for f, r in jobs:
            pieces = []
            for p in split_wide(clean(ring_from(simple, r))):
                p = [(float(fmt(x, decimals)), float(fmt(y, decimals))) for x, y in p]
                for q in split_pinches(clean(p)):
                    q = clean(q)
                    # A pinch can leave a loop with no area (a spike): nothing to keep.
                    if len(q) >= 3 and ring_area_km2(q) > 0.0:
                        pieces.append(q)
            bad = [problem(q) for q in pieces if problem(q)]
            if bad or not pieces:
                failing.append((f, r, bad[0] if bad else "nothing left"))
            else:
                out.setdefault(f, []).extend(pieces)
        if not failing:
            return features, out, arc_tol
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
    ap.add_argument("--min-island-km2", type=float, default=10.0, help="rings smaller than this are dropped unless a feature's largest (default 10)")
    a = ap.parse_args()

    topo = load_topology()
    features, rings, arc_tol = build(topo, a.tolerance, a.decimals, a.min_island_km2)
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
        f"  dropped (a country's largest ring is always kept), holes dropped: {stats['rings']} rings,\n"
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
    return 0


if __name__ == "__main__":
    sys.exit(main())
