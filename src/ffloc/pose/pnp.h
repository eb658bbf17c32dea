#pragma once

#include <cstdint>
#include <string>

#include "ffloc/geometry/camera.h"
#include "ffloc/geometry/pose.h"
#include "ffloc/pose/correspondences.h"

namespace ffloc {

enum class PnpSolver {
  kOpenCvUsac,  // cv::solvePnPRansac with USAC (P3P minimal solver, local optimisation)
  kLoRansac,    // the project's own LO-RANSAC around a P3P minimal solver
};
const char* toString(PnpSolver solver);                // "opencv-usac", "lo-ransac"
PnpSolver parsePnpSolver(const std::string& name);  // throws InputError for unknown names

// Defaults are the paper's: drop C < 1.5, keep at most 5000 pairs. kLoRansac is the default
// solver because in bench/pnp_bench (7-Scenes geometry, 5000 pairs) it is 2-4x faster than
// OpenCV's USAC at the same accuracy, more accurate with noisy scene coordinates, and
// reproducible for a seed.
struct PnpOptions {
  PnpSolver solver = PnpSolver::kLoRansac;
  float confidence_threshold = 1.5f;
  size_t max_correspondences = 5000;
  // Fewer pairs than this above the threshold: the most confident this many are used instead
  // (selectCorrespondences). 0 keeps the threshold strict.
  size_t min_correspondences = 500;
  uint64_t seed = 0;  // seeds the subsampling and, for kLoRansac, the minimal samples
  double inlier_threshold_px = 8.0;
  int max_iterations = 10000;  // cap on minimal samples; the count adapts below it
  double success_probability = 0.9999;
  // A success also needs well more inliers than a random pose would collect by chance with this
  // many pairs, image size and threshold (pure noise must fail, not return a wrong pose).
  int min_inliers = 12;
  bool refine = true;  // non-linear refinement on the final inliers
};

enum class PnpStatus {
  kSuccess,
  kTooFewCorrespondences,  // fewer than 4 pairs after the confidence filter
  kNoModel,                // no hypothesis, or one whose inliers are collinear (pose ambiguous)
  kTooFewInliers,          // best model has fewer than min_inliers inliers
};
const char* toString(PnpStatus status);

struct PnpResult {
  PnpStatus status = PnpStatus::kNoModel;
  // Valid when status == kSuccess; with kTooFewInliers it holds the rejected best model.
  Pose camera_to_world;
  int inliers = 0;  // pairs within inlier_threshold_px (positive depth) of the final pose
  // The inliers a success needs: min_inliers, or more where pairs at random would collect that
  // many (a small image, many pairs). 0 when no model was found.
  int required_inliers = 0;
  int used_correspondences = 0;  // after the confidence filter and subsampling
  double seconds = 0;
  bool ok() const { return status == PnpStatus::kSuccess; }
};

// Confidence filter, seeded subsampling, robust estimation and refinement. `camera` is the
// pinhole camera of the pixels (no distortion). Never throws for a failed estimate: failure is
// a status. Throws InputError, naming the field, for an invalid camera or options and for
// correspondences whose arrays differ in length. kLoRansac gives the same result for the same
// seed and input.
PnpResult estimatePose(const Correspondences& correspondences, const Intrinsics& camera,
                       const PnpOptions& options = {});

}  // namespace ffloc
