#include "ffloc/pose/focal_scan.h"

#include <algorithm>

namespace ffloc {

FocalScan scanFocalLengths(const Correspondences& correspondences, const Intrinsics& camera, const PnpOptions& pnp,
                           int given_inliers) {
  FocalScan scan;
  int best = -1;
  for (const double factor : kScannedFocalFactors) {
    Intrinsics scaled = camera;
    scaled.fx *= factor;
    scaled.fy *= factor;
    const PnpResult pose = estimatePose(correspondences, scaled, pnp);
    if (!pose.ok() || pose.inliers <= best) continue;
    best = pose.inliers;
    scan.valid = true;
    scan.factor = factor;
  }
  if (scan.valid) scan.inlier_gain = static_cast<double>(best) / std::max(1, given_inliers);
  return scan;
}

}  // namespace ffloc
