"""Makes the text-id fixtures of tests/it/gis_attributes.rs (issue 47): footprints whose ids
are text, not whole numbers.

Run with GDAL's Python binding pyogrio (tested with pyogrio 0.13.0, GDAL 3.12.4) in a scratch
virtual environment outside the repository:

    python3 -m venv ../venv && ../venv/bin/pip install pyogrio
    ../venv/bin/python tests/data/gis/make_text_id_fixtures.py tests/data/gis

- `guids.fgb`: four 10 x 8 m footprints in New York Long Island State Plane, US survey feet
  (EPSG:2263), ids in Esri's `GlobalID` column as braced GUIDs (not XML-id characters), New
  York's `heightroof` (feet) and `num_floors`, and `bin` (integer, an attribute).
- `bag.gpkg`: four footprints in RD New (EPSG:28992, the Dutch national grid), ids in the BAG's
  `identificatie` (`NL.IMBAG.Pand.` and 16 digits, leading zero), 3DBAG's `b3_h_dak_max` over
  `b3_h_maaiveld` and `b3_bouwlagen`, and `status` (text, an attribute).
"""
import struct
import sys

import numpy as np
import pyogrio.raw

out = sys.argv[1]


def square(x, y, w, d):
    ring = [(x, y), (x + w, y), (x + w, y + d), (x, y + d), (x, y)]
    b = struct.pack("<BII", 1, 3, 1) + struct.pack("<I", len(ring))
    for px, py in ring:
        b += struct.pack("<dd", px, py)
    return b


FT = 1200.0 / 3937.0
pyogrio.raw.write(
    f"{out}/guids.fgb",
    np.array([square(988_000.0 + 120.0 * i, 211_900.0, 10.0 / FT, 8.0 / FT) for i in range(4)], dtype=object),
    field_data=[
        np.array([
            "{3F2504E0-4F89-11D3-9A0C-0305E82C3301}",
            "{3F2504E0-4F89-11D3-9A0C-0305E82C3302}",
            "{7C9E6679-7425-40DE-944B-E07FC1F90AE7}",
            "{A1B2C3D4-0000-4000-8000-00000000BEEF}",
        ], dtype=object),
        np.array([30.0, 45.5, 62.0, 20.0], dtype=np.float64),
        np.array([3, 4, 6, 2], dtype=np.int32),
        np.array([1001001, 1001002, 1001003, 1001004], dtype=np.int64),
    ],
    fields=["GlobalID", "heightroof", "num_floors", "bin"],
    crs="EPSG:2263", geometry_type="Polygon", driver="FlatGeobuf", layer="guids",
)
pyogrio.raw.write(
    f"{out}/bag.gpkg",
    np.array([square(92_500.0 + 20.0 * i, 437_000.0, 10.0, 8.0) for i in range(4)], dtype=object),
    field_data=[
        np.array([
            "NL.IMBAG.Pand.0599100000012345",
            "NL.IMBAG.Pand.0599100000012346",
            "NL.IMBAG.Pand.0599100000670001",
            "NL.IMBAG.Pand.0599100000670002",
        ], dtype=object),
        np.array([9.25, 12.5, 15.0, 6.75], dtype=np.float64),
        np.array([-1.25, -1.0, -0.5, -1.5], dtype=np.float64),
        np.array([3, 4, 5, 2], dtype=np.int32),
        np.array(["Pand in gebruik"] * 4, dtype=object),
    ],
    fields=["identificatie", "b3_h_dak_max", "b3_h_maaiveld", "b3_bouwlagen", "status"],
    crs="EPSG:28992", geometry_type="Polygon", driver="GPKG", layer="pand",
)
