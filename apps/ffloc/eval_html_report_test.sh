#!/usr/bin/env bash
# 'ffloc eval --html' end to end on a small synthetic scene: the page is written with its charts
# and thumbnails, and an output folder that does not exist is an error naming the file.
# With "browser": headless Chromium renders the page, and the screenshot must not be blank
# (a blank page compresses to about 15 kB); skipped (exit 77) when Chromium is not installed.
set -euo pipefail
ffloc=$1
mode=${2:-cli}
chromium=${CHROMIUM:-/usr/bin/chromium}
if [ "$mode" = browser ] && [ ! -x "$chromium" ]; then
  echo "skipped: $chromium not found (Debian package chromium)"
  exit 77
fi

work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
"$ffloc" synth --out "$work/synth" --seed 3 --kind indoor --size 128x96 --mapping-frames 10 --query-frames 6 --quiet
scene="$work/synth/scene_000_indoor"
report="$work/report.html"
"$ffloc" eval --dataset "$scene" --methods oracle-depth --quiet --html "$report" >/dev/null

if [ "$mode" = cli ]; then
  grep -q '<path class="cdf"' "$report"
  grep -q '<path class="mapping"' "$report"
  grep -q 'src="data:image/jpeg;base64,' "$report"
  missing="$work/no-such-folder/report.html"
  if "$ffloc" eval --dataset "$scene" --methods oracle-depth --quiet --html "$missing" >/dev/null 2>"$work/error"; then
    echo "eval wrote to a folder that does not exist"
    exit 1
  fi
  grep -qF "$missing" "$work/error"
  echo "report written and checked ($(wc -c <"$report") bytes)"
  exit 0
fi

"$chromium" --headless --no-sandbox --disable-gpu --disable-quic --no-first-run --disable-background-networking \
  --disable-component-update --disable-sync --user-data-dir="$work/profile" --window-size=1400,2400 \
  --screenshot="$work/report.png" "file://$report" >/dev/null 2>&1
size=$(wc -c <"$work/report.png")
if [ "$size" -lt 60000 ]; then
  echo "screenshot of $size bytes: the page rendered blank"
  exit 1
fi
echo "rendered: $size bytes of PNG"
