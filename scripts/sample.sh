#!/usr/bin/env bash
# The main job: install, build the shadowcull executable (its libraries, nothing else: no
# tests, benchmarks or fuzz replays), and bake the bundled sample space into
# build/sample-out/ (the sample space itself is left as committed).
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/install-deps.sh
scripts/build.sh --target shadowcull
rm -rf build/sample-out
build/bin/shadowcull bake data/sample --out build/sample-out --results build/sample-out/results.json
