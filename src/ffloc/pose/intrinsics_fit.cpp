#include "ffloc/pose/intrinsics_fit.h"

#include <Eigen/Cholesky>
#include <cmath>
#include <optional>

#include "ffloc/pose/reprojection.h"

namespace ffloc {
namespace {

// The intrinsic parameters a fit frees: `Parameters::kCount` of them, zero at the intrinsics
// given. `camera(x)` gives the intrinsics at x, `jacobian(camera(x), projected)` the pixel's
// derivative by x.
struct FocalScaleParameters {
  static constexpr int kCount = 1;  // ln(scale)
  const Intrinsics& given;
  Intrinsics camera(const Eigen::Matrix<double, 1, 1>& x) const {
    Intrinsics k = given;
    k.fx *= std::exp(x(0));
    k.fy *= std::exp(x(0));
    return k;
  }
  static Eigen::Matrix<double, 2, 1> jacobian(const Intrinsics& k, const Eigen::Vector2d& projected) {
    return projected - Eigen::Vector2d(k.cx, k.cy);
  }
};

struct FocalAspectParameters {
  static constexpr int kCount = 1;  // ln(aspect)
  const Intrinsics& given;
  Intrinsics camera(const Eigen::Matrix<double, 1, 1>& x) const {
    Intrinsics k = given;
    k.fx *= std::exp(-0.5 * x(0));
    k.fy *= std::exp(0.5 * x(0));
    return k;
  }
  static Eigen::Matrix<double, 2, 1> jacobian(const Intrinsics& k, const Eigen::Vector2d& projected) {
    return Eigen::Vector2d(-0.5 * (projected.x() - k.cx), 0.5 * (projected.y() - k.cy));
  }
};

struct PrincipalPointParameters {
  static constexpr int kCount = 2;  // the shift in pixels
  const Intrinsics& given;
  Intrinsics camera(const Eigen::Vector2d& x) const {
    Intrinsics k = given;
    k.cx += x(0);
    k.cy += x(1);
    return k;
  }
  static Eigen::Matrix2d jacobian(const Intrinsics&, const Eigen::Vector2d&) { return Eigen::Matrix2d::Identity(); }
};

template <int M>
struct IntrinsicsEstimate {
  Eigen::Matrix<double, M, 1> value;
  Eigen::Matrix<double, M, M> covariance;
  Pose world_to_camera;  // the pose fitted with them
};

// Levenberg-Marquardt on the pose (its left perturbation, as in projectionJacobian) and the
// parameters, started at `world_to_camera` and `start`; their estimate with its predicted
// covariance (the pixel noise from the residuals), none when the fit is singular or fewer than 5
// pairs are in front of the camera.
template <typename Parameters>
std::optional<IntrinsicsEstimate<Parameters::kCount>> fitIntrinsics(
    const Parameters& parameters, const std::vector<Eigen::Vector2d>& pixels,
    const std::vector<Eigen::Vector3d>& points, const std::vector<int>& indices, const Pose& world_to_camera,
    const Eigen::Matrix<double, Parameters::kCount, 1>& start) {
  constexpr int M = Parameters::kCount;
  constexpr int D = 6 + M;
  using Vector = Eigen::Matrix<double, D, 1>;
  using Matrix = Eigen::Matrix<double, D, D>;
  using Intrinsic = Eigen::Matrix<double, M, 1>;

  const auto cost = [&](const Pose& pose, const Intrinsic& x) {
    const Intrinsics k = parameters.camera(x);
    double sum = 0;
    int in_front = 0;
    for (int i : indices) {
      const Eigen::Vector3d p = pose * points[i];
      if (!(p.z() > 0)) continue;
      sum += (k.project(p) - pixels[i]).squaredNorm();
      ++in_front;
    }
    return std::make_pair(sum, in_front);
  };
  const auto linearize = [&](const Pose& pose, const Intrinsic& x, Matrix* H, Vector* g) {
    const Intrinsics k = parameters.camera(x);
    H->setZero();
    g->setZero();
    for (int i : indices) {
      const Eigen::Vector3d p = pose * points[i];
      if (!(p.z() > 0)) continue;
      const Eigen::Vector2d projected = k.project(p);
      Eigen::Matrix<double, 2, D> J;
      J.template leftCols<6>() = projectionJacobian(k, p);
      J.template rightCols<M>() = Parameters::jacobian(k, projected);
      H->noalias() += J.transpose() * J;
      g->noalias() += J.transpose() * (projected - pixels[i]);
    }
  };

  Pose pose = world_to_camera;
  Intrinsic x = start;
  auto [current_cost, in_front] = cost(pose, x);
  // Five pairs leave at least two degrees of freedom for the noise estimate.
  if (in_front < 5) return std::nullopt;
  double damping = 1e-4;
  Matrix H;
  Vector g;
  for (int iteration = 0; iteration < 50; ++iteration) {
    linearize(pose, x, &H, &g);
    Matrix damped = H;
    damped.diagonal() += damping * H.diagonal().cwiseMax(1e-12);
    const Vector step = -damped.ldlt().solve(g);
    if (!step.allFinite()) break;
    const Pose candidate = perturbedLeft(pose, step.template head<6>());
    const Intrinsic candidate_x = x + step.template tail<M>();
    const auto [candidate_cost, candidate_in_front] = cost(candidate, candidate_x);
    if (candidate_in_front >= in_front && candidate_cost < current_cost) {
      const bool converged = current_cost - candidate_cost <= 1e-9 * current_cost;
      pose = candidate;
      x = candidate_x;
      current_cost = candidate_cost;
      in_front = candidate_in_front;
      damping = std::max(damping * 0.1, 1e-12);
      if (converged) break;
    } else {
      damping *= 10;
      if (damping > 1e8) break;
    }
  }
  linearize(pose, x, &H, &g);
  // Judged and inverted with the parameters scaled to unit diagonal: rotation, translation and a
  // principal point in pixels differ by ten orders of magnitude in H, which an unscaled pivot
  // ratio reads as singular.
  if (!(H.diagonal().minCoeff() > 0)) return std::nullopt;
  const Vector scale = H.diagonal().cwiseSqrt().cwiseInverse();
  const Matrix normalized = scale.asDiagonal() * H * scale.asDiagonal();
  const Eigen::LDLT<Matrix> factor(normalized);
  if (factor.info() != Eigen::Success || !factor.isPositive() ||
      factor.vectorD().minCoeff() <= 1e-12 * factor.vectorD().maxCoeff())
    return std::nullopt;
  const double pixel_variance = current_cost / (2 * in_front - D);
  const Matrix covariance = pixel_variance * scale.asDiagonal() * factor.solve(Matrix::Identity()) * scale.asDiagonal();
  IntrinsicsEstimate<M> estimate{x, covariance.template bottomRightCorner<M, M>(), pose};
  if (!estimate.value.allFinite() || !estimate.covariance.allFinite() || !(estimate.covariance.diagonal().minCoeff() >= 0))
    return std::nullopt;
  return estimate;
}

// The fit over `indices`, then again over the pairs within `inlier_threshold_px` under the
// fitted intrinsics and pose, until they stop changing (at most kIntrinsicsRefitRounds fits);
// one fit when the threshold is 0.
template <typename Parameters>
std::optional<IntrinsicsEstimate<Parameters::kCount>> fitOnExplainedPairs(
    const Parameters& parameters, const std::vector<Eigen::Vector2d>& pixels,
    const std::vector<Eigen::Vector3d>& points, const std::vector<int>& indices, const Pose& world_to_camera,
    double inlier_threshold_px) {
  std::optional<IntrinsicsEstimate<Parameters::kCount>> latest;
  std::vector<int> fitted = indices;
  Pose pose = world_to_camera;
  Eigen::Matrix<double, Parameters::kCount, 1> start = Eigen::Matrix<double, Parameters::kCount, 1>::Zero();
  for (int round = 0; round < kIntrinsicsRefitRounds; ++round) {
    const auto estimate = fitIntrinsics(parameters, pixels, points, fitted, pose, start);
    if (!estimate) break;
    latest = estimate;
    if (!(inlier_threshold_px > 0)) break;
    std::vector<int> explained =
        findInliers(pixels, points, parameters.camera(estimate->value), estimate->world_to_camera, inlier_threshold_px);
    if (explained == fitted) break;
    fitted = std::move(explained);
    pose = estimate->world_to_camera;
    start = estimate->value;
  }
  return latest;
}

// A fit of Parameters' one parameter, the logarithm of a factor.
template <typename Parameters>
FactorFit fitFactor(const Parameters& parameters, const std::vector<Eigen::Vector2d>& pixels,
                    const std::vector<Eigen::Vector3d>& points, const std::vector<int>& indices,
                    const Pose& world_to_camera, double inlier_threshold_px) {
  static_assert(Parameters::kCount == 1);
  FactorFit fit;
  const auto estimate = fitOnExplainedPairs(parameters, pixels, points, indices, world_to_camera, inlier_threshold_px);
  if (!estimate) return fit;
  fit.valid = true;
  fit.factor = std::exp(estimate->value(0));
  fit.log_sigma = std::sqrt(estimate->covariance(0, 0));
  return fit;
}

}  // namespace

FactorFit fitFocalScale(const std::vector<Eigen::Vector2d>& pixels, const std::vector<Eigen::Vector3d>& points,
                        const std::vector<int>& indices, const Intrinsics& camera, const Pose& world_to_camera,
                        double inlier_threshold_px) {
  return fitFactor(FocalScaleParameters{camera}, pixels, points, indices, world_to_camera, inlier_threshold_px);
}

FactorFit fitFocalAspect(const std::vector<Eigen::Vector2d>& pixels, const std::vector<Eigen::Vector3d>& points,
                         const std::vector<int>& indices, const Intrinsics& camera, const Pose& world_to_camera,
                         double inlier_threshold_px) {
  return fitFactor(FocalAspectParameters{camera}, pixels, points, indices, world_to_camera, inlier_threshold_px);
}

PrincipalPointFit fitPrincipalPoint(const std::vector<Eigen::Vector2d>& pixels,
                                    const std::vector<Eigen::Vector3d>& points, const std::vector<int>& indices,
                                    const Intrinsics& camera, const Pose& world_to_camera, double inlier_threshold_px) {
  PrincipalPointFit fit;
  const auto estimate = fitOnExplainedPairs(PrincipalPointParameters{camera}, pixels, points, indices, world_to_camera,
                                            inlier_threshold_px);
  if (!estimate) return fit;
  const Eigen::LDLT<Eigen::Matrix2d> covariance(estimate->covariance);
  if (covariance.info() != Eigen::Success || !covariance.isPositive()) return fit;
  fit.valid = true;
  fit.shift_px = estimate->value;
  fit.significance = std::sqrt(std::max(0.0, estimate->value.dot(covariance.solve(estimate->value))));
  return fit;
}

}  // namespace ffloc
