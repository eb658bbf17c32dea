#!/usr/bin/env python3
"""Model-card table from per-frame CSVs of `ffloc eval` (the <stem>.frames.csv beside --json).

For each CSV (labelled LABEL=PATH) and method: queries within (25 cm, 5 deg) and (10 cm, 10 deg),
median errors, and the (25 cm, 5 deg) share per synthetic query kind (near, far, opposite: the
kind is in the query's file name) and for the real datasets, as markdown.

  scripts/model_card_table.py step0=runs/eval/step0.frames.csv trained=runs/eval/trained.frames.csv
"""
import csv
import math
import statistics
import sys


def share(rows, t, r):
    if not rows:
        return "-"
    hits = sum(1 for row in rows if float(row["translation_error"]) <= t and float(row["rotation_error_deg"]) <= r)
    return f"{100.0 * hits / len(rows):.1f}% ({hits}/{len(rows)})"


def median(rows, key):
    values = [float(row[key]) for row in rows]
    return statistics.median(values) if values else math.inf


def kind_of(row):
    if not row["dataset"].startswith("scene_"):
        return row["dataset"]
    for kind in ("near", "far", "opposite"):
        if kind in row["frame"]:
            return "synthetic " + kind
    return "synthetic other"


def main(arguments):
    if not arguments or any("=" not in a for a in arguments):
        sys.exit(__doc__)
    print("| model | method | set | queries | 25cm,5deg | 10cm,10deg | median t (m) | median r (deg) |")
    print("|---|---|---|---:|---:|---:|---:|---:|")
    for argument in arguments:
        label, path = argument.split("=", 1)
        with open(path, newline="") as f:
            rows = list(csv.DictReader(f))
        for method in sorted({row["method"] for row in rows}):
            mine = [row for row in rows if row["method"] == method]
            synthetic = [row for row in mine if row["dataset"].startswith("scene_")]
            groups = [("all synthetic", synthetic)]
            for kind in sorted({kind_of(row) for row in mine}):
                groups.append((kind, [row for row in mine if kind_of(row) == kind]))
            for name, group in groups:
                if not group:
                    continue
                print(f"| {label} | {method} | {name} | {len(group)} | {share(group, 0.25, 5)} | "
                      f"{share(group, 0.10, 10)} | {median(group, 'translation_error'):.3f} | "
                      f"{median(group, 'rotation_error_deg'):.2f} |")


if __name__ == "__main__":
    main(sys.argv[1:])
