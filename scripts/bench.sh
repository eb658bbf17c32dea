#!/usr/bin/env bash
# `make bench`: the network timings and the Google Benchmark micro-benchmarks that were built,
# each saved under <build_dir>/bench/results/.
#
# The network: `ffloc bench model --json` (fp32, large config) and the PyTorch eager comparator
# bench/dust3r_eager.py (when Debian's python3-torch is installed) run in turns, one process
# each, FFLOC_BENCH_ROUNDS rounds (default 3) for each thread count of FFLOC_BENCH_THREADS
# (default "2 1"); then scripts/bench_ratios.py prints the medians and the eager/ffloc ratios.
# Ratios of back-to-back runs hold up on a loaded machine better than times do; the load
# average is saved beside them. Extra arguments go to `ffloc bench model` (e.g. --repeats 5).
set -euo pipefail
build_dir=${1:-build}
shared=${2:-../shared}
shift $(( $# < 2 ? $# : 2 ))
rounds=${FFLOC_BENCH_ROUNDS:-3}
thread_counts=${FFLOC_BENCH_THREADS:-"2 1"}
# Debian's python3-torch is installed for /usr/bin/python3, which a pyenv on PATH would hide.
python=${FFLOC_BENCH_PYTHON:-/usr/bin/python3}
[ -x "$python" ] || python=python3
source_dir=$(cd "$(dirname "$0")/.." && pwd)

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
  comparator=yes
  "$python" -c "import torch" 2> /dev/null || {
    comparator=no
    echo "(no python3-torch for $python: ffloc alone, no ratios; apt-get install python3-torch)"
  }
  rm -f "$out"/model_t*_r*.jsonl "$out"/eager_t*_r*.jsonl
  echo "== ffloc bench model and the PyTorch eager comparator, $rounds rounds (minutes per round on 2 cores) =="
  for round in $(seq 1 "$rounds"); do
    for threads in $thread_counts; do
      echo "round $round, $threads threads, load $(cut -d' ' -f1-3 /proc/loadavg)" | tee -a "$out/machine.txt"
      "$ffloc" bench model --dtype fp32 --features 1500 --repeats 3 --threads "$threads" --json "$@" \
        > "$out/model_t${threads}_r${round}.jsonl"
      if [ "$comparator" = yes ]; then
        "$python" "$source_dir/bench/dust3r_eager.py" --bench --threads "$threads" --repeats 3 --json \
          > "$out/eager_t${threads}_r${round}.jsonl"
      fi
    done
  done
  "$python" "$source_dir/scripts/bench_ratios.py" "$out" | tee "$out/model.txt"
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
