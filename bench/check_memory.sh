#!/bin/sh
# check_memory.sh: peak memory of `shadowcull check --pictures` against the original
# method's bake alone (`bake --method gpu --dry-run`), side by side on the same worlds in
# one run (issue 32, item 4: check's memory follows the window, flat in world size).
#
# usage: bench/check_memory.sh [SIZES] [RES]     (default: S,R 1024; run from the repo root
#        after scripts/build.sh -DSHADOWCULL_BUILD_TESTS=ON)
# prints one row per world: seconds and peak RSS of each command and their ratio.
set -eu
sizes=${1:-S,R}
res=${2:-1024}
work=${WORK:-/tmp/shadowcull-check-memory}
bin=build/bin
mkdir -p "$work"
"$bin/bake_bench" --sizes "$sizes" --gen-only --work "$work" >/dev/null
printf '%-28s %12s %12s %12s %12s %7s\n' world "bake gpu s" "bake gpu MB" "check s" "check MB" ratio
for space in "$work"/world-*; do
    [ -f "$space/space.xml" ] || continue
    /usr/bin/time -o "$work/time" -f '%e %M' "$bin/shadowcull" bake "$space" --method gpu \
        --dry-run --gpu-resolution "$res" >/dev/null 2>&1 || true
    bt=$(tail -1 "$work/time")
    rm -rf "$work/pictures"
    # exit 1 (GPU false culls found) is the expected outcome on these worlds
    /usr/bin/time -o "$work/time" -f '%e %M' "$bin/shadowcull" check "$space" \
        --gpu-resolution "$res" --pictures "$work/pictures" >/dev/null 2>&1 || true
    ct=$(tail -1 "$work/time")
    set -- $bt $ct
    printf '%-28s %12s %12d %12s %12d %7.2f\n' "$(basename "$space")" "$1" $(($2 / 1024)) \
        "$3" $(($4 / 1024)) "$(echo "$4 / $2" | bc -l)"
done
