#pragma once

#include <Eigen/Core>
#include <vector>

namespace ffloc {

// 2D-3D pairs for one query: pixels in the query's undistorted pixel grid (OpenCV convention),
// points in the world frame, and one confidence per pair (the network's C >= 1; sources with
// no notion of confidence use +inf so no filter drops them).
struct Correspondences {
  std::vector<Eigen::Vector2d> pixels;
  std::vector<Eigen::Vector3d> points;
  std::vector<float> confidences;

  size_t size() const { return pixels.size(); }
  void reserve(size_t n) {
    pixels.reserve(n);
    points.reserve(n);
    confidences.reserve(n);
  }
  void add(const Eigen::Vector2d& pixel, const Eigen::Vector3d& point, float confidence) {
    pixels.push_back(pixel);
    points.push_back(point);
    confidences.push_back(confidence);
  }
};

}  // namespace ffloc
