#include "ffloc/geometry/triangulation.h"

#include <Eigen/Dense>
#include <cmath>
#include <limits>

namespace ffloc {
namespace {

constexpr double kPi = 3.14159265358979323846;

// The point in the camera frame of an observation.
Eigen::Vector3d toCamera(const Observation& observation, const Eigen::Vector3d& point) {
  return observation.camera_to_world.R.transpose() * (point - observation.camera_to_world.t);
}

// The algebraic solution. The world is expressed relative to the cameras' mean centre and
// scaled by their spread, and every equation is normalised, so distant scenes and mixed focal
// lengths do not skew the least-squares problem.
std::optional<Eigen::Vector3d> linearTriangulation(const std::vector<Observation>& observations) {
  const size_t n = observations.size();
  if (n < 2) return std::nullopt;
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
  for (const Observation& o : observations) centre += o.camera_to_world.t;
  centre /= static_cast<double>(n);
  double spread = 0;
  for (const Observation& o : observations) spread += (o.camera_to_world.t - centre).norm();
  spread /= static_cast<double>(n);
  if (!(spread > 0) || !std::isfinite(spread)) spread = 1;

  Eigen::MatrixXd A(2 * n, 4);
  for (size_t i = 0; i < n; ++i) {
    const Observation& o = observations[i];
    // Projection of the conditioned point Y (X = centre + spread * Y) into normalised coordinates.
    Eigen::Matrix<double, 3, 4> P;
    P.leftCols<3>() = o.camera_to_world.R.transpose();
    P.col(3) = -o.camera_to_world.R.transpose() * (o.camera_to_world.t - centre) / spread;
    const Eigen::Vector3d m = o.K.inverse() * o.pixel.homogeneous();
    const Eigen::RowVector4d row_x = m.x() / m.z() * P.row(2) - P.row(0);
    const Eigen::RowVector4d row_y = m.y() / m.z() * P.row(2) - P.row(1);
    A.row(2 * i) = row_x / row_x.norm();
    A.row(2 * i + 1) = row_y / row_y.norm();
  }
  if (!A.allFinite()) return std::nullopt;
  const Eigen::JacobiSVD<Eigen::MatrixXd> svd(A, Eigen::ComputeFullV);
  const Eigen::Vector4d Y = svd.matrixV().col(3);
  // A point at (or numerically near) infinity: the rays are parallel.
  if (std::abs(Y.w()) < 1e-12 * Y.head<3>().norm() || Y.w() == 0) return std::nullopt;
  const Eigen::Vector3d point = centre + spread * Y.head<3>() / Y.w();
  if (!point.allFinite()) return std::nullopt;
  return point;
}

double squaredReprojectionCost(const std::vector<Observation>& observations, const Eigen::Vector3d& point) {
  double cost = 0;
  for (const Observation& o : observations) {
    const double e = reprojectionError(o, point);
    cost += e * e;
  }
  return cost;
}

// Gauss-Newton on the summed squared pixel error; returns the input when a step would not help.
Eigen::Vector3d refinePoint(const std::vector<Observation>& observations, Eigen::Vector3d point, int iterations) {
  double cost = squaredReprojectionCost(observations, point);
  for (int it = 0; it < iterations && std::isfinite(cost); ++it) {
    Eigen::Matrix3d H = Eigen::Matrix3d::Zero();
    Eigen::Vector3d g = Eigen::Vector3d::Zero();
    for (const Observation& o : observations) {
      const Eigen::Matrix3d Rt = o.camera_to_world.R.transpose();
      const Eigen::Vector3d h = o.K * (Rt * (point - o.camera_to_world.t));
      const Eigen::Vector2d residual = h.head<2>() / h.z() - o.pixel;
      // d(h_xy / h_z)/dh, chained through K and R^T.
      Eigen::Matrix<double, 2, 3> dproj;
      dproj << 1 / h.z(), 0, -h.x() / (h.z() * h.z()), 0, 1 / h.z(), -h.y() / (h.z() * h.z());
      const Eigen::Matrix<double, 2, 3> J = dproj * o.K * Rt;
      H += J.transpose() * J;
      g += J.transpose() * residual;
    }
    const Eigen::Vector3d step = H.ldlt().solve(-g);
    if (!step.allFinite()) break;
    const Eigen::Vector3d candidate = point + step;
    const double candidate_cost = squaredReprojectionCost(observations, candidate);
    if (!(candidate_cost < cost)) break;
    const bool converged = step.norm() <= 1e-12 * (1 + point.norm());
    point = candidate;
    cost = candidate_cost;
    if (converged) break;
  }
  return point;
}

bool passesChecks(const std::vector<Observation>& observations, const Eigen::Vector3d& point,
                  const TriangulationOptions& options) {
  for (const Observation& o : observations)
    if (!(reprojectionError(o, point) <= options.max_reprojection_error_px)) return false;
  return maxTriangulationAngleDeg(observations, point) >= options.min_angle_deg;
}

}  // namespace

double reprojectionError(const Observation& observation, const Eigen::Vector3d& point) {
  const Eigen::Vector3d camera_point = toCamera(observation, point);
  if (!(camera_point.z() > 0)) return std::numeric_limits<double>::infinity();
  const Eigen::Vector3d h = observation.K * camera_point;
  return (h.head<2>() / h.z() - observation.pixel).norm();
}

double maxTriangulationAngleDeg(const std::vector<Observation>& observations, const Eigen::Vector3d& point) {
  double best = 0;
  for (size_t i = 0; i < observations.size(); ++i) {
    const Eigen::Vector3d a = point - observations[i].camera_to_world.t;
    for (size_t j = i + 1; j < observations.size(); ++j) {
      const Eigen::Vector3d b = point - observations[j].camera_to_world.t;
      // atan2 stays accurate for the small angles this threshold is about.
      const double angle = std::atan2(a.cross(b).norm(), a.dot(b));
      if (std::isfinite(angle)) best = std::max(best, angle);
    }
  }
  return best * 180.0 / kPi;
}

std::optional<Eigen::Vector3d> triangulate(const std::vector<Observation>& observations,
                                           const TriangulationOptions& options) {
  std::optional<Eigen::Vector3d> point = linearTriangulation(observations);
  if (!point) return std::nullopt;
  if (options.refine) point = refinePoint(observations, *point, options.max_refine_iterations);
  if (!passesChecks(observations, *point, options)) return std::nullopt;
  return point;
}

std::optional<Eigen::Vector3d> triangulateRobust(const std::vector<Observation>& observations,
                                                 const TriangulationOptions& options, std::vector<bool>* inliers) {
  const size_t n = observations.size();
  if (inliers) inliers->assign(n, false);
  if (n < 2) return std::nullopt;
  if (std::optional<Eigen::Vector3d> point = triangulate(observations, options)) {
    if (inliers) inliers->assign(n, true);
    return point;
  }
  if (n == 2) return std::nullopt;

  std::vector<bool> best_support;
  size_t best_count = 0;
  double best_cost = std::numeric_limits<double>::infinity();
  for (size_t i = 0; i < n; ++i) {
    for (size_t j = i + 1; j < n; ++j) {
      const std::optional<Eigen::Vector3d> proposal = triangulate({observations[i], observations[j]}, options);
      if (!proposal) continue;
      std::vector<bool> support(n, false);
      size_t count = 0;
      double cost = 0;
      for (size_t k = 0; k < n; ++k) {
        const double e = reprojectionError(observations[k], *proposal);
        if (e <= options.max_reprojection_error_px) {
          support[k] = true;
          ++count;
          cost += e * e;
        }
      }
      if (count > best_count || (count == best_count && cost < best_cost)) {
        best_support = std::move(support);
        best_count = count;
        best_cost = cost;
      }
    }
  }
  if (best_count < 2) return std::nullopt;

  std::vector<Observation> agreeing;
  for (size_t k = 0; k < n; ++k)
    if (best_support[k]) agreeing.push_back(observations[k]);
  const std::optional<Eigen::Vector3d> point = triangulate(agreeing, options);
  if (point && inliers) *inliers = best_support;
  return point;
}

}  // namespace ffloc
