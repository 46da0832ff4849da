#!/usr/bin/env python3
"""Writes data/monaco/monaco-srtm3.tif (issue 44): the part of the NASA SRTM3 tile N43E007
(3 arc-second, public domain) around Monaco, as a GeoTIFF citygen reads with --dem and GDAL
reads as the same grid.

Source: N43E007.hgt from the test data of github.com/agrenott/pyhgtmap (tests/data/), which
took it from NASA SRTM (public domain). Usage (numpy only, no GDAL):

    python3 scripts/make_monaco_dem.py /path/to/N43E007.hgt [data/monaco/monaco-srtm3.tif]

The crop keeps the SRTM samples as they are (int16 metres above the EGM96 geoid, -32768 void):
columns and rows of the tile from WEST..EAST and SOUTH..NORTH (whole samples), written as
GDAL writes a translated .hgt: PixelIsArea with the corner half a sample beyond the first
sample's centre (EPSG:4326), plus the vertical CRS (EPSG:5773, EGM96 height) and
GDAL_NODATA=-32768. Strips of 16 rows, deflate with the horizontal predictor. The same input
gives the same bytes (zlib level 9).
"""
import struct
import sys
import zlib

import numpy as np

# Monaco's buildings are within 7.408-7.441°E, 43.723-43.752°N; the crop adds about 1 km.
WEST, EAST, SOUTH, NORTH = 7.39, 7.46, 43.715, 43.765
SIDE = 1201
ROWS_PER_STRIP = 16
TILE = (7, 43)  # south-west corner of N43E007


def crop(hgt_path):
    z = np.fromfile(hgt_path, dtype=">i2")
    if z.size != SIDE * SIDE:
        sys.exit(f"{hgt_path}: {z.size * 2} bytes, not an SRTM3 tile ({SIDE * SIDE * 2})")
    z = z.reshape(SIDE, SIDE)
    step = 1.0 / (SIDE - 1)
    c0 = int(np.floor((WEST - TILE[0]) / step))
    c1 = int(np.ceil((EAST - TILE[0]) / step))
    r0 = int(np.floor((TILE[1] + 1 - NORTH) / step))
    r1 = int(np.ceil((TILE[1] + 1 - SOUTH) / step))
    return z[r0 : r1 + 1, c0 : c1 + 1].astype("<i2"), c0, r0, step


def strips(z):
    """Deflated strips, horizontal predictor (differences along each row, int16 wrapping)."""
    out = []
    for r in range(0, z.shape[0], ROWS_PER_STRIP):
        block = z[r : r + ROWS_PER_STRIP].astype(np.int32)
        diff = block.copy()
        diff[:, 1:] = block[:, 1:] - block[:, :-1]
        raw = ((diff + 65536) % 65536).astype("<u2").tobytes()
        out.append(zlib.compress(raw, 9))
    return out


def tiff(z, corner, step, description):
    """A little-endian classic TIFF with one int16 band in `strips` and the GeoTIFF tags."""
    h, w = z.shape
    data = strips(z)
    # (tag, type, values): 3 SHORT, 4 LONG, 2 ASCII, 12 DOUBLE.
    geo_ascii = "WGS 84|\0"
    keys = [
        (1024, 0, 1, 2),  # GTModelType: geographic
        (1025, 0, 1, 1),  # GTRasterType: PixelIsArea
        (2048, 0, 1, 4326),  # GeographicType: WGS 84
        (2049, 34737, 7, 0),  # GeogCitation
        (2054, 0, 1, 9102),  # GeogAngularUnits: degree
        (4096, 0, 1, 5773),  # VerticalCSType: EGM96 height
        (4099, 0, 1, 9001),  # VerticalUnits: metre
    ]
    keydir = [1, 1, 0, len(keys)] + [v for k in keys for v in k]
    n = len(data)
    entries = [
        (256, 3, [w]),
        (257, 3, [h]),
        (258, 3, [16]),
        (259, 3, [8]),  # deflate
        (262, 3, [1]),  # BlackIsZero
        (270, 2, description + "\0"),
        (273, 4, [0] * n),  # strip offsets, set below
        (277, 3, [1]),
        (278, 3, [ROWS_PER_STRIP]),
        (279, 4, [len(s) for s in data]),
        (284, 3, [1]),
        (317, 3, [2]),  # horizontal predictor
        (339, 3, [2]),  # signed integers
        (33550, 12, [step, step, 0.0]),
        (33922, 12, [0.0, 0.0, 0.0, corner[0], corner[1], 0.0]),
        (34735, 3, keydir),
        (34737, 2, geo_ascii),
        (42113, 2, "-32768\0"),
    ]
    size = {2: 1, 3: 2, 4: 4, 12: 8}
    code = {3: "H", 4: "I", 12: "d"}

    def payload(typ, vals):
        if typ == 2:
            return vals.encode("ascii")
        return struct.pack("<" + code[typ] * len(vals), *vals)

    ifd_at = 8
    ifd_len = 2 + 12 * len(entries) + 4
    extra_at = ifd_at + ifd_len
    # Out-of-line values, then the strips.
    extra = b""
    offsets = {}
    for tag, typ, vals in entries:
        p = payload(typ, vals)
        if len(p) > 4:
            offsets[tag] = extra_at + len(extra)
            extra += p + (b"\0" if len(p) % 2 else b"")
    strip_at = []
    at = extra_at + len(extra)
    for s in data:
        strip_at.append(at)
        at += len(s)
    entries = [(t, ty, strip_at if t == 273 else v) for t, ty, v in entries]
    # Recompute the strip offsets' payload (same length as before).
    extra = b""
    for tag, typ, vals in entries:
        p = payload(typ, vals)
        if len(p) > 4:
            assert offsets[tag] == extra_at + len(extra)
            extra += p + (b"\0" if len(p) % 2 else b"")
    ifd = struct.pack("<H", len(entries))
    for tag, typ, vals in entries:
        p = payload(typ, vals)
        count = len(p) // size[typ]
        if len(p) > 4:
            ifd += struct.pack("<HHII", tag, typ, count, offsets[tag])
        else:
            ifd += struct.pack("<HHI", tag, typ, count) + p.ljust(4, b"\0")
    ifd += struct.pack("<I", 0)
    return b"II" + struct.pack("<HI", 42, ifd_at) + ifd + extra + b"".join(data)


def main():
    if len(sys.argv) not in (2, 3):
        sys.exit(__doc__)
    out = sys.argv[2] if len(sys.argv) == 3 else "data/monaco/monaco-srtm3.tif"
    z, c0, r0, step = crop(sys.argv[1])
    # The first sample's centre, then half a sample out to its corner.
    lon0 = TILE[0] + c0 * step
    lat0 = TILE[1] + 1 - r0 * step
    corner = (lon0 - step / 2, lat0 + step / 2)
    description = (
        "NASA SRTM3 (3 arc-second) tile N43E007, samples %d-%d x %d-%d, public domain; "
        "heights in metres above EGM96; cropped by citygen scripts/make_monaco_dem.py"
        % (c0, c0 + z.shape[1] - 1, r0, r0 + z.shape[0] - 1)
    )
    with open(out, "wb") as f:
        f.write(tiff(z, corner, step, description))
    voids = int((z == -32768).sum())
    print(
        f"{out}: {z.shape[1]} x {z.shape[0]} samples, centres {lon0:.6f}..{lon0 + (z.shape[1] - 1) * step:.6f}E "
        f"{lat0 - (z.shape[0] - 1) * step:.6f}..{lat0:.6f}N, heights {z[z != -32768].min()}..{z.max()} m, "
        f"{voids} voids"
    )


if __name__ == "__main__":
    main()
