#include <gtest/gtest.h>

#include <ATen/TensorOperators.h>
#include <ATen/ops/equal.h>
#include <ATen/ops/full.h>
#include <ATen/ops/zeros.h>

#include <cmath>
#include <limits>
#include <set>

#include "ffloc/core/error.h"
#include "ffloc/geometry/rays.h"
#include "ffloc/model/map_assembly.h"

namespace ffloc {
namespace {

// Three 64 x 48 cameras (a 4 x 3 token grid each at 16 px patches) along x, looking along z.
std::vector<MapCamera> threeCameras() {
  std::vector<MapCamera> cameras;
  for (int k = 0; k < 3; ++k) {
    MapCamera camera;
    camera.intrinsics.width = 64;
    camera.intrinsics.height = 48;
    camera.intrinsics.fx = camera.intrinsics.fy = 50;
    camera.intrinsics.cx = 31.5;
    camera.intrinsics.cy = 23.5;
    camera.camera_to_world.t = Eigen::Vector3d(1.0 + 2.0 * k, 0.5, -3.0);
    camera.name = "image_" + std::to_string(k);
    cameras.push_back(camera);
  }
  return cameras;
}

TEST(MapAssembly, PlansTheNormalisedFrameRaysAndTokenSample) {
  const std::vector<MapCamera> cameras = threeCameras();
  const MapLayout layout = planMap(cameras, 16, 20, 5);
  // P_0 is the first camera, and the farthest camera lies at normalised distance 1.
  EXPECT_TRUE(layout.normalization.normalize(cameras[0].camera_to_world).t.isZero(1e-12));
  EXPECT_NEAR(layout.normalization.normalize(cameras[2].camera_to_world).t.norm(), 1.0, 1e-12);
  ASSERT_EQ(layout.rays.size(), 3u);
  EXPECT_EQ(layout.tokens_per_image, (std::vector<int64_t>{12, 12, 12}));
  EXPECT_EQ(layout.rays[1].sizes(), at::IntArrayRef({1, 12, 6}));
  // Token 5 of image 1 is patch (row 1, col 1): its ray goes through that patch centre.
  const std::vector<Ray> rays = patchRays(cameras[1].intrinsics, layout.normalization.normalize(cameras[1].camera_to_world), 16);
  for (int c = 0; c < 3; ++c) {
    EXPECT_NEAR(layout.rays[1][0][5][c].item<double>(), rays[5].origin[c], 1e-6);
    EXPECT_NEAR(layout.rays[1][0][5][3 + c].item<double>(), rays[5].direction[c], 1e-6);
  }
  ASSERT_EQ(layout.indices.sizes(), at::IntArrayRef({20, 2}));
  std::set<std::pair<int64_t, int64_t>> distinct;
  for (int64_t i = 0; i < 20; ++i) {
    const int64_t image = layout.indices[i][0].item<int64_t>(), token = layout.indices[i][1].item<int64_t>();
    EXPECT_TRUE(image >= 0 && image < 3 && token >= 0 && token < 12);
    distinct.insert({image, token});
  }
  EXPECT_EQ(distinct.size(), 20u);
  EXPECT_TRUE(at::equal(planMap(cameras, 16, 20, 5).indices, layout.indices));
  EXPECT_FALSE(at::equal(planMap(cameras, 16, 20, 6).indices, layout.indices));
  // Asking for more tokens than the images hold gives all of them.
  EXPECT_EQ(planMap(cameras, 16, 100, 5).indices.size(0), 36);
}

TEST(MapAssembly, GathersTheSampledTokensWithTheirRays) {
  const std::vector<MapCamera> cameras = threeCameras();
  const MapLayout layout = planMap(cameras, 16, 7, 11);
  std::vector<Dust3rEncoding> encodings;
  for (int k = 0; k < 3; ++k) {
    Dust3rEncoding encoding;
    // Every channel of token t of image k holds 100 k + t.
    encoding.tokens = at::zeros({1, 12, 4});
    for (int t = 0; t < 12; ++t) encoding.tokens[0][t].fill_(100.0 * k + t);
    encoding.positions = patchPositions(1, 3, 4, at::kCPU);
    encoding.height = 48;
    encoding.width = 64;
    encodings.push_back(encoding);
  }
  const MapTokens map = assembleMapTokens(layout, encodings);
  ASSERT_EQ(map.features.sizes(), at::IntArrayRef({1, 7, 4}));
  for (int64_t i = 0; i < 7; ++i) {
    const int64_t image = layout.indices[i][0].item<int64_t>(), token = layout.indices[i][1].item<int64_t>();
    EXPECT_EQ(map.features[0][i][2].item<double>(), 100.0 * image + token);
    EXPECT_TRUE(at::equal(map.rays[0][i], layout.rays[static_cast<size_t>(image)][0][token]));
    EXPECT_EQ(map.positions[0][i][0].item<int64_t>(), token / 4);
    EXPECT_EQ(map.positions[0][i][1].item<int64_t>(), token % 4);
  }
}

TEST(MapAssembly, RefusesAnImageSmallerThanAPatch) {
  std::vector<MapCamera> cameras = threeCameras();
  cameras[2].intrinsics.height = 8;
  try {
    planMap(cameras, 16, 10, 0);
    ADD_FAILURE() << "an 8 px tall image was planned";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("image_2"), std::string::npos) << e.what();
  }
}

TEST(MapAssembly, QueryPointsGoBackToTheWorldAndTheOriginalPixels) {
  const MapLayout layout = planMap(threeCameras(), 16, 5, 0);
  Dust3rPointMap query;
  query.pts3d = at::zeros({2, 2, 3, 3});  // batch of 2, 2 x 3 pixels
  query.conf = at::full({2, 2, 3}, 2.0);
  query.pts3d[1][0][1][0] = 0.25;
  query.pts3d[1][0][1][2] = 1.0;
  query.pts3d[1][1][2][0] = std::numeric_limits<float>::quiet_NaN();
  PreprocessGeometry geometry;
  geometry.original_width = 6;
  geometry.original_height = 4;
  geometry.resized_width = 3;
  geometry.resized_height = 2;
  geometry.width = 3;
  geometry.height = 2;

  const Correspondences grid = queryCorrespondences(query, 1, layout.normalization, 1);
  ASSERT_EQ(grid.size(), 5u);  // the NaN pixel is left out
  EXPECT_EQ(grid.pixels[1], Eigen::Vector2d(1, 0));
  EXPECT_TRUE(grid.points[1].isApprox(layout.normalization.toWorld(Eigen::Vector3d(0.25, 0, 1.0))));
  EXPECT_EQ(grid.confidences[1], 2.0f);

  const Correspondences original = queryCorrespondences(query, 1, layout.normalization, 1, &geometry);
  EXPECT_TRUE(original.pixels[1].isApprox(geometry.toOriginal(Eigen::Vector2d(1, 0))));
  EXPECT_TRUE(original.pixels[1].isApprox(Eigen::Vector2d(2.5, 0.5)));
}

}  // namespace
}  // namespace ffloc
