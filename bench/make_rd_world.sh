#!/usr/bin/env bash
# World RD: world R (20 x 20 chunks of 64 m, small rocks and trees) with world D's 6 x 6
# chunks of scanned rocks (51k-180k triangles) in its middle: dense chunks among light ones,
# as a real map has them. The shards' balance is measured on it (bench/shard_figures.sh,
# docs/cluster.md): counting objects alone gave the shards holding the rocks 1.59x the mean
# CPU time; weighing their triangles too, 1.19x.
#
#   bench/make_rd_world.sh WORK      (writes WORK/world-RD; generates R and D there if missing)
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
work="$(realpath -m "${1:?usage: $0 WORK}")"
mkdir -p "$work"
"$root/build/bin/bake_bench" --sizes R,D --gen-only --work "$work" > "$work/gen-rd.log"
r="$(ls -d "$work"/world-R-* | head -n 1)" d="$(ls -d "$work"/world-D-* | head -n 1)"
rm -rf "$work/world-RD"
cp -r "$r" "$work/world-RD"
# D's chunks replace R's at the same grid positions (both 64 m chunks), with their meshes
# and terrains; R's space.xml (its lights) stays.
cp "$d"/models/scan_* "$work/world-RD/models/"
cp "$d"/terrain/* "$work/world-RD/terrain/"
cp "$d"/*.chunk "$work/world-RD/"
echo "$work/world-RD: $(ls "$work/world-RD" | grep -c '\.chunk$') chunk files"
