"""val3dity's per-surface checks, emulated with CGAL's own code, on CityJSON files.

    python3 scripts/val3dity-lite.py OUT.city.json...      (needs: pip install cgal numpy)

val3dity (TU Delft) is not on PyPI; this follows its src/Surface.cpp and src/geomtools.cpp
(read, not copied): each shell's points merged within the 1 mm snap tolerance in input order
(101/102 after the merge), the least-squares plane of each polygon's points (the eigenvector of
the smallest eigenvalue, as CGAL's linear_least_squares_fitting_3) with every point within 1 cm
(203), the rings projected with CGAL's Plane_3.to_2d, triangulated by CGAL's constrained
Delaunay triangulation, the faces inside the polygon marked by nesting level as CGAL's
mark_domains does (a flood fill across constrained edges), and every triangle's normal
within 20 degrees of the first one's (204). Not emulated: the GEOS ring checks (104-108, done
by tests/it/iso19107.rs) and the shell and solid checks (3xx, 4xx).

Slow (pure Python over CGAL): Monaco's LOD3 CityJSON, 1.6 M surfaces, takes about an hour of
a loaded machine. Prints the counts of each error code and the first objects found."""
import json, sys, math
import numpy as np
from CGAL.CGAL_Kernel import Point_3, Vector_3, Plane_3, Point_2
from CGAL.CGAL_Triangulation_2 import Constrained_Delaunay_triangulation_2

def check_surface(rings3):
    """rings3: list of rings, each a list of (x,y,z) floats, already snapped. Returns error code or None."""
    allp = np.array([p for r in rings3 for p in r])
    c = allp.mean(axis=0)
    cov = (allp - c).T @ (allp - c)
    w, v = np.linalg.eigh(cov)
    n = v[:, 0]
    d = np.abs((allp - c) @ n)
    if len(allp) > 3 and d.max() > 0.01:
        return "203 %.4f" % d.max()
    if len(rings3) == 1 and len(rings3[0]) == 3:
        return None
    plane = Plane_3(Point_3(*c), Vector_3(*n))
    cdt = Constrained_Delaunay_triangulation_2()
    rings2 = []
    where = {}
    for r in rings3:
        pts2 = []
        hs = []
        for p in r:
            q = plane.to_2d(Point_3(*p))
            pts2.append((q.x(), q.y()))
            h = cdt.insert(q)
            where.setdefault((q.x(), q.y()), p)
            hs.append(h)
        for i in range(len(hs)):
            cdt.insert_constraint(hs[i], hs[(i + 1) % len(hs)])
        rings2.append(pts2)
    # CGAL's mark_domains (as val3dity): nesting levels by flood fill from the infinite face
    # across constrained edges; a face is in the domain when its level is odd.
    def key(f):
        return frozenset(None if cdt.is_infinite(f.vertex(i)) else (f.vertex(i).point().x(), f.vertex(i).point().y()) for i in range(3))
    level = {}
    from collections import deque
    from CGAL.CGAL_Triangulation_2 import Constrained_Delaunay_triangulation_2_Edge as E
    border = deque([(cdt.infinite_face(), 0)])
    while border:
        f0, lev = border.popleft()
        if key(f0) in level:
            continue
        q = deque([f0]); level[key(f0)] = lev
        while q:
            f = q.popleft()
            for i in range(3):
                n = f.neighbor(i)
                if key(n) in level:
                    continue
                if cdt.is_constrained(E(f, i)):
                    border.append((n, lev + 1))
                else:
                    level[key(n)] = lev
                    q.append(n)
    first = None
    worst = 0.0
    for f in cdt.finite_faces():
        t2 = [f.vertex(i).point() for i in range(3)]
        if level.get(key(f), 0) % 2 != 1:
            continue
        q = [np.array(where[(p.x(), p.y())]) for p in t2]
        nn = np.cross(q[1] - q[0], q[2] - q[0])
        L = np.linalg.norm(nn)
        if L == 0:
            continue
        nn = nn / L
        if first is None:
            first = nn
            continue
        ang = math.degrees(math.atan2(np.linalg.norm(np.cross(first, nn)), first @ nn))
        worst = max(worst, ang)
    if worst > 20:
        return "204 %.1f" % worst
    return None

def main(path, tol=0.001):
    cj = json.load(open(path))
    sc = cj["transform"]["scale"]; tr = cj["transform"]["translate"]
    V = [(a * sc[0] + tr[0], b * sc[1] + tr[1], c_ * sc[2] + tr[2]) for a, b, c_ in cj["vertices"]]
    counts = {}
    bad = []
    nsurf = 0
    for oid, o in cj["CityObjects"].items():
        for g in o.get("geometry", []):
            t = g["type"]
            if t == "Solid":
                shells = g["boundaries"]
            elif t in ("MultiSurface", "CompositeSurface"):
                shells = [g["boundaries"]]
            else:
                continue
            for sh in shells:
                # val3dity's add_point: merge within tol of an earlier point of this primitive
                kept = []
                grid = {}
                def snap(i):
                    p = V[i]
                    key = tuple(int(math.floor(x / tol)) for x in p)
                    for dx in (-1, 0, 1):
                        for dy in (-1, 0, 1):
                            for dz in (-1, 0, 1):
                                for j in grid.get((key[0]+dx, key[1]+dy, key[2]+dz), []):
                                    q = kept[j]
                                    if (p[0]-q[0])**2 + (p[1]-q[1])**2 + (p[2]-q[2])**2 <= tol * tol:
                                        return j
                    kept.append(p); grid.setdefault(key, []).append(len(kept) - 1)
                    return len(kept) - 1
                for surf in sh:
                    nsurf += 1
                    rings = [[snap(i) for i in r] for r in surf]
                    err = None
                    for r in rings:
                        if len(r) < 3: err = "101"
                        elif any(r[k] == r[(k + 1) % len(r)] for k in range(len(r))): err = "102"
                    if err is None:
                        err = check_surface([[kept[i] for i in r] for r in rings])
                    if err:
                        code = err.split()[0]
                        counts[code] = counts.get(code, 0) + 1
                        if len(bad) < 15:
                            bad.append((oid, err))
    print(path, "surfaces", nsurf, "errors", counts)
    for b in bad:
        print("  ", *b)

if __name__ == "__main__":
    for p in sys.argv[1:]:
        main(p)
