#include "ffloc/data/overlap.h"

#include <algorithm>
#include <cmath>

#include "ffloc/core/error.h"

namespace ffloc {
namespace {

Intrinsics depthIntrinsics(const Frame& frame, const cv::Mat1f& depth) {
  if (frame.intrinsics.hasDistortion())
    throwInputError(frame.name, 0, "overlap needs an undistorted camera; undistort the depth first");
  if (!frame.intrinsics.isValid()) throwInputError(frame.name, 0, "invalid intrinsics");
  const Intrinsics& k = frame.intrinsics;
  if (depth.cols == k.width && depth.rows == k.height) return k;
  return k.scaled(static_cast<double>(depth.cols) / k.width,
                  static_cast<double>(depth.rows) / k.height, depth.cols, depth.rows);
}

bool validDepth(float d) { return d > 0.0f && std::isfinite(d); }

}  // namespace

double viewOverlap(const Frame& a, const cv::Mat1f& depth_a, const Frame& b,
                   const cv::Mat1f& depth_b, const OverlapOptions& options) {
  if (options.stride < 1) throwInputError("OverlapOptions", 0, "stride must be at least 1");
  if (!(options.relative_depth_tolerance >= 0.0))
    throwInputError("OverlapOptions", 0, "relative_depth_tolerance must be non-negative");
  const Intrinsics ka = depthIntrinsics(a, depth_a);
  const Intrinsics kb = depthIntrinsics(b, depth_b);
  // A camera point to B's camera: world_from_b^-1 * world_from_a.
  const Pose b_from_a = b.camera_to_world.inverse() * a.camera_to_world;
  const Eigen::Matrix3d& R = b_from_a.R;
  const Eigen::Vector3d& t = b_from_a.t;
  size_t valid = 0, agreeing = 0;
  for (int v = 0; v < depth_a.rows; v += options.stride) {
    const float* row = depth_a.ptr<float>(v);
    const double y = (v - ka.cy) / ka.fy;
    for (int u = 0; u < depth_a.cols; u += options.stride) {
      const float d = row[u];
      if (!validDepth(d)) continue;
      ++valid;
      const Eigen::Vector3d point_a((u - ka.cx) / ka.fx * d, y * d, d);
      const Eigen::Vector3d point_b = R * point_a + t;
      if (point_b.z() <= 0.0) continue;
      const double ub = kb.fx * point_b.x() / point_b.z() + kb.cx;
      const double vb = kb.fy * point_b.y() / point_b.z() + kb.cy;
      // Pixel (i, j) covers [i - 0.5, i + 0.5): the nearest pixel centre.
      const double col = std::floor(ub + 0.5), rw = std::floor(vb + 0.5);
      if (col < 0 || rw < 0 || col >= depth_b.cols || rw >= depth_b.rows) continue;
      const float db = depth_b(static_cast<int>(rw), static_cast<int>(col));
      if (!validDepth(db)) continue;
      if (std::fabs(point_b.z() - db) <= options.relative_depth_tolerance * db) ++agreeing;
    }
  }
  return valid == 0 ? 0.0 : static_cast<double>(agreeing) / static_cast<double>(valid);
}

double pairOverlap(const Frame& a, const cv::Mat1f& depth_a, const Frame& b,
                   const cv::Mat1f& depth_b, const OverlapOptions& options) {
  return std::min(viewOverlap(a, depth_a, b, depth_b, options),
                  viewOverlap(b, depth_b, a, depth_a, options));
}

}  // namespace ffloc
