#!/usr/bin/env bash
# Load test of `ffloc serve` with wrk, on loopback only, bounded in requests and time:
# a small synthetic classical map behind an API key, 32 connections, a mix of good queries and
# designed refusals (missing intrinsics 400, bad key 401, another map 403, busy 503), first
# 1,000 then 9,000 more requests, with the server's defaults (4 queries waiting, 64 connections). Prints the answers by status, wrk's latency percentiles, the
# server's RSS after 1k and after 10k requests, and /health latencies measured during the load.
#
#   scripts/load_test.sh [BUILD_DIR] [TOTAL_REQUESTS]
#
# SERVE_ARGS adds options to `ffloc serve`: SERVE_ARGS="--max-waiting 32" admits every query of
# the 32 connections, so that none is refused as busy and every good request is localised.
set -euo pipefail
build_dir=${1:-build}
total=${2:-10000}
ffloc="$(realpath "$build_dir/bin/ffloc")"
command -v wrk >/dev/null || { echo "wrk is not installed (apt-get install wrk)"; exit 1; }
work=$(mktemp -d /tmp/ffloc-load.XXXXXX)
server_pid=
cleanup() {
  [ -n "$server_pid" ] && kill "$server_pid" 2>/dev/null && wait "$server_pid" 2>/dev/null
  [ -n "${KEEP:-}" ] || rm -rf "$work"
}
trap cleanup EXIT

"$ffloc" synth --out "$work/data" --kind indoor --mapping-frames 20 --query-frames 1 --quiet
scene="$work/data/scene_000_indoor"
"$ffloc" map --dataset "$scene" -o "$work/small.ffmap" --quiet >/dev/null
key=load-test-key-0123456789
echo "$key small" >"$work/keys.txt"
query=$(python3 -c "import json; m=json.load(open('$scene/manifest.json')); q=[f for f in m['frames'] if f.get('split')=='query'][0]; k=m['cameras'][q['camera']]; print(q['image'], k['fx'], k['fy'], k['cx'], k['cy'])")
read -r image fx fy cx cy <<<"$query"
cp "$scene/$image" "$work/query.png"

port=$(python3 -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')
"$ffloc" serve --map "small=$work/small.ffmap" --keys "$work/keys.txt" --port "$port" \
  ${SERVE_ARGS:-} 2>"$work/server.log" &
server_pid=$!
for _ in $(seq 100); do curl -s "http://127.0.0.1:$port/health" >/dev/null && break; sleep 0.2; done

cat >"$work/mix.lua" <<EOF
-- Each thread stops after its share of the answers and leaves a file saying so (the script then
-- interrupts wrk, which prints its summary); answers are counted by status.
local image = io.open("$work/query.png", "rb"):read("*a")
local good = "/maps/small/localize?fx=$fx&fy=$fy&cx=$cx&cy=$cy"
local threads = {}
function setup(thread)
  table.insert(threads, thread)
  thread:set("id", #threads)
end
function init(args)
  share = tonumber(args[1]); sent = 0; answered = 0; counts = {}; marker = args[2]
end
function request()
  sent = sent + 1
  local kind = sent % 20
  local headers = {["Content-Type"] = "image/png", ["Authorization"] = "Bearer $key"}
  if kind == 1 then return wrk.format("POST", "/maps/small/localize?fx=$fx", headers, image) end          -- 400
  if kind == 2 then headers["Authorization"] = "Bearer wrong-key-0123456789" end                          -- 401
  if kind == 3 then return wrk.format("POST", "/maps/other/localize?fx=$fx&fy=$fy&cx=$cx&cy=$cy", headers, image) end -- 403
  return wrk.format("POST", good, headers, image)
end
function response(status, headers, body)
  counts[status] = (counts[status] or 0) + 1
  answered = answered + 1
  if answered == share then
    io.open(marker .. "." .. tostring(id), "w"):close()
    wrk.thread:stop()
  end
end
function done(summary, latency, requests)
  local all = {}
  for _, thread in ipairs(threads) do
    for status, n in pairs(thread:get("counts")) do all[status] = (all[status] or 0) + n end
  end
  local line = "answers by status:"
  for status, n in pairs(all) do line = line .. " " .. status .. "=" .. n end
  print(line)
  print(string.format("latency p50 %.1f ms, p90 %.1f ms, p99 %.1f ms, max %.1f ms; socket errors: connect %d, read %d, write %d, timeout %d",
    latency:percentile(50) / 1000, latency:percentile(90) / 1000, latency:percentile(99) / 1000, latency.max / 1000,
    summary.errors.connect, summary.errors.read, summary.errors.write, summary.errors.timeout))
end
EOF

rss() { awk '/VmRSS/ {printf "%.1f MiB", $2 / 1024}' "/proc/$server_pid/status"; }
health_during() {  # /health latencies while wrk runs
  while kill -0 "$1" 2>/dev/null; do
    curl -s -o /dev/null -w '%{time_total}\n' --max-time 10 "http://127.0.0.1:$port/health" || echo timeout
    sleep 0.5
  done >"$work/health.txt"
}
run() {  # requests
  rm -f "$work"/stopped.*
  wrk -t2 -c32 -d900s --timeout 30s -s "$work/mix.lua" "http://127.0.0.1:$port" -- $(($1 / 2)) "$work/stopped" \
    >"$work/wrk.txt" &
  local wrk_pid=$!
  health_during $wrk_pid &
  local health_pid=$!
  # wrk waits out its duration even when its threads stopped; SIGINT makes it print its summary.
  while [ "$(ls "$work"/stopped.* 2>/dev/null | wc -l)" -lt 2 ] && kill -0 $wrk_pid 2>/dev/null; do sleep 0.2; done
  kill -INT $wrk_pid 2>/dev/null || true
  wait $wrk_pid || true
  wait $health_pid
  grep -E "answers by status|latency p50|Requests/sec" "$work/wrk.txt"
  sort -n "$work/health.txt" | awk '{a[NR]=$1} END {printf "/health during the load: %d answers, median %.1f ms, max %.1f ms\n", NR, 1000*a[int((NR+1)/2)], 1000*a[NR]}'
}

echo "machine: $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | sed 's/^ *//'), $(nproc) cores; load: $(cut -d' ' -f1-3 /proc/loadavg)"
echo "serve options: ${SERVE_ARGS:-(defaults)}"
echo "server RSS idle: $(rss)"
echo "== first 1000 requests"
run 1000
echo "server RSS after 1000: $(rss)"
echo "== $((total - 1000)) more"
run $((total - 1000))
echo "server RSS after $total: $(rss)"
grep -c " 200 " "$work/server.log" | sed 's/^/server log: 200 answers: /'
