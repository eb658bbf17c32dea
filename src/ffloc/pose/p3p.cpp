#include "ffloc/pose/p3p.h"

#include <Eigen/Eigenvalues>
#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <limits>

namespace ffloc {
namespace {

// Real roots of a x^2 + b x + c, in the cancellation-free form. A slightly negative
// discriminant is read as a double root: exact instances land there up to rounding.
int solveQuadratic(double a, double b, double c, double roots[2]) {
  const double scale = std::max({std::abs(a), std::abs(b), std::abs(c)});
  if (scale == 0.0) return 0;
  if (std::abs(a) <= 1e-14 * scale) {
    if (std::abs(b) <= 1e-14 * scale) return 0;
    roots[0] = -c / b;
    return 1;
  }
  double discriminant = b * b - 4.0 * a * c;
  if (discriminant < 0.0) {
    if (discriminant < -1e-10 * b * b - 1e-14 * scale * scale) return 0;
    discriminant = 0.0;
  }
  const double q = -0.5 * (b + std::copysign(std::sqrt(discriminant), b));
  if (q == 0.0) {
    roots[0] = 0.0;
    return 1;
  }
  roots[0] = q / a;
  roots[1] = c / q;
  return 2;
}

// Real roots of c3 x^3 + c2 x^2 + c1 x + c0 in closed form, each polished by Newton steps on the
// undepressed polynomial, which the closed form leaves a few digits short of.
int solveCubic(double c3, double c2, double c1, double c0, double roots[3]) {
  const double scale = std::max({std::abs(c3), std::abs(c2), std::abs(c1), std::abs(c0)});
  if (scale == 0.0) return 0;
  if (std::abs(c3) <= 1e-12 * scale) return solveQuadratic(c2, c1, c0, roots);
  const double a = c2 / c3, b = c1 / c3, c = c0 / c3;
  const double p = b - a * a / 3.0;
  const double q = 2.0 * a * a * a / 27.0 - a * b / 3.0 + c;
  const double discriminant = 0.25 * q * q + p * p * p / 27.0;
  int count = 0;
  if (discriminant > 0.0) {
    const double root = std::sqrt(discriminant);
    roots[count++] = std::cbrt(-0.5 * q + root) + std::cbrt(-0.5 * q - root) - a / 3.0;
  } else if (p >= 0.0) {
    roots[count++] = std::cbrt(-q) - a / 3.0;
  } else {
    const double radius = 2.0 * std::sqrt(-p / 3.0);
    const double cos_arg = std::clamp(3.0 * q / (p * radius), -1.0, 1.0);
    const double angle = std::acos(cos_arg) / 3.0;
    for (int k = 0; k < 3; ++k) roots[count++] = radius * std::cos(angle - 2.0 * M_PI * k / 3.0) - a / 3.0;
  }
  for (int i = 0; i < count; ++i) {
    for (int step = 0; step < 3; ++step) {
      const double x = roots[i];
      const double value = ((x + a) * x + b) * x + c;
      const double slope = (3.0 * x + 2.0 * a) * x + b;
      if (slope == 0.0) break;
      roots[i] = x - value / slope;
    }
  }
  return count;
}

// Columns are the cross products of the rows: A^-1 * det(A) without dividing, so it stays
// defined for the singular matrices of the pencil.
Eigen::Matrix3d adjugate(const Eigen::Matrix3d& A) {
  Eigen::Matrix3d adj;
  adj.col(0) = A.row(1).transpose().cross(A.row(2).transpose());
  adj.col(1) = A.row(2).transpose().cross(A.row(0).transpose());
  adj.col(2) = A.row(0).transpose().cross(A.row(1).transpose());
  return adj;
}

struct DepthConstraints {
  double b12, b13, b23;  // cosines between the bearings
  double a12, a13, a23;  // squared world distances

  Eigen::Vector3d residuals(const Eigen::Vector3d& l) const {
    return {l(0) * l(0) + l(1) * l(1) - 2.0 * b12 * l(0) * l(1) - a12,
            l(0) * l(0) + l(2) * l(2) - 2.0 * b13 * l(0) * l(2) - a13,
            l(1) * l(1) + l(2) * l(2) - 2.0 * b23 * l(1) * l(2) - a23};
  }
};

// Gauss-Newton on the three distance equations: the plane/conic construction loses a few digits
// to the eigen-decomposition, which this wins back.
Eigen::Vector3d refineDepths(const DepthConstraints& k, Eigen::Vector3d depths) {
  Eigen::Vector3d residuals = k.residuals(depths);
  for (int iteration = 0; iteration < 5; ++iteration) {
    const double cost = residuals.squaredNorm();
    if (cost < 1e-30) break;
    const Eigen::Vector3d& l = depths;
    Eigen::Matrix3d J;
    J << 2.0 * (l(0) - k.b12 * l(1)), 2.0 * (l(1) - k.b12 * l(0)), 0.0,
        2.0 * (l(0) - k.b13 * l(2)), 0.0, 2.0 * (l(2) - k.b13 * l(0)),
        0.0, 2.0 * (l(1) - k.b23 * l(2)), 2.0 * (l(2) - k.b23 * l(1));
    const Eigen::FullPivLU<Eigen::Matrix3d> lu(J);
    if (!lu.isInvertible()) break;
    const Eigen::Vector3d candidate = depths - lu.solve(residuals);
    const Eigen::Vector3d candidate_residuals = k.residuals(candidate);
    if (!(candidate_residuals.squaredNorm() < cost)) break;
    depths = candidate;
    residuals = candidate_residuals;
  }
  return depths;
}

}  // namespace

int solveP3P(const std::array<Eigen::Vector3d, 3>& bearings,
             const std::array<Eigen::Vector3d, 3>& points, std::vector<Pose>* world_to_camera) {
  const Eigen::Vector3d& y1 = bearings[0];
  const Eigen::Vector3d& y2 = bearings[1];
  const Eigen::Vector3d& y3 = bearings[2];
  const Eigen::Vector3d d12 = points[0] - points[1];
  const Eigen::Vector3d d13 = points[0] - points[2];
  const Eigen::Vector3d normal = d12.cross(d13);
  // A collinear triple fixes no rotation about its line; the pose is then not determined.
  if (!(normal.norm() > 1e-9 * d12.norm() * d13.norm())) return 0;

  DepthConstraints k;
  k.b12 = y1.dot(y2);
  k.b13 = y1.dot(y3);
  k.b23 = y2.dot(y3);
  k.a12 = d12.squaredNorm();
  k.a13 = d13.squaredNorm();
  k.a23 = (points[1] - points[2]).squaredNorm();

  // Lambda^T M_ij Lambda = a_ij are the three distance constraints on the depths Lambda.
  Eigen::Matrix3d M12, M13, M23;
  M12 << 1, -k.b12, 0, -k.b12, 1, 0, 0, 0, 0;
  M13 << 1, 0, -k.b13, 0, 0, 0, -k.b13, 0, 1;
  M23 << 0, 0, 0, 0, 1, -k.b23, 0, -k.b23, 1;
  // Two homogeneous conics through every solution; a singular member of their pencil
  // D1 + gamma * D2 is a pair of planes through every solution.
  const Eigen::Matrix3d D1 = k.a23 * M12 - k.a12 * M23;
  const Eigen::Matrix3d D2 = k.a23 * M13 - k.a13 * M23;
  double gammas[3];
  const int gamma_count = solveCubic(D2.determinant(), (adjugate(D2) * D1).trace(),
                                     (adjugate(D1) * D2).trace(), D1.determinant(), gammas);
  if (gamma_count == 0) return 0;

  // Any root makes the pencil singular; the best one leaves a clean zero eigenvalue and two of
  // opposite sign (two distinct real planes).
  double best_quality = std::numeric_limits<double>::infinity();
  double gamma = 0, sigma_pos = 0, sigma_neg = 0;
  Eigen::Vector3d e_pos, e_neg;
  bool found = false;
  for (int r = 0; r < gamma_count; ++r) {
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eigen(D1 + gammas[r] * D2);
    const Eigen::Vector3d values = eigen.eigenvalues();  // ascending
    int zero = 0;
    for (int i = 1; i < 3; ++i)
      if (std::abs(values(i)) < std::abs(values(zero))) zero = i;
    const int i1 = zero == 0 ? 1 : 0;
    const int i2 = zero == 2 ? 1 : 2;
    const double magnitude = std::min(std::abs(values(i1)), std::abs(values(i2)));
    if (magnitude == 0.0) continue;
    // Opposite signs first, then the cleanest zero.
    const double quality = std::abs(values(zero)) / magnitude + (values(i1) * values(i2) < 0 ? 0.0 : 1e6);
    if (quality < best_quality) {
      best_quality = quality;
      gamma = gammas[r];
      // values(i2) >= values(i1) as the eigenvalues come sorted.
      sigma_pos = values(i2);
      sigma_neg = values(i1);
      e_pos = eigen.eigenvectors().col(i2);
      e_neg = eigen.eigenvectors().col(i1);
      found = true;
    }
  }
  if (!found) return 0;

  // sigma_pos (e_pos.L)^2 + sigma_neg (e_neg.L)^2 = 0: L lies on e_pos.L = +-s e_neg.L.
  const double s = (sigma_pos > 0 && sigma_neg < 0) ? std::sqrt(-sigma_neg / sigma_pos) : 0.0;
  // On those planes D1 = -gamma * D2; cut with the larger of the two for conditioning.
  const Eigen::Matrix3d& cut = std::abs(gamma) >= 1.0 ? D1 : D2;
  // Scale from the longest side: the best-conditioned of the inhomogeneous constraints.
  const Eigen::Matrix3d* scale_form = &M12;
  double scale_distance = k.a12;
  if (k.a13 > scale_distance) scale_distance = k.a13, scale_form = &M13;
  if (k.a23 > scale_distance) scale_distance = k.a23, scale_form = &M23;

  Eigen::Matrix3d X;
  X << d12, d13, normal;
  const Eigen::Matrix3d X_inverse = X.inverse();

  int count = 0;
  const int plane_count = s > 0 ? 2 : 1;
  for (int plane_index = 0; plane_index < plane_count; ++plane_index) {
    const Eigen::Vector3d plane = e_pos - (plane_index == 0 ? s : -s) * e_neg;
    // Eliminate the depth with the largest plane coefficient; L = lambda_j * (A tau + B) with
    // tau = lambda_i / lambda_j.
    int kk = 0;
    plane.cwiseAbs().maxCoeff(&kk);
    const int i = (kk + 1) % 3, j = (kk + 2) % 3;
    Eigen::Vector3d A = Eigen::Vector3d::Zero(), B = Eigen::Vector3d::Zero();
    A(i) = 1.0;
    A(kk) = -plane(i) / plane(kk);
    B(j) = 1.0;
    B(kk) = -plane(j) / plane(kk);
    double taus[2];
    const int tau_count = solveQuadratic(A.dot(cut * A), 2.0 * A.dot(cut * B), B.dot(cut * B), taus);
    for (int t = 0; t < tau_count; ++t) {
      Eigen::Vector3d direction = A * taus[t] + B;
      const double form = direction.dot(*scale_form * direction);
      if (!(form > 0)) continue;
      direction *= std::sqrt(scale_distance / form);
      if (direction.sum() < 0) direction = -direction;
      if (!(direction.minCoeff() > 0)) continue;
      const Eigen::Vector3d depths = refineDepths(k, direction);
      if (!(depths.minCoeff() > 0)) continue;

      const Eigen::Vector3d c1 = depths(0) * y1;
      const Eigen::Vector3d c12 = c1 - depths(1) * y2;
      const Eigen::Vector3d c13 = c1 - depths(2) * y3;
      Eigen::Matrix3d Y;
      Y << c12, c13, c12.cross(c13);
      Pose pose;
      pose.R = Y * X_inverse;
      pose.t = c1 - pose.R * points[0];
      // Rays that (nearly) coincide leave the camera-side triangle flat, and Y X^-1 is then no
      // rotation (det 4e-21 for 200 pixels at one spot, which LO-RANSAC reported as a pose).
      if (!pose.isFinite() || orthogonalityError(pose.R) > kRigidRotationTolerance || pose.R.determinant() < 0) continue;
      world_to_camera->push_back(pose);
      ++count;
    }
  }
  return count;
}

}  // namespace ffloc
