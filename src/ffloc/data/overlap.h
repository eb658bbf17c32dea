#pragma once

#include <opencv2/core.hpp>

#include "ffloc/data/scene.h"

namespace ffloc {

struct OverlapOptions {
  // A reprojected point agrees with view B when |z_predicted - z_B| <= this * z_B (Kinect-class
  // depth is good to a few percent; synthetic depth is exact).
  double relative_depth_tolerance = 0.05;
  // Sample every stride-th pixel of view A in x and y (1: all of them).
  int stride = 1;
};

// The fraction of view A's pixels with valid depth (> 0, finite) that, back-projected with A's
// depth and pose and projected into view B, land inside B's image and agree with B's depth at
// the nearest pixel. Directional: a close-up B seen whole by a wide A gives
// viewOverlap(B, A) = 1 but viewOverlap(A, B) < 1; two views related by a symmetric motion
// give the same value both ways; a view with itself gives 1. Depth maps may be smaller or
// larger than the frames' intrinsics (the intrinsics are rescaled to them). 0 when A has no
// valid depth. Throws InputError for distorted cameras (depth must be undistorted) or
// non-positive strides.
double viewOverlap(const Frame& a, const cv::Mat1f& depth_a, const Frame& b,
                   const cv::Mat1f& depth_b, const OverlapOptions& options = {});

// The smaller of the two directional overlaps: a pair passes a threshold only when each view
// sees enough of the other. Training picks mapping images with this in [0.2, 0.85].
double pairOverlap(const Frame& a, const cv::Mat1f& depth_a, const Frame& b,
                   const cv::Mat1f& depth_b, const OverlapOptions& options = {});

}  // namespace ffloc
