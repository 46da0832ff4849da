#!/usr/bin/env bash
# Submits a region to Slurm: the shard array, then the merge once every task has succeeded.
# Usage: SHARDS=8 INPUT=region.osm.pbf KB=kb.xml OUT=out [CITYGEN_BIN=citygen LOD=2 TILE=500]
#        deploy/slurm/submit.sh [extra sbatch options, e.g. --partition=batch]
set -euo pipefail
here=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
: "${SHARDS:?set SHARDS (the number of shards)}"
: "${INPUT:?set INPUT}" "${KB:?set KB}" "${OUT:?set OUT}"
case $SHARDS in
  '' | *[!0-9]* | 0*) echo "SHARDS must be a positive integer, not '$SHARDS'" >&2; exit 2 ;;
esac
export SHARDS INPUT KB OUT
mkdir -p "$OUT"

# --parsable prints "jobid" or "jobid;cluster".
array=$(sbatch --parsable --export=ALL --array="0-$((SHARDS - 1))" "$@" "$here/shards.sbatch")
array=${array%%;*}
merge=$(sbatch --parsable --export=ALL --dependency="afterok:$array" "$@" "$here/merge.sbatch")
merge=${merge%%;*}
echo "shards: job $array (array 0-$((SHARDS - 1))), merge: job $merge after it"
