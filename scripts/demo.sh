#!/usr/bin/env bash
# The README's main job: generate a synthetic scene and evaluate localisation on it; add the real
# 7-Scenes and Strecha samples when ../shared is present.
set -euo pipefail
ffloc=${1:-build/bin/ffloc}
out=${2:-build/demo}
shared=${3:-../shared}

mkdir -p "$out"
echo "== synthetic indoor scene (seed 7) =="
"$ffloc" synth --out "$out/synthetic" --seed 7 --scenes 1 --kind indoor
scene_dir=$(find "$out/synthetic" -name manifest.json -printf '%h\n' | sort | head -n1)
"$ffloc" eval --dataset "$scene_dir" --methods oracle-depth,sift-baseline --outliers 0.3 --noise-px 0.5 \
  --json "$out/synthetic_eval.json"

if [ -d "$shared/data/7scenes_redkitchen" ]; then
  echo "== 7-Scenes redkitchen (real): oracle depth with 30% outliers =="
  "$ffloc" eval --dataset "$shared/data/7scenes_redkitchen" --methods oracle-depth --outliers 0.3 \
    --json "$out/redkitchen_eval.json"
  echo "== Strecha fountain-P11 (real, LIDAR ground truth): SIFT baseline =="
  "$ffloc" eval --dataset "$shared/data/strecha_fountain_p11" --methods sift-baseline \
    --json "$out/fountain_eval.json"
else
  echo "(../shared/data not found: skipping the real-data evaluations)"
fi
echo "results: $out/*.json, per-frame CSVs and markdown tables beside them"
