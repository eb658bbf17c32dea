#include "ffloc/eval/metrics.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "ffloc/core/statistics.h"

namespace ffloc {

const std::array<AccuracyThreshold, 5>& accuracyThresholds() {
  static const std::array<AccuracyThreshold, 5> thresholds = {{
      {"5cm_5deg", 0.05, 5.0},
      {"10cm_10deg", 0.10, 10.0},
      {"20cm_20deg", 0.20, 20.0},
      {"10cm_1deg", 0.10, 1.0},
      {"25cm_5deg", 0.25, 5.0},
  }};
  return thresholds;
}

const AccuracyThreshold& verdictThreshold() { return accuracyThresholds()[4]; }

MethodSummary summarize(const std::vector<FrameResult>& frames) {
  MethodSummary s;
  if (frames.empty()) return s;
  s.dataset = frames.front().dataset;
  s.method = frames.front().method;
  s.frames = static_cast<int>(frames.size());
  const double inf = std::numeric_limits<double>::infinity();
  std::vector<double> t, r, latency_ms;
  std::array<int, 5> hits{};
  for (const FrameResult& f : frames) {
    const bool ok = f.succeeded();
    if (!ok) ++s.failed;
    const double te = ok ? f.translation_error : inf;
    const double re = ok ? f.rotation_error_deg : inf;
    t.push_back(te);
    r.push_back(re);
    latency_ms.push_back(f.totalSeconds() * 1000.0);
    for (size_t k = 0; k < accuracyThresholds().size(); ++k)
      if (te <= accuracyThresholds()[k].translation && re <= accuracyThresholds()[k].rotation_deg) ++hits[k];
    const bool within = te <= verdictThreshold().translation && re <= verdictThreshold().rotation_deg;
    const bool localized = f.verdict == PoseStatus::kLocalized;
    s.localized += localized;
    s.localized_correct += localized && within;
    s.correct += within;
  }
  s.median_translation = median(t);
  s.median_rotation_deg = median(r);
  for (size_t k = 0; k < hits.size(); ++k) s.accuracy_percent[k] = 100.0 * hits[k] / s.frames;
  s.latency_median_ms = median(latency_ms);
  s.latency_p90_ms = percentile(latency_ms, 0.9);
  return s;
}

MethodSummary summarizePooled(const std::vector<FrameResult>& frames, const std::string& method,
                              const std::string& label) {
  std::vector<FrameResult> selected;
  for (const FrameResult& frame : frames)
    if (frame.method == method) selected.push_back(frame);
  MethodSummary pooled = summarize(selected);
  pooled.dataset = label;
  pooled.method = method;
  return pooled;
}

}  // namespace ffloc
