#!/usr/bin/env bash
# Produces the per-frame CSVs behind the verdict's calibration and its measured precision and
# recall (docs/verdict.md): tuning scenes (synthetic seed 5000 and the shared real data) and
# held-out scenes (synthetic seeds 9000 and 9500, never used for tuning). Usage:
#   scripts/verdict_runs.sh BUILD_DIR SHARED_DIR OUT_DIR
# The rule is tuned on the methods that localise (classical, sift-baseline); FastForward runs on the
# held-out and real scenes, where its precision is measured.
set -euo pipefail
build=${1:-build}
shared=${2:-../shared}
out=${3:-build/verdict}
tuned=classical,sift-baseline
all=classical,sift-baseline,fastforward
ffloc="$build/bin/ffloc"
mkdir -p "$out"
[ -d "$out/tuning" ] || "$ffloc" synth --out "$out/tuning" --seed 5000 --scenes 9 --kind mixed --quiet
[ -d "$out/heldout" ] || "$ffloc" synth --out "$out/heldout" --seed 9000 --scenes 10 --kind mixed --quiet
# A second held-out set, rendered after the first had been measured (docs/verdict.md says why).
[ -d "$out/heldout2" ] || "$ffloc" synth --out "$out/heldout2" --seed 9500 --scenes 10 --kind mixed --quiet
# evaluate SET METHODS: every synthetic scene of the set, once.
evaluate() {
  local scene name
  for scene in "$out/$1"/scene_*; do
    name=$(basename "$scene")
    [ -f "$out/$1.$name.frames.csv" ] || "$ffloc" eval --dataset "$scene" --methods "$2" --quiet \
      --json "$out/$1.$name.json" > /dev/null
  done
}
evaluate tuning "$tuned"
for data in 7scenes_redkitchen strecha_fountain_p11 strecha_herzjesu_p8 instant_ngp_fox 7scenes_stairs_kapture_sample/stairs; do
  [ -d "$shared/data/$data" ] || continue
  label=$(basename "$data")
  # The default model (the matching family) needs mapping depth; where a dataset has none, ffloc
  # eval refuses it by name and the classical methods run alone.
  [ -f "$out/real.$label.frames.csv" ] || "$ffloc" eval --dataset "$shared/data/$data" --methods "$all" --quiet \
    --json "$out/real.$label.json" > /dev/null || "$ffloc" eval --dataset "$shared/data/$data" --methods "$tuned" \
    --quiet --json "$out/real.$label.json" > /dev/null
done
evaluate heldout "$all"
evaluate heldout2 "$all"
echo "per-frame CSVs in $out"
