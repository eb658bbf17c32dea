#include "ffloc/localization/localizer.h"

#include <chrono>
#include <cmath>
#include <set>
#include <sstream>

#include "ffloc/core/clock.h"
#include "ffloc/core/error.h"
#include "ffloc/core/number_text.h"

namespace ffloc {

const char* toString(LocalizationMethod method) {
  return method == LocalizationMethod::kClassical ? "classical" : "fastforward";
}

bool methodUsesSetting(LocalizationMethod method, const std::string& field) {
  static const std::set<std::string> kFastForwardOnly = {"features", "selection", "retrieval", "verify", "model", "dtype"};
  static const std::set<std::string> kClassicalOnly = {"pose_guided"};
  return !(method == LocalizationMethod::kClassical ? kFastForwardOnly : kClassicalOnly).count(field);
}

LocalizationMethod parseLocalizationMethod(const std::string& name) {
  if (name == "classical") return LocalizationMethod::kClassical;
  if (name == "fastforward") return LocalizationMethod::kFastForward;
  throw InputError("method: unknown method '" + name + "' (expected classical or fastforward)");
}

const char* toString(FastForwardRetrieval retrieval) {
  switch (retrieval) {
    case FastForwardRetrieval::kEncoder:
      return "encoder";
    case FastForwardRetrieval::kVlad:
      return "vlad";
    case FastForwardRetrieval::kTokenVlad:
      return "token-vlad";
  }
  return "encoder";
}

FastForwardRetrieval parseFastForwardRetrieval(const std::string& name) {
  for (const FastForwardRetrieval retrieval :
       {FastForwardRetrieval::kEncoder, FastForwardRetrieval::kVlad, FastForwardRetrieval::kTokenVlad}) {
    if (name == toString(retrieval)) return retrieval;
  }
  throw InputError("retrieval: unknown retrieval '" + name + "' (expected encoder, vlad or token-vlad)");
}

LocalizeOptions LocalizeOptions::preset(const std::string& name) {
  LocalizeOptions options;
  if (name == "indoor") return options;
  if (name == "outdoor") {
    options.top_k = 20;
    options.num_features = 3000;
    return options;
  }
  throw InputError("preset: unknown preset '" + name + "' (expected indoor or outdoor)");
}

void LocalizeOptions::check() const {
  if (top_k == 0) throw InputError("top_k: must be positive");
  if (num_features <= 0) throw InputError("num_features: must be positive, got " + std::to_string(num_features));
  if (long_side < 0) throw InputError("long_side: must not be negative");
  if (!(pnp.confidence_threshold == pnp.confidence_threshold))
    throw InputError("pnp.confidence_threshold: must be a number, got NaN");
  if (!(pnp.inlier_threshold_px > 0 && std::isfinite(pnp.inlier_threshold_px)))
    throw InputError("pnp.inlier_threshold_px: must be positive and finite");
  if (pnp.max_correspondences < 4) throw InputError("pnp.max_correspondences: must be at least 4");
  if (pnp.max_iterations <= 0) throw InputError("pnp.max_iterations: must be positive");
  if (pnp.min_inliers < 0) throw InputError("pnp.min_inliers: must not be negative, got " + std::to_string(pnp.min_inliers));
  if (!(pnp.success_probability > 0 && pnp.success_probability < 1))
    throw InputError("pnp.success_probability: must be in (0, 1)");
  verdict.check();
}

LocalizeOptions localizeOptions(const QuerySettings& settings) {
  LocalizeOptions options = LocalizeOptions::preset(settings.preset);
  if (settings.top_k) {
    if (*settings.top_k <= 0) throw InputError("top_k: must be positive, got " + std::to_string(*settings.top_k));
    options.top_k = static_cast<size_t>(*settings.top_k);
  }
  if (settings.features) options.num_features = *settings.features;
  options.seed = settings.seed;
  options.pnp.seed = settings.seed;
  options.selection = parseImageSelection(settings.selection);
  options.retrieval = parseFastForwardRetrieval(settings.retrieval);
  options.pnp.solver = parsePnpSolver(settings.solver);
  options.verify_with_second_reference = settings.verify;
  options.pose_guided_retrieval = settings.pose_guided;
  options.check();
  return options;
}

void stopIfRequested(const LocalizeOptions& options, const std::string& stage) {
  if (options.stop_requested && options.stop_requested()) throw QueryStopped("stopped " + stage);
}

LocalizationResult Localizer::localize(const cv::Mat& rgb, const Intrinsics& intrinsics, const std::string& name,
                                       const LocalizeOptions& options) const {
  options.check();
  if (rgb.empty()) throw InputError(name + ": the image is empty");
  checkIntrinsicsFitImage(intrinsics, rgb.cols, rgb.rows);
  Intrinsics sized = intrinsics;
  sized.width = rgb.cols;
  sized.height = rgb.rows;

  LocalizationResult result;
  std::optional<PnpResult> second;
  PoseGuidedLooks pose_guided;
  predict(rgb, sized, name, options, result, second, pose_guided);
  stopIfRequested(options, "before PnP");
  estimateAndJudge(result, second, options);
  if (options.pose_guided_retrieval) {
    lookAgain(pose_guided.more_images, false, options, result);
    lookAgain(pose_guided.nearby_pairs, true, options, result);
  }
  return result;
}

void Localizer::lookAgain(const PoseGuidedLooks::Look& look, bool only_if_localized, const LocalizeOptions& options,
                          LocalizationResult& result) const {
  if (!look || result.localized() || !result.pnp.ok()) return;
  stopIfRequested(options, "before a pose-guided look");
  LocalizationResult again = result;
  const size_t before = again.correspondences.size();
  const auto start = std::chrono::steady_clock::now();
  look(result.pnp.camera_to_world, again);
  again.timings.matching += secondsSince(start);
  const bool added = again.correspondences.size() > before;
  if (added) {
    stopIfRequested(options, "before PnP on the pose-guided look");
    estimateAndJudge(again, std::nullopt, options);
  }
  if (added && again.pnp.ok() && (!only_if_localized || again.localized())) {
    result = std::move(again);
  } else {
    result.timings = again.timings;  // the answer before stands; the look still took its time
  }
}

void Localizer::estimateAndJudge(LocalizationResult& result, std::optional<PnpResult> second,
                                 const LocalizeOptions& options) const {
  const bool independent = second.has_value();
  result.pnp = estimatePose(result.correspondences, result.camera, options.pnp);
  result.timings.pnp += result.pnp.seconds;
  // The verdict's work is verification: its second estimate and its evidence (the intrinsics
  // fits and the focal scan were counted in no stage, so the stages fell short of the query's time).
  const auto start = std::chrono::steady_clock::now();
  if (!second && result.pnp.ok()) second = halfSampleEstimate(result.correspondences, result.camera, options.pnp);
  PoseEvidence evidence =
      measureEvidence(result.correspondences, result.camera, result.pnp, options.pnp, second ? &*second : nullptr,
                      intrinsicsFitPairs());
  result.timings.verification += secondsSince(start);
  evidence.independent_second_estimate = independent;
  scalePredictedUncertainty(evidence, uncertaintyScale());
  result.verdict = judgePose(evidence, result.pnp, metric(), options.verdict);
}

std::string warmUp(const Localizer& localizer, const LocalizeOptions& options) {
  Intrinsics camera;
  camera.width = 640;
  camera.height = 480;
  camera.fx = camera.fy = 525;
  camera.cx = 320;
  camera.cy = 240;
  if (!localizer.cameras().empty()) camera = localizer.cameras().front().intrinsics;
  cv::Mat noise(camera.height, camera.width, CV_8UC3);
  cv::RNG rng(0);
  rng.fill(noise, cv::RNG::UNIFORM, 0, 256);
  const auto start = std::chrono::steady_clock::now();
  try {
    localizer.localize(noise, camera, "warm-up", options);
  } catch (const InputError& e) {
    return std::string("not warmed up: a made-up query at its first mapping camera was refused: ") + e.what();
  }
  return "warmed up by a made-up query in " + formatSignificant(secondsSince(start)) + " s";
}

}  // namespace ffloc
