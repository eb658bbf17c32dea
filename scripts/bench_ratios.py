#!/usr/bin/env python3
"""The ratio table of `make bench` (scripts/bench.sh): ffloc against the PyTorch eager comparator.

Reads the JSON lines that scripts/bench.sh saved per round and thread count
(model_t<T>_r<R>.jsonl from `ffloc bench model --json`, eager_t<T>_r<R>.jsonl from
bench/dust3r_eager.py --bench --json) and prints, per row and thread count, the medians over
rounds and the median of the per-round ratios (ratios of runs that ran back to back are less
exposed to the machine's load than either time alone).
"""
import glob
import json
import os
import re
import sys


def median(values):
    s = sorted(values)
    n = len(s)
    if n == 0:
        return None
    return s[n // 2] if n % 2 else 0.5 * (s[n // 2 - 1] + s[n // 2])


def read(folder, kind):
    runs = {}  # (threads, round) -> {row: object}
    for path in glob.glob(os.path.join(folder, kind + "_t*_r*.jsonl")):
        match = re.search(r"_t(\d+)_r(\d+)\.jsonl$", path)
        rows = {}
        with open(path) as f:
            for line in f:
                line = line.strip()
                if line.startswith("{"):
                    obj = json.loads(line)
                    if "row" in obj:
                        rows[obj["row"]] = obj
        runs[(int(match.group(1)), int(match.group(2)))] = rows
    return runs


def main(folder):
    ours, eager = read(folder, "model"), read(folder, "eager")
    if not ours:
        print("no ffloc results in %s" % folder)
        return 1
    names = []
    for rows in ours.values():
        for name, obj in rows.items():
            if "median_s" in obj and name not in names:
                names.append(name)
    print("| row | threads | rounds | ffloc median s | eager median s | eager / ffloc | ffloc GFLOP/s | sgemm GFLOP/s | share of sgemm |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|")
    for threads in sorted({t for t, _ in ours}):
        rounds = sorted(r for t, r in ours if t == threads)
        for name in names:
            mine = [ours[(threads, r)][name] for r in rounds if name in ours[(threads, r)]]
            if not mine:  # a run that did not get this far
                continue
            theirs = [eager[(threads, r)][name]["median_s"] for r in rounds
                      if (threads, r) in eager and name in eager[(threads, r)]]
            ratios = [eager[(threads, r)][name]["median_s"] / ours[(threads, r)][name]["median_s"] for r in rounds
                      if (threads, r) in eager and name in eager[(threads, r)] and name in ours[(threads, r)]]
            sgemm = [ours[(threads, r)]["sgemm"]["gflops"] for r in rounds if "sgemm" in ours[(threads, r)]]
            m = median([o["median_s"] for o in mine])
            e = median(theirs)
            ratio = median(ratios)
            rate = median([o["gflops"] for o in mine])
            share = median([o["sgemm_share"] for o in mine])
            print("| %s | %d | %d | %.2f | %s | %s | %.1f | %s | %.0f %% |" % (
                name, threads, len(mine), m, "%.2f" % e if e else "-", "%.2f" % ratio if ratio else "-", rate,
                "%.1f" % median(sgemm) if sgemm else "-", 100 * share))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1] if len(sys.argv) > 1 else "build/bench/results"))
