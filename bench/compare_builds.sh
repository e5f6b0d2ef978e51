#!/usr/bin/env bash
# Two builds of shadowcull side by side on the same worlds: the whole bake's wall and CPU
# time, medians of ROUNDS runs made alternately (old, new, old, new ...: both see the same
# machine load), their ratio, and whether the two bakes' verdicts and evidence are identical
# (bench/compare_results.py on --results). "Faster than main, same verdicts" (issue 38).
#
#   bench/compare_builds.sh OLD_BIN NEW_BIN [WORLDS] [ROUNDS] [WORK]
#
# WORLDS: comma-separated; a name (S, M, R, D, ...) is the bench world WORK/world-NAME-*
# (generate it first: bake_bench --sizes NAME --gen-only --work WORK), anything else a
# space directory. Default R,M; ROUNDS 3; WORK /tmp/scb. Bakes run with --dry-run and
# every thread; stderr of each bake goes to WORK/compare_builds.log.
set -euo pipefail
[ $# -ge 2 ] || { sed -n 2,13p "$0" >&2; exit 2; }
old=$1 new=$2 worlds=${3:-R,M} rounds=${4:-3} work=${5:-/tmp/scb}
here=$(cd "$(dirname "$0")" && pwd)
for b in "$old" "$new"; do [ -x "$b" ] || { echo "compare_builds: $b is not an executable" >&2; exit 2; }; done
log=$work/compare_builds.log
mkdir -p "$work"
: > "$log"
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT

median() { sort -g | awk '{a[NR]=$1} END {print (NR % 2) ? a[(NR + 1) / 2] : (a[NR / 2] + a[NR / 2 + 1]) / 2}'; }

echo "# Two builds side by side"
echo
echo "Machine: $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2- | sed 's/^ //'), $(nproc) hardware threads; load average before: $(cut -d' ' -f1-3 /proc/loadavg)."
echo "Old: $old; new: $new; medians of $rounds rounds, run alternately."
echo
echo "| world | old wall s | new wall s | wall old / new | old CPU s | new CPU s | CPU old / new | verdicts and evidence |"
echo "|---|---:|---:|---:|---:|---:|---:|---|"
IFS=, read -ra list <<< "$worlds"
for w in "${list[@]}"; do
  dir=$w
  [ -d "$dir" ] || dir=$(ls -d "$work"/world-"$w"-* 2>/dev/null | head -1 || true)
  [ -n "$dir" ] && [ -d "$dir" ] || { echo "| $w | | | | | | | no such world (generate it: bake_bench --sizes $w --gen-only --work $work) |"; continue; }
  for tag in old new; do : > "$out/$tag.wall"; : > "$out/$tag.cpu"; done
  for r in $(seq "$rounds"); do
    for tag in old new; do
      bin=$old; [ $tag = new ] && bin=$new
      res=$out/$tag-$r.json
      /usr/bin/time -f '%e %U %S' -o "$out/time" "$bin" bake "$dir" --dry-run -q --results "$res" 2>> "$log" || {
        echo "compare_builds: the $tag build failed on $w (see $log)" >&2; exit 1; }
      read -r wall user sys < "$out/time"
      echo "$wall" >> "$out/$tag.wall"
      echo "$user $sys" | awk '{print $1 + $2}' >> "$out/$tag.cpu"
    done
  done
  ow=$(median < "$out/old.wall") nw=$(median < "$out/new.wall")
  oc=$(median < "$out/old.cpu") nc=$(median < "$out/new.cpu")
  same=$(python3 "$here/compare_results.py" "$out/old-1.json" "$out/new-1.json" 2>&1 | head -1 || true)
  printf '| %s | %.2f | %.2f | %.2fx | %.2f | %.2f | %.2fx | %s |\n' "$w" "$ow" "$nw" \
    "$(echo "$ow $nw" | awk '{print $1 / $2}')" "$oc" "$nc" "$(echo "$oc $nc" | awk '{print $1 / $2}')" "$same"
done
echo
echo "Load average after: $(cut -d' ' -f1-3 /proc/loadavg)."
