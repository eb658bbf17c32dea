// Both solvers on real 7-Scenes geometry: pairs from the ground-truth depth and pose of query
// frames of redkitchen, 1 px pixel noise, 30% of the world points replaced by random points.
#include <gtest/gtest.h>

#include <cstdio>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <random>

#include "ffloc/core/testing/shared_data.h"
#include "ffloc/pose/pnp.h"

namespace ffloc {
namespace {

Intrinsics redkitchenCamera() {
  Intrinsics camera;
  camera.fx = camera.fy = 585;
  camera.cx = 320;
  camera.cy = 240;
  camera.width = 640;
  camera.height = 480;
  return camera;
}

Pose readPose(const std::filesystem::path& path) {
  std::ifstream in(path);
  Eigen::Matrix4d T;
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c) in >> T(r, c);
  EXPECT_TRUE(in) << path;
  return Pose::fromMatrix(T);
}

struct RealQuery {
  Pose camera_to_world;
  Correspondences correspondences;
  int outliers = 0;
};

RealQuery makeQuery(const std::filesystem::path& dir, int frame, int count, uint64_t seed) {
  char stem[32];
  std::snprintf(stem, sizeof(stem), "frame-%06d", frame);
  RealQuery q;
  q.camera_to_world = readPose(dir / (std::string(stem) + ".pose.txt"));
  const cv::Mat depth = cv::imread((dir / (std::string(stem) + ".depth.png")).string(), cv::IMREAD_ANYDEPTH);
  EXPECT_EQ(depth.type(), CV_16UC1) << stem;
  if (depth.type() != CV_16UC1) return q;

  std::vector<cv::Point> valid;
  for (int v = 0; v < depth.rows; ++v)
    for (int u = 0; u < depth.cols; ++u) {
      const uint16_t d = depth.at<uint16_t>(v, u);
      if (d != 0 && d != 65535) valid.emplace_back(u, v);
    }
  std::mt19937_64 rng(seed);
  std::shuffle(valid.begin(), valid.end(), rng);
  valid.resize(std::min<size_t>(valid.size(), count));

  const Intrinsics camera = redkitchenCamera();
  std::normal_distribution<double> noise(0, 1.0);
  for (const cv::Point& p : valid) {
    const Eigen::Vector2d pixel(p.x, p.y);
    const Eigen::Vector3d point = q.camera_to_world * camera.backproject(pixel, 0.001 * depth.at<uint16_t>(p));
    q.correspondences.add(pixel + Eigen::Vector2d(noise(rng), noise(rng)), point, 2.0f);
  }
  Eigen::Vector3d low = q.correspondences.points.front(), high = low;
  for (const Eigen::Vector3d& p : q.correspondences.points) {
    low = low.cwiseMin(p);
    high = high.cwiseMax(p);
  }
  std::uniform_real_distribution<double> unit(0, 1);
  for (Eigen::Vector3d& p : q.correspondences.points) {
    if (unit(rng) >= 0.3) continue;
    p = low + (high - low).cwiseProduct(Eigen::Vector3d(unit(rng), unit(rng), unit(rng)));
    ++q.outliers;
  }
  return q;
}

TEST(PnpRedkitchen, BothSolversRecoverQueryPosesFromDepthWithOutliers) {
  FFLOC_REQUIRE_SHARED(dir, "data/7scenes_redkitchen");
  for (int frame : {600, 700, 800, 900, 996}) {
    const RealQuery q = makeQuery(dir, frame, 3000, frame);
    ASSERT_EQ(q.correspondences.size(), 3000u) << frame;
    const int inliers = static_cast<int>(q.correspondences.size()) - q.outliers;
    for (PnpSolver solver : {PnpSolver::kLoRansac, PnpSolver::kOpenCvUsac}) {
      PnpOptions options;
      options.solver = solver;
      const PnpResult result = estimatePose(q.correspondences, redkitchenCamera(), options);
      ASSERT_TRUE(result.ok()) << toString(solver) << " frame " << frame << ": " << toString(result.status);
      EXPECT_LT(translationError(result.camera_to_world, q.camera_to_world), 0.05) << toString(solver) << " frame " << frame;
      EXPECT_LT(rotationErrorDeg(result.camera_to_world, q.camera_to_world), 5.0) << toString(solver) << " frame " << frame;
      EXPECT_GE(result.inliers, inliers * 99 / 100) << toString(solver) << " frame " << frame;
      EXPECT_EQ(result.used_correspondences, 3000);
    }
  }
}

}  // namespace
}  // namespace ffloc
