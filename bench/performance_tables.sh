#!/usr/bin/env bash
# performance_tables.sh: every table of docs/performance.md, in the page's order, in one run.
#
#   bench/performance_tables.sh [--quick] [--work DIR] [--only SECTIONS] [--list]
#
# Run from anywhere after building the benchmarks (SHADOWCULL_BUILD_TESTS=ON, the default):
#   ninja -C build shadowcull bake_bench stage_figures gltf_bench
# Prints Markdown on stdout: per section the exact command, then what it printed. Progress
# and the programs' stderr go to WORK/performance_tables.log.
#
#   --quick        a smaller subset (fewer chunks, fewer settings, no memory section)
#   --work DIR     where the worlds are generated and the runs write (default
#                  ${TMPDIR:-/tmp}/shadowcull-perf); generated worlds are reused
#   --only LIST    comma-separated sections: machine,stages,worlds,size,dense,shards,memory,
#                  whole,accuracy,closeup (default: all, in this order)
#   --list         print the commands without running them
#
# Environment: BUILD (default: the repository's build/), NICE (default "nice"; set empty to
# run at normal priority). Bench programs each fork one child per bake, so their peak RSS
# figures are per bake.
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
build="${BUILD:-$root/build}"
bin="$build/bin"
nice_cmd="${NICE-nice}"
quick=0
list=0
work="${TMPDIR:-/tmp}/shadowcull-perf"
only="machine,stages,worlds,size,dense,shards,memory,whole,accuracy,closeup"
while [ $# -gt 0 ]; do
    case "$1" in
        --quick) quick=1 ;;
        --list) list=1 ;;
        --work) work="$2"; shift ;;
        --only) only="$2"; shift ;;
        -h|--help) awk 'NR > 1 && /^#/ { sub(/^# ?/, ""); print; next } NR > 1 { exit }' "$0"; exit 0 ;;
        *) echo "performance_tables.sh: unknown option $1 (see --help)" >&2; exit 2 ;;
    esac
    shift
done
for exe in shadowcull bake_bench stage_figures gltf_bench; do
    [ -x "$bin/$exe" ] || { echo "performance_tables.sh: $bin/$exe missing: build it first" >&2; exit 2; }
done
mkdir -p "$work"
work="$(cd "$work" && pwd)"
log="$work/performance_tables.log"
cd "$root"

want() { case ",$only," in *",$1,"*) return 0 ;; *) return 1 ;; esac; }
started=$(date +%s)
section() { printf '\n## %s\n\n' "$1"; echo "== $1 ($(date -u +%H:%M:%S))" >> "$log"; }
# run CMD...: print the command as the page shows it, then run it (stdout kept, stderr logged)
run() {
    local shown="" a
    for a in "$@"; do case "$a" in *" "*) shown+=" \"$a\"" ;; *) shown+=" $a" ;; esac; done
    printf '```sh\n%s\n```\n\n' "${shown# }" |
        sed "s#$bin/#build/bin/#g; s#$work#\$WORK#g; s#world-\([A-Za-z0-9]*\)-[0-9a-f]\{16\}#world-\1-*#g"
    [ "$list" = 1 ] && return 0
    local t0=$(date +%s)
    $nice_cmd "$@" 2>> "$log" || echo "(exit code $?: see $log)"
    echo "(ran $(( $(date +%s) - t0 )) s)" >> "$log"
    printf '\n_(%d s wall)_\n' "$(( $(date +%s) - t0 ))"
}
# the newest complete generated world of a size (world-<size>-<hash>, hash of the generator)
# (or the pattern, with --list before the worlds exist)
world() {
    local d
    for d in $(ls -td "$work"/world-"$1"-*/ 2>/dev/null); do
        [ -f "$d/bench-world.json" ] && { echo "${d%/}"; return; }
    done
    echo "$work/world-$1-*"
}

if want machine; then
    section "Machine and build"
    echo "- CPU: $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2- | sed 's/^ //'), $(nproc) hardware threads, $(awk '/MemTotal/ { printf "%.1f GiB", $2 / 1048576 }' /proc/meminfo)"
    echo "- OpenGL: $("$bin/shadowcull" --version 2>/dev/null | grep -m1 '^OpenGL:' | sed 's/^OpenGL: //')"
    echo "- $(grep -m1 CMAKE_BUILD_TYPE: "$build/CMakeCache.txt" 2>/dev/null | cut -d= -f2) build, $(c++ --version | head -1), commit $(git -C "$root" rev-parse --short HEAD 2>/dev/null || echo unknown)"
    echo "- load average at the start: $(cut -d' ' -f1-3 /proc/loadavg)"
fi

if want stages; then
    section "What each stage proves and costs"
    run "$bin/stage_figures" "$work/stage-figures"
fi

if want closeup || want worlds || want size || want dense || want whole || want shards || want memory; then
    [ "$list" = 1 ] || $nice_cmd "$bin/bake_bench" --sizes S,M,R,R10,D,D2k --gen-only --work "$work" > /dev/null 2>> "$log"
fi

if want worlds; then
    section "Benchmark worlds: stages, the original method, bare Embree, size"
    if [ "$quick" = 1 ]; then run "$bin/bake_bench" --sizes S,M --max-chunks 4 --work "$work"
    else run "$bin/bake_bench" --sizes S,M,L --max-chunks 10 --work "$work"; fi
fi

if want size; then
    section "Scaling with world size: M against L, per chunk"
    if [ "$quick" = 1 ]; then run "$bin/bake_bench" --sizes M,L --max-chunks 6 --gpu-baseline none --no-baseline --work "$work"
    else run "$bin/bake_bench" --sizes M,L --max-chunks 25 --gpu-baseline none --no-baseline --work "$work"; fi
fi

if want dense; then
    section "Dense meshes: D against D2k"
    rounds=6; [ "$quick" = 1 ] && rounds=1
    run "$bin/bake_bench" --sizes D,D2k --rounds "$rounds" --no-baseline --gpu-baseline none --work "$work"
fi

if want shards; then
    section "Sharded bakes"
    if [ "$quick" = 1 ]; then run bench/shard_figures.sh "$(world S)" "$work/shards" "1 2" 2
    else run bench/shard_figures.sh "$(world R)" "$work/shards" "1 2 4" 2; fi
fi

if want memory && [ "$quick" = 0 ]; then
    section "Memory that follows the window (M against XL, 100 x 100 chunks)"
    run "$bin/bake_bench" --sizes M,XL --max-chunks 250 --contiguous --gpu-baseline none --no-baseline --work "$work"
    section "check --pictures against the original method's bake"
    export WORK="$work/check-memory"
    run bench/check_memory.sh S 512
    run bench/check_memory.sh R 1024
    unset WORK
    section "Importing glTF scenes"
    run "$bin/gltf_bench" --nodes 10000,40000,80000 --meshes 500,2000,4000 --work "$work/gltf"
fi

if want whole; then
    section "Whole-space windows against window-only"
    if [ "$quick" = 1 ]; then
        run "$bin/bake_bench" --sizes S,R --max-chunks 9 --window-only --gpu-baseline none --no-baseline --work "$work"
    else
        run "$bin/bake_bench" --sizes S,R10,R,M --max-chunks 25 --window-only --gpu-baseline none --no-baseline --work "$work"
    fi
fi

if want accuracy; then
    section "Accuracy against time: samples and GPU resolution (data/sample)"
    if [ "$quick" = 1 ]; then run "$bin/shadowcull" sweep data/sample --quick
    else run "$bin/shadowcull" sweep data/sample; fi
fi

if want closeup; then
    section "Accuracy against time: the GPU close-up (world S)"
    settings="0 256 512 1024"
    [ "$quick" = 1 ] && settings="0 512"
    printf '```sh\nfor n in %s; do build/bin/shadowcull bake $WORK/world-S-* --dry-run --gpu-close-up $n; done\n```\n\n' "$settings"
    if [ "$list" = 0 ]; then
        echo "| --gpu-close-up | culled | undecided (kept as 1) | bake s | close-up s (GPU time) |"
        echo "|---:|---:|---:|---:|---:|"
        for n in $settings; do
            out="$($nice_cmd "$bin/shadowcull" bake "$(world S)" --dry-run --gpu-close-up "$n" 2>&1)"
            culled=$(sed -n 's/^bits [0-9]*: kept [0-9]*, culled \([0-9]*\).*/\1/p' <<< "$out")
            und=$(sed -n 's/^  undecided, kept as 1 *\([0-9]*\).*/\1/p' <<< "$out")
            total=$(sed -n 's/^time: .*total \([0-9.]*\) s.*/\1/p' <<< "$out")
            close=$(sed -n 's/^time: .*gpu (close-up) \([0-9.]* s\)[^,]*(GPU time \([0-9.]* s\)).*/\1 (\2)/p' <<< "$out")
            echo "| $n | $culled | $und | $total | ${close:--} |"
        done
    fi
fi

echo "performance_tables.sh: done in $(( $(date +%s) - started )) s ($log)" >&2
