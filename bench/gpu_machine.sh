#!/usr/bin/env bash
# The bake against the original GPU method on a machine with a real GPU and many cores: the
# original method (stencil + occlusion queries per light view, gpu/baseline.h) on the EGL
# device, against the whole analytic bake at full thread count, on the same chunks of the
# same worlds, each in its own process; prints the machine (CPU, threads), the OpenGL
# renderer each bake ran on, and the table "GPU / analytic" (the ratio of their wall times)
# with the original method's false culls. Runs anywhere; without a GPU, EGL falls back to
# llvmpipe (named in the OpenGL line), which is what this project's CI machine measures.
#
#   bench/gpu_machine.sh [--quick] [--work DIR] [--worlds R,M] [--res 2048] [--device N]
#
# --quick: 10 spread chunks of R only (a minute on 2 cores with llvmpipe); the default bakes
# R and M whole (M's original method alone takes about 14 minutes on llvmpipe, seconds on a
# GPU). --device N: the EGL device to use (SHADOWCULL_GL_DEVICE; `shadowcull check --gl egl`
# lists them in its OpenGL line).
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
work="${TMPDIR:-/tmp}/shadowcull-gpu-machine"
worlds="R,M"
res=2048
extra=()
while [ $# -gt 0 ]; do
  case "$1" in
    --quick) worlds="R"; extra=(--max-chunks 10) ;;
    --work) work="$2"; shift ;;
    --worlds) worlds="$2"; shift ;;
    --res) res="$2"; shift ;;
    --device) export SHADOWCULL_GL_DEVICE="$2"; shift ;;
    -h|--help) sed -n '2,16p' "$0"; exit 0 ;;
    *) echo "gpu_machine.sh: unknown option $1" >&2; exit 2 ;;
  esac
  shift
done
bench="$root/build/bin/bake_bench"
[ -x "$bench" ] || { echo "gpu_machine.sh: build bake_bench first (scripts/build.sh -DSHADOWCULL_BUILD_BENCH=ON)" >&2; exit 2; }
mkdir -p "$work"
export SHADOWCULL_GL=egl  # the EGL device where there is one (else EGL's surfaceless llvmpipe)
log="$work/gpu_machine.log"
"$bench" --sizes "$worlds" --gpu-baseline "$worlds" --gpu-res "$res" --threads "$(nproc)" --no-baseline \
  "${extra[@]}" --work "$work" > "$log"
# The machine line, the OpenGL renderers, and the comparison table.
grep -m1 '^Machine:' "$log"
grep -o 'OpenGL: .*' "$log" | sed 's/)\.$/)/' | sort -u
sed -n '/^## The original GPU method/,/^## /p' "$log" | sed '$d' | sed '/^$/N;/^\n$/D'
echo "(full output: $log)"
