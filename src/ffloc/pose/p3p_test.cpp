#include "ffloc/pose/p3p.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <random>

namespace ffloc {
namespace {

Eigen::Matrix3d randomRotation(std::mt19937_64& rng) {
  std::normal_distribution<double> normal;
  return Eigen::Quaterniond(normal(rng), normal(rng), normal(rng), normal(rng)).normalized().toRotationMatrix();
}

struct Instance {
  Pose world_to_camera;
  std::array<Eigen::Vector3d, 3> bearings;
  std::array<Eigen::Vector3d, 3> points;
};

// Points in front of a random camera, anywhere in a wide field of view, at depths 0.5-10.
Instance randomInstance(std::mt19937_64& rng) {
  std::uniform_real_distribution<double> lateral(-1.0, 1.0), depth(0.5, 10.0), position(-5.0, 5.0);
  Instance instance;
  instance.world_to_camera.R = randomRotation(rng);
  instance.world_to_camera.t = Eigen::Vector3d(position(rng), position(rng), position(rng));
  const Pose camera_to_world = instance.world_to_camera.inverse();
  for (int i = 0; i < 3; ++i) {
    const double z = depth(rng);
    const Eigen::Vector3d camera_point(lateral(rng) * z, lateral(rng) * z, z);
    instance.bearings[i] = camera_point.normalized();
    instance.points[i] = camera_to_world * camera_point;
  }
  return instance;
}

double poseDistance(const Pose& a, const Pose& b) {
  return (a.R - b.R).norm() + (a.t - b.t).norm() / (1.0 + b.t.norm());
}

TEST(P3P, RecoversTheTruthOnExactRandomInstances) {
  std::mt19937_64 rng(1);
  int recovered = 0;
  const int trials = 2000;
  for (int trial = 0; trial < trials; ++trial) {
    const Instance instance = randomInstance(rng);
    std::vector<Pose> solutions;
    const int count = solveP3P(instance.bearings, instance.points, &solutions);
    ASSERT_EQ(count, static_cast<int>(solutions.size()));
    ASSERT_LE(count, 4);
    double best = 1e9;
    for (const Pose& solution : solutions) best = std::min(best, poseDistance(solution, instance.world_to_camera));
    if (best < 1e-6) ++recovered;
  }
  // Random triples include near-degenerate ones; the Gauss-Newton polish keeps even those exact.
  EXPECT_EQ(recovered, trials);
}

TEST(P3P, EverySolutionIsAValidPoseThatReprojectsExactly) {
  std::mt19937_64 rng(2);
  for (int trial = 0; trial < 500; ++trial) {
    const Instance instance = randomInstance(rng);
    std::vector<Pose> solutions;
    solveP3P(instance.bearings, instance.points, &solutions);
    for (const Pose& solution : solutions) {
      EXPECT_LT((solution.R.transpose() * solution.R - Eigen::Matrix3d::Identity()).norm(), 1e-8);
      EXPECT_NEAR(solution.R.determinant(), 1.0, 1e-8);
      for (int i = 0; i < 3; ++i) {
        const Eigen::Vector3d camera_point = solution.R * instance.points[i] + solution.t;
        EXPECT_GT(camera_point.z(), 0.0);
        EXPECT_LT((camera_point.normalized() - instance.bearings[i]).norm(), 1e-8);
      }
    }
  }
}

TEST(P3P, RecoversTheTruthInASymmetricConfiguration) {
  // Equilateral world triangle seen head-on from its axis: several distinct poses fit. Every
  // solution must be exact and the truth among them.
  std::mt19937_64 rng(3);
  Instance instance;
  instance.world_to_camera = Pose::identity();
  for (int i = 0; i < 3; ++i) {
    const double angle = 2.0 * M_PI * i / 3.0;
    instance.points[i] = Eigen::Vector3d(std::cos(angle), std::sin(angle), 3.0);
    instance.bearings[i] = instance.points[i].normalized();
  }
  std::vector<Pose> solutions;
  const int count = solveP3P(instance.bearings, instance.points, &solutions);
  EXPECT_GE(count, 1);
  double best = 1e9;
  for (const Pose& solution : solutions) best = std::min(best, poseDistance(solution, instance.world_to_camera));
  EXPECT_LT(best, 1e-6);
}

TEST(P3P, RejectsCollinearPoints) {
  std::array<Eigen::Vector3d, 3> points = {Eigen::Vector3d(0, 0, 2), Eigen::Vector3d(1, 0, 3),
                                           Eigen::Vector3d(2, 0, 4)};
  std::array<Eigen::Vector3d, 3> bearings;
  for (int i = 0; i < 3; ++i) bearings[i] = points[i].normalized();
  std::vector<Pose> solutions;
  EXPECT_EQ(solveP3P(bearings, points, &solutions), 0);
  EXPECT_TRUE(solutions.empty());
}

// Three rays along one direction, or 1e-12 to 1e-6 apart, with a proper triangle of points: the
// construction gave matrices 1e-4 to 1.7 off orthonormal (determinant ~0 for one direction), and
// LO-RANSAC reported one as a pose. Whatever is returned is a rotation.
TEST(P3P, NearlyCoincidentRaysGiveOnlyRotations) {
  const std::array<Eigen::Vector3d, 3> points = {Eigen::Vector3d(0, 0, 4), Eigen::Vector3d(1, 0, 5),
                                                 Eigen::Vector3d(0, 1, 3)};
  const Eigen::Vector3d ray = Eigen::Vector3d(0.1, -0.05, 1).normalized();
  std::vector<Pose> solutions;
  for (double apart : {0.0, 1e-12, 1e-9, 1e-6})
    solveP3P({ray, (ray + Eigen::Vector3d(apart, 0, 0)).normalized(), (ray + Eigen::Vector3d(0, apart, 0)).normalized()},
             points, &solutions);
  for (const Pose& pose : solutions) {
    EXPECT_LT(orthogonalityError(pose.R), 1e-6);
    EXPECT_GT(pose.R.determinant(), 0);
  }
}

}  // namespace
}  // namespace ffloc
