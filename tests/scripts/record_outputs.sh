#!/usr/bin/env bash
# Records a fixed set of outputs of one build, so two builds can be compared bit for bit:
#   bash tests/scripts/record_outputs.sh BUILD/displace OUT_DIR
#   cmp -s / diff -r OUT_A OUT_B   (the .csv files hold wall times: compare the images)
# Frames and AOVs of water (unbounded and patch), calm and bricks, and the cone maps of water and bricks,
# each on both backends, with every frame's own cone map (lag 0) and with lagged maps (lag 3 at budget 0: each frame an even share of the first stage).
set -euo pipefail

if [[ $# -ne 2 ]]; then
  echo "usage: record_outputs.sh DISPLACE_BINARY OUT_DIR" >&2
  exit 2
fi
bin=$1
out=$2
mkdir -p "$out"

frames() { # name, then flags
  local name=$1
  shift
  "$bin" sequence --frames 0:2 --size 160x96 --map-size 128 "$@" \
    --output "$out/$name/frame_##.png" \
    --aov "uv=$out/$name/uv_##.exr" --aov "depth=$out/$name/depth_##.exr" \
    --aov "iterations=$out/$name/iterations_##.exr" --aov "fetches=$out/$name/fetches_##.exr" >/dev/null
  rm -f "$out/$name"/*.csv "$out/$name"/*.manifest
}

for backend in cpu device; do
  frames "water-$backend" --scene water --backend "$backend"
  frames "water-patch-$backend" --scene water --extent patch --backend "$backend"
  frames "calm-$backend" --scene calm --backend "$backend"
  frames "bricks-$backend" --scene bricks --backend "$backend"
  frames "water-lag3-$backend" --scene water --backend "$backend" --budget-ms 0 --cone-lag 3
  frames "calm-lag3-$backend" --scene calm --extent patch --backend "$backend" --budget-ms 0 --cone-lag 3
  for scene in water bricks; do
    "$bin" bake --scene "$scene" --map-size 128 --sectors 4 --cones bilinear --mode budgeted --backend "$backend" \
      --output "$out/cones-$scene-$backend.exr" >/dev/null
  done
done
echo "recorded $(find "$out" -type f | wc -l) files in $out"
