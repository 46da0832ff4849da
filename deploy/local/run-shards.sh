#!/usr/bin/env bash
# A region on one big machine: SHARDS shards run PARALLEL at a time (xargs -P), then the merge.
# The same shards and manifests as on a cluster, so a failed shard can be re-run alone
# (citygen ... --shard I/SHARDS) and the merge repeated.
# Usage: SHARDS=8 INPUT=region.osm.pbf KB=kb.xml OUT=out [PARALLEL=4 CITYGEN_BIN=citygen
#        LOD=2 TILE=500 THREADS=...] deploy/local/run-shards.sh
# Exits non-zero when any shard fails (then no merge runs) or the merge fails.
set -euo pipefail

CITYGEN_BIN=${CITYGEN_BIN:-citygen}
INPUT=${INPUT:?set INPUT to the input .osm.pbf}
KB=${KB:?set KB to the knowledge base}
OUT=${OUT:?set OUT to the output folder}
SHARDS=${SHARDS:?set SHARDS (the number of shards)}
cores=$(nproc 2>/dev/null || echo 2)
PARALLEL=${PARALLEL:-$(( cores / 2 > 0 ? cores / 2 : 1 ))}
LOD=${LOD:-2}
TILE=${TILE:-500}
# The cores shared out between the shards running at once.
THREADS=${THREADS:-$(( cores / PARALLEL > 0 ? cores / PARALLEL : 1 ))}
case $SHARDS in
  '' | *[!0-9]* | 0*) echo "SHARDS must be a positive integer, not '$SHARDS'" >&2; exit 2 ;;
esac

mkdir -p "$OUT"
# xargs runs every shard and exits 123 if any of them failed.
if ! seq 0 $((SHARDS - 1)) | xargs -P "$PARALLEL" -I{} \
  "$CITYGEN_BIN" --osm "$INPUT" --kb "$KB" --lod "$LOD" --tile "$TILE" --threads "$THREADS" \
    --shard "{}/$SHARDS" \
    --cityjson "$OUT/region.city.json" \
    --cityjsonseq "$OUT/region.city.jsonl" \
    --tiles3d "$OUT/3dtiles" \
    --report "$OUT/report.json"; then
  echo "run-shards: a shard failed (see above); re-run it with --shard I/$SHARDS, then merge" >&2
  exit 1
fi

"$CITYGEN_BIN" merge "$OUT" \
  --tiles3d "$OUT/3dtiles" \
  --cityjsonseq "$OUT/region.city.jsonl" \
  --report "$OUT/report.json" \
  --preview "$OUT/region.png"
