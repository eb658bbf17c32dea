#!/usr/bin/env bash
# CTest's entry to browser_test.mjs: skipped (77), saying why, when Chromium, Node or the npm
# packages are missing and `npm ci` cannot bring them.
# Usage: run_browser_tests.sh FFLOC_CLI SCREENSHOT_DIR
set -uo pipefail
here=$(cd "$(dirname "$0")" && pwd)
chromium=${CHROMIUM:-/usr/bin/chromium}
if [ ! -x "$chromium" ]; then
  echo "skipped: $chromium not found (Debian package chromium)"
  exit 77
fi
if ! command -v node >/dev/null; then
  echo "skipped: node not found"
  exit 77
fi
if [ ! -d "$here/node_modules/playwright-core" ]; then
  echo "web/node_modules missing: npm ci"
  if ! (cd "$here" && timeout 300 npm ci --no-audit --no-fund); then
    echo "skipped: npm ci failed (no registry?); web/node_modules has no playwright-core"
    exit 77
  fi
fi
export CHROMIUM=$chromium
exec node "$here/browser_test.mjs" "$1" "$2"
