#!/usr/bin/env bash
# Installs the Debian 12 packages shadowcull needs to build and test, and any packages
# named as arguments (scripts/fuzz.sh: clang). Idempotent. chromium, nodejs and npm are for
# the three.js frame check (examples/threejs; its npm packages: examples/threejs/install.sh).
set -euo pipefail
packages=(
  build-essential cmake ninja-build pkg-config
  libglm-dev libtinyxml2-dev libpng-dev libtbb-dev libembree-dev libcgal-dev
  libosmesa6-dev mesa-common-dev
  libegl-dev libegl-mesa0 libgl1-mesa-dri
  nlohmann-json3-dev libcli11-dev
  libmeshoptimizer-dev gltfpack libdraco-dev
  googletest libgtest-dev libbenchmark-dev
  slurm-wlm munge
  chromium nodejs
  "$@"
)
# npm: Debian's package, unless node came with its own (NodeSource's nodejs includes npm
# and conflicts with Debian's npm package).
command -v npm >/dev/null || packages+=(npm)
missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
  SUDO=""
  [ "$(id -u)" -ne 0 ] && SUDO="sudo"
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
fi
