#!/usr/bin/env bash
# Installs, builds and runs the whole test suite.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/install-deps.sh
scripts/build.sh -DSHADOWCULL_BUILD_TESTS=ON
ctest --test-dir build --output-on-failure -j "$(nproc)"
# A short fuzz run of every reader (clang + libFuzzer in build-fuzz/, fuzz/README.md; about
# 4 minutes with the clang build on 2 cores): fails on a crash not known in fuzz/pending/.
scripts/fuzz.sh 10
