#!/bin/sh
# merge_memory.sh: peak memory of `shadowcull merge` on a large bake's shards against a small
# one's, side by side in one run (issue 37, item 4: the merge's peak must not follow the world
# or its largest chunk; target: within 1.5x of the small merge's).
#
# usage: bench/merge_memory.sh "LARGE_SHARD_FILES" "SMALL_SHARD_FILES"   (run from the repo root)
#   e.g. bench/merge_memory.sh "$WORK/m-shard-*.json" "$WORK/sample-shard-*.json"
# The shard files are `bake SPACE --shard K/N --results FILE` of each K (world M: bake_bench
# --sizes M --gen-only --work DIR, then 4 shards of a few minutes each; data/sample: seconds).
# Prints one row per merge (input MB, largest chunk's text, seconds, peak RSS) and the ratio.
set -eu
bin=${BUILD:-build}/bin
work=${WORK:-/tmp/shadowcull-merge-memory}
mkdir -p "$work"
printf '%-8s %7s %10s %17s %8s %9s\n' merge shards "input MB" "largest chunk MB" seconds "peak MiB"
measure() {
    # $1: the row's name; the rest: the shard files.
    name=$1
    shift
    /usr/bin/time -o "$work/time" -f '%e %M' "$bin/shadowcull" merge "$work/$name.json" "$@" >/dev/null
    shards=$#
    bytes=$(cat "$@" | wc -c)
    # A chunk of the writer's layout runs from a line "  {" to a line "  }" or "  },".
    largest=$(awk '/^  \{$/ { n = 0 } { n += length($0) + 1 } /^  \},?$/ { if (n > m) m = n } END { print m + 0 }' "$@")
    read -r seconds peak < "$work/time"
    printf '%-8s %7d %10.1f %17.2f %8s %9.1f\n' "$name" "$shards" "$(echo "$bytes / 1000000" | bc -l)" \
        "$(echo "$largest / 1000000" | bc -l)" "$seconds" "$(echo "$peak / 1024" | bc -l)"
}
# The lists unquoted: split into files and their globs expanded.
# shellcheck disable=SC2086
measure large $1
largePeak=$peak
# shellcheck disable=SC2086
measure small $2
printf 'large / small: %.2fx (target: within 1.5x)\n' "$(echo "$largePeak / $peak" | bc -l)"
