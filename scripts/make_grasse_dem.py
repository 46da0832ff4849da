#!/usr/bin/env python3
"""Writes data/grasse/grasse-srtm3-3857-{west,east}.tif (issue 44): a held-out DEM of a
mountainous region other than Monaco, in another CRS, as two tiles.

Source: N43E006_3857.tiff from the test data of github.com/agrenott/pyhgtmap (tests/data/,
commit 9882f34): NASA's SRTM3 tile N43E006 (3 arc-second, public domain, NASA/USGS) that
GDAL warped to WGS 84 / Pseudo-Mercator (EPSG:3857), 1201 x 1201 pixels of 92.77 x 127.89 m
(about 67 x 93 m on the ground), int16 metres above the EGM96 geoid, uncompressed,
PixelIsArea, GDAL_NODATA -32768. Usage (numpy only, no GDAL):

    python3 scripts/make_grasse_dem.py /path/to/N43E006_3857.tiff [data/grasse]

The crop is the pixels whose centres fall within WEST..EAST, SOUTH..NORTH (Grasse and the
Prealpes above it: 105 to about 1,100 m), samples unchanged, cut into two tiles that share
one column of pixels (as SRTM tiles share their edge samples): the west tile ends on column
SPLIT, the east tile starts on it. Each is written PixelIsArea with its own tiepoint, the
source's pixel size, ProjectedCSType 3857, VerticalCSType 5773 (EGM96 height), GDAL_NODATA,
strips of 16 rows, deflate with the horizontal predictor (zlib level 9: the same input gives
the same bytes).
"""
import math
import struct
import sys
import zlib

import numpy as np

WEST, EAST, SOUTH, NORTH = 6.895, 6.955, 43.635, 43.685
ROWS_PER_STRIP = 16
R = 6378137.0


def ifd(data):
    """The first IFD's tags of a little-endian classic TIFF: {tag: tuple of values}."""
    assert data[:4] == b"II*\0", "not a little-endian classic TIFF"
    (at,) = struct.unpack_from("<I", data, 4)
    (n,) = struct.unpack_from("<H", data, at)
    fmt = {1: "B", 2: "c", 3: "H", 4: "I", 12: "d", 16: "Q"}
    tags = {}
    for k in range(n):
        tag, typ, count, val = struct.unpack_from("<HHI4s", data, at + 2 + 12 * k)
        size = struct.calcsize(fmt[typ]) * count
        raw = val if size <= 4 else data[struct.unpack("<I", val)[0] :][:size]
        tags[tag] = struct.unpack("<" + fmt[typ] * count, raw[:size])
    return tags


def read(path):
    data = open(path, "rb").read()
    t = ifd(data)
    w, h = t[256][0], t[257][0]
    assert t[259] == (1,) and t[258] == (16,) and t[339] == (2,), "int16 uncompressed"
    keys = t[34735]
    assert (3072, 0, 1, 3857) in zip(*[iter(keys[4:])] * 4), "not EPSG:3857"
    raw = b"".join(data[o : o + c] for o, c in zip(t[273], t[279]))
    z = np.frombuffer(raw, dtype="<i2").reshape(h, w)
    sx, sy = t[33550][:2]
    x0, y0 = t[33922][3:5]
    return z, x0, y0, sx, sy


def merc(lon, lat):
    return R * math.radians(lon), R * math.log(math.tan(math.pi / 4 + math.radians(lat) / 2))


def strips(z):
    out = []
    for r in range(0, z.shape[0], ROWS_PER_STRIP):
        block = z[r : r + ROWS_PER_STRIP].astype(np.int32)
        diff = block.copy()
        diff[:, 1:] = block[:, 1:] - block[:, :-1]
        raw = ((diff + 65536) % 65536).astype("<u2").tobytes()
        out.append(zlib.compress(raw, 9))
    return out


def tiff(z, corner, scale, description):
    """A little-endian classic TIFF: one int16 band in deflated strips, the GeoTIFF tags."""
    h, w = z.shape
    data = strips(z)
    geo_ascii = "WGS 84 / Pseudo-Mercator|WGS 84|\0"
    keys = [
        (1024, 0, 1, 1),  # GTModelType: projected
        (1025, 0, 1, 1),  # GTRasterType: PixelIsArea
        (1026, 34737, 25, 0),  # GTCitation
        (2049, 34737, 7, 25),  # GeogCitation
        (2054, 0, 1, 9102),  # GeogAngularUnits: degree
        (3072, 0, 1, 3857),  # ProjectedCSType: WGS 84 / Pseudo-Mercator
        (3076, 0, 1, 9001),  # ProjLinearUnits: metre
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
        (33550, 12, [scale[0], scale[1], 0.0]),
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
    extra_at = ifd_at + 2 + 12 * len(entries) + 4
    offsets, at = {}, extra_at
    for tag, typ, vals in entries:
        p = payload(typ, vals)
        if len(p) > 4:
            offsets[tag] = at
            at += len(p) + len(p) % 2
    strip_at = []
    for s in data:
        strip_at.append(at)
        at += len(s)
    entries = [(t, ty, strip_at if t == 273 else v) for t, ty, v in entries]
    extra = b""
    for tag, typ, vals in entries:
        p = payload(typ, vals)
        if len(p) > 4:
            assert offsets[tag] == extra_at + len(extra)
            extra += p + (b"\0" if len(p) % 2 else b"")
    out = struct.pack("<H", len(entries))
    for tag, typ, vals in entries:
        p = payload(typ, vals)
        count = len(p) // size[typ]
        if len(p) > 4:
            out += struct.pack("<HHII", tag, typ, count, offsets[tag])
        else:
            out += struct.pack("<HHI", tag, typ, count) + p.ljust(4, b"\0")
    out += struct.pack("<I", 0)
    return b"II" + struct.pack("<HI", 42, ifd_at) + out + extra + b"".join(data)


def main():
    if len(sys.argv) not in (2, 3):
        sys.exit(__doc__)
    out = sys.argv[2] if len(sys.argv) == 3 else "data/grasse"
    z, x0, y0, sx, sy = read(sys.argv[1])
    (xw, ys), (xe, yn) = merc(WEST, SOUTH), merc(EAST, NORTH)
    # Pixels whose centres are inside the box.
    c0 = math.ceil((xw - x0) / sx - 0.5)
    c1 = math.floor((xe - x0) / sx - 0.5)
    r0 = math.ceil((y0 - yn) / sy - 0.5)
    r1 = math.floor((y0 - ys) / sy - 0.5)
    crop = z[r0 : r1 + 1, c0 : c1 + 1]
    assert (crop != -32768).all(), "voids in the crop"
    split = crop.shape[1] // 2
    for name, a, b in (("west", 0, split), ("east", split, crop.shape[1] - 1)):
        tile = np.ascontiguousarray(crop[:, a : b + 1]).astype("<i2")
        corner = (x0 + (c0 + a) * sx, y0 - r0 * sy)
        description = (
            "NASA SRTM3 tile N43E006 (public domain) as GDAL warped it to EPSG:3857 "
            "(pyhgtmap's tests/data/N43E006_3857.tiff), pixels %d-%d x %d-%d; heights in metres "
            "above EGM96; cropped by citygen scripts/make_grasse_dem.py"
            % (c0 + a, c0 + b, r0, r1)
        )
        path = "%s/grasse-srtm3-3857-%s.tif" % (out, name)
        with open(path, "wb") as f:
            f.write(tiff(tile, corner, (sx, sy), description))
        print(path, tile.shape, int(tile.min()), int(tile.max()))


if __name__ == "__main__":
    main()
