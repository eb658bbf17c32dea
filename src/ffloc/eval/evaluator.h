#pragma once

#include <functional>
#include <vector>

#include "ffloc/eval/coordinate_source.h"
#include "ffloc/eval/metrics.h"
#include "ffloc/pose/pnp.h"

namespace ffloc {

struct EvaluationOptions {
  PnpOptions pnp;
  size_t max_queries = 0;  // 0 = every query frame; otherwise evenly spaced queries
  bool quiet = false;      // no progress bar
};

// Runs every query frame of `scene` through `source` and the PnP solver and scores the poses
// against the ground truth. Throws InputError when the scene has no query or no mapping frame.
std::vector<FrameResult> evaluate(const Scene& scene, CoordinateSource& source,
                                  const EvaluationOptions& options = {});

}  // namespace ffloc
