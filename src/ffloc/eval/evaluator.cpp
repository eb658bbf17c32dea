#include "ffloc/eval/evaluator.h"

#include <algorithm>
#include <chrono>
#include <limits>

#include "ffloc/core/clock.h"
#include "ffloc/core/error.h"
#include "ffloc/core/progress.h"
#include "ffloc/data/dataset.h"
#include "ffloc/data/pose_check.h"
#include "ffloc/io/image.h"

namespace ffloc {
namespace {

std::vector<size_t> selectQueries(const Scene& scene, size_t max_queries) {
  const std::vector<size_t> all = scene.queryIndices();
  if (max_queries == 0 || max_queries >= all.size()) return all;
  std::vector<size_t> chosen;
  for (size_t k = 0; k < max_queries; ++k) chosen.push_back(all[k * all.size() / max_queries]);
  return chosen;
}

void score(FrameResult& r, const PnpResult& pose, const PoseVerdict& verdict) {
  r.status = pose.status;
  r.inliers = pose.inliers;
  r.verdict = verdict.status;
  r.evidence = verdict.evidence;
  if (pose.ok()) {
    r.estimate = pose.camera_to_world;
    r.translation_error = translationError(r.estimate, r.truth);
    r.rotation_error_deg = rotationErrorDeg(r.estimate, r.truth);
  } else {
    r.translation_error = std::numeric_limits<double>::infinity();
    r.rotation_error_deg = std::numeric_limits<double>::infinity();
  }
}

}  // namespace

std::vector<FrameResult> evaluate(const Scene& scene, CoordinateSource& source, const EvaluationOptions& options) {
  requireSplits(scene);
  source.prepare(scene);
  const std::vector<size_t> queries = selectQueries(scene, options.max_queries);

  std::vector<FrameResult> results;
  ProgressBar progress(scene.name + " " + source.name(), queries.size(), options.quiet);
  for (size_t q = 0; q < queries.size(); ++q) {
    const Frame& frame = scene.frames[queries[q]];
    FrameResult r;
    r.dataset = scene.name;
    r.method = source.name();
    r.frame = frame.name;
    r.truth = frame.camera_to_world;

    const auto start = std::chrono::steady_clock::now();
    const Correspondences pairs = source.correspondences(scene, queries[q]);
    r.source_seconds = secondsSince(start);
    r.correspondences = static_cast<int>(pairs.size());

    PnpOptions pnp = options.pnp;
    pnp.seed = options.pnp.seed + queries[q];
    const PnpResult pose = estimatePose(pairs, frame.intrinsics.undistorted(), pnp);
    r.pnp_seconds = pose.seconds;
    const auto verification_start = std::chrono::steady_clock::now();
    const PnpResult second = pose.ok() ? halfSampleEstimate(pairs, frame.intrinsics.undistorted(), pnp) : PnpResult{};
    r.source_seconds += secondsSince(verification_start);
    const PoseVerdict verdict = judgePose(
        measureEvidence(pairs, frame.intrinsics.undistorted(), pose, pnp, pose.ok() ? &second : nullptr), pose,
        scene.metric, options.verdict);
    score(r, pose, verdict);
    results.push_back(r);
    progress.update(q + 1);
  }
  progress.finish();
  return results;
}

std::vector<FrameResult> evaluateLocalizer(const Scene& scene, const Localizer& localizer, const std::string& method,
                                           const LocalizeOptions& localize, const EvaluationOptions& options,
                                           const LocalizationObserver& on_result) {
  requireSplits(scene);
  if (localizer.metric() != scene.metric)
    throw InputError(scene.root.string() + ": the map is " + (localizer.metric() ? "metric" : "not metric") +
                     " and the dataset is " + (scene.metric ? "metric" : "not metric") + ": not the same scene");
  const std::vector<size_t> queries = selectQueries(scene, options.max_queries);
  std::vector<FrameResult> results;
  ProgressBar progress(scene.name + " " + method, queries.size(), options.quiet);
  for (size_t q = 0; q < queries.size(); ++q) {
    const Frame& frame = scene.frames[queries[q]];
    FrameResult r;
    r.dataset = scene.name;
    r.method = method;
    r.frame = frame.name;
    r.truth = frame.camera_to_world;
    // The seeds `ffloc localize` and the server give every query: a seed per frame made the
    // evaluated map answer otherwise than localize on one query in four.
    LocalizeOptions query_options = localize;
    query_options.pnp = options.pnp;
    query_options.verdict = options.verdict;
    const auto start = std::chrono::steady_clock::now();
    LocalizationResult result;
    try {
      result = localizer.localize(readImageRgb(frame.image_path), frame.intrinsics, frame.name, query_options);
    } catch (const InputError& error) {
      // "cx, cy: ..." named no frame of the hundreds evaluated.
      throw InputError(scene.name + ": query frame '" + frame.name + "': " + error.what());
    }
    r.pnp_seconds = result.timings.pnp;  // every PnP of the query, a second look's included
    r.source_seconds = secondsSince(start) - r.pnp_seconds;
    r.correspondences = static_cast<int>(result.correspondences.size());
    score(r, result.pnp, result.verdict);
    if (on_result) on_result(frame, result);
    results.push_back(r);
    progress.update(q + 1);
  }
  progress.finish();
  return results;
}

std::vector<std::string> mapScoringWarnings(const Scene& scene, const std::vector<MapCamera>& map_cameras) {
  // By pose, not by name: names depend on the reader (a dataset converted to another format and
  // mapped from there is the same capture under other names), while synthetic scenes of other
  // seeds share every name. Sorted by the centre's x, a frame compares with the few map cameras
  // near its own.
  std::vector<const Pose*> mapped;
  for (const MapCamera& camera : map_cameras) mapped.push_back(&camera.camera_to_world);
  std::sort(mapped.begin(), mapped.end(), [](const Pose* a, const Pose* b) { return a->t.x() < b->t.x(); });
  const auto is_mapped = [&](const Pose& pose) {
    const double window = 2e-5 * std::max(1.0, pose.t.norm());
    auto it = std::lower_bound(mapped.begin(), mapped.end(), pose.t.x() - window,
                               [](const Pose* a, double x) { return a->t.x() < x; });
    for (; it != mapped.end() && (*it)->t.x() <= pose.t.x() + window; ++it)
      if (isSamePoseAsMapped(**it, pose)) return true;
    return false;
  };
  const auto count_mapped = [&](Split split, std::string& first) {
    size_t count = 0;
    for (const size_t index : scene.indices(split)) {
      const Frame& frame = scene.frames[index];
      if (!is_mapped(frame.camera_to_world)) continue;
      if (count++ == 0) first = frame.name;
    }
    return count;
  };
  std::vector<std::string> warnings;
  std::string first_query;
  const size_t queries = count_mapped(Split::kQuery, first_query);
  if (queries > 0)
    warnings.push_back("the map holds " + std::to_string(queries) + " of the " +
                       std::to_string(scene.indices(Split::kQuery).size()) + " query frames of " + scene.name +
                       " (first '" + first_query + "'): each is localized against its own image");
  std::string first_mapping;
  const size_t mapping = scene.indices(Split::kMapping).size();
  if (mapping > 0 && count_mapped(Split::kMapping, first_mapping) == 0)
    warnings.push_back("the map holds none of the " + std::to_string(mapping) + " mapping frames of " + scene.name +
                       ": its poses are right against this ground truth only if its capture shares the " +
                       "dataset's coordinate frame");
  return warnings;
}

}  // namespace ffloc
