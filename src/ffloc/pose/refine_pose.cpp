#include "ffloc/pose/refine_pose.h"

#include <Eigen/Cholesky>
#include <cmath>

#include "ffloc/pose/reprojection.h"

namespace ffloc {
namespace {

struct Evaluation {
  double cost = 0;
  int in_front = 0;
};

class ReprojectionProblem {
 public:
  ReprojectionProblem(const std::vector<Eigen::Vector2d>& pixels,
                      const std::vector<Eigen::Vector3d>& points, const std::vector<int>& indices,
                      const Intrinsics& camera, const RefinePoseOptions& options)
      : pixels_(pixels), points_(points), indices_(indices), camera_(camera), options_(options),
        scale_squared_(options.loss_scale_px * options.loss_scale_px) {}

  Evaluation evaluate(const Pose& pose) const {
    Evaluation e;
    for (int i : indices_) {
      const Eigen::Vector3d p = pose.R * points_[i] + pose.t;
      if (!(p.z() > 0)) continue;
      const Eigen::Vector2d r = camera_.project(p) - pixels_[i];
      e.cost += rho(r.squaredNorm());
      ++e.in_front;
    }
    return e;
  }

  // Gauss-Newton normal equations with IRLS weights, for a left perturbation
  // X_cam -> exp([omega]x) X_cam + v with the parameters (omega, v).
  void linearize(const Pose& pose, Eigen::Matrix<double, 6, 6>* H,
                 Eigen::Matrix<double, 6, 1>* g) const {
    H->setZero();
    g->setZero();
    for (int i : indices_) {
      const Eigen::Vector3d p = pose.R * points_[i] + pose.t;
      if (!(p.z() > 0)) continue;
      const Eigen::Vector2d r = camera_.project(p) - pixels_[i];
      const double w = weight(r.squaredNorm());
      const Eigen::Matrix<double, 2, 6> J = projectionJacobian(camera_, p);
      const Eigen::Matrix<double, 6, 2> weighted_Jt = w * J.transpose();
      H->noalias() += weighted_Jt.lazyProduct(J);
      g->noalias() += weighted_Jt * r;
    }
  }

 private:
  double rho(double s) const {
    return options_.loss == RefineLoss::kCauchy ? scale_squared_ * std::log1p(s / scale_squared_) : s;
  }
  double weight(double s) const {
    return options_.loss == RefineLoss::kCauchy ? 1.0 / (1.0 + s / scale_squared_) : 1.0;
  }

  const std::vector<Eigen::Vector2d>& pixels_;
  const std::vector<Eigen::Vector3d>& points_;
  const std::vector<int>& indices_;
  const Intrinsics& camera_;
  const RefinePoseOptions& options_;
  const double scale_squared_;
};

}  // namespace

RefinePoseSummary refinePose(const std::vector<Eigen::Vector2d>& pixels,
                             const std::vector<Eigen::Vector3d>& points,
                             const std::vector<int>& indices, const Intrinsics& camera,
                             const RefinePoseOptions& options, Pose* world_to_camera) {
  const ReprojectionProblem problem(pixels, points, indices, camera, options);
  Pose pose = *world_to_camera;
  Evaluation current = problem.evaluate(pose);
  RefinePoseSummary summary;
  summary.initial_cost = current.cost;

  double damping = 1e-4;
  Eigen::Matrix<double, 6, 6> H;
  Eigen::Matrix<double, 6, 1> g;
  bool relinearize = true;
  while (summary.iterations < options.max_iterations && current.in_front >= 3) {
    ++summary.iterations;
    if (relinearize) problem.linearize(pose, &H, &g);
    // Marquardt's diagonal scaling: rotation and translation live on different scales.
    Eigen::Matrix<double, 6, 6> damped = H;
    damped.diagonal() += damping * H.diagonal().cwiseMax(1e-12);
    const Eigen::Matrix<double, 6, 1> step = -damped.ldlt().solve(g);
    if (!step.allFinite()) break;
    const Pose candidate = perturbedLeft(pose, step);
    const Evaluation trial = problem.evaluate(candidate);
    if (trial.in_front >= current.in_front && trial.cost < current.cost) {
      pose = candidate;
      const double decrease = current.cost - trial.cost;
      current = trial;
      damping = std::max(damping * 0.1, 1e-12);
      relinearize = true;
      if (step.norm() < options.step_tolerance || decrease <= options.relative_decrease_tolerance * current.cost) break;
    } else {
      damping *= 10.0;
      relinearize = false;
      if (damping > 1e8) break;
    }
  }
  summary.final_cost = current.cost;
  *world_to_camera = pose;
  return summary;
}

}  // namespace ffloc
