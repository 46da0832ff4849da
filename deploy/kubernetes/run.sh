#!/usr/bin/env bash
# Runs a region on Kubernetes: the shard Job, then (once every shard is done) the merge Job.
# Edit the PARAM lines of shards-job.yaml and merge-job.yaml first (deploy/README.md).
# Usage: deploy/kubernetes/run.sh [NAMESPACE]
set -euo pipefail
here=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
ns=(--namespace "${1:-default}")

# Waits until the Job is Complete (returns 0) or Failed (returns 1).
wait_job() {
  local job=$1 state
  while :; do
    state=$(kubectl "${ns[@]}" get job "$job" \
      -o jsonpath='{range .status.conditions[?(@.status=="True")]}{.type}{" "}{end}')
    case " $state " in
      *" Complete "*) return 0 ;;
      *" Failed "*) echo "job $job failed:" >&2
        kubectl "${ns[@]}" describe job "$job" >&2 || true
        return 1 ;;
    esac
    sleep 10
  done
}

# A Job's spec cannot be changed: remove the last run's first (its pods' logs go with it).
kubectl "${ns[@]}" delete job citygen-shards citygen-merge --ignore-not-found
kubectl "${ns[@]}" apply -f "$here/shards-job.yaml"
wait_job citygen-shards
kubectl "${ns[@]}" apply -f "$here/merge-job.yaml"
wait_job citygen-merge
kubectl "${ns[@]}" logs job/citygen-merge
