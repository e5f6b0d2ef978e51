#!/usr/bin/env bash
# Shard start-up with and without a plan (shadowcull plan, docs/cluster.md): the seconds a
# shard takes from exec to opening its first chunk file (the start of its first window),
# for shard 1 of two worlds cut into shards of the same size (25 chunks: M in 4, XL in
# 400). Without a plan every shard scans the whole world first (its "time: load" is shown);
# with one it reads the plan, space.xml and the names of the chunk files. Prints a Markdown table. Needs strace (the
# times are read off its timestamps) and the generated worlds (bake_bench --gen-only).
#
#   bench/plan_startup.sh WORK [REPEATS]     (default 15; the table shows min and median)
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
exe="$root/build/bin/shadowcull"
work="$(realpath -m "${1:?usage: $0 WORK [REPEATS]}")"
repeats="${2:-15}"
command -v strace > /dev/null || { echo "$0: needs strace (apt-get install strace)" >&2; exit 2; }
mkdir -p "$work"
"$root/build/bin/bake_bench" --sizes M,XL --gen-only --work "$work" > "$work/gen.log"
world() { ls -d "$work"/world-"$1"-* | head -n 1; }

# scanned SPACE K/N: the load time a shard without a plan prints (its scan of the space).
scanned() {
  rm -rf "$work/startup-out"
  "$exe" bake "$1" --shard "$2" --out "$work/startup-out" --dry-run --stages raycast --samples 1 --threads 1 2>/dev/null |
    sed -n 's/.*time: load \([0-9.]*\) s.*/\1/p'
}

# startup SPACE K/N PLAN: seconds from exec to the first *.chunk opened (the first window's).
startup() {
  local args=(bake "$1" --shard "$2" --out "$work/startup-out" --dry-run --stages raycast --samples 1 --threads 1 -q)
  [ -n "${3:-}" ] && args+=(--plan "$3")
  rm -rf "$work/startup-out"
  timeout 600 strace -f -ttt -e trace=execve,openat -o "$work/startup.strace" "$exe" "${args[@]}" > /dev/null 2>&1 || true
  awk '/execve\(/ && !t0 { t0 = $2 } /openat\(.*\.chunk"/ && !/shadowcull-tmp/ { printf "%.4f\n", $2 - t0; exit }' "$work/startup.strace"
}
stats() { sort -n | awk '{ v[NR] = $1 } END { printf "%.3f %.3f\n", v[1], v[int((NR + 1) / 2)] }'; }

echo "| world | shard | chunks in the world | chunks its windows hold | plan s (once) | start-up without a plan s | start-up with a plan s, min / median of $repeats |"
echo "|---|---|---:|---:|---:|---:|---:|"
for spec in M:4 XL:400; do
  size="${spec%%:*}" n="${spec##*:}"
  space="$(world "$size")" plan="$work/plan-$size-$n"
  t0=$(date +%s.%N)
  "$exe" plan "$space" --shards "$n" --plan "$plan" --quiet 2> "$work/plan-$size.err" || [ $? -eq 1 ]  # 1: warnings
  plan_s=$(awk -v a="$t0" -v b="$(date +%s.%N)" 'BEGIN { printf "%.1f", b - a }')
  held=$(python3 -c "import json,sys; print(len(json.load(open(sys.argv[1]))['chunks']))" "$plan/shard-1-of-$n.json")
  chunks=$(ls "$space" | grep -c '\.chunk$')
  scan=$(scanned "$space" "1/$n")
  read -r lo med < <(for _ in $(seq 1 "$repeats"); do startup "$space" "1/$n" "$plan"; done | stats)
  echo "| $size | 1/$n | $chunks | $held | $plan_s | $scan | $lo / $med |"
done
