#pragma once

#include <array>
#include <string>
#include <vector>

#include "ffloc/geometry/pose.h"
#include "ffloc/localization/verdict.h"
#include "ffloc/pose/pnp.h"

namespace ffloc {

// The outcome of localising one query frame with one method.
struct FrameResult {
  std::string dataset;
  std::string method;
  std::string frame;
  PnpStatus status = PnpStatus::kNoModel;
  Pose estimate;  // camera-to-world; meaningful when succeeded()
  Pose truth;
  double translation_error = 0;  // dataset units; +inf when the frame failed
  double rotation_error_deg = 0;  // +inf when the frame failed
  int correspondences = 0;  // produced by the coordinate source
  int inliers = 0;
  double source_seconds = 0;  // producing the correspondences (and the verdict's second estimate)
  double pnp_seconds = 0;
  PoseStatus verdict = PoseStatus::kFailed;
  PoseEvidence evidence;

  bool succeeded() const { return status == PnpStatus::kSuccess; }
  double totalSeconds() const { return source_seconds + pnp_seconds; }
};

// A (translation, rotation) accuracy threshold: a frame passes when both errors are within.
struct AccuracyThreshold {
  const char* key;  // the summary JSON key, e.g. "5cm_5deg"
  double translation;  // dataset units (metres where metric)
  double rotation_deg;
};

// The paper's thresholds, in the order the reports list them.
const std::array<AccuracyThreshold, 5>& accuracyThresholds();

struct MethodSummary {
  std::string dataset;
  std::string method;
  int frames = 0;
  int failed = 0;
  double median_translation = 0;  // +inf when half the frames or more failed
  double median_rotation_deg = 0;
  std::array<double, 5> accuracy_percent{};  // per accuracyThresholds()
  double latency_median_ms = 0;
  double latency_p90_ms = 0;
  // The verdict against the truth, at the (25 cm, 5 deg) threshold: how many frames were marked
  // localized, how many of those are within it (precision = localized_correct / localized), and
  // how many frames with a pose are within it whatever their mark (recall's denominator).
  int localized = 0;
  int localized_correct = 0;
  int correct = 0;
};

// The threshold the verdict's precision and recall are measured at: (25 cm, 5 deg).
const AccuracyThreshold& verdictThreshold();

// Failed frames count as infinite error in the medians and as misses in the accuracies.
MethodSummary summarize(const std::vector<FrameResult>& frames);

// One method's frames of every dataset together, as one summary named `label`: the pooled row
// of a multi-scene evaluation (medians over all frames, not a mean of per-scene medians).
MethodSummary summarizePooled(const std::vector<FrameResult>& frames, const std::string& method,
                              const std::string& label);

}  // namespace ffloc
