#!/usr/bin/env python3
"""Validate many output files (the tiles of a region) with the shared validators, in parallel,
keeping a ledger so that a long validation can stop and resume, across runs and machines.

  scripts/validate-tiles [--geometry] [--jobs N] --ledger LEDGER.tsv FILE...

Each file gets the check `validate-outputs FILE` runs ("schema": IFC schema and WHERE rules,
the CityGML 2.0 XSDs, the glTF validator); with --geometry each IFC file also gets the check
`validate-outputs --geometry` adds ("geom": IfcOpenShell's geometry kernel builds every
product, openings cut). The checks are the shared tool's own functions (validate_outputs.py),
called in N long-lived workers so the imports and the CityGML schema load once per worker.

The ledger has one tab-separated line per check done:
  OK|FAIL  schema|geom  file-name  bytes  sha256  seconds  summary
followed, for a failure, by its messages on lines starting with '#'. A check is done again
only if the ledger has no result for that check on a file with that sha256, so running the
same command again after a stop does only what is left, and a file whose bytes changed is
checked again. Outputs are deterministic, so the ledger of one machine holds for the files
the same citygen version writes on another (compare the sha256).

Prints one line per check and, last, "N passed (M from the ledger), K failed". Exit status 1
when any check of the given files failed, in this run or in the ledger.
"""
import argparse
import hashlib
import os
import sys
import time
from multiprocessing import Pool
from pathlib import Path

SHARED_TOOLS = Path(os.environ.get("CITYGEN_SHARED", Path(__file__).resolve().parent.parent.parent / "shared")) / "tools"
# The shared tool's module (validate_outputs.py), imported by each worker on its first check.
sys.path.insert(0, str(SHARED_TOOLS))


def sha256(path):
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def check(job):
    mode, path, digest = job
    import validate_outputs as v

    start = time.time()
    p = Path(path)
    try:
        if mode == "geom":
            import ifcopenshell

            failures, total = v.ifc_geometry_failures(ifcopenshell.open(str(p)))
            errors = [f"geometry: {x}" for x in failures]
            summary = f"shapes={total - len(failures)}/{total}"
        else:
            v.GEOMETRY = False
            name = p.name.lower()
            if name.endswith(".ifc"):
                errors, summary = v.check_ifc(p)
            elif name.endswith((".glb", ".gltf")):
                errors, summary = v.check_gltf(p)
            else:
                errors, summary = v.check_citygml(p)
    except Exception as exc:  # a file the validator cannot open is a failure
        errors, summary = [f"{type(exc).__name__}: {exc}"], ""
    # Validator messages may hold IfcOpenShell objects, which do not cross processes.
    errors = [str(e)[:400] for e in errors[:10]]
    return mode, p.name, os.path.getsize(p), digest, errors, round(time.time() - start, 1), summary


def read_ledger(path):
    done = {}
    if path.exists():
        for line in path.read_text().splitlines():
            cols = line.split("\t")
            if len(cols) >= 5 and cols[0] in ("OK", "FAIL"):
                done[(cols[1], cols[4])] = cols[0]
    return done


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--geometry", action="store_true")
    ap.add_argument("--jobs", type=int, default=os.cpu_count() or 1)
    ap.add_argument("--ledger", type=Path, required=True)
    ap.add_argument("files", nargs="+")
    a = ap.parse_args()

    done = read_ledger(a.ledger)
    jobs, reused, failed = [], 0, 0
    # Largest first, so that the workers end together.
    for f in sorted(a.files, key=lambda f: -os.path.getsize(f)):
        digest = sha256(f)
        modes = ["schema"] + (["geom"] if a.geometry and f.lower().endswith(".ifc") else [])
        for mode in modes:
            previous = done.get((mode, digest))
            if previous is None:
                jobs.append((mode, f, digest))
            else:
                reused += 1
                failed += previous == "FAIL"
                print(f"{previous:<4} {mode:<6} {f} (ledger)")
    passed = reused_ok = reused - failed
    with open(a.ledger, "a", buffering=1) as ledger, Pool(max(1, a.jobs), maxtasksperchild=20) as pool:
        for mode, name, size, digest, errors, secs, summary in pool.imap_unordered(check, jobs, chunksize=1):
            result = "FAIL" if errors else "OK"
            ledger.write(f"{result}\t{mode}\t{name}\t{size}\t{digest}\t{secs}\t{summary}\n")
            ledger.writelines(f"#   {e}\n" for e in errors)
            print(f"{result:<4} {mode:<6} {name} {summary} ({secs} s)", flush=True)
            for e in errors:
                print(f"     {e}")
            failed += bool(errors)
            passed += not errors
    print(f"validate-tiles: {passed} passed ({reused_ok} from the ledger), {failed} failed")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
