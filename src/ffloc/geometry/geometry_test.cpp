#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>

#include "ffloc/core/error.h"
#include "ffloc/geometry/camera.h"
#include "ffloc/geometry/normalization.h"
#include "ffloc/geometry/pose.h"
#include "ffloc/geometry/rays.h"

namespace ffloc {
namespace {

Pose randomPose(std::mt19937& rng, double translation_scale = 3.0) {
  std::normal_distribution<double> n(0.0, 1.0);
  Eigen::Quaterniond q(n(rng), n(rng), n(rng), n(rng));
  q.normalize();
  Pose p;
  p.R = q.toRotationMatrix();
  p.t = Eigen::Vector3d(n(rng), n(rng), n(rng)) * translation_scale;
  return p;
}

TEST(Pose, InverseAndComposition) {
  std::mt19937 rng(1);
  const Pose a = randomPose(rng), b = randomPose(rng);
  EXPECT_LT(((a * a.inverse()).matrix() - Eigen::Matrix4d::Identity()).norm(), 1e-12);
  EXPECT_LT(((a * b).matrix() - a.matrix() * b.matrix()).norm(), 1e-12);
  const Eigen::Vector3d x(0.3, -1.2, 2.0);
  EXPECT_LT(((a * b) * x - a * (b * x)).norm(), 1e-12);
}

TEST(Pose, QuaternionRoundTrip) {
  std::mt19937 rng(2);
  const Pose a = randomPose(rng);
  const Eigen::Quaterniond q = a.quaternion();
  const Pose b = Pose::fromQuaternion(q.w(), q.x(), q.y(), q.z(), a.t);
  EXPECT_LT((a.matrix() - b.matrix()).norm(), 1e-12);
  // A 90 degree turn about z, scalar first.
  const Pose z90 = Pose::fromQuaternion(std::sqrt(0.5), 0, 0, std::sqrt(0.5), Eigen::Vector3d::Zero());
  EXPECT_LT((z90 * Eigen::Vector3d(1, 0, 0) - Eigen::Vector3d(0, 1, 0)).norm(), 1e-12);
}

TEST(Pose, Errors) {
  Pose a;
  Pose b;
  b.R = Eigen::AngleAxisd(10.0 * M_PI / 180.0, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  b.t = Eigen::Vector3d(0.03, 0.04, 0);
  EXPECT_NEAR(rotationErrorDeg(a, b), 10.0, 1e-9);
  EXPECT_NEAR(translationError(a, b), 0.05, 1e-12);
  // Accurate for tiny and near-half-turn angles, where acos(trace) is not.
  b.R = Eigen::AngleAxisd(1e-7, Eigen::Vector3d::UnitY()).toRotationMatrix();
  EXPECT_NEAR(rotationErrorDeg(a, b), 1e-7 * 180.0 / M_PI, 1e-12);
  b.R = Eigen::AngleAxisd(M_PI - 1e-4, Eigen::Vector3d::UnitX()).toRotationMatrix();
  EXPECT_NEAR(rotationErrorDeg(a, b), 180.0 - 1e-4 * 180.0 / M_PI, 1e-6);
}

TEST(Pose, ProjectToRotation) {
  Eigen::Matrix3d R = Eigen::AngleAxisd(0.4, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  R(0, 0) += 1e-5;  // digits lost in a text file
  EXPECT_TRUE(projectToRotation(R));
  EXPECT_LT((R.transpose() * R - Eigen::Matrix3d::Identity()).norm(), 1e-12);
  Eigen::Matrix3d bad = Eigen::Matrix3d::Identity() * 2.0;
  EXPECT_FALSE(projectToRotation(bad));
  Eigen::Matrix3d reflection = Eigen::Matrix3d::Identity();
  reflection(2, 2) = -1;
  EXPECT_FALSE(projectToRotation(reflection));
  Eigen::Matrix3d nan = Eigen::Matrix3d::Identity();
  nan(1, 1) = std::numeric_limits<double>::quiet_NaN();
  EXPECT_FALSE(projectToRotation(nan));
}

TEST(Intrinsics, ProjectBackproject) {
  Intrinsics c{585, 585, 320, 240, 640, 480, {}};
  const Eigen::Vector3d p(0.2, -0.1, 2.5);
  const Eigen::Vector2d uv = c.project(p);
  EXPECT_LT((c.backproject(uv, 2.5) - p).norm(), 1e-12);
}

TEST(Intrinsics, ScaleKeepsPixelEdges) {
  Intrinsics c{500, 500, 319.5, 239.5, 640, 480, {}};  // principal point at the image centre
  const Intrinsics half = c.scaled(0.5, 0.5, 320, 240);
  EXPECT_DOUBLE_EQ(half.cx, 159.5);  // still the centre of the 320-wide image
  EXPECT_DOUBLE_EQ(half.fx, 250);
  const Intrinsics crop = c.cropped(10, 20, 600, 440);
  EXPECT_DOUBLE_EQ(crop.cx, 309.5);
  EXPECT_DOUBLE_EQ(crop.cy, 219.5);
}

TEST(Intrinsics, UndistortPixelsInvertsDistortion) {
  Intrinsics c{1375.52, 1374.49, 554.558, 965.268, 1080, 1920, {0.0578421, -0.0805099, -0.000980296, 0.00015575}};
  // Distort ideal pixels with the OpenCV model, then undistort them back.
  std::vector<Eigen::Vector2d> ideal = {{100, 100}, {540, 960}, {1000, 1800}, {20, 1900}};
  std::vector<Eigen::Vector2d> distorted;
  for (const auto& p : ideal) {
    const double x = (p.x() - c.cx) / c.fx, y = (p.y() - c.cy) / c.fy;
    const double r2 = x * x + y * y;
    const double radial = 1 + c.distortion[0] * r2 + c.distortion[1] * r2 * r2;
    const double p1 = c.distortion[2], p2 = c.distortion[3];
    const double xd = x * radial + 2 * p1 * x * y + p2 * (r2 + 2 * x * x);
    const double yd = y * radial + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y;
    distorted.emplace_back(xd * c.fx + c.cx, yd * c.fy + c.cy);
  }
  const auto recovered = undistortPixels(c, distorted);
  for (size_t i = 0; i < ideal.size(); ++i) EXPECT_LT((recovered[i] - ideal[i]).norm(), 1e-3) << i;
  EXPECT_FALSE(c.undistorted().hasDistortion());
}

// Distortion is judged by what it does over the image, not coefficient by coefficient.
TEST(Intrinsics, DistortionProblemJudgesWhatTheModelDoesOverTheImage) {
  const auto camera = [](double f, std::vector<double> distortion) {
    return Intrinsics{f, f, 319.5, 239.5, 640, 480, std::move(distortion)};
  };
  // A 60 mm macro lens's weakly constrained high-order terms: huge, and 1.2 px at the corner.
  EXPECT_EQ(distortionProblem(camera(8000, {0, -500, 0, 0, 300})), "");
  // A wide-angle rational-model calibration (k1 k2 p1 p2 k3 k4 k5 k6).
  EXPECT_EQ(distortionProblem(camera(300, {25, 10, 0, 0, 0, 25, 15, 0})), "");
  EXPECT_EQ(distortionProblem(camera(500, {-0.28, 0.07, 1e-4, -2e-4})), "");
  // instant_ngp_fox's phone camera.
  EXPECT_EQ(distortionProblem({1375.52, 1374.49, 554.058, 964.768, 1080, 1920,
                               {0.0578421, -0.0805099, -0.000980296, 0.00015575}}),
            "");

  EXPECT_EQ(distortionProblem(camera(500, {1e10, 0, 0, 0})),
            "k1 1e+10: moves the image corner (0, 0) by 2.5e+12 px, more than the 640x480 image's diagonal "
            "(800 px): no lens's distortion does");
  // A principal point in k1's column, printed as read.
  EXPECT_NE(distortionProblem(camera(500, {320.0000001, 0, 0, 0})).find("k1 320.0000001: moves the image corner"),
            std::string::npos);
  EXPECT_NE(distortionProblem(camera(500, {-320, 0, 0, 0})).find("k1 -320: moves the image corner"), std::string::npos);
  EXPECT_EQ(distortionProblem(camera(500, {0.1, std::nan(""), 0, 0})), "k2 nan: distortion coefficients must be finite");
  EXPECT_EQ(distortionProblem(camera(500, {0.1, 0, 0, 0, 0, 0, 0, -std::numeric_limits<double>::infinity()})),
            "k6 -inf: distortion coefficients must be finite");
  // Within the diagonal at the border, but turning back on the way there: k1 = -1 at r = 0.8.
  const std::string fold = distortionProblem(camera(500, {-1, 0, 0, 0}));
  EXPECT_NE(fold.find("k1 -1: folds the image: on the way from the principal point to the image edge's midpoint"),
            std::string::npos)
      << fold;
  // A wide lens's calibration turning back only in the corners (k1 = -0.4 beyond r = 0.91; the
  // corner is at r = 1, the edges' midpoints at 0.8 and 0.6), and a principal point on an edge.
  EXPECT_EQ(distortionProblem(camera(400, {-0.4, 0, 0, 0})), "");
  EXPECT_EQ(distortionProblem({500, 500, 0, 239.5, 640, 480, {-0.1, 0, 0, 0}}), "");
  // A rational model whose denominator vanishes inside the image.
  EXPECT_NE(distortionProblem(camera(500, {0, 0, 0, 0, 0, -2, 0, 0})).find("k4 -2: "), std::string::npos);
  // Judged over the image the pinhole part describes: over another (the principal point in other
  // units) a real lens was blamed; a focal length of a few pixels is named beside the coefficients.
  EXPECT_EQ(distortionProblem({500, 500, 6400, 239.5, 640, 480, {0.05, -0.08, 0, 0}}), "");
  EXPECT_EQ(distortionProblem({500, 500, 319.5, 239.5, 640, 480, {0.05, -0.08, 0, 0}}), "");
  const std::string short_focal = distortionProblem(camera(5, {0.05, -0.08, 0, 0}));
  EXPECT_NE(short_focal.find("k1 0.05, k2 -0.08: moves the image corner"), std::string::npos) << short_focal;
  EXPECT_NE(short_focal.find("; or the focal length is wrong: fx 5, fy 5 put that point 79.9 focal lengths from the "
                             "principal point, 179 deg across"),
            std::string::npos)
      << short_focal;
  EXPECT_EQ(distortionProblem(camera(500, {1e10, 0, 0, 0})).find("focal length is wrong"), std::string::npos);
  // Without a size only the numbers themselves can be judged.
  EXPECT_EQ(distortionProblem(Intrinsics{500, 500, 319.5, 239.5, 0, 0, {1e10, 0, 0, 0}}), "");
  EXPECT_THROW(checkIntrinsicsFitImage(Intrinsics{500, 500, 319.5, 239.5, 0, 0, {1e10, 0, 0, 0}}, 640, 480),
               InputError);
}

// Pixel centres at integers, a 640 x 480 image spans [-0.5, 639.5] x [-0.5, 479.5]; corners
// there, [0, 640] x [0, 480]. Either convention's principal point is taken, nothing beyond.
TEST(Intrinsics, ThePrincipalPointMayLieAnywhereOnTheImageAndNowhereElse) {
  auto fits = [](double cx, double cy) {
    try {
      checkIntrinsicsFitImage(Intrinsics{500, 500, cx, cy, 640, 480, {}}, 640, 480);
      return true;
    } catch (const InputError&) {
      return false;
    }
  };
  EXPECT_TRUE(fits(319.5, 239.5));
  EXPECT_TRUE(fits(-0.4, 479.5));
  EXPECT_TRUE(fits(639.5, -0.5));
  EXPECT_TRUE(fits(640, 480));
  EXPECT_FALSE(fits(640.1, 239.5));
  EXPECT_FALSE(fits(319.5, 480.1));
  EXPECT_FALSE(fits(-0.6, 239.5));
}

TEST(Normalization, ReferenceAtOriginAndUnitScale) {
  std::mt19937 rng(3);
  std::vector<Pose> poses;
  for (int i = 0; i < 6; ++i) poses.push_back(randomPose(rng, 4.0));
  const auto n = SceneNormalization::fromMappingPoses(poses, 2);
  const Pose ref = n.normalize(poses[2]);
  EXPECT_LT((ref.matrix() - Eigen::Matrix4d::Identity()).norm(), 1e-12);
  double largest = 0;
  for (const Pose& p : poses) largest = std::max(largest, n.normalize(p).t.cwiseAbs().maxCoeff());
  EXPECT_NEAR(largest, 1.0, 1e-12);
  // Points: normalise then back to world is the identity, and consistent with poses.
  const Eigen::Vector3d x(1.5, -2.0, 0.25);
  EXPECT_LT((n.toWorld(n.normalize(x)) - x).norm(), 1e-12);
  const Pose back = n.denormalize(n.normalize(poses[4]));
  EXPECT_LT((back.matrix() - poses[4].matrix()).norm(), 1e-12);
  // A point seen by camera 4 at camera-frame position c stays at c in the normalised camera.
  const Eigen::Vector3d in_camera(0.1, 0.2, 1.0);
  const Pose normalized_camera = n.normalize(poses[4]);
  EXPECT_LT((normalized_camera.inverse() * n.normalize(poses[4] * in_camera) - in_camera / n.scale).norm(), 1e-12);
}

TEST(Normalization, InvariantToWorldSimilarity) {
  std::mt19937 rng(4);
  std::vector<Pose> poses;
  for (int i = 0; i < 5; ++i) poses.push_back(randomPose(rng));
  const Pose motion = randomPose(rng);
  const double scale = 7.5;
  std::vector<Pose> moved;
  for (Pose p : poses) {
    p.t *= scale;
    moved.push_back(motion * p);
  }
  const auto a = SceneNormalization::fromMappingPoses(poses);
  const auto b = SceneNormalization::fromMappingPoses(moved);
  EXPECT_NEAR(b.scale, a.scale * scale, 1e-9);
  for (size_t i = 0; i < poses.size(); ++i)
    EXPECT_LT((a.normalize(poses[i]).matrix() - b.normalize(moved[i]).matrix()).norm(), 1e-9);
}

TEST(Normalization, DegenerateCasesHaveUnitScale) {
  Pose only;
  only.t = Eigen::Vector3d(5, 6, 7);
  auto n = SceneNormalization::fromMappingPoses({only});
  EXPECT_EQ(n.scale, 1.0);
  Pose rotated = only;
  rotated.R = Eigen::AngleAxisd(0.5, Eigen::Vector3d::UnitY()).toRotationMatrix();
  n = SceneNormalization::fromMappingPoses({only, rotated});  // same centre, s would be 0
  EXPECT_EQ(n.scale, 1.0);
  EXPECT_TRUE(n.normalize(rotated).t.isZero(1e-12));
}

TEST(Normalization, RejectsNonFinitePoseNamingFrame) {
  Pose bad;
  bad.t.x() = std::numeric_limits<double>::quiet_NaN();
  try {
    SceneNormalization::fromMappingPoses({Pose(), bad}, 0, {"a.png", "b.png"});
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("b.png"), std::string::npos) << e.what();
  }
  EXPECT_THROW(SceneNormalization::fromMappingPoses({}), InputError);
}

TEST(Rays, PatchCentresFollowThePaperDefinition) {
  Intrinsics c{400, 410, 255.5, 191.5, 512, 384, {}};
  std::mt19937 rng(5);
  const Pose pose = randomPose(rng);
  const auto rays = patchRays(c, pose, 16);
  ASSERT_EQ(rays.size(), 32u * 24u);
  // Token n = row n / 32, col n % 32; direction = (K R^-1)^-1 [u v 1] with R^-1 the world-to-camera rotation.
  const int n = 5 * 32 + 7;
  const Eigen::Vector3d uv1(7 * 16 + 7.5, 5 * 16 + 7.5, 1.0);
  const Eigen::Vector3d expected = (c.K() * pose.R.transpose()).inverse() * uv1;
  EXPECT_LT((rays[n].direction - expected).norm(), 1e-12);
  EXPECT_LT((rays[n].origin - pose.t).norm(), 1e-12);
  // The ray passes through the point it was cast from.
  const Eigen::Vector3d world_point = rays[n].origin + 2.0 * rays[n].direction;
  const Eigen::Vector2d reprojected = c.project(pose.inverse() * world_point);
  EXPECT_LT((reprojected - uv1.head<2>()).norm(), 1e-9);
}

}  // namespace
}  // namespace ffloc
