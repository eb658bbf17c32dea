#pragma once

#include <functional>
#include <string>
#include <vector>

#include "ffloc/eval/coordinate_source.h"
#include "ffloc/eval/metrics.h"
#include "ffloc/localization/localizer.h"
#include "ffloc/pose/pnp.h"

namespace ffloc {

struct EvaluationOptions {
  PnpOptions pnp;
  VerdictOptions verdict;
  size_t max_queries = 0;  // 0 = every query frame; otherwise evenly spaced queries
  bool quiet = false;      // no progress bar
};

// Runs every query frame of `scene` through `source` and the PnP solver and scores the poses
// against the ground truth. Throws InputError when the scene has no query or no mapping frame.
std::vector<FrameResult> evaluate(const Scene& scene, CoordinateSource& source,
                                  const EvaluationOptions& options = {});

// The same through a Localizer, exactly as `ffloc localize` runs a query: each query frame's
// image and intrinsics go in, the pose and verdict come out. `localize` supplies the query
// options; options.pnp and options.verdict replace its own, and the RANSAC seed is offset per
// frame as above. `on_result`, when set, sees every result.
using LocalizationObserver = std::function<void(const Frame&, const LocalizationResult&)>;
std::vector<FrameResult> evaluateLocalizer(const Scene& scene, const Localizer& localizer, const std::string& method,
                                           const LocalizeOptions& localize, const EvaluationOptions& options = {},
                                           const LocalizationObserver& on_result = nullptr);

// What makes a saved map's scores mislead on `scene`, one sentence each, or none: query frames
// the map holds (each is then localized against itself), or none of the scene's mapping frames
// (a map of another capture is scored against this one's ground truth, right only when both share
// a coordinate frame). A frame is the map's when the map holds a camera of its pose, whatever its
// name. Not refused: a map of the same scene's other
// capture, or of every frame, is a deliberate choice; the caller warns.
std::vector<std::string> mapScoringWarnings(const Scene& scene, const std::vector<MapCamera>& map_cameras);

}  // namespace ffloc
