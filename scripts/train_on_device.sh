#!/usr/bin/env bash
# Turns a lent GPU machine's minutes into checks and training (docs/training.md, "A GPU run").
#
#   scripts/train_on_device.sh BUDGET_S [CONFIG]
#
# Run from the repository root on the device machine (PyTorch 2.x with CUDA, CMake, a compiler),
# with device_data/ carried: sysroot.tar.xz (scripts/device_sysroot.sh) and shared/fixtures/dust3r
# (a copy of ../shared/fixtures/dust3r). In BUDGET_S seconds, all steps together:
#   1. unpack the Debian dependencies, configure against the libtorch inside the machine's PyTorch
#      and build the CLI and the model tests with every core (skipped when build-device/ holds
#      them, as on a machine still warm from the last call);
#   2. the DUSt3R parity tests on the GPU (FFLOC_TEST_DEVICE=cuda) and on its CPU;
#   3. synthetic training scenes (seed 1000) and the model card's held-out scenes (seed 9000);
#   4. train CONFIG on the GPU in bf16 for the time left, resuming runs/device when it holds a
#      run, so that a second call continues the first;
#   5. ffloc eval of the trained weights and of the run's initial weights on the held-out scenes.
# Under $OUT: env.txt, build.log, parity.log, train.log, log.csv, model.safetensors (the last
# checkpoint's weights), eval.txt and summary.json.
set -uo pipefail

budget=${1:?usage: scripts/train_on_device.sh BUDGET_S [CONFIG]}
config=${2:-models/ffloc-sift-small-256.gpu_config.json}
out=${OUT:-device_out}
build=build-device
runs=runs/device
start=$(date +%s)
left() { echo $((budget - ($(date +%s) - start))); }
mkdir -p "$out" "$runs"
: >"$out/summary.parts"
summary() {  # key value (value already JSON)
  printf '"%s": %s\n' "$1" "$2" >>"$out/summary.parts"
}
finish() {
  { echo "{"; paste -sd, "$out/summary.parts"; echo "}"; } >"$out/summary.json"
  rm -f "$out/summary.parts"
  cat "$out/summary.json"
}
trap finish EXIT
summary budget_s "$budget"

{
  nvidia-smi --query-gpu=name,memory.total,driver_version --format=csv,noheader
  lscpu | grep -E "Model name|^CPU\(s\)"
  g++ --version | head -n1
  cmake --version | head -n1
  python3 -c 'import torch; print("torch", torch.__version__, "cuda", torch.version.cuda, "cxx11abi", torch._C._GLIBCXX_USE_CXX11_ABI)'
} >"$out/env.txt" 2>&1
cat "$out/env.txt"

# 1. Build.
sysroot=/tmp/ffloc-sysroot
if [ ! -d "$sysroot/usr" ]; then
  mkdir -p "$sysroot" && tar -xJf device_data/sysroot.tar.xz -C "$sysroot" || { summary build '"no sysroot"'; exit 1; }
fi
export LD_LIBRARY_PATH=$sysroot/usr/lib/x86_64-linux-gnu${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}
torch_prefix=$(python3 -c 'import torch; print(torch.utils.cmake_prefix_path)')
nccl_include=$(python3 -c 'import os, nvidia.nccl as n; print(os.path.join(list(n.__path__)[0], "include"))' 2>/dev/null)
build_start=$(date +%s)
if [ ! -x "$build/bin/ffloc" ] || [ ! -x "$build/src/ffloc/model/ffloc_model_test" ]; then
  cmake -S . -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=Release -DCMAKE_PREFIX_PATH="$torch_prefix;$sysroot/usr" \
    -DFFLOC_BUILD_BENCHMARKS=OFF -DFFLOC_SHARED_DIR="$PWD/device_data/shared" \
    -DFFLOC_NCCL_INCLUDE_DIR="$nccl_include" >"$out/build.log" 2>&1
  # -k 0: every error of the first build against this libtorch in one log.
  timeout "$(left)" cmake --build "$build" --target ffloc_cli ffloc_model_test -- -k 0 >>"$out/build.log" 2>&1
fi
if [ ! -x "$build/bin/ffloc" ]; then
  summary build '"failed, see build.log"'
  grep -E "error|Error" "$out/build.log" | head -n 60
  exit 1
fi
summary build_s $(($(date +%s) - build_start))
ffloc="$PWD/$build/bin/ffloc"

# 2. Parity: float32 to 1e-5 on the GPU and on this libtorch's CPU kernels, and the bf16 checks.
if [ ! -s "$out/parity.log" ] && [ ! -f "$runs/parity.done" ]; then
  for device in cuda cpu; do
    echo "== $device" >>"$out/parity.log"
    FFLOC_SHARED_DIR=$PWD/device_data/shared FFLOC_TEST_DEVICE=$device timeout 240 \
      "$build/src/ffloc/model/ffloc_model_test" --gtest_filter='Dust3rParity.*' >>"$out/parity.log" 2>&1
    result=$([ $? -eq 0 ] && echo passed || echo failed)
    skipped=$(sed -n "/^== $device/,\$p" "$out/parity.log" | grep -c '^\[  SKIPPED \]')
    summary "parity_$device" "\"$result, $skipped skipped\""
  done
  touch "$runs/parity.done"
  grep -E "^== |OK \]|FAILED \]|relative" "$out/parity.log" | head -n 60
fi

# 3. Data.
[ -d runs/train ] || "$ffloc" synth --out runs/train --seed 1000 --scenes 48 --quiet >"$out/train.log" 2>&1
[ -d runs/val ] || "$ffloc" synth --out runs/val --seed 9000 --scenes 10 --quiet >>"$out/train.log" 2>&1
train_data=$(ls -d runs/train/scene_* | paste -sd,)
val_data=$(ls -d runs/val/scene_* | paste -sd,)

# 4. Train for what is left, keeping time for the two evaluations and the copy back.
train_seconds=$(($(left) - 150))
if [ "$train_seconds" -gt 20 ]; then
  resume=()
  [ -e "$runs/checkpoints/latest" ] && resume=(--resume)
  timeout $((train_seconds + 90)) "$ffloc" train --config "$config" --data "$train_data" --out "$runs" \
    --device cuda --precision bf16 --loader-threads 12 --max-seconds "$train_seconds" "${resume[@]}" \
    >>"$out/train.log" 2>&1
  summary train_exit $?
fi
tail -n 5 "$out/train.log"
cp "$runs/log.csv" "$out/log.csv" 2>/dev/null
latest=$(cat "$runs/checkpoints/latest" 2>/dev/null)
if [ -n "$latest" ] && [ -f "$runs/checkpoints/$latest/model.safetensors" ]; then
  cp "$runs/checkpoints/$latest/model.safetensors" "$out/model.safetensors"
  summary checkpoint "\"$latest\""
  summary last_log_line "\"$(tail -n1 "$runs/log.csv" | cut -d, -f1-12)\""
fi

# 5. The held-out scenes: trained weights against the initial ones, on this machine's CPU.
initial=$(python3 -c 'import json, sys; print(json.load(open(sys.argv[1]))["model"])' "$config")
for name in initial trained; do
  model=$initial
  [ "$name" = trained ] && model=$out/model.safetensors
  [ -f "$model" ] || continue
  [ "$(left)" -gt 20 ] || break
  echo "== $name: $model" >>"$out/eval.txt"
  timeout "$(left)" "$ffloc" eval --dataset "$val_data" --methods fastforward --model "$model" --quiet \
    --json "runs/eval_$name.json" >>"$out/eval.txt" 2>&1
  pooled=$(python3 -c '
import json, sys
rows = json.load(open(sys.argv[1]))["results"]
frames = sum(r["frames"] for r in rows)
print(round(sum(r["acc"]["25cm_5deg"] * r["frames"] for r in rows) / frames, 2))' "runs/eval_$name.json" 2>/dev/null)
  summary "val_25cm_5deg_$name" "${pooled:-null}"
done
