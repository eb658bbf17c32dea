#pragma once

#include <Eigen/Core>
#include <vector>

#include "ffloc/core/random.h"
#include "ffloc/geometry/camera.h"
#include "ffloc/geometry/pose.h"
#include "ffloc/pose/pnp.h"

namespace ffloc {

struct LoRansacOutput {
  bool found = false;
  Pose world_to_camera;  // X_cam = R * X_world + t
  int iterations = 0;    // minimal samples drawn
};

// LO-RANSAC (Chum, Matas & Kittler 2003; Lebeda, Matas & Chum 2012) around the P3P solver:
// MSAC scoring by pixel reprojection error, an iteration count that adapts to the best inlier
// ratio so far (capped by options.max_iterations), an iterated least-squares local optimisation
// with a shrinking threshold whenever the best model improves, and a final Cauchy-loss
// refinement on the pairs near the model when options.refine. Draws its samples from `rng`, so a seeded engine makes it
// deterministic. The inputs are the pairs left after filtering (no confidences).
LoRansacOutput loRansacPnp(const std::vector<Eigen::Vector2d>& pixels,
                           const std::vector<Eigen::Vector3d>& points, const Intrinsics& camera,
                           const PnpOptions& options, Rng* rng);

}  // namespace ffloc
