#!/usr/bin/env bash
# Submits a sharded bake of SPACE to Slurm: a plan job (plan.sbatch: the space scanned once,
# the partition and each shard's part written to WORK/plan), a job array of N bake tasks
# (bake.sbatch, one shard each reading its part of the plan, --resume on) that starts when
# the plan succeeded, and a merge job that starts when all of them succeeded
# (--dependency=afterok). Prints the three job ids. See docs/cluster.md.
#
#   scripts/slurm/submit.sh SPACE N [WORK]
#
# WORK (default ./shadowcull-farm-<space name>): shard results, the merged results.json and
# the jobs' logs; on the shared filesystem, like SPACE and the shadowcull executable.
# Environment: SHADOWCULL (executable; default: shadowcull on PATH, else this checkout's
# build/bin/shadowcull), SHADOWCULL_OUT (write baked chunk files there instead of in place),
# SHADOWCULL_BAKE_ARGS (more bake options for every shard), SHADOWCULL_PLAN_ARGS (more plan
# options, e.g. "--res DIR"), SHADOWCULL_SBATCH_ARGS (more sbatch options for every job, e.g. "--partition=bake --time=02:00:00"),
# SHADOWCULL_CPUS (CPUs per shard, default 1: the shard's --threads), SHADOWCULL_MAX_RUNNING
# (at most this many shards at once: the array's %N throttle; default no limit).
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
if [ $# -lt 2 ] || [ $# -gt 3 ]; then
  echo "usage: $0 SPACE N [WORK]" >&2
  exit 2
fi
space="$(realpath "$1")"
n="$2"
case "$n" in ''|*[!0-9]*|0) echo "$0: N must be a positive integer, not '$n'" >&2; exit 2 ;; esac
[ -f "$space/space.xml" ] || { echo "$0: $space has no space.xml" >&2; exit 2; }
work="$(realpath -m "${3:-shadowcull-farm-$(basename "$space")}")"
exe="${SHADOWCULL:-$(command -v shadowcull || echo "$here/../../build/bin/shadowcull")}"
exe="$(realpath "$exe")"
[ -x "$exe" ] || { echo "$0: no shadowcull executable at $exe (set SHADOWCULL)" >&2; exit 2; }
out="${SHADOWCULL_OUT:+$(realpath -m "$SHADOWCULL_OUT")}"
mkdir -p "$work/logs"
[ -n "$out" ] && mkdir -p "$out"
export SHADOWCULL="$exe" SHADOWCULL_SPACE="$space" SHADOWCULL_SHARDS="$n" SHADOWCULL_WORK="$work" SHADOWCULL_OUT="$out"
export SHADOWCULL_BAKE_ARGS="${SHADOWCULL_BAKE_ARGS:-}" SHADOWCULL_PLAN_ARGS="${SHADOWCULL_PLAN_ARGS:-}"
cpus="${SHADOWCULL_CPUS:-1}"
throttle="${SHADOWCULL_MAX_RUNNING:+%$SHADOWCULL_MAX_RUNNING}"
case "${SHADOWCULL_MAX_RUNNING:-1}" in ''|*[!0-9]*|0) echo "$0: SHADOWCULL_MAX_RUNNING must be a positive integer" >&2; exit 2 ;; esac
# shellcheck disable=SC2206
extra=(${SHADOWCULL_SBATCH_ARGS:-})
plan_id=$(sbatch --parsable --export=ALL --cpus-per-task="$cpus" --chdir="$work" \
  --output="$work/logs/plan-%j.log" "${extra[@]}" "$here/plan.sbatch")
plan_id="${plan_id%%;*}"  # "ID;cluster" on federated clusters
bake_id=$(sbatch --parsable --export=ALL --dependency="afterok:$plan_id" --kill-on-invalid-dep=yes \
  --array="1-$n$throttle" --cpus-per-task="$cpus" --chdir="$work" \
  --output="$work/logs/bake-%A_%a.log" "${extra[@]}" "$here/bake.sbatch")
bake_id="${bake_id%%;*}"
merge_id=$(sbatch --parsable --export=ALL --dependency="afterok:$bake_id" --kill-on-invalid-dep=yes --chdir="$work" \
  --output="$work/logs/merge-%j.log" "${extra[@]}" "$here/merge.sbatch")
merge_id="${merge_id%%;*}"
echo "plan: $plan_id -> $work/plan"
echo "bake array: $bake_id ($n shards, after the plan succeeds)"
echo "merge: $merge_id (after the array succeeds) -> $work/results.json"
