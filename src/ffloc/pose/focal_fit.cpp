#include "ffloc/pose/focal_fit.h"

#include <Eigen/Cholesky>
#include <cmath>

#include "ffloc/pose/reprojection.h"

namespace ffloc {
namespace {

using Vector7d = Eigen::Matrix<double, 7, 1>;
using Matrix7d = Eigen::Matrix<double, 7, 7>;

struct FocalProblem {
  const std::vector<Eigen::Vector2d>& pixels;
  const std::vector<Eigen::Vector3d>& points;
  const std::vector<int>& indices;
  const Intrinsics& camera;

  Intrinsics scaled(double scale) const {
    Intrinsics k = camera;
    k.fx *= scale;
    k.fy *= scale;
    return k;
  }

  // Sum of squared pixel residuals and the pairs in front of the camera.
  std::pair<double, int> cost(const Pose& pose, double scale) const {
    const Intrinsics k = scaled(scale);
    double sum = 0;
    int in_front = 0;
    for (int i : indices) {
      const Eigen::Vector3d p = pose * points[i];
      if (!(p.z() > 0)) continue;
      sum += (k.project(p) - pixels[i]).squaredNorm();
      ++in_front;
    }
    return {sum, in_front};
  }

  // Normal equations in (omega, v, ln scale): the pose's left perturbation as in
  // projectionJacobian, and d(pixel)/d(ln scale) = pixel - principal point.
  void linearize(const Pose& pose, double scale, Matrix7d* H, Vector7d* g) const {
    const Intrinsics k = scaled(scale);
    H->setZero();
    g->setZero();
    for (int i : indices) {
      const Eigen::Vector3d p = pose * points[i];
      if (!(p.z() > 0)) continue;
      const Eigen::Vector2d projected = k.project(p);
      Eigen::Matrix<double, 2, 7> J;
      J.leftCols<6>() = projectionJacobian(k, p);
      J.col(6) = projected - Eigen::Vector2d(k.cx, k.cy);
      H->noalias() += J.transpose() * J;
      g->noalias() += J.transpose() * (projected - pixels[i]);
    }
  }
};

}  // namespace

FocalFit fitFocalScale(const std::vector<Eigen::Vector2d>& pixels, const std::vector<Eigen::Vector3d>& points,
                       const std::vector<int>& indices, const Intrinsics& camera, const Pose& world_to_camera) {
  const FocalProblem problem{pixels, points, indices, camera};
  Pose pose = world_to_camera;
  double log_scale = 0;
  auto [cost, in_front] = problem.cost(pose, 1.0);
  FocalFit fit;
  // Five pairs leave three degrees of freedom for the noise estimate.
  if (in_front < 5) return fit;
  double damping = 1e-4;
  Matrix7d H;
  Vector7d g;
  for (int iteration = 0; iteration < 50; ++iteration) {
    problem.linearize(pose, std::exp(log_scale), &H, &g);
    Matrix7d damped = H;
    damped.diagonal() += damping * H.diagonal().cwiseMax(1e-12);
    const Vector7d step = -damped.ldlt().solve(g);
    if (!step.allFinite()) break;
    const Pose candidate = perturbedLeft(pose, step.head<6>());
    const double candidate_log_scale = log_scale + step(6);
    const auto [candidate_cost, candidate_in_front] = problem.cost(candidate, std::exp(candidate_log_scale));
    if (candidate_in_front >= in_front && candidate_cost < cost) {
      const bool converged = cost - candidate_cost <= 1e-9 * cost;
      pose = candidate;
      log_scale = candidate_log_scale;
      cost = candidate_cost;
      in_front = candidate_in_front;
      damping = std::max(damping * 0.1, 1e-12);
      if (converged) break;
    } else {
      damping *= 10;
      if (damping > 1e8) break;
    }
  }
  problem.linearize(pose, std::exp(log_scale), &H, &g);
  const Eigen::LDLT<Matrix7d> factor(H);
  if (factor.info() != Eigen::Success || !factor.isPositive() ||
      factor.vectorD().minCoeff() <= 1e-12 * factor.vectorD().maxCoeff())
    return fit;
  const double pixel_variance = cost / (2 * in_front - 7);
  const Matrix7d covariance = pixel_variance * factor.solve(Matrix7d::Identity());
  if (!(covariance(6, 6) >= 0) || !std::isfinite(log_scale)) return fit;
  fit.valid = true;
  fit.scale = std::exp(log_scale);
  fit.log_scale_sigma = std::sqrt(covariance(6, 6));
  return fit;
}

}  // namespace ffloc
