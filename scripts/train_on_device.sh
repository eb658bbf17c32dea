#!/usr/bin/env bash
# Turns a lent GPU machine's time into training (docs/training.md, "A GPU run").
#
#   scripts/train_on_device.sh BUDGET_S [CONFIG] [DATA]
#
# Run from the repository root on the device machine (PyTorch 2.x with CUDA, CMake, a compiler).
# In BUDGET_S seconds, all steps together:
#   1. configure against the libtorch inside the machine's PyTorch and build only the CLI and the
#      model tests, with every core;
#   2. the DUSt3R parity tests on the GPU in float32 and the bf16 agreement checks
#      (FFLOC_TEST_DEVICE=cuda; fixtures from FFLOC_SHARED_DIR, default device_data/shared, a
#      git-ignored folder the device tool carries);
#   3. find the largest batch that fits (doubling from 1 with two-step bf16 runs);
#   4. train CONFIG on DATA with bf16 autocast and that batch for the time left, ending with a
#      checkpoint (ffloc train --max-seconds).
# Everything lands under $OUT (default device_out/): build.log, parity.log, batch_probe.log,
# run/ (log.csv, config.json, checkpoints/), train.log and summary.json.
set -uo pipefail

budget=${1:?usage: scripts/train_on_device.sh BUDGET_S [CONFIG] [DATA]}
config=${2:-models/ffloc-small-256.train_config.json}
data=${3:-device_data/train}
out=${OUT:-device_out}
shared=${FFLOC_SHARED_DIR:-device_data/shared}
build=${BUILD_DIR:-build-device}
mkdir -p "$out"
start=$(date +%s)
left() { echo $((budget - ($(date +%s) - start))); }
summary() {  # key value (value already JSON)
  printf '%s\n' "\"$1\": $2" >>"$out/summary.parts"
}
finish() {
  { echo "{"; paste -sd, "$out/summary.parts" 2>/dev/null; echo "}"; } >"$out/summary.json"
  rm -f "$out/summary.parts"
  cat "$out/summary.json"
}
trap finish EXIT
: >"$out/summary.parts"
summary budget_s "$budget"
nvidia-smi --query-gpu=name,memory.total --format=csv,noheader >"$out/gpu.txt" 2>&1 || true
summary gpu "\"$(head -n1 "$out/gpu.txt" | tr -d '"')\""

# 1. Build.
torch_prefix=$(python3 -c 'import torch; print(torch.utils.cmake_prefix_path)' 2>>"$out/build.log")
torch_version=$(python3 -c 'import torch; print(torch.__version__)' 2>/dev/null)
summary torch "\"${torch_version:-none}\""
if [ -z "$torch_prefix" ]; then
  summary build "\"no PyTorch with libtorch found\""
  exit 1
fi
build_start=$(date +%s)
if ! { cmake -S . -B "$build" -DCMAKE_BUILD_TYPE=Release -DCMAKE_PREFIX_PATH="$torch_prefix" \
         -DFFLOC_BUILD_BENCHMARKS=OFF -DFFLOC_SHARED_DIR="$(realpath -m "$shared")" &&
       cmake --build "$build" -j "$(nproc)" --target ffloc_cli ffloc_model_test; } >>"$out/build.log" 2>&1; then
  summary build "\"failed, see build.log\""
  tail -n 30 "$out/build.log"
  exit 1
fi
summary build_s $(($(date +%s) - build_start))
ffloc="$build/bin/ffloc"

# 2. Parity on the GPU: float32 to 1e-5, and the bf16 agreement tests.
FFLOC_SHARED_DIR=$(realpath -m "$shared") FFLOC_TEST_DEVICE=cuda \
  timeout "$(left)" "$build/src/ffloc/model/ffloc_model_test" --gtest_filter='Dust3rParity.*' >"$out/parity.log" 2>&1
parity=$?
summary parity "\"$([ $parity -eq 0 ] && echo passed || echo "failed ($parity)")\""
grep -E "worst relative|relative [0-9]" "$out/parity.log" | head -n 40

# 3. The largest batch that fits: a two-step bf16 run per candidate.
best=0
for batch in 1 2 4 8 16 32 64; do
  [ "$(left)" -gt 120 ] || break
  rm -rf "$out/probe"
  if timeout 300 "$ffloc" train --quiet --config "$config" --data "$data" --out "$out/probe" --device cuda \
       --precision bf16 --steps 2 --batch-size "$batch" >>"$out/batch_probe.log" 2>&1; then
    best=$batch
    echo "batch $batch fits" | tee -a "$out/batch_probe.log"
  else
    echo "batch $batch does not fit or failed" | tee -a "$out/batch_probe.log"
    break
  fi
done
rm -rf "$out/probe"
summary batch_size "$best"
[ "$best" -gt 0 ] || exit 1

# 4. Train for what is left, keeping a minute for the final checkpoint and the copy back.
train_seconds=$(($(left) - 60))
[ "$train_seconds" -gt 30 ] || exit 1
timeout $((train_seconds + 120)) "$ffloc" train --config "$config" --data "$data" --out "$out/run" --device cuda \
  --precision bf16 --batch-size "$best" --max-seconds "$train_seconds" >"$out/train.log" 2>&1
summary train_exit $?
summary steps "$(tail -n1 "$out/run/log.csv" 2>/dev/null | cut -d, -f1 | grep -E '^[0-9]+$' || echo 0)"
summary samples_per_s "$(tail -n1 "$out/run/log.csv" 2>/dev/null | cut -d, -f9 | grep -E '^[0-9.e+-]+$' || echo 0)"
