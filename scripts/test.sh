#!/usr/bin/env bash
# Installs, builds and runs the whole test suite.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/install-deps.sh
scripts/build.sh -DSHADOWCULL_BUILD_TESTS=ON
ctest --test-dir build --output-on-failure -j "$(nproc)"
