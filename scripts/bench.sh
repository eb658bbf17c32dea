#!/usr/bin/env bash
# `make bench`: the network timings (`ffloc bench model`, large config, fp32 and bf16) and the
# Google Benchmark micro-benchmarks that were built, each saved under <build_dir>/bench/results/.
# Timings are only worth comparing on an otherwise idle machine: the load average is saved
# beside them. Extra arguments go to `ffloc bench model` (e.g. --repeats 3 --dtype bf16).
set -euo pipefail
build_dir=${1:-build}
shared=${2:-../shared}
shift $(( $# < 2 ? $# : 2 ))

out="$build_dir/bench/results"  # build_dir/bench itself is the CMake folder of bench/
mkdir -p "$out"
if [ -d "$shared" ]; then
  export FFLOC_SHARED_DIR
  FFLOC_SHARED_DIR=$(cd "$shared" && pwd)
else
  echo "($shared not found: no Python reference ratios, and benchmarks on shared data are skipped)"
fi

{ date -u; uptime; nproc; } > "$out/machine.txt"
grep -m1 "model name" /proc/cpuinfo >> "$out/machine.txt" || true

ffloc="$build_dir/bin/ffloc"
if "$ffloc" bench --help > /dev/null 2>&1; then
  echo "== ffloc bench model (several minutes on 2 cores) =="
  "$ffloc" bench model "$@" | tee "$out/model.txt"
else
  echo "(ffloc was built without libtorch: no network timings)"
fi

for binary in "$build_dir"/bin/*_bench; do
  [ -x "$binary" ] || continue
  name=$(basename "$binary")
  echo "== $name =="
  "$binary" --benchmark_out="$out/$name.json" --benchmark_out_format=json | tee "$out/$name.txt"
done
echo "results in $out"
