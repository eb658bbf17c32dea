#!/usr/bin/env bash
# The classical method as a user runs it (a saved map) beside the evaluation-only `sift-baseline`,
# which rebuilds every retrieved mapping image's features per query (docs/classical.md,
# "Measured"). For each dataset: `ffloc map` and `ffloc eval --methods sift-baseline --map M`,
# each under /usr/bin/time -v, then one table of accuracy and latency per query and one of
# mapping time, map size per image and peak memory. Usage:
#   scripts/classical_vs_baseline.sh BUILD_DIR SHARED_DIR OUT_DIR [DATASET...]
# DATASETs are folders under SHARED_DIR/data (default: 7scenes_redkitchen, strecha_fountain_p11,
# strecha_herzjesu_p8). Run it on an idle machine: the latencies are wall-clock times.
set -euo pipefail
build=${1:-build}
shared=${2:-../shared}
out=${3:-build/classical_vs_baseline}
datasets=("${@:4}")
[ ${#datasets[@]} -gt 0 ] || datasets=(7scenes_redkitchen strecha_fountain_p11 strecha_herzjesu_p8)
ffloc="$build/bin/ffloc"
[ -x /usr/bin/time ] || { echo "error: /usr/bin/time is missing (apt-get install time)" >&2; exit 2; }
for dataset in "${datasets[@]}"; do  # all of them before the first run
  [ -d "$shared/data/$dataset" ] || { echo "error: $shared/data/$dataset: no such dataset folder" >&2; exit 2; }
done
mkdir -p "$out"
{ date -u; grep -m1 "model name" /proc/cpuinfo; nproc; uptime; } | tee "$out/machine.txt"

# peak_mib LOG: the peak resident set size /usr/bin/time -v wrote, in MiB.
peak_mib() { awk -F': ' '/Maximum resident set size/ {printf "%.0f", $2 / 1024}' "$1"; }

resources="$out/resources.md"
echo "| dataset | images mapped | mapping time per image | map size per image | peak RSS, mapping | peak RSS, eval |" > "$resources"
echo "|---|---:|---:|---:|---:|---:|" >> "$resources"
accuracy="$out/accuracy.md"
: > "$accuracy"
for dataset in "${datasets[@]}"; do
  data="$shared/data/$dataset"
  label=$(basename "$dataset")
  map="$out/$label.ffmap"
  echo "== $label: ffloc map =="
  rm -f "$map"
  /usr/bin/time -v -o "$out/$label.map.time" "$ffloc" map --dataset "$data" --output "$map" --quiet \
    | tee "$out/$label.map.log"
  images=$(sed -n 's/.* holds \([0-9]*\) images.*/\1/p' "$out/$label.map.log")
  per_image=$(sed -n 's/.*(\([0-9.]*\) s\/image).*/\1/p' "$out/$label.map.log")
  echo "== $label: ffloc eval --methods sift-baseline --map $map =="
  /usr/bin/time -v -o "$out/$label.eval.time" "$ffloc" eval --dataset "$data" --methods sift-baseline --map "$map" \
    --quiet --json "$out/$label.json" > /dev/null
  if [ -s "$accuracy" ]; then tail -n +3 "$out/$label.md" >> "$accuracy"; else cat "$out/$label.md" >> "$accuracy"; fi
  awk -v d="$label" -v n="$images" -v t="$per_image" -v bytes="$(stat -c %s "$map")" \
    -v m="$(peak_mib "$out/$label.map.time")" -v e="$(peak_mib "$out/$label.eval.time")" \
    'BEGIN {printf "| %s | %d | %.3f s | %.2f MiB | %d MiB | %d MiB |\n", d, n, t, bytes / n / 1048576, m, e}' >> "$resources"
done
echo
cat "$accuracy"
echo
echo "(mapping time per image: as 'ffloc map' reports it, without start-up)"
cat "$resources"
