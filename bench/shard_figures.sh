#!/usr/bin/env bash
# Sharding figures: a space baked in 1, 2 and 4 shards on this machine, as scripts/slurm's
# jobs on one node with CPUS cores and --cpus-per-task=1 would run them (the plan, then at
# most CPUS shards at a time, each --threads 1 reading the plan, then the merge); prints a
# Markdown table, with the balance of the partition: the slowest shard's CPU time against
# the mean. Needs GNU time.
#
#   bench/shard_figures.sh SPACE [WORK] [SHARD_COUNTS] [CPUS]   (default: 1 2 4, and nproc)
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
exe="$root/build/bin/shadowcull"
space="$(realpath "$1")"
work="$(realpath -m "${2:-${TMPDIR:-/tmp}/shadowcull-shard-figures}")"
counts="${3:-1 2 4}"
cpus="${4:-$(nproc)}"
mkdir -p "$work"
now() { date +%s.%N; }
echo "| shards | plan s | array wall s | sum of CPU s (user + sys) | slowest shard s | slowest / mean shard CPU | merge s | chunks |"
echo "|---:|---:|---:|---:|---:|---:|---:|---:|"
for n in $counts; do
  run="$work/n$n"
  rm -rf "$run"
  mkdir -p "$run"
  /usr/bin/time -f "%e %U %S" -o "$run/plan-time" "$exe" plan "$space" --shards "$n" --plan "$run/plan" --threads 1 --quiet \
    2> "$run/plan.err" || [ $? -eq 1 ]  # 1: warnings, carried by the shards
  t0=$(now)
  seq 1 "$n" | xargs -P "$cpus" -I K /usr/bin/time -f "%e %U %S" -o "$run/time-K" \
    "$exe" bake "$space" --out "$run/out" --results "$run/shard-K.json" --shard "K/$n" --plan "$run/plan" --resume \
    --threads 1 --quiet
  t1=$(now)
  shards=()
  for k in $(seq 1 "$n"); do shards+=("$run/shard-$k.json"); done
  /usr/bin/time -f "%e %U %S" -o "$run/time-merge" "$exe" merge "$run/results.json" "${shards[@]}" > /dev/null
  cpu=$(cat "$run"/time-[0-9]* | awk '{ s += $2 + $3 } END { printf "%.1f", s }')
  slowest=$(cat "$run"/time-[0-9]* | awk '{ if ($1 > m) m = $1 } END { printf "%.1f", m }')
  balance=$(cat "$run"/time-[0-9]* | awk '{ c = $2 + $3; s += c; if (c > m) m = c } END { printf "%.2f", m / (s / NR) }')
  plan=$(awk '{ printf "%.2f", $1 }' "$run/plan-time")
  merge=$(awk '{ printf "%.2f", $1 }' "$run/time-merge")
  chunks=$(ls "$run/out" | grep -c '\.chunk$')
  echo "| $n | $plan | $(awk -v a="$t0" -v b="$t1" 'BEGIN { printf "%.1f", b - a }') | $cpu | $slowest | $balance | $merge | $chunks |"
done
