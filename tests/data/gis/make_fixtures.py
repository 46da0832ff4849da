"""Makes the FlatGeobuf and GeoPackage fixtures of tests/it/gis_attributes.rs (issue 47).

Run with GDAL's Python binding pyogrio (tested with pyogrio 0.13.0, GDAL 3.12.4) in a scratch
virtual environment outside the repository:

    python3 -m venv ../venv && ../venv/bin/pip install pyogrio
    ../venv/bin/python tests/data/gis/make_fixtures.py tests/data/gis

Five 10 x 8 m footprints in ETRS89 / UTM 32N (EPSG:25832, near Munich) with German municipal
column names: OBJECTID (the id), HOEHE (height, m), GESCHOSSE (storeys), DACHFORM (roof
shape), and columns citygen does not read: NUTZUNG (text), BAUJAHR (integer), FLAECHE (real),
DENKMAL (boolean), ERFASST (date). The GeoPackage has a second polygon layer, `anbau`, named
first alphabetically, so that only `--layer gebaeude` reads the buildings.
"""
import struct
import sys

import numpy as np
import pyogrio.raw

out = sys.argv[1]


def square(x, y, w=10.0, d=8.0):
    ring = [(x, y), (x + w, y), (x + w, y + d), (x, y + d), (x, y)]
    b = struct.pack("<BII", 1, 3, 1) + struct.pack("<I", len(ring))
    for px, py in ring:
        b += struct.pack("<dd", px, py)
    return b


X0, Y0 = 691_000.0, 5_334_000.0
geoms = np.array([square(X0 + 20.0 * i, Y0) for i in range(5)], dtype=object)
fields = ["OBJECTID", "HOEHE", "GESCHOSSE", "DACHFORM", "NUTZUNG", "BAUJAHR", "FLAECHE", "DENKMAL", "ERFASST"]
data = [
    np.array([501, 502, 503, 504, 505], dtype=np.int64),
    np.array([7.2, 9.9, 12.34, 5.0, 15.5], dtype=np.float64),
    np.array([2, 3, 4, 1, 5], dtype=np.int32),
    np.array(["Satteldach", "Flachdach", "Flachdach", "Walmdach", "Flachdach"], dtype=object),
    np.array(["Wohnen", "Gewerbe", "Wohnen & Büro", "Garage", "Schule"], dtype=object),
    np.array([1965, 1990, 2004, 1978, 1931], dtype=np.int32),
    np.array([80.0, 80.5, 79.25, 80.0, 81.75], dtype=np.float64),
    np.array([False, True, False, False, True], dtype=bool),
    np.array(["2021-05-04", "2019-11-30", "2020-01-15", "2018-07-01", "2022-03-09"], dtype="datetime64[D]"),
]
for name, driver in [("municipal.fgb", "FlatGeobuf"), ("municipal.gpkg", "GPKG")]:
    pyogrio.raw.write(
        f"{out}/{name}", geoms, field_data=data, fields=fields, crs="EPSG:25832",
        geometry_type="Polygon", driver=driver, layer="gebaeude",
    )
# A small outbuilding layer named before `gebaeude`: the default reads it, --layer does not.
pyogrio.raw.write(
    f"{out}/municipal.gpkg", np.array([square(X0, Y0 + 40.0, 4.0, 3.0)], dtype=object),
    field_data=[np.array([901], dtype=np.int64)], fields=["OBJECTID"], crs="EPSG:25832",
    geometry_type="Polygon", driver="GPKG", layer="anbau", append=True,
)
