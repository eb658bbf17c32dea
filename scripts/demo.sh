#!/usr/bin/env bash
# The README's main job: map a synthetic RGB-D scene with the default (classical) method, localize
# its queries exactly as a user would (ffloc localize on the saved map, then ffloc eval --map for
# the table), and run the experimental FastForward path beside it. Adds the real 7-Scenes query
# split when ../shared is present.
set -euo pipefail
ffloc=${1:-build/bin/ffloc}
out=${2:-build/demo}
shared=${3:-../shared}

start=$(date +%s)
mkdir -p "$out"
echo "== synthetic indoor RGB-D scene (seed 7, 640x480) =="
rm -rf "$out/synthetic"  # synth writes only into a new or empty folder
"$ffloc" synth --out "$out/synthetic" --seed 7 --scenes 1 --kind indoor --size 640x480 --quiet
scene_dir=$(find "$out/synthetic" -name manifest.json -printf '%h\n' | sort | head -n1)
"$ffloc" map --dataset "$scene_dir" -o "$out/synthetic.ffmap" --quiet
echo "-- the default method, classical, on the saved map (what ffloc localize and ffloc serve run) --"
"$ffloc" eval --dataset "$scene_dir" --map "$out/synthetic.ffmap" --quiet \
  --json "$out/synthetic_classical.json" --ply "$out/synthetic_classical.ply"
echo "-- experimental: FastForward with the default model (models/MODEL_CARD.md: nearest-neighbour" \
  "matching of dense SIFT through the FastForward pipeline; far below classical) --"
"$ffloc" eval --dataset "$scene_dir" --methods fastforward --model default --quiet --max-queries 5 \
  --json "$out/synthetic_fastforward.json"

if [ -d "$shared/data/7scenes_redkitchen" ]; then
  kitchen="$shared/data/7scenes_redkitchen"
  echo "== 7-Scenes redkitchen (real RGB-D; mapping split 0-596, queries 600-996) =="
  "$ffloc" map --dataset "$kitchen" -o "$out/redkitchen.ffmap" --quiet
  echo "-- one query, as a user localizes it (status localized: exit code 0) --"
  "$ffloc" localize --map "$out/redkitchen.ffmap" --image "$kitchen/frame-000800.color.jpg" --intrinsics 525,525,320,240
  "$ffloc" eval --dataset "$kitchen" --map "$out/redkitchen.ffmap" --quiet --json "$out/redkitchen_classical.json"
  echo "-- experimental: FastForward, 10 queries --"
  "$ffloc" eval --dataset "$kitchen" --methods fastforward --model default --quiet --max-queries 10 \
    --json "$out/redkitchen_fastforward.json"
else
  echo "(../shared/data not found: skipping the real-data evaluation)"
fi
echo "results: $out/*.json, per-frame CSVs and markdown tables beside them; maps: $out/*.ffmap;" \
  "PLY (mapping cameras grey, ground truth green, estimates blue, points red): $out/*.ply"
echo "demo time: $(( $(date +%s) - start )) s"
