#!/usr/bin/env python3
"""Render part of a citygen GLB to a PNG (matplotlib, flat shaded) to look at the geometry.

  python3 scripts/render_glb.py out/monaco.glb out/monaco.png [--center X Z] [--radius R]
          [--elev 35] [--azim -60]

X/Z are glTF coordinates (east, -north) around the file's local origin. Needs numpy and
matplotlib (pip install numpy matplotlib).
"""
import argparse, json, struct
import numpy as np
import matplotlib
matplotlib.use("Agg")
import matplotlib.pyplot as plt
from mpl_toolkits.mplot3d.art3d import Poly3DCollection

ap = argparse.ArgumentParser()
ap.add_argument("glb"); ap.add_argument("png")
ap.add_argument("--center", nargs=2, type=float); ap.add_argument("--radius", type=float, default=120)
ap.add_argument("--elev", type=float, default=35); ap.add_argument("--azim", type=float, default=-60)
a = ap.parse_args()
data = open(a.glb, "rb").read()
jlen = struct.unpack_from("<I", data, 12)[0]
doc = json.loads(data[20:20 + jlen]); bin_ = data[20 + jlen + 8:]

def accessor(i):
    acc = doc["accessors"][i]; view = doc["bufferViews"][acc["bufferView"]]
    off = view.get("byteOffset", 0) + acc.get("byteOffset", 0); n = acc["count"]
    ct = acc["componentType"]
    if ct == 5126:
        stride = view.get("byteStride", 12)
        return np.array([struct.unpack_from("<3f", bin_, off + k * stride) for k in range(n)])
    fmt, size = ("<H", 2) if ct == 5123 else ("<I", 4)
    return np.array([struct.unpack_from(fmt, bin_, off + k * size)[0] for k in range(n)])

tris, cols = [], []
center = np.array(a.center) if a.center else None
for root in doc["scenes"][0]["nodes"]:
    node = doc["nodes"][root]
    for c in node.get("children", []):
        child = doc["nodes"][c]
        for prim in doc["meshes"][child["mesh"]]["primitives"]:
            pos = accessor(prim["attributes"]["POSITION"])
            if center is not None and np.min(np.hypot(pos[:, 0] - center[0], pos[:, 2] - center[1])) > a.radius:
                continue
            idx = accessor(prim["indices"]).reshape(-1, 3)
            nrm = accessor(prim["attributes"]["NORMAL"])
            base = np.array(doc["materials"][prim["material"]]["pbrMetallicRoughness"]["baseColorFactor"][:3]) ** (1 / 2.2)
            for t in idx:
                p = pos[t]
                shade = 0.55 + 0.45 * max(0.0, float(np.dot(nrm[t[0]], [0.4, 0.8, 0.45])))
                tris.append(p[:, [0, 2, 1]] * [1, -1, 1]); cols.append(np.clip(base * shade, 0, 1))
fig = plt.figure(figsize=(12, 9), dpi=110)
ax = fig.add_subplot(projection="3d")
ax.add_collection3d(Poly3DCollection(tris, facecolors=cols, edgecolors=(0, 0, 0, 0.15), linewidths=0.2))
allp = np.concatenate(tris)
lo, hi = allp.min(0), allp.max(0); span = (hi - lo).max()
mid = (lo + hi) / 2
ax.set_xlim(mid[0] - span / 2, mid[0] + span / 2); ax.set_ylim(mid[1] - span / 2, mid[1] + span / 2)
ax.set_zlim(0, span / 2)
ax.set_box_aspect((1, 1, 0.5)); ax.view_init(a.elev, a.azim); ax.set_axis_off()
plt.tight_layout(); plt.savefig(a.png)
print(f"{len(tris)} triangles -> {a.png}")
