#!/usr/bin/env python3
"""Write a copy of a citygen GLB that keeps some buildings and leaves out some classes, to look
inside a LOD4 building (standard library only; the binary chunk is copied unchanged).

  python3 scripts/glb_filter.py IN.glb OUT.glb [--building KEY,...] [--skip walls,roof,...]

KEY is a building node's name (e.g. shp_309, way_123); classes are the child node names
(walls, roof, ground, windows, doors, balconies, floors, interior walls, interior doors,
stairs, slabs). Then: scripts/screenshot OUT.glb OUT.png.
"""
import argparse, json, struct

ap = argparse.ArgumentParser()
ap.add_argument("src"); ap.add_argument("dst")
ap.add_argument("--building", default=""); ap.add_argument("--skip", default="")
a = ap.parse_args()
data = open(a.src, "rb").read()
jlen = struct.unpack_from("<I", data, 12)[0]
doc = json.loads(data[20:20 + jlen])
rest = data[20 + jlen:]
keep = set(k for k in a.building.split(",") if k)
skip = set(k for k in a.skip.split(",") if k)
scene = doc["scenes"][doc.get("scene", 0)]
scene["nodes"] = [n for n in scene["nodes"] if not keep or doc["nodes"][n].get("name") in keep]
for n in scene["nodes"]:
    node = doc["nodes"][n]
    if "children" in node:
        node["children"] = [c for c in node["children"] if doc["nodes"][c].get("name") not in skip]
        if not node["children"]:
            del node["children"]
js = json.dumps(doc, separators=(",", ":")).encode()
js += b" " * (-len(js) % 4)
out = struct.pack("<III", 0x46546C67, 2, 12 + 8 + len(js) + len(rest)) + struct.pack("<II", len(js), 0x4E4F534A) + js + rest
open(a.dst, "wb").write(out)
print(f"{len(scene['nodes'])} buildings -> {a.dst}")
