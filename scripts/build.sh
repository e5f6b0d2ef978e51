#!/usr/bin/env bash
# Configures and builds into build/ (Release with debug info).
#   scripts/build.sh [--target NAME ...] [CMAKE_ARGS ...]
# --target builds only those targets and what they need (scripts/sample.sh: the shadowcull
# executable and its libraries); without it, everything the options enable. The remaining
# arguments go to cmake (-DSHADOWCULL_BUILD_TESTS=ON, -DSHADOWCULL_BUILD_BENCH=ON).
set -euo pipefail
cd "$(dirname "$0")/.."
targets=()
while [ $# -gt 0 ] && [ "$1" = --target ]; do
  [ $# -ge 2 ] || { echo "build.sh: --target needs a name" >&2; exit 2; }
  targets+=(--target "$2")
  shift 2
done
generator=()
command -v ninja >/dev/null && generator=(-G Ninja)
[ -f build/CMakeCache.txt ] && generator=()
cmake -S . -B build "${generator[@]}" -DCMAKE_BUILD_TYPE=RelWithDebInfo "$@"
cmake --build build -j "$(nproc)" "${targets[@]}"
