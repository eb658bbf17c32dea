#pragma once

#include "ffloc/geometry/camera.h"
#include "ffloc/pose/correspondences.h"
#include "ffloc/pose/pnp.h"

namespace ffloc {

// PnP-RANSAC again with the focal length given scaled by each of kScannedFocalFactors. The fits
// of intrinsics_fit.h start from the pose's inliers, which are the pairs the focal length given
// explains: FastForward's redkitchen queries given 0.8 times their focal length fit 1.00-1.07 of
// it at 1-3 % predicted uncertainty, not 1.25, and were `localized` 0.25-0.6 m off. Run on all
// the pairs, the right focal length gathers its own inliers: 1.1-2.0 times as many there.
inline constexpr double kScannedFocalFactors[] = {1 / 1.3, 1 / 1.2, 1.2, 1.3};

struct FocalScan {
  bool valid = false;        // a factor gave a pose
  double factor = 1;         // the factor whose pose had the most inliers
  double inlier_gain = 0;    // its inliers over `given_inliers`
};

// `given_inliers`: the inliers of the pose at the focal length given, with the same `pnp`.
FocalScan scanFocalLengths(const Correspondences& correspondences, const Intrinsics& camera, const PnpOptions& pnp,
                           int given_inliers);

}  // namespace ffloc
