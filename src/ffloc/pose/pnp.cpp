#include "ffloc/pose/pnp.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <optional>
#include <sstream>

#include "ffloc/core/clock.h"
#include "ffloc/core/error.h"
#include "ffloc/pose/lo_ransac.h"
#include "ffloc/pose/opencv_usac.h"
#include "ffloc/pose/reprojection.h"
#include "ffloc/pose/select_correspondences.h"

namespace ffloc {
namespace {

void validate(const Correspondences& correspondences, const Intrinsics& camera,
              const PnpOptions& options) {
  if (correspondences.points.size() != correspondences.pixels.size() ||
      correspondences.confidences.size() != correspondences.pixels.size()) {
    std::ostringstream what;
    what << "pixels (" << correspondences.pixels.size() << "), points ("
         << correspondences.points.size() << ") and confidences ("
         << correspondences.confidences.size() << ") differ in length";
    throwInputError("Correspondences", 0, what.str());
  }
  if (!camera.isValid())
    throwInputError("Intrinsics", 0, "fx, fy must be finite and positive, width and height positive");
  if (!(options.inlier_threshold_px > 0) || !std::isfinite(options.inlier_threshold_px))
    throwInputError("PnpOptions", 0, "inlier_threshold_px must be finite and positive");
  if (options.max_iterations < 1)
    throwInputError("PnpOptions", 0, "max_iterations must be at least 1");
  if (!(options.success_probability > 0 && options.success_probability < 1))
    throwInputError("PnpOptions", 0, "success_probability must lie in (0, 1)");
}

// The pose is fixed only up to a rotation about the line when every inlier lies on it.
bool collinear(const std::vector<Eigen::Vector3d>& points, const std::vector<int>& indices) {
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (int i : indices) mean += points[i];
  mean /= static_cast<double>(indices.size());
  Eigen::Matrix3d scatter = Eigen::Matrix3d::Zero();
  for (int i : indices) scatter += (points[i] - mean) * (points[i] - mean).transpose();
  const Eigen::Vector3d spread = Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(scatter, Eigen::EigenvaluesOnly)
                                     .eigenvalues();  // ascending
  return !(spread(1) > 1e-10 * spread(2));
}

// The inliers a wrong pose collects by chance: a pixel unrelated to its point lands within the
// threshold of the projection with probability about pi t^2 / (W H). RANSAC keeps the best of
// thousands of hypotheses, so a success must clear the expected count by a wide margin; otherwise
// pure noise with many pairs comes back as a confident wrong pose.
int chanceInlierBound(size_t used, const Intrinsics& camera, double threshold_px) {
  const double area = static_cast<double>(camera.width) * camera.height;
  const double probability = std::min(1.0, M_PI * threshold_px * threshold_px / area);
  const double expected = static_cast<double>(used) * probability;
  return static_cast<int>(std::ceil(expected + 8.0 * std::sqrt(expected) + 6.0));
}

}  // namespace

const char* toString(PnpSolver solver) {
  switch (solver) {
    case PnpSolver::kOpenCvUsac: return "opencv-usac";
    case PnpSolver::kLoRansac: return "lo-ransac";
  }
  return "unknown";
}

PnpSolver parsePnpSolver(const std::string& name) {
  if (name == "opencv-usac") return PnpSolver::kOpenCvUsac;
  if (name == "lo-ransac") return PnpSolver::kLoRansac;
  throwInputError("pnp.solver", 0, "unknown solver '" + name + "' (expected opencv-usac or lo-ransac)");
}

const char* toString(PnpStatus status) {
  switch (status) {
    case PnpStatus::kSuccess: return "success";
    case PnpStatus::kTooFewCorrespondences: return "too few correspondences";
    case PnpStatus::kNoModel: return "no model";
    case PnpStatus::kTooFewInliers: return "too few inliers";
  }
  return "unknown";
}

PnpResult estimatePose(const Correspondences& correspondences, const Intrinsics& camera,
                       const PnpOptions& options) {
  const auto start = std::chrono::steady_clock::now();
  validate(correspondences, camera, options);
  PnpResult result;
  const auto finish = [&](PnpStatus status) {
    result.status = status;
    result.seconds = secondsSince(start);
    return result;
  };

  Rng rng(options.seed);
  const std::vector<int> selected =
      selectCorrespondences(correspondences, options.confidence_threshold, options.max_correspondences, &rng,
                            options.min_correspondences);
  result.used_correspondences = static_cast<int>(selected.size());
  if (selected.size() < 4) return finish(PnpStatus::kTooFewCorrespondences);

  std::vector<Eigen::Vector2d> pixels;
  std::vector<Eigen::Vector3d> points;
  pixels.reserve(selected.size());
  points.reserve(selected.size());
  for (int i : selected) {
    pixels.push_back(correspondences.pixels[i]);
    points.push_back(correspondences.points[i]);
  }

  std::optional<Pose> world_to_camera;
  if (options.solver == PnpSolver::kOpenCvUsac) {
    world_to_camera = opencvUsacPnp(pixels, points, camera, options);
  } else {
    const LoRansacOutput output = loRansacPnp(pixels, points, camera, options, &rng);
    if (output.found) world_to_camera = output.world_to_camera;
  }
  if (!world_to_camera) return finish(PnpStatus::kNoModel);

  result.camera_to_world = world_to_camera->inverse();
  const std::vector<int> inliers = findInliers(pixels, points, camera, *world_to_camera, options.inlier_threshold_px);
  result.inliers = static_cast<int>(inliers.size());
  result.required_inliers = std::max({options.min_inliers, 4,
                                      chanceInlierBound(selected.size(), camera, options.inlier_threshold_px)});
  if (result.inliers < result.required_inliers) return finish(PnpStatus::kTooFewInliers);
  if (collinear(points, inliers)) return finish(PnpStatus::kNoModel);
  return finish(PnpStatus::kSuccess);
}

}  // namespace ffloc
