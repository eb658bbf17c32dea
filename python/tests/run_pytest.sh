#!/usr/bin/env bash
# CTest's entry to the Python tests: skipped (77) when the interpreter lacks pytest or NumPy; a
# run that collects no test (pytest's exit code 5) fails, as it means the tests were lost.
set -uo pipefail
python=$1
tests=$2
for module in pytest numpy; do
  if ! "$python" -c "import $module" 2>/dev/null; then
    echo "skipped: $python cannot import $module (Debian python3-pytest, python3-numpy)"
    exit 77
  fi
done
# Nothing written into the source tree: no .pytest_cache, no __pycache__.
PYTHONDONTWRITEBYTECODE=1 "$python" -m pytest -q -p no:cacheprovider "$tests"
status=$?
if [ "$status" -eq 5 ]; then
  echo "pytest collected no test in $tests"
  exit 1
fi
exit "$status"
