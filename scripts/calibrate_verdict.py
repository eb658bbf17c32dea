#!/usr/bin/env python3
"""Calibrates the verdict's rule (src/ffloc/localization/verdict.h) on per-frame CSVs of
`ffloc eval` (scripts/verdict_runs.sh) and prints its precision and recall per method and dataset.

A pose counts as correct within (25 cm, 5 deg). Files are named SET.*: the tuning sets are tuning
(synthetic seed 5000), heldout (seed 9000), heldout2 (seed 9500), heldout3 (9900), heldout4 (9950),
t640 and h640 (seeds 5000 and 9000 at 640 x 480) and real, each 256 x 192 one held out once before
it was folded into tuning (docs/verdict.md); heldout5 to heldout12 (seeds 9975, 9990, 9995 at
640 x 480, 9985, 9997, and 9999, 9998 and 9996 at 640 x 480) are only reported, never searched over.

  scripts/calibrate_verdict.py DIR            search, then report the best rule
  scripts/calibrate_verdict.py DIR --report   report the rule in verdict.h's defaults
  scripts/calibrate_verdict.py DIR --report-uncertainty-rule   the same for UNCERTAINTY_RULE
  scripts/calibrate_verdict.py DIR --compare  the best rule with each choice of pixel noise, and
                                              without the predicted uncertainty
"""
import csv
import glob
import math
import os
import sys

TUNING_SETS = ("tuning", "heldout", "heldout2", "heldout3", "heldout4", "t640", "h640", "real")
SYNTHETIC_TUNING_SETS = TUNING_SETS[:-1]
METHODS = ("classical", "sift-baseline", "fastforward")
INF = math.inf

# verdict.h's VerdictOptions defaults. pixel_noise: the pixel noise the predicted uncertainty is
# scaled to (noise_scale); verdict.cpp uses the residuals' estimate.
DEFAULT = dict(min_inliers=12, min_inlier_ratio=0.1, min_inlier_spread=0.1, pixel_noise=("estimated", 0),
               max_centre_sigma_relative=INF, max_centre_sigma_m=0.10, max_rotation_sigma_deg=INF,
               max_focal_deviation=0.2, max_moderate_focal_deviation=0.15, max_principal_point_shift=0.1,
               max_certain_focal_deviation=0.05, max_focal_aspect_deviation=0.12,
               max_certain_focal_aspect_deviation=0.07,
               max_certain_principal_point_shift=0.04, max_focal_scan_gain=1.25,
               max_agreement_translation=0.05, max_agreement_rotation_deg=2.0,
               max_agreement_distance_m=0.05, require_agreement=True)

# The rule this search gave with the predicted uncertainty (3 Dec 2026), frozen before the held-out
# set heldout3 was rendered and measured there once: no better than DEFAULT (docs/verdict.md), so
# verdict.h keeps DEFAULT.
UNCERTAINTY_RULE = dict(min_inliers=20, min_inlier_ratio=0.1, min_inlier_spread=0.1, pixel_noise=("estimated", 0),
                        max_centre_sigma_relative=0.015, max_centre_sigma_m=0.075, max_rotation_sigma_deg=1.0,
                        max_agreement_translation=0.05, max_agreement_rotation_deg=2.0, max_agreement_distance_m=0.1,
                        require_agreement=False)


def number(text):
    return INF if text in ("inf", "") else float(text)


def load(directory):
    frames = []
    for path in sorted(glob.glob(os.path.join(directory, "*.frames.csv"))):
        group = os.path.basename(path).split(".")[0]
        for row in csv.DictReader(open(path)):
            row["group"] = group
            row["metric"] = "instant_ngp_fox" not in path
            row["correct"] = number(row["translation_error"]) <= 0.25 and number(row["rotation_error_deg"]) <= 5
            for key in ("inlier_ratio", "inlier_spread", "agreement_translation", "agreement_rotation_deg",
                        "agreement_distance", "residual_sigma_px", "predicted_centre_sigma",
                        "predicted_centre_sigma_relative", "predicted_rotation_sigma_deg", "focal_scale",
                        "focal_scale_log_sigma", "principal_point_shift", "principal_point_shift_significance",
                        "focal_aspect", "focal_aspect_log_sigma", "focal_scan_factor", "focal_scan_inlier_gain"):
                row[key] = number(row.get(key, "inf"))
            row["inliers"] = int(row["inliers"])
            # PnP's outcome; CSVs written before 5 Dec 2026 named the column status.
            row["pnp_status"] = row.get("pnp_status", row.get("status"))
            frames.append(row)
    return frames


def noise_scale(row, rule):
    """How much larger the predicted uncertainty is with the pixel noise taken as
    rule["pixel_noise"] than with the residuals' estimate: ("estimated", 0), ("at least", PX) or
    ("fixed", PX)."""
    kind, px = rule["pixel_noise"]
    sigma = row["residual_sigma_px"]
    if kind == "estimated" or not math.isfinite(sigma):
        return 1.0
    if sigma <= 0:
        return INF
    return (max(sigma, px) if kind == "at least" else px) / sigma


def scaled(row, key, rule):
    return row[key] * noise_scale(row, rule)


# The tests of the rule, one per setting, in the order of verdict.cpp's judgePose; a frame is
# `localized` when PnP gave a pose and it passes all of them and the agreement test.
TESTS = dict(
    min_inliers=lambda row, rule: row["inliers"] >= rule["min_inliers"],
    min_inlier_ratio=lambda row, rule: row["inlier_ratio"] >= rule["min_inlier_ratio"],
    min_inlier_spread=lambda row, rule: row["inlier_spread"] >= rule["min_inlier_spread"],
    max_centre_sigma_relative=lambda row, rule: (scaled(row, "predicted_centre_sigma_relative", rule)
                                                 <= rule["max_centre_sigma_relative"]),
    max_centre_sigma_m=lambda row, rule: (not row["metric"]
                                          or scaled(row, "predicted_centre_sigma", rule) <= rule["max_centre_sigma_m"]),
    max_rotation_sigma_deg=lambda row, rule: (scaled(row, "predicted_rotation_sigma_deg", rule)
                                              <= rule["max_rotation_sigma_deg"]),
)

FOCAL_SIGNIFICANCE = 6  # VerdictOptions::kFocalSignificance
MODERATE_FOCAL_SIGNIFICANCE = 8  # VerdictOptions::kModerateFocalSignificance
FOCAL_ASPECT_SIGNIFICANCE = 10  # VerdictOptions::kFocalAspectSignificance
PRINCIPAL_POINT_SIGNIFICANCE = 8  # VerdictOptions::kPrincipalPointSignificance
CERTAIN_SIGNIFICANCE = 30  # VerdictOptions::kCertainSignificance


def deviation_counts(deviation, significance, tiers):
    """verdict.cpp's deviationCounts: past a tier's deviation at more than its significance."""
    return any(deviation > bound and significance > least for bound, least in tiers)


def setting(rule, name):
    return rule.get(name, DEFAULT[name])


def factor_fits(factor, sigma, fraction_tiers):
    """verdict.cpp's factorMisfits, negated: a fitted factor (over the one given) too far from 1
    for its significance fails; a factor that was not measured passes."""
    if not (factor > 0 and math.isfinite(factor)):
        return True
    deviation = abs(math.log(factor))
    significance = deviation / sigma if sigma > 0 else INF
    return not deviation_counts(deviation, significance,
                                [(math.log1p(fraction), least) for fraction, least in fraction_tiers])


def fits_focal(row, rule):
    """verdict.cpp's focal test on the inliers' best focal length; CSVs without the columns pass."""
    return factor_fits(row["focal_scale"], row["focal_scale_log_sigma"],
                       [(setting(rule, "max_focal_deviation"), FOCAL_SIGNIFICANCE),
                        (setting(rule, "max_moderate_focal_deviation"), MODERATE_FOCAL_SIGNIFICANCE),
                        (setting(rule, "max_certain_focal_deviation"), CERTAIN_SIGNIFICANCE)])


def fits_focal_aspect(row, rule):
    """verdict.cpp's aspect test on the ratio fy / fx the inliers fit; CSVs without the columns pass."""
    return factor_fits(row["focal_aspect"], row["focal_aspect_log_sigma"],
                       [(setting(rule, "max_focal_aspect_deviation"), FOCAL_ASPECT_SIGNIFICANCE),
                        (setting(rule, "max_certain_focal_aspect_deviation"), CERTAIN_SIGNIFICANCE)])


def fits_principal_point(row, rule):
    """verdict.cpp's principal point test; CSVs without the columns pass."""
    shift, significance = row["principal_point_shift"], row["principal_point_shift_significance"]
    if not (shift >= 0 and math.isfinite(shift)):
        return True
    return not deviation_counts(shift, significance,
                                [(setting(rule, "max_principal_point_shift"), PRINCIPAL_POINT_SIGNIFICANCE),
                                 (setting(rule, "max_certain_principal_point_shift"), CERTAIN_SIGNIFICANCE)])


def fits_focal_scan(row, rule):
    """verdict.cpp's focal scan test: no other focal length's pose has that many more inliers; CSVs
    without the columns (inf) and poses without a scan (-1) pass."""
    gain = row["focal_scan_inlier_gain"]
    return not (math.isfinite(gain) and gain >= setting(rule, "max_focal_scan_gain"))


TESTS["max_focal_deviation"] = fits_focal
TESTS["max_focal_aspect_deviation"] = fits_focal_aspect
TESTS["max_focal_scan_gain"] = fits_focal_scan
TESTS["max_principal_point_shift"] = fits_principal_point
UNCERTAINTY_TESTS = ("max_centre_sigma_relative", "max_centre_sigma_m", "max_rotation_sigma_deg")


def passes_agreement(row, rule):
    agreement_t = row["agreement_translation"]
    if agreement_t < 0 or math.isinf(agreement_t):  # no second estimate, or it failed
        # FastForward's second estimate is its own second prediction: failing counts against it.
        return row["method"] != "fastforward" and not rule["require_agreement"]
    return (agreement_t <= rule["max_agreement_translation"]
            and row["agreement_rotation_deg"] <= rule["max_agreement_rotation_deg"]
            and (not row["metric"] or row["agreement_distance"] <= rule["max_agreement_distance_m"]))


def localized(row, rule):
    return (row["pnp_status"] == "success" and all(test(row, rule) for test in TESTS.values())
            and passes_agreement(row, rule))


def score(frames, rule):
    marked = [f for f in frames if localized(f, rule)]
    good = sum(f["correct"] for f in marked)
    correct = sum(f["correct"] for f in frames if f["pnp_status"] == "success")
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


# The settings searched. An agreement choice sets the four agreement settings together; INF
# switches a test off.
GRID = dict(
    min_inliers=[12, 15, 20, 25, 30, 40],
    min_inlier_ratio=[0.1, 0.15, 0.2, 0.25],
    min_inlier_spread=[0.05, 0.1, 0.15],
    max_centre_sigma_relative=[0.005, 0.0075, 0.01, 0.015, 0.02, 0.03, INF],
    max_centre_sigma_m=[0.01, 0.015, 0.02, 0.03, 0.05, 0.075, 0.1, INF],
    max_rotation_sigma_deg=[0.25, 0.5, 0.75, 1.0, 1.5, 2.0, INF],
)
PIXEL_NOISES = [("estimated", 0), ("at least", 1.0), ("at least", 2.0), ("at least", 3.0), ("fixed", 1.0),
                ("fixed", 2.0)]
AGREEMENTS = [
    dict(max_agreement_translation=INF, max_agreement_rotation_deg=INF, max_agreement_distance_m=INF,
         require_agreement=False),
    dict(max_agreement_translation=0.1, max_agreement_rotation_deg=5.0, max_agreement_distance_m=0.2,
         require_agreement=False),
    dict(max_agreement_translation=0.05, max_agreement_rotation_deg=2.0, max_agreement_distance_m=0.1,
         require_agreement=False),
    dict(max_agreement_translation=0.05, max_agreement_rotation_deg=2.0, max_agreement_distance_m=0.05,
         require_agreement=False),
    dict(max_agreement_translation=0.05, max_agreement_rotation_deg=2.0, max_agreement_distance_m=0.05,
         require_agreement=True),
]


# The least recall on the real data: the default method (fastforward) must not lose what the rule
# before gave it (59.5 % on redkitchen) for the synthetic scenes' sake.
REAL_RECALL = {"classical": 0.9, "fastforward": 0.5}


def search(frames, noises=PIXEL_NOISES, grid=GRID, agreements=AGREEMENTS):
    """The rule with the best recall of the classical method on the synthetic tuning scenes among
    those that keep, on the tuning sets, a precision of at least 99 % pooled and 97 % on each
    synthetic set for every method, at least 95 % on every real dataset for classical and
    fastforward and 90 % for sift-baseline (six of its redkitchen poses are the queries whose
    ground truth drifts by 5-6 deg, docs/verdict.md), and the recall on the real data of
    REAL_RECALL; ties go to the rule that marks the most correct poses of the other two methods,
    synthetic and real.

    Frames are the bits of an int, so that a rule's `localized` set is the AND of one mask per
    setting."""
    frames = [f for f in frames if f["group"] in TUNING_SETS and f["pnp_status"] == "success"]

    def mask(keep):
        return sum(1 << i for i, f in enumerate(frames) if keep(f))

    correct = mask(lambda f: f["correct"])
    subset = {}
    for method in METHODS:
        subset[method, "synthetic"] = mask(lambda f: f["method"] == method and f["group"] != "real")
        subset[method, "real"] = mask(lambda f: f["method"] == method and f["group"] == "real")
        for group in SYNTHETIC_TUNING_SETS:
            subset[method, group] = mask(lambda f: f["method"] == method and f["group"] == group)
        for dataset in sorted({f["dataset"] for f in frames if f["group"] == "real"}):
            subset[method, "real", dataset] = mask(
                lambda f: f["method"] == method and f["group"] == "real" and f["dataset"] == dataset)

    def precise(marked, share):
        return (marked & correct).bit_count() >= share * marked.bit_count()

    def acceptable(marked):
        for method in METHODS:
            if not precise(marked & subset[method, "synthetic"], 0.99):
                return False
            if not all(precise(marked & subset[method, group], 0.97) for group in SYNTHETIC_TUNING_SETS):
                return False
        for key, bits in subset.items():
            if len(key) == 3 and not precise(marked & bits, 0.9 if key[0] == "sift-baseline" else 0.95):
                return False
        return all((marked & subset[method, "real"] & correct).bit_count()
                   >= share * (subset[method, "real"] & correct).bit_count() for method, share in REAL_RECALL.items())

    # masks[noise][name][value]: the frames passing that one test.
    masks = {}
    for noise in noises:
        masks[noise] = {name: {value: mask(lambda f: TESTS[name](f, dict(DEFAULT, pixel_noise=noise, **{name: value})))
                               for value in values} for name, values in grid.items()}
    agreement_masks = [mask(lambda f: passes_agreement(f, a)) for a in agreements]
    target = subset["classical", "synthetic"] & correct
    others = (subset["sift-baseline", "synthetic"] | subset["fastforward", "synthetic"] | subset["sift-baseline", "real"]
              | subset["fastforward", "real"]) & correct
    names = list(grid)
    best = [(-1, -1), None]

    def descend(level, marked, rule):
        if (marked & target).bit_count() < best[0][0]:
            return  # every further test only removes frames
        if level == len(names):
            for agreement, agreement_mask in zip(agreements, agreement_masks):
                final = marked & agreement_mask
                if acceptable(final):
                    key = ((final & target).bit_count(), (final & others).bit_count())
                    if key > best[0]:
                        best[:] = [key, dict(rule, **agreement)]
            return
        name = names[level]
        for value, bits in masks[rule["pixel_noise"]][name].items():
            descend(level + 1, marked & bits, dict(rule, **{name: value}))

    # The tests the grid does not search keep verdict.h's defaults.
    fixed = mask(lambda f: all(test(f, DEFAULT) for name, test in TESTS.items() if name not in grid))
    for noise in noises:
        descend(0, fixed, dict(pixel_noise=noise))
    return best[1]


def summary(frames, rule):
    """Precision and recall per method on the synthetic tuning scenes, pooled."""
    parts = []
    for method in METHODS:
        subset = [f for f in frames if f["method"] == method and f["group"] in SYNTHETIC_TUNING_SETS]
        marked, good, correct = score(subset, rule)
        parts.append("%s %d/%d correct, recall %d/%d" % (method, good, marked, good, correct))
    return "; ".join(parts)


def compare(frames):
    """The best rule of each kind, to show what each piece of evidence is worth: with each choice
    of pixel noise, and without the predicted uncertainty (its tests off, the agreement thresholds
    searched as they were before it)."""
    for noise in PIXEL_NOISES:
        rule = search(frames, noises=[noise])
        print("pixel noise %s %g:" % noise, rule)
        if rule:
            print("  ", summary(frames, rule))
    without = dict(GRID, max_centre_sigma_relative=[INF], max_centre_sigma_m=[INF], max_rotation_sigma_deg=[INF])
    agreements = [dict(max_agreement_translation=t, max_agreement_rotation_deg=r, max_agreement_distance_m=d,
                       require_agreement=required)
                  for t in (0.02, 0.05, 0.1) for r in (1.0, 2.0, 3.0, 5.0) for d in (0.05, 0.1, 0.2)
                  for required in (True, False)]
    rule = search(frames, noises=[("estimated", 0)], grid=without, agreements=agreements)
    print("without the predicted uncertainty:", rule)
    if rule:
        print("  ", summary(frames, rule))
    print("verdict.h's defaults:", summary(frames, DEFAULT))


def main():
    directory = sys.argv[1]
    frames = load(directory)
    if "--compare" in sys.argv:
        compare(frames)
        return
    if "--report" in sys.argv:
        rule = DEFAULT
    elif "--report-uncertainty-rule" in sys.argv:
        rule = UNCERTAINTY_RULE
    else:
        rule = search(frames)
    if rule is None:
        sys.exit("no rule in the grid meets the constraints")
    print("rule:", rule)
    report(frames, rule)


if __name__ == "__main__":
    main()
