#!/usr/bin/env bash
# The query as users run it with a large-config FastForward map (docs/benchmarks.md, "A query
# against a 150-image large map"): a synthetic scene of 150 mapping images at 512x384, mapped with
# the large config, then `ffloc localize` on its queries, each in its own process under
# /usr/bin/time for the peak RSS. Weights are random (random:large): the work, and so the time and
# memory, do not depend on them. Prints the per-stage latency of every query, its peak RSS, the
# map's size and its encoding time per image, and what the paper's pipeline would add per query:
# it re-encodes the K retrieved mapping images instead of reading their tokens from the map.
# Usage: scripts/bench_large_map.sh BUILD_DIR OUT_DIR [THREADS] [QUERIES]
set -euo pipefail
build=${1:-build}
out=${2:-build/large_map}
threads=${3:-2}
queries=${4:-3}
ffloc="$build/bin/ffloc"
model=random:large:7
mkdir -p "$out"

[ -d "$out/scene" ] || "$ffloc" synth --out "$out/scene" --seed 42 --kind indoor --size 512x384 \
  --mapping-frames 150 --query-frames "$queries" --quiet
scene=$(ls -d "$out"/scene/scene_*)
{ date -u; uptime; grep -m1 "model name" /proc/cpuinfo; } | tee "$out/machine.txt"

if [ ! -f "$out/large.ffmap" ]; then
  start=$(date +%s.%N)
  /usr/bin/time -v -o "$out/map.time" "$ffloc" map --method fastforward --model "$model" --dataset "$scene" \
    --threads "$threads" --output "$out/large.ffmap"
  end=$(date +%s.%N)
  echo "$start $end" > "$out/map.seconds"
fi
read -r start end < "$out/map.seconds"
map_s=$(python3 -c "print(f'{$end - $start:.1f}')")
per_image=$(python3 -c "print(f'{($end - $start) / 150:.2f}')")
echo "map: 150 images in $map_s s ($per_image s per image, load at the end $(cut -d' ' -f1-3 /proc/loadavg))," \
  "$(du -m "$out/large.ffmap" | cut -f1) MiB," \
  "peak RSS $(awk -F': ' '/Maximum resident/ {printf "%.0f MiB", $2 / 1024}' "$out/map.time")"

python3 - "$scene/manifest.json" > "$out/queries.txt" <<'EOF'
import json, sys
manifest = json.load(open(sys.argv[1]))
for frame in manifest["frames"]:
    if frame["split"] == "query":
        k = manifest["cameras"][frame["camera"]]
        print(frame["image"], k["fx"], k["fy"], k["cx"], k["cy"])
EOF

i=0
while read -r image fx fy cx cy; do
  i=$((i + 1))
  /usr/bin/time -v -o "$out/query_$i.time" "$ffloc" localize --map "$out/large.ffmap" --model "$model" \
    --threads "$threads" --image "$scene/$image" --intrinsics "$fx,$fy,$cx,$cy" --json > "$out/query_$i.json" || true
  python3 - "$out/query_$i.json" "$out/query_$i.time" "$per_image" <<'EOF'
import json, sys
answer = json.load(open(sys.argv[1]))
rss = next(int(line.split(":")[1]) for line in open(sys.argv[2]) if "Maximum resident" in line) / 1024
per_image = float(sys.argv[3])
t = answer["timings_ms"]
stages = ", ".join(f"{k} {v:.0f}" for k, v in t.items())
k = answer.get("selected", [])
top_k = len(k) if isinstance(k, list) and k else 10
paper = t["total"] + top_k * per_image * 1000
print(f"query {answer['name']}: {stages} ms; peak RSS {rss:.0f} MiB; "
      f"the paper's pipeline, re-encoding K = {top_k} images at {per_image:.2f} s each: {paper / 1000:.1f} s")
EOF
done < "$out/queries.txt"
