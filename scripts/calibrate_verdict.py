#!/usr/bin/env python3
"""Calibrates the verdict's rule (src/ffloc/localization/verdict.h) on per-frame CSVs of
`ffloc eval` (scripts/verdict_runs.sh) and prints its precision and recall per method and dataset.

A pose counts as correct within (25 cm, 5 deg). Tuning files are named tuning.*, heldout.* (the
first held-out set, seed 9000: measured once, then folded into tuning, docs/verdict.md) and real.*;
the files heldout2.* are only reported, never searched over.

  scripts/calibrate_verdict.py DIR            search, then report the best rule
  scripts/calibrate_verdict.py DIR --report   report the rule in verdict.h's defaults
"""
import csv
import glob
import itertools
import math
import os
import sys

DEFAULT = dict(min_inliers=12, min_inlier_ratio=0.1, min_inlier_spread=0.1,
               max_agreement_translation=0.05, max_agreement_rotation_deg=2.0, max_agreement_distance_m=0.05,
               require_agreement=True)


def number(text):
    return math.inf if text in ("inf", "") else float(text)


def load(directory):
    frames = []
    for path in sorted(glob.glob(os.path.join(directory, "*.frames.csv"))):
        group = os.path.basename(path).split(".")[0]
        for row in csv.DictReader(open(path)):
            row["group"] = group
            row["metric"] = "instant_ngp_fox" not in path
            row["correct"] = number(row["translation_error"]) <= 0.25 and number(row["rotation_error_deg"]) <= 5
            frames.append(row)
    return frames


def localized(row, rule):
    if row["status"] != "success":
        return False
    agreement_t, agreement_r = number(row["agreement_translation"]), number(row["agreement_rotation_deg"])
    distance = number(row.get("agreement_distance", "inf"))
    if not (int(row["inliers"]) >= rule["min_inliers"] and float(row["inlier_ratio"]) >= rule["min_inlier_ratio"]
            and float(row["inlier_spread"]) >= rule["min_inlier_spread"]):
        return False
    if agreement_t < 0 or math.isinf(agreement_t):  # no second estimate, or it failed
        # FastForward's second estimate is its own second prediction: failing counts against it.
        return row["method"] != "fastforward" and not rule["require_agreement"]
    return (agreement_t <= rule["max_agreement_translation"] and agreement_r <= rule["max_agreement_rotation_deg"]
            and (not row["metric"] or distance <= rule["max_agreement_distance_m"]))


def score(frames, rule):
    marked = [f for f in frames if localized(f, rule)]
    good = sum(f["correct"] for f in marked)
    correct = sum(f["correct"] for f in frames if f["status"] == "success")
    return len(marked), good, correct


def report(frames, rule):
    print("| set | dataset | method | frames | localized | precision | recall |")
    print("|---|---|---|---:|---:|---:|---:|")
    keys = sorted({(f["group"], f["dataset"], f["method"]) for f in frames})
    pooled = {}
    for group, dataset, method in keys:
        subset = [f for f in frames if (f["group"], f["dataset"], f["method"]) == (group, dataset, method)]
        pooled.setdefault((group, method), []).extend(subset)
        if group == "real":
            print_row(group, dataset, method, subset, rule)
    for (group, method), subset in sorted(pooled.items()):
        print_row(group, "all %d scenes" % len({f["dataset"] for f in subset}), method, subset, rule)


def print_row(group, dataset, method, subset, rule):
    marked, good, correct = score(subset, rule)
    precision = "%.1f%%" % (100.0 * good / marked) if marked else "-"
    recall = "%.1f%%" % (100.0 * good / correct) if correct else "-"
    print("| %s | %s | %s | %d | %d | %s | %s |" % (group, dataset, method, len(subset), marked, precision, recall))


def search(frames):
    """The rule with the best recall for the default method, classical, on the tuning scenes, among
    those with at most one wrong `localized` pose in a hundred of classical and of sift-baseline
    on the synthetic tuning scenes (a margin: 97 % there gave 92 % on the first held-out set) and
    a classical precision of at least 95 % on every real dataset; ties go to the better
    sift-baseline precision."""
    tuning = [f for f in frames if f["group"] in ("tuning", "heldout", "real")]
    classical = [f for f in tuning if f["method"] == "classical"]
    sift = [f for f in tuning if f["method"] == "sift-baseline"]
    real_sets = [[f for f in classical if f["dataset"] == d] for d in sorted({f["dataset"] for f in classical
                                                                              if f["group"] == "real"})]
    synthetic = [f for f in classical if f["group"] != "real"]
    synthetic_sift = [f for f in sift if f["group"] != "real"]
    best = None
    grid = dict(min_inliers=[12, 15, 20, 25, 30, 40], min_inlier_ratio=[0.1, 0.15, 0.2, 0.25, 0.3],
                min_inlier_spread=[0.05, 0.08, 0.1, 0.12, 0.15], max_agreement_translation=[0.02, 0.05, 0.1],
                max_agreement_rotation_deg=[1.0, 2.0, 3.0, 5.0], max_agreement_distance_m=[0.05, 0.1, 0.2],
                require_agreement=[True, False])
    names = list(grid)
    for values in itertools.product(*(grid[n] for n in names)):
        rule = dict(zip(names, values))
        marked, good, correct = score(classical, rule)
        if not marked:
            continue
        if any(m and g < 0.95 * m for m, g, _ in (score(s, rule) for s in real_sets)):
            continue
        synthetic_marked, synthetic_good, _ = score(synthetic, rule)
        if synthetic_good < 0.99 * synthetic_marked:
            continue
        synthetic_sift_marked, synthetic_sift_good, _ = score(synthetic_sift, rule)
        if synthetic_sift_good < 0.99 * synthetic_sift_marked:
            continue
        sift_marked, sift_good, _ = score(sift, rule)
        key = (good / max(correct, 1), sift_good / max(sift_marked, 1))
        if best is None or key > best[0]:
            best = (key, rule)
    return best[1] if best else DEFAULT


def main():
    directory = sys.argv[1]
    frames = load(directory)
    rule = DEFAULT if "--report" in sys.argv else search(frames)
    print("rule:", rule)
    report(frames, rule)


if __name__ == "__main__":
    main()
