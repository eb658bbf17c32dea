#!/usr/bin/env bash
# Training throughput on this machine: samples/s and rank 0's step-time breakdown for batches of
# 1, 4 and 16 samples per rank on 1 and 2 ranks, with the shipped model's settings (small preset,
# 256 px, encoder trained, fp32) on two synthetic scenes. Meaningful on an idle machine only: the
# load average is printed beside the table.
#
#   scripts/bench_training.sh [BUILD_DIR] [STEPS]
set -euo pipefail
build_dir=${1:-build}
steps=${2:-4}
ffloc="$build_dir/bin/ffloc"
work=$(mktemp -d /tmp/ffloc-bench-training.XXXXXX)
trap 'rm -rf "$work"' EXIT

"$ffloc" synth --out "$work/data" --scenes 2 --kind indoor --size 320x240 --mapping-frames 30 --query-frames 2 --quiet
data="$work/data/scene_000_indoor,$work/data/scene_001_indoor"
cat >"$work/config.json" <<EOF
{"model": "random:small", "long_side": 256, "train_encoder": true, "colour_jitter": 0.2, "steps": $steps,
 "warmup_steps": 1, "log_every": 1, "checkpoint_every": 100000, "keep_checkpoints": 1, "seed": 1}
EOF

echo "machine: $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | sed 's/^ *//'), $(nproc) cores; load: $(cut -d' ' -f1-3 /proc/loadavg)"
echo "| batch per rank | ranks | global batch | samples/s | step s | waiting for data | all-reduce | optimiser | peak RSS per rank |"
echo "|---:|---:|---:|---:|---:|---:|---:|---:|---:|"
for batch in 1 4 16; do
  for ranks in 1 2; do
    out="$work/run_${batch}_${ranks}"
    /usr/bin/time -f "%M" -o "$work/rss" "$ffloc" train --quiet --config "$work/config.json" --data "$data" \
      --out "$out" --batch-size "$batch" --nproc-per-node "$ranks"
    # Steps after the first (which fills the caches); the means of the logged columns.
    awk -F, -v batch="$batch" -v ranks="$ranks" -v rss="$(cat "$work/rss")" '
      NR > 2 { n++; rate += $9; step += $10; wait += $11; reduce += $12; optimiser += $13 }
      END {
        printf "| %d | %d | %d | %.2f | %.2f | %.0f %% | %.0f %% | %.0f %% | %.0f MiB |\n", batch, ranks, batch * ranks,
          rate / n, step / n, 100 * wait / step, 100 * reduce / step, 100 * optimiser / step, rss / 1024
      }' "$out/log.csv"
  done
done
