#include "ffloc/synthetic/synthetic.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <iterator>
#include <map>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <set>

#include "ffloc/core/error.h"
#include "ffloc/core/testing/shared_data.h"
#include "ffloc/data/depth.h"
#include "ffloc/data/manifest.h"
#include "ffloc/data/overlap.h"
#include "ffloc/synthetic/det_math.h"
#include "ffloc/synthetic/shapes.h"

namespace ffloc {
namespace {

using synthetic::Vec3;

SyntheticOptions smallOptions(SceneKind kind, uint64_t seed) {
  SyntheticOptions options;
  options.kind = kind;
  options.seed = seed;
  options.width = 160;
  options.height = 120;
  options.mapping_frames = 10;
  options.query_frames = 6;
  return options;
}

std::string readBytes(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

// Every file under `dir`, by relative path.
std::map<std::string, std::string> readTree(const std::filesystem::path& dir) {
  std::map<std::string, std::string> files;
  for (const auto& entry : std::filesystem::recursive_directory_iterator(dir))
    if (entry.is_regular_file())
      files[entry.path().lexically_relative(dir).generic_string()] = readBytes(entry.path());
  return files;
}

class EveryKind : public ::testing::TestWithParam<SceneKind> {};

// The acceptance test for exact geometry: a pixel of view A back-projected with A's stored
// depth (float32 TIFF) and A's pose (from the manifest) lands, in every other view B where it
// is visible, on the surface B's ray through that (sub-pixel) point hits. The only other
// outcome allowed is occlusion: B sees something nearer.
TEST_P(EveryKind, DepthAndPosesReprojectConsistently) {
  const SyntheticOptions options = smallOptions(GetParam(), 11);
  const auto dir = testing::makeTempDir("ffloc-synth-consistency");
  const Scene scene = generateSyntheticScene(options, dir);
  const SyntheticScene plan = planSyntheticScene(options);
  ASSERT_EQ(static_cast<int>(scene.frames.size()), plan.frameCount());

  std::vector<cv::Mat1f> depths;
  for (const auto& frame : scene.frames) depths.push_back(readDepthMetres(frame));
  size_t occluded = 0, inconsistent = 0, checked = 0;
  std::vector<double> errors;  // relative depth disagreement of the visible points
  for (size_t a = 0; a < scene.frames.size(); a += 3) {
    const Frame& fa = scene.frames[a];
    for (size_t b = 0; b < scene.frames.size(); ++b) {
      if (a == b) continue;
      const Frame& fb = scene.frames[b];
      const Pose b_from_a = fb.camera_to_world.inverse() * fa.camera_to_world;
      for (int v = 1; v < depths[a].rows; v += 7) {
        for (int u = 2; u < depths[a].cols; u += 7) {
          const double d = depths[a](v, u);
          if (d <= 0.0) continue;
          const Eigen::Vector3d in_b = b_from_a * fa.intrinsics.backproject({u, v}, d);
          if (in_b.z() <= 1e-3) continue;
          const Eigen::Vector2d p = fb.intrinsics.project(in_b);
          if (p.x() < -0.5 || p.y() < -0.5 || p.x() >= fb.intrinsics.width - 0.5 ||
              p.y() >= fb.intrinsics.height - 0.5)
            continue;
          ++checked;
          const double seen = synthetic::castDepth(plan.layout.world, fb.intrinsics,
                                                   fb.camera_to_world, p.x(), p.y());
          const double relative = (seen - in_b.z()) / in_b.z();
          if (seen > 0.0 && std::fabs(relative) <= 1e-4) {
            errors.push_back(std::fabs(relative));
          } else if (seen > 0.0 && relative < 0.0) {
            ++occluded;
          } else {
            ++inconsistent;
          }
        }
      }
    }
  }
  SCOPED_TRACE(toString(GetParam()));
  EXPECT_GT(checked, 2000u);
  EXPECT_GT(errors.size(), checked / 4);
  EXPECT_GT(occluded, 0u);
  // Float depth moves a point by up to 6e-8 of its depth along A's ray; B, seeing the surface
  // at a grazing angle, magnifies that (up to ~1e-5 here), and on a silhouette the ray could
  // in principle slip past the edge, hence a tiny allowance.
  EXPECT_LE(inconsistent, checked / 2000) << inconsistent << " of " << checked;
  std::sort(errors.begin(), errors.end());
  EXPECT_LT(errors[errors.size() / 2], 2e-7);
  EXPECT_LT(errors[errors.size() * 99 / 100], 2e-6);
  std::filesystem::remove_all(dir);
}

TEST_P(EveryKind, DepthMapIsTheRayParameterAtPixelCentres) {
  const SyntheticOptions options = smallOptions(GetParam(), 5);
  const SyntheticScene plan = planSyntheticScene(options);
  for (int f : {0, plan.frameCount() - 1}) {
    const auto view = renderSyntheticFrame(plan, f);
    for (int v = 0; v < view.depth.rows; v += 5)
      for (int u = 0; u < view.depth.cols; u += 5)
        ASSERT_EQ(view.depth(v, u), static_cast<float>(synthetic::castDepth(
                                        plan.layout.world, plan.camera, plan.pose(f), u, v)))
            << "frame " << f << " pixel " << u << "," << v;
  }
}

TEST_P(EveryKind, RendersAVariedSceneWithBothSplits) {
  const SyntheticOptions options = smallOptions(GetParam(), 3);
  const auto dir = testing::makeTempDir("ffloc-synth-kind");
  const Scene scene = generateSyntheticScene(options, dir);
  EXPECT_EQ(scene.format, "manifest");
  EXPECT_TRUE(scene.metric);
  EXPECT_EQ(scene.mappingIndices().size(), 10u);
  EXPECT_EQ(scene.queryIndices().size(), 6u);
  EXPECT_TRUE(std::filesystem::exists(dir / "synthetic.json"));
  for (const auto& frame : scene.frames) {
    SCOPED_TRACE(frame.name);
    const cv::Mat image = cv::imread(frame.image_path.string(), cv::IMREAD_COLOR);
    ASSERT_EQ(image.cols, 160);
    ASSERT_EQ(image.rows, 120);
    cv::Mat grey;
    cv::cvtColor(image, grey, cv::COLOR_BGR2GRAY);
    cv::Scalar mean, stddev;
    cv::meanStdDev(grey, mean, stddev);
    EXPECT_GT(stddev[0], 8.0);  // not a flat image
    EXPECT_GT(mean[0], 30.0);   // not black
    std::set<int> colours;
    for (int v = 0; v < image.rows; ++v)
      for (int u = 0; u < image.cols; ++u) {
        const auto& p = image.at<cv::Vec3b>(v, u);
        colours.insert(p[0] << 16 | p[1] << 8 | p[2]);
      }
    EXPECT_GT(colours.size(), 400u);  // shading and texture, not a few flat colours
    const cv::Mat1f depth = readDepthMetres(frame);
    const double valid = cv::countNonZero(depth > 0.0f) / static_cast<double>(depth.total());
    // Rooms are closed; outdoors the sky has no depth.
    EXPECT_GT(valid, GetParam() == SceneKind::kOutdoor ? 0.3 : 0.999);
  }
  std::filesystem::remove_all(dir);
}

TEST_P(EveryKind, QueriesAreNearFarAndOpposite) {
  SyntheticOptions options = smallOptions(GetParam(), 9);
  options.mapping_frames = 30;
  options.query_frames = 9;
  const SyntheticScene plan = planSyntheticScene(options);
  const auto& kinds = plan.layout.queries.kinds;
  const int m = options.mapping_frames;
  double near_distance = 0, far_distance = 0;
  int near = 0, far = 0, opposite = 0;
  for (int q = 0; q < options.query_frames; ++q) {
    const Pose query = plan.pose(m + q);
    double closest = 1e300, facing = -1.0;
    for (int i = 0; i < m; ++i) {
      const Pose map = plan.pose(i);
      const double d = (map.t - query.t).norm();
      if (d < closest) {
        closest = d;
        facing = map.R.col(2).dot(query.R.col(2));
      }
    }
    switch (kinds[q]) {
      case synthetic::QueryKind::kNear: near_distance += closest; ++near; break;
      case synthetic::QueryKind::kFar: far_distance += closest; ++far; break;
      case synthetic::QueryKind::kOpposite:
        ++opposite;
        EXPECT_LT(facing, 0.0) << "an opposite query looks the way its nearest mapping view does";
        break;
    }
  }
  ASSERT_GT(near, 0);
  ASSERT_GT(far, 0);
  EXPECT_GT(opposite, 0);
  EXPECT_GT(far_distance / far, 2.0 * near_distance / near);
}

TEST_P(EveryKind, QueriesAreLitDifferently) {
  const SyntheticOptions options = smallOptions(GetParam(), 21);
  SyntheticScene plan = planSyntheticScene(options);
  const int query = options.mapping_frames;
  const auto relit = renderSyntheticFrame(plan, query);
  plan.layout.query_lighting[0] = plan.layout.mapping_lighting;
  const auto as_mapped = renderSyntheticFrame(plan, query);
  EXPECT_EQ(cv::norm(relit.depth, as_mapped.depth, cv::NORM_INF), 0.0);
  cv::Mat difference;
  cv::absdiff(relit.rgb, as_mapped.rgb, difference);
  EXPECT_GT(cv::mean(difference)[0] + cv::mean(difference)[1] + cv::mean(difference)[2], 6.0);
}

TEST_P(EveryKind, MappingNeighboursOverlapMoreThanDistantFrames) {
  SyntheticOptions options = smallOptions(GetParam(), 4);
  options.mapping_frames = 40;
  options.query_frames = 0;
  const SyntheticScene plan = planSyntheticScene(options);
  std::vector<Frame> frames(3);
  std::vector<cv::Mat1f> depths;
  const int indices[3] = {0, 1, 20};
  for (int i = 0; i < 3; ++i) {
    frames[i].name = plan.imageName(indices[i]);
    frames[i].intrinsics = plan.camera;
    frames[i].camera_to_world = plan.pose(indices[i]);
    depths.push_back(renderSyntheticFrame(plan, indices[i]).depth);
  }
  const double neighbours = pairOverlap(frames[0], depths[0], frames[1], depths[1]);
  const double across = pairOverlap(frames[0], depths[0], frames[2], depths[2]);
  EXPECT_GT(neighbours, 0.5);
  EXPECT_LT(across, neighbours);
}

INSTANTIATE_TEST_SUITE_P(Synthetic, EveryKind,
                         ::testing::Values(SceneKind::kIndoor, SceneKind::kOutdoor,
                                           SceneKind::kObject),
                         [](const auto& info) { return std::string(toString(info.param)); });

TEST(Synthetic, SameSeedGivesIdenticalBytes) {
  SyntheticOptions options = smallOptions(SceneKind::kOutdoor, 77);
  options.image_noise = 2.0;
  options.depth_noise = 0.01;
  // Same folder name: the manifest records it as the scene name.
  const auto first = testing::makeTempDir("ffloc-synth-a") / "scene";
  const auto second = testing::makeTempDir("ffloc-synth-b") / "scene";
  generateSyntheticScene(options, first);
  options.threads = 2;  // thread count must not matter
  generateSyntheticScene(options, second);
  const auto a = readTree(first), b = readTree(second);
  ASSERT_EQ(a.size(), 2u * 16u + 2u);  // images, depth maps, manifest.json, synthetic.json
  for (const auto& [name, bytes] : a) {
    ASSERT_TRUE(b.count(name)) << name;
    EXPECT_TRUE(bytes == b.at(name)) << name << " differs between two runs";
  }
  options.seed = 78;
  const auto third = testing::makeTempDir("ffloc-synth-c") / "scene";
  generateSyntheticScene(options, third);
  EXPECT_NE(readBytes(first / "images/mapping_0000.png"), readBytes(third / "images/mapping_0000.png"));
  for (const auto& dir : {first, second, third}) std::filesystem::remove_all(dir.parent_path());
}

TEST(Synthetic, ManifestPosesAreThePlannedPosesBitForBit) {
  const SyntheticOptions options = smallOptions(SceneKind::kObject, 2);
  const auto dir = testing::makeTempDir("ffloc-synth-poses");
  generateSyntheticScene(options, dir);
  const Scene scene = readManifest(dir / kManifestFileName);
  const SyntheticScene plan = planSyntheticScene(options);
  ASSERT_EQ(static_cast<int>(scene.frames.size()), plan.frameCount());
  for (int f = 0; f < plan.frameCount(); ++f) {
    EXPECT_TRUE(scene.frames[f].camera_to_world.matrix() == plan.pose(f).matrix()) << f;
    EXPECT_EQ(scene.frames[f].intrinsics.fx, plan.camera.fx);
    EXPECT_EQ(scene.frames[f].split, plan.isQuery(f) ? Split::kQuery : Split::kMapping);
    // Camera-to-world rotations are proper rotations.
    EXPECT_NEAR(plan.pose(f).R.determinant(), 1.0, 1e-12);
  }
  std::filesystem::remove_all(dir);
}

TEST(Synthetic, NoiseOptionsPerturbOnlyWhatTheySay) {
  SyntheticOptions options = smallOptions(SceneKind::kIndoor, 8);
  const auto clean = renderSyntheticFrame(planSyntheticScene(options), 0);
  options.image_noise = 3.0;
  const auto noisy = renderSyntheticFrame(planSyntheticScene(options), 0);
  EXPECT_EQ(cv::norm(clean.depth, noisy.depth, cv::NORM_INF), 0.0);
  EXPECT_GT(cv::norm(clean.rgb, noisy.rgb, cv::NORM_L1), 0.0);
  options.image_noise = 0.0;
  options.depth_noise = 0.01;
  const auto bumpy = renderSyntheticFrame(planSyntheticScene(options), 0);
  EXPECT_EQ(cv::norm(clean.rgb, bumpy.rgb, cv::NORM_INF), 0.0);
  const double relative = cv::norm(clean.depth - bumpy.depth, cv::NORM_L2) / cv::norm(clean.depth, cv::NORM_L2);
  EXPECT_GT(relative, 0.003);
  EXPECT_LT(relative, 0.03);
}

TEST(Synthetic, RejectsBadOptions) {
  EXPECT_THROW(parseSceneKind("garden"), InputError);
  EXPECT_EQ(parseSceneKind("object"), SceneKind::kObject);
  SyntheticOptions options;
  options.width = 0;
  EXPECT_THROW(planSyntheticScene(options), InputError);
  options = SyntheticOptions();
  options.mapping_frames = 1;
  EXPECT_THROW(planSyntheticScene(options), InputError);
  options = SyntheticOptions();
  options.min_fov_deg = 90;
  options.max_fov_deg = 60;
  EXPECT_THROW(planSyntheticScene(options), InputError);
  options = SyntheticOptions();
  options.image_noise = -1;
  EXPECT_THROW(planSyntheticScene(options), InputError);
  try {
    parseSceneKind("garden", "--kind");
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("--kind"), std::string::npos);
    EXPECT_NE(std::string(e.what()).find("garden"), std::string::npos);
  }
}

// 100000000 mapping frames took 3.9 GB in 8 s with nothing written: refused by the option check.
TEST(Synthetic, FrameCountsBeyondTheirBoundAreRefusedNamingTheField) {
  for (const auto& [field, frames] : std::vector<std::pair<std::string, int>>{
           {"mapping_frames", kMaxSyntheticFrames + 1}, {"mapping_frames", 100000000},
           {"query_frames", kMaxSyntheticFrames + 1}, {"query_frames", -1}}) {
    SyntheticOptions options;
    (field == "mapping_frames" ? options.mapping_frames : options.query_frames) = frames;
    try {
      planSyntheticScene(options);
      ADD_FAILURE() << field << " = " << frames << " accepted";
    } catch (const InputError& e) {
      EXPECT_EQ(std::string(e.what()).rfind(field + ": must be in [", 0), 0u) << e.what();
    }
  }
  SyntheticOptions at_bound;
  at_bound.mapping_frames = kMaxSyntheticFrames;
  at_bound.query_frames = kMaxSyntheticFrames;
  EXPECT_NO_THROW(validate(at_bound));
}

// A scene written over an earlier one replaced its manifest and kept the earlier frames the new
// one did not overwrite, mixing two scenes in one folder.
TEST(Synthetic, ANonEmptyFolderIsRefusedAndKeptAsItWas) {
  const auto dir = testing::makeTempDir("ffloc-synth-nonempty");
  std::ofstream(dir / "earlier.txt") << "kept";
  SyntheticOptions options = smallOptions(SceneKind::kIndoor, 3);
  options.mapping_frames = 2;
  options.query_frames = 0;
  try {
    generateSyntheticScene(options, dir);
    ADD_FAILURE() << "a non-empty folder accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find(dir.string() + ": output folder is not empty"), std::string::npos) << e.what();
  }
  EXPECT_EQ(readTree(dir), (std::map<std::string, std::string>{{"earlier.txt", "kept"}}));
  std::filesystem::remove_all(dir);
}

TEST(SyntheticMath, DeterministicSineAndCosineMatchLibm) {
  for (double x = -40.0; x <= 40.0; x += 0.0137) {
    EXPECT_NEAR(synthetic::detSin(x), std::sin(x), 4e-15) << x;
    EXPECT_NEAR(synthetic::detCos(x), std::cos(x), 4e-15) << x;
  }
}

TEST(SyntheticShapes, RaysHitEachPrimitiveWhereExpected) {
  using synthetic::Shape;
  using synthetic::ShapeKind;
  auto hit = [](ShapeKind kind, const Vec3& half, const synthetic::Ray& ray) {
    Shape s;
    s.kind = kind;
    s.half = half;
    double t = -1;
    Vec3 n;
    return synthetic::intersect(s, ray, 0.0, 1e9, t, n) ? t : -1.0;
  };
  // From (-5, 0, 0) along +x (unit speed); from above along -z.
  const synthetic::Ray side{{-5, 0, 0}, {1, 0, 0}};
  const synthetic::Ray top{{0.2, 0, 5}, {0, 0, -2}};  // t counts half-units of distance
  EXPECT_DOUBLE_EQ(hit(ShapeKind::kBox, {1, 2, 3}, side), 4.0);
  EXPECT_DOUBLE_EQ(hit(ShapeKind::kEllipsoid, {2, 2, 2}, side), 3.0);
  EXPECT_DOUBLE_EQ(hit(ShapeKind::kCylinder, {1.5, 1.5, 1}, side), 3.5);
  EXPECT_DOUBLE_EQ(hit(ShapeKind::kCylinder, {1.5, 1.5, 1}, top), 2.0);
  // Cone of base radius 1 at z = -1, apex at z = 1: at x = 0.5 the surface is at z = 0.
  EXPECT_NEAR(hit(ShapeKind::kCone, {1, 1, 1}, side), 5.0 - 0.5, 1e-12);
  EXPECT_NEAR(hit(ShapeKind::kCone, {1, 1, 1}, {{0.5, 0, 5}, {0, 0, -1}}), 5.0, 1e-12);
  // Wedge of half-width 1, half-height 1: at x = 0.2 the roof is at z = 1 - 2 * 0.2 = 0.6.
  EXPECT_NEAR(hit(ShapeKind::kWedge, {1, 1, 1}, top), (5.0 - 0.6) / 2.0, 1e-12);
  EXPECT_LT(hit(ShapeKind::kEllipsoid, {1, 1, 1}, {{-5, 2, 0}, {1, 0, 0}}), 0.0);
}

}  // namespace
}  // namespace ffloc
