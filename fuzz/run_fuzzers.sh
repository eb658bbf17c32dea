#!/usr/bin/env bash
# Configures and builds the libFuzzer targets (clang, ASan + UBSan) in their own build tree,
# then runs each for a while, one at a time, and prints per target: executions, coverage
# (libFuzzer's cov: edges and ft: features) and the crashes, leaks, timeouts and out-of-memory
# inputs it saved. Exit status: 0 when nothing was found, 1 when something was, 77 (CTest's skip)
# when clang or libFuzzer is missing.
#
#   fuzz/run_fuzzers.sh [--build-dir DIR] [--build-type TYPE] [--seconds N] [--jobs J] [TARGET...]
#   fuzz/run_fuzzers.sh [--build-dir DIR] --write-seeds    (fuzz/corpus/ written again)
#
# Each target starts from its seeds in fuzz/corpus/<target> and from what earlier runs in the
# same build tree added (DIR/corpus/<target>); findings go to DIR/findings/<target>/. TYPE is
# CMake's build type for a new build tree: RelWithDebInfo (the default) for real runs, None (no
# optimisation, no debug information: several times faster to build) for the CI smoke pass.
set -euo pipefail

source_dir=$(cd "$(dirname "$0")/.." && pwd)
build_dir="$source_dir/build-fuzz"
build_type=RelWithDebInfo
seconds=60
jobs=1
write_seeds=0
targets=()
while (($#)); do
  case "$1" in
    --build-dir) build_dir=$2; shift 2 ;;
    --build-type) build_type=$2; shift 2 ;;
    --seconds) seconds=$2; shift 2 ;;
    --jobs) jobs=$2; shift 2 ;;
    --write-seeds) write_seeds=1; shift ;;
    -h|--help) sed -n '2,16p' "$0"; exit 0 ;;
    *) targets+=("$1"); shift ;;
  esac
done

if ! command -v clang++ >/dev/null 2>&1; then
  echo "SKIP: clang++ not found (Debian: apt-get install clang libclang-rt-14-dev)"
  exit 77
fi
if ! echo 'extern "C" int LLVMFuzzerTestOneInput(const unsigned char*, unsigned long) { return 0; }' |
    clang++ -x c++ -fsanitize=fuzzer,address,undefined - -o /dev/null 2>/dev/null; then
  echo "SKIP: clang++ cannot link libFuzzer with ASan and UBSan (Debian: apt-get install libclang-rt-14-dev)"
  exit 77
fi

mkdir -p "$build_dir"
build_dir=$(cd "$build_dir" && pwd)
if [ ! -f "$build_dir/CMakeCache.txt" ]; then
  CXX=clang++ cmake -S "$source_dir" -B "$build_dir" -DCMAKE_BUILD_TYPE="$build_type" -DFFLOC_BUILD_FUZZERS=ON \
    -DFFLOC_BUILD_TESTS=OFF -DFFLOC_BUILD_BENCHMARKS=OFF >"$build_dir/configure.log" ||
    { cat "$build_dir/configure.log"; exit 1; }
fi
if ((write_seeds)); then
  cmake --build "$build_dir" --target ffloc_fuzz_seed_writer -j "$jobs" >"$build_dir/build.log" 2>&1 ||
    { tail -n 40 "$build_dir/build.log"; exit 1; }
  rm -rf "$source_dir/fuzz/corpus"
  "$build_dir/fuzz/ffloc_fuzz_seed_writer" "$source_dir/fuzz/corpus"
  exit 0
fi
if ! ((seconds > 0)); then
  echo "--seconds must be positive (libFuzzer takes 0 as no limit)"
  exit 2
fi
cmake --build "$build_dir" --target fuzzers -j "$jobs" >"$build_dir/build.log" 2>&1 ||
  { tail -n 40 "$build_dir/build.log"; exit 1; }

if ((${#targets[@]} == 0)); then
  for binary in "$build_dir"/fuzz/*_fuzzer; do targets+=("$(basename "$binary" _fuzzer)"); done
fi

found=0
printf '%-20s %12s %8s %8s %8s  %s\n' target executions cov ft findings "new findings"
for target in "${targets[@]}"; do
  corpus="$build_dir/corpus/$target"
  findings="$build_dir/findings/$target"
  log="$build_dir/logs/$target.log"
  mkdir -p "$corpus" "$findings" "$(dirname "$log")"
  before=$(find "$findings" -type f | sort)
  status=0
  # Memory: the parsers must refuse, not allocate, what the input cannot back. Hangs: 10 s.
  nice -n 19 "$build_dir/fuzz/${target}_fuzzer" "$corpus" "$source_dir/fuzz/corpus/$target" \
    -max_total_time="$seconds" -timeout=10 -rss_limit_mb=2048 -malloc_limit_mb=1024 \
    -print_final_stats=1 -artifact_prefix="$findings/" >"$log" 2>&1 || status=$?
  executions=$(sed -n 's/^stat::number_of_executed_units: *//p' "$log" | tail -n 1)
  coverage=$(grep -o 'cov: [0-9]*' "$log" | tail -n 1 | cut -d' ' -f2)
  features=$(grep -o 'ft: [0-9]*' "$log" | tail -n 1 | cut -d' ' -f2)
  new=$(comm -13 <(echo "$before") <(find "$findings" -type f | sort) | xargs -r -n1 basename | tr '\n' ' ')
  count=$(echo -n "$new" | wc -w)
  printf '%-20s %12s %8s %8s %8s  %s\n' "$target" "${executions:-?}" "${coverage:-?}" "${features:-?}" "$count" "$new"
  if ((status != 0 || count > 0)); then
    found=1
    echo "  $target: exit status $status; log $log"
    grep -m 3 -E '^(==[0-9]+==ERROR|SUMMARY|ffloc fuzz:|.*runtime error)' "$log" | sed 's/^/    /' || true
  fi
done
exit "$found"
