#!/usr/bin/env python3
"""Writes the GDAL-made GeoTIFF fixtures of tests/data/dem/ (issue 44) and points.json:
for each file, a few pixel centres as GDAL places them (rasterio's `xy`, centre of the pixel)
with the pixel's value, which citygen's own GeoTIFF georeferencing must read back exactly.

Synthetic heights, no outside data. Run with rasterio installed:
    python3 -m venv "$VENV" && "$VENV/bin/pip" install rasterio
    "$VENV/bin/python" scripts/make_dem_fixtures.py      (VENV: any scratch folder)
"""
import json
import os

import numpy as np
import rasterio
from rasterio.crs import CRS
from rasterio.transform import from_origin

OUT = os.path.join(os.path.dirname(__file__), "..", "tests", "data", "dem")


def write(name, data, transform, crs, **kw):
    path = os.path.join(OUT, name)
    profile = dict(
        driver="GTiff",
        height=data.shape[0],
        width=data.shape[1],
        count=1,
        dtype=data.dtype,
        crs=crs,
        transform=transform,
    )
    profile.update(kw)
    area_or_point = profile.pop("area_or_point", None)
    with rasterio.open(path, "w", **profile) as dst:
        if area_or_point:
            dst.update_tags(AREA_OR_POINT=area_or_point)
        dst.write(data, 1)
    points = []
    with rasterio.open(path) as src:
        band = src.read(1)
        rows, cols = band.shape
        for r, c in [(0, 0), (rows - 1, cols - 1), (rows // 2, cols // 3), (3, cols - 2)]:
            x, y = src.xy(r, c)
            v = float(band[r, c])
            if src.nodata is not None and v == src.nodata:
                continue
            points.append([x, y, v])
    return name, points


def main():
    os.makedirs(OUT, exist_ok=True)
    out = {}
    # UTM 32N, 2 m pixels, 64 x 48, float32 tiled 16 x 16, deflate with the float predictor,
    # a nodata hole.
    x0, y0 = 370000.0, 4842000.0
    rows, cols = 48, 64
    jj, ii = np.mgrid[0:rows, 0:cols]
    z = (10.0 + 0.01 * (ii * 2.0 + 1.0) - 0.02 * (jj * 2.0 + 1.0)).astype("float32")
    z[20:24, 30:34] = -9999.0
    name, pts = write(
        "utm_tiled_deflate.tif",
        z,
        from_origin(x0, y0, 2.0, 2.0),
        CRS.from_epsg(32632),
        tiled=True,
        blockxsize=16,
        blockysize=16,
        compress="deflate",
        predictor=3,
        nodata=-9999.0,
    )
    out[name] = pts
    # The same place, PixelIsPoint, int16 in strips, LZW with the horizontal predictor.
    zi = (100 + ii + 2 * jj).astype("int16")
    # PixelIsPoint: the transform's origin is the first pixel's centre in GDAL's reading.
    name, pts = write(
        "utm_point_i16.tif",
        zi,
        from_origin(x0 - 1.0, y0 + 1.0, 2.0, 2.0),
        CRS.from_epsg(32632),
        compress="lzw",
        predictor=2,
        area_or_point="Point",
    )
    out[name] = pts
    # WGS84 degrees (EGM96 heights stated), 0.0001 degree pixels near Monaco, float32, deflate.
    rows, cols = 30, 40
    jj, ii = np.mgrid[0:rows, 0:cols]
    lon0, lat0, d = 7.41, 43.74, 0.0001
    zg = (50.0 + 1000.0 * (ii + 0.5) * d + 500.0 * (jj + 0.5) * d).astype("float32")
    name, pts = write(
        "geo_egm96.tif",
        zg,
        from_origin(lon0, lat0, d, d),
        CRS.from_string("EPSG:4326+5773"),
        compress="deflate",
    )
    out[name] = pts
    with open(os.path.join(OUT, "points.json"), "w") as f:
        json.dump(out, f, indent=1, sort_keys=True)
        f.write("\n")


if __name__ == "__main__":
    main()
