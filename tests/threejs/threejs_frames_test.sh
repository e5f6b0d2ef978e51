#!/usr/bin/env bash
# A real engine reads the masks. three.js (WebGL2 in headless Chromium,
# examples/threejs) renders each exported scene per light with every caster and with the
# kept ones; the check must find no false-cull pixel and fewer shadow-pass draw calls:
#   1. the courtyard (data/gltf-courtyard): import, bake, export, check;
#   2. a generated scene of rows of culled casters (examples/threejs/gen_scene.mjs), with
#      --sun, a point and a spot light, a normal bias on the point light;
#   3. that export with two kept casters' bits cleared: the check must fail and name them.
#
#   tests/threejs/threejs_frames_test.sh [BUILD_BIN_DIR] [PICTURES_DIR]
#
# BUILD_BIN_DIR (default build/bin) holds shadowcull and make_gltf_scene; the pictures
# (all | kept | difference, per light) go to PICTURES_DIR (default: a temporary directory,
# removed). Exit 0 pass, 1 fail, 77 skipped (only when node/npm or chromium are missing
# and cannot be installed).
set -euo pipefail
root="$(cd "$(dirname "$0")/../.." && pwd)"
bin="$(realpath "${1:-$root/build/bin}")"
example="$root/examples/threejs"

skip() { echo "SKIPPED: three.js frame check: $*"; exit 77; }
fail() { echo "FAIL: $*"; exit 1; }

# --- the tools: node and npm, Debian's chromium (a browser download does not work here) ---
install_packages() {
  [ "$(id -u)" -eq 0 ] && command -v apt-get >/dev/null || return 1
  echo "installing $*"
  { apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends "$@"; } >/dev/null
}
command -v node >/dev/null || install_packages nodejs || skip "node is not installed and cannot be (not root, or apt-get failed)"
command -v npm >/dev/null || install_packages npm || skip "npm is not installed and cannot be (not root, or apt-get failed)"
chromium="${CHROMIUM:-/usr/bin/chromium}"
[ -x "$chromium" ] || install_packages chromium || skip "chromium is not installed and cannot be (not root, or apt-get failed)"
[ -x "$chromium" ] || skip "no $chromium"
for exe in shadowcull make_gltf_scene; do [ -x "$bin/$exe" ] || fail "no $bin/$exe (build first)"; done
"$example/install.sh" || fail "npm ci in examples/threejs failed"
# The parameter mapping's own checks (page/bias_mapping.js), before any frame.
node --test "$example/test/bias_mapping.test.mjs" >/dev/null || { node --test "$example/test/bias_mapping.test.mjs"; fail "examples/threejs/test: the bias mapping"; }

tmp="$(mktemp -d /tmp/shadowcull-threejs-test.XXXXXX)"
trap 'rm -rf "$tmp"' EXIT
pictures="${2:-$tmp/pictures}"
mkdir -p "$pictures"

# import, bake and export SCENE into $tmp/NAME-*; extra import arguments after NAME.
bake_and_export() {
  local scene="$1" name="$2"
  shift 2
  "$bin/shadowcull" import "$scene" "$tmp/$name-space" "$@" >"$tmp/$name-import.log" || { cat "$tmp/$name-import.log"; fail "$name: import"; }
  "$bin/shadowcull" bake "$tmp/$name-space" --quiet --results "$tmp/$name-results.json" || fail "$name: bake"
  "$bin/shadowcull" export "$tmp/$name-space" "$tmp/$name-results.json" --gltf "$scene" --out "$tmp/$name-culled.glb" \
    || fail "$name: export"
}

# The check on an export; its output in $tmp/NAME.log. Returns the driver's exit code.
check() {
  local glb="$1" name="$2" rc=0
  echo "--- $name: node examples/threejs/check_frames.mjs $(basename "$glb")"
  node "$example/check_frames.mjs" "$glb" --out "$pictures" --json "$tmp/$name-report.json" >"$tmp/$name.log" 2>&1 || rc=$?
  cat "$tmp/$name.log"
  return "$rc"
}

start=$SECONDS

# 1. The courtyard.
"$bin/make_gltf_scene" "$tmp/courtyard.glb" >/dev/null
bake_and_export "$tmp/courtyard.glb" courtyard
check "$tmp/courtyard-culled.glb" courtyard || fail "courtyard: the frame check failed (see above)"

# 2. Rows of culled casters: the masks first (so that nothing passes by keeping everything).
node "$example/gen_scene.mjs" "$tmp/rows.glb" >/dev/null
bake_and_export "$tmp/rows.glb" rows --sun 0,60 --bias 0.05
node "$root/tests/threejs/expect_masks.mjs" "$tmp/rows-culled.glb" \
  'OnGround_*:sun=1' 'UnderRoof_*:sun=0' 'UnderRoof_2:lamp=0' 'UnderRoof_*:spot=0' \
  'Stack_0:sun=0,1' 'Floating_*:sun=0' 'Roof_*:sun=1' 'Roof_2:lamp=1' 'GapCube:lamp=1' \
  'NoShadowRoof:sun=0' 'UnderNoShadowRoof:sun=1' 'SpotCube:spot=1' 'SpotHidden:spot=0' 'SpotHidden:sun=1' \
  || fail "rows: the bake's masks are not the expected ones"
# The lamp's normal bias comes from its node's extras.shadowcull_normal_bias (0.03 m):
# import reads it, the bake honours it and export hands it to the engine.
lamp_normal_bias="$(node --input-type=module -e "
  import { readGlb } from '$example/lib/glb.mjs';
  const L = readGlb('$tmp/rows-culled.glb').json.extras.shadowcull.lights.find((l) => l.name === 'lamp');
  console.log(L.normalBias ?? 0);")"
[ "$lamp_normal_bias" = "0.03" ] || fail "rows: the export says lamp normalBias $lamp_normal_bias, not its node's 0.03"
check "$tmp/rows-culled.glb" rows || fail "rows: the frame check failed (see above)"

# 3. Deliberate false culls, each a real shadow of a kept caster: OnGround_2's on the
# ground (itself culled for the sun: receivers are all surfaces), and the top primitive of
# Stack_0's on its roof (a kept surface). The check must fail and name both.
node "$example/edit_export.mjs" "$tmp/rows-culled.glb" "$tmp/broken.glb" cull OnGround_2 sun
node "$example/edit_export.mjs" "$tmp/broken.glb" "$tmp/broken.glb" cull Stack_0 sun 1
rc=0
check "$tmp/broken.glb" broken || rc=$?
[ "$rc" -eq 1 ] || fail "broken export: the check exited $rc, not 1: it did not catch the false culls"
for culprit in "'OnGround_2' (OnGround_2)" "'Stack_0' (Stack_0\\[1\\])"; do
  grep -q "FALSE CULL: node [0-9]* $culprit for light [0-9]* 'sun'" "$tmp/broken.log" \
    || fail "broken export: the check did not name $culprit and light sun"
done
kept_surface_false_culls="$(node -e "
  const r = require('$tmp/broken-report.json');
  console.log(r.lights.flatMap((L) => L.cameras).reduce((n, c) => n + c.falseCullOnKept, 0));")"
[ "$kept_surface_false_culls" -gt 0 ] || fail "broken export: no false-cull pixel on a kept surface (Stack_0's shadow on its roof)"
echo "the deliberate false culls (OnGround_2 and Stack_0[1], sun) were caught, $kept_surface_false_culls px of them on kept surfaces"

echo "PASS: three.js frame check ($((SECONDS - start)) s)"
