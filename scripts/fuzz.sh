#!/usr/bin/env bash
# Fuzzes every reader with libFuzzer (fuzz/README.md): installs clang if needed, builds the
# fuzz targets into build-fuzz/ (clang, ASan + UBSan), runs each for SECONDS (default 60),
# two at a time on two cores, and prints per target: runs, coverage, crashes. A new
# crashing input is written to fuzz/regressions/<reader>/ (where the ordinary build's
# ctest replays it) and the exit status is 1. A crash the same as one already in
# fuzz/pending/<reader>/ (found before, not fixed yet) is counted as known and does not
# fail the run. The reproducers in fuzz/regressions/ are replayed first, under the
# sanitizers; one that crashes again fails the run too.
#
#   scripts/fuzz.sh [SECONDS] [READER ...]        READER: space chunk model obj gltf terrain diff bake import layout plan
set -euo pipefail
cd "$(dirname "$0")/.."
seconds=${1:-60}
shift || true
readers=("$@")
[ ${#readers[@]} -gt 0 ] || readers=(space chunk model obj gltf terrain diff bake import layout plan)

# clang plus compiler-rt (libclang-rt-14-dev holds libFuzzer, -fsanitize=fuzzer, on Debian
# 12); llvm for llvm-symbolizer (stack traces with file and line).
fuzz_packages=(clang libclang-rt-14-dev llvm)
scripts/install-deps.sh "${fuzz_packages[@]}"

start=$(date +%s)
mkdir -p build-fuzz
log=build-fuzz/build.log
cmake -S . -B build-fuzz -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCMAKE_CXX_COMPILER=clang++ \
  -DSHADOWCULL_BUILD_TESTS=ON -DSHADOWCULL_FUZZ=ON >"$log" 2>&1 || { cat "$log"; exit 1; }
targets=()
for r in "${readers[@]}"; do targets+=("fuzz_$r"); done
cmake --build build-fuzz -j "$(nproc)" --target "${targets[@]}" >>"$log" 2>&1 || { tail -50 "$log"; exit 1; }
echo "fuzz: build-fuzz ready in $(($(date +%s) - start)) s (log: $log)"

# Input size limits: a few times the largest seed, so that inputs can grow but runs stay fast.
declare -A max_len=([space]=4096 [chunk]=8192 [model]=8192 [obj]=8192 [gltf]=8192 [terrain]=8192 [diff]=16384 [bake]=8192 [import]=16384 [layout]=8192 [plan]=16384)
# Dictionaries (fuzz/dict/): the element names, keys and keywords each reader compares against.
declare -A dicts=([space]="xml space" [chunk]="xml chunk" [model]="xml model obj gltf split" [obj]="obj split"
                  [gltf]="gltf split" [terrain]="xml png split" [diff]="results split"
                  [bake]="xml space chunk obj png split" [import]="gltf import split"
                  [layout]="xml space chunk obj png split" [plan]="plan split")

scratch=$(mktemp -d /dev/shm/shadowcull-fuzz.XXXXXX 2>/dev/null || mktemp -d)
trap 'rm -rf "$scratch"' EXIT
export SHADOWCULL_FUZZ_TMPDIR=$scratch/files
export ASAN_OPTIONS=${ASAN_OPTIONS:-detect_leaks=1:allocator_may_return_null=1}
export UBSAN_OPTIONS=${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}
mkdir -p build-fuzz/logs build-fuzz/dict build-fuzz/known

artifacts() { find "fuzz/regressions/$1" -maxdepth 1 -type f \( -name 'crash-*' -o -name 'timeout-*' -o -name 'oom-*' -o -name 'leak-*' \) | sort; }

# What a crash is: the sanitizer's (or libFuzzer's) kind of error and the first frame in
# the project's own code, e.g. "runtime error @ cli/diff.cpp:159". Found by running the
# input alone; empty when it does not crash.
signature() {
  local out kind frame
  out=$(timeout 60 "build-fuzz/bin/fuzz_$1" -timeout=10 -rss_limit_mb=4096 "$2" 2>&1) && return 0
  kind=$(grep -o -m1 -E 'runtime error|LeakSanitizer|AddressSanitizer: [a-z-]+|libFuzzer: [a-z-]+|loader broke its promise|broken promise' <<<"$out" || true)
  frame=$(grep -E '^ +#[0-9]+ ' <<<"$out" | grep -o -m1 -E '/(util|core|io|cli|raycast|geometry|gpu|gltf)/[^ :]+:[0-9]+' | sed 's|^/||' || true)
  echo "${kind:-crash} @ ${frame:-?}"
}

fuzz_one() {
  local r=$1 f a sig found
  mkdir -p "build-fuzz/corpus/$r" "fuzz/regressions/$r"
  local dict=build-fuzz/dict/$r.dict
  (for d in ${dicts[$r]}; do cat "fuzz/dict/$d.dict"; done) >"$dict"
  artifacts "$r" >"$scratch/$r.before"
  # The reproducers saved so far, under the sanitizers (the ordinary build's ctest replays
  # them without): one that crashes again is a regression.
  : >"$scratch/$r.regressed"
  for f in fuzz/regressions/"$r"/*; do
    [ -f "$f" ] && ! grep -qxF "$f" "$scratch/$r.before" || continue
    sig=$(signature "$r" "$f")
    [ -z "$sig" ] || echo "$f: $sig" >>"$scratch/$r.regressed"
  done
  # Fork mode: a crash, timeout or out-of-memory is saved and fuzzing goes on, so that a
  # known crash (fuzz/pending/) does not end the target's time. New inputs go to
  # build-fuzz/corpus/<reader> (kept between runs); the seeds stay as committed.
  "build-fuzz/bin/fuzz_$r" "build-fuzz/corpus/$r" "fuzz/corpus/$r" -fork=1 -ignore_crashes=1 -ignore_timeouts=1 \
    -ignore_ooms=1 -max_total_time="$seconds" -max_len="${max_len[$r]}" -rss_limit_mb=4096 -timeout=10 \
    -dict="$dict" -artifact_prefix="fuzz/regressions/$r/" -print_final_stats=1 >"build-fuzz/logs/$r.log" 2>&1 || true
  # Sort the new reproducers: a crash the same as one in fuzz/pending/<reader>/ (not fixed
  # yet) is known and moved to build-fuzz/known/<reader>/; one that does not crash again
  # alone goes to build-fuzz/unrepeated/<reader>/; the rest are new and stay in
  # fuzz/regressions/<reader>/.
  : >"$scratch/$r.new"
  : >"$scratch/$r.known"
  : >"$scratch/$r.unrepeated"
  found=$(artifacts "$r" | comm -13 "$scratch/$r.before" -)
  [ -n "$found" ] || return 0
  : >"$scratch/$r.known-sigs"
  for p in fuzz/pending/"$r"/*; do [ -f "$p" ] && signature "$r" "$p" >>"$scratch/$r.known-sigs"; done
  for a in $found; do
    sig=$(signature "$r" "$a")
    if [ -z "$sig" ]; then
      # E.g. a timeout of a machine busy with other work: kept aside, not a failure.
      echo "$a" >>"$scratch/$r.unrepeated"
      mkdir -p "build-fuzz/unrepeated/$r"
      mv "$a" "build-fuzz/unrepeated/$r/"
    elif grep -qxF "$sig" "$scratch/$r.known-sigs"; then
      echo "$sig" >>"$scratch/$r.known"
      mkdir -p "build-fuzz/known/$r"
      mv "$a" "build-fuzz/known/$r/"
    else
      echo "$a: $sig" >>"$scratch/$r.new"
    fi
  done
}

# Two targets at a time on two cores (one per core elsewhere).
for r in "${readers[@]}"; do
  while [ "$(jobs -rp | wc -l)" -ge "$(nproc)" ]; do wait -n || true; done
  fuzz_one "$r" &
done
wait

failed=0
printf '%-8s %10s %8s %8s %8s %10s\n' reader runs coverage new known unrepeated
for r in "${readers[@]}"; do
  log=build-fuzz/logs/$r.log
  runs=$(grep -o '^#[0-9]*' "$log" | tail -1 | tr -d '#' || true)
  cov=$(grep -o 'cov: [0-9]*' "$log" | tail -1 | grep -o '[0-9]*$' || true)
  printf '%-8s %10s %8s %8s %8s %10s\n' "$r" "${runs:-?}" "${cov:-?}" "$(wc -l <"$scratch/$r.new")" \
    "$(wc -l <"$scratch/$r.known")" "$(wc -l <"$scratch/$r.unrepeated")"
done
for r in "${readers[@]}"; do
  # A target that never ran (no log, no executions) fails: silence is not a pass.
  if ! grep -q '^#[0-9]' "build-fuzz/logs/$r.log" 2>/dev/null; then
    failed=1
    echo "DID NOT RUN: fuzz_$r (see build-fuzz/logs/$r.log and the messages above)"
  fi
  if [ -s "$scratch/$r.regressed" ]; then
    failed=1
    echo "REGRESSED: saved reproducers of $r crash again:"
    sed 's/^/  /' "$scratch/$r.regressed"
  fi
  if [ -s "$scratch/$r.new" ]; then
    failed=1
    echo "NEW crashes of $r (reproducers stay in fuzz/regressions/$r/; log build-fuzz/logs/$r.log):"
    sed 's/^/  /' "$scratch/$r.new"
  fi
  [ -s "$scratch/$r.known" ] && { echo "known crashes of $r (fuzz/pending/$r/):"; sort "$scratch/$r.known" | uniq -c | sed 's/^/  /'; }
  [ -s "$scratch/$r.unrepeated" ] && { echo "did not crash again alone (moved to build-fuzz/unrepeated/$r/):"; sed 's/^/  /' "$scratch/$r.unrepeated"; }
done
echo "fuzz: ${#readers[@]} targets, ${seconds} s each, $(($(date +%s) - start)) s in all"
# The closing line CI reads: a target fails when a saved reproducer regressed or a new crash was found.
bad=0
for r in "${readers[@]}"; do [ -s "$scratch/$r.regressed" ] || [ -s "$scratch/$r.new" ] && bad=$((bad + 1)); done
echo "fuzz: $((${#readers[@]} - bad)) passed, $bad failed"
exit $failed
