#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <filesystem>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "ffloc/core/error.h"
#include "ffloc/core/testing/shared_data.h"
#include "ffloc/io/image.h"
#include "ffloc/model/torch_threads.h"
#include "ffloc/pipeline/fastforward_localizer.h"
#include "ffloc/pipeline/mapper.h"
#include "ffloc/model/model_loader.h"
#include "ffloc/pipeline/query_descriptor.h"
#include "ffloc/pipeline/token_vlad.h"
#include "ffloc/retrieval/image_selection.h"
#include "ffloc/retrieval/retrieval_recall.h"

namespace ffloc {
namespace {

namespace fs = std::filesystem;

constexpr int kLongSide = 128;  // small network input: the test is about plumbing, not accuracy

// Six posed mapping images of smooth random texture around a circle, the odd ones with lens
// distortion so the query path must undistort exactly as the mapper does.
Scene texturedScene(const fs::path& dir) {
  Scene scene;
  scene.name = "textured";
  scene.root = dir;
  scene.format = "test";
  cv::RNG rng(11);
  for (int i = 0; i < 6; ++i) {
    cv::Mat noise(30, 40, CV_8UC3);
    rng.fill(noise, cv::RNG::UNIFORM, cv::Scalar::all(0), cv::Scalar::all(255));
    cv::Mat image;
    cv::resize(noise, image, cv::Size(160, 120), 0, 0, cv::INTER_CUBIC);
    Frame frame;
    frame.name = "frame" + std::to_string(i) + ".png";
    frame.image_path = dir / frame.name;
    cv::imwrite(frame.image_path.string(), image);
    frame.intrinsics.fx = frame.intrinsics.fy = 150;
    frame.intrinsics.cx = 79.5;
    frame.intrinsics.cy = 59.5;
    frame.intrinsics.width = 160;
    frame.intrinsics.height = 120;
    if (i % 2) frame.intrinsics.distortion = {0.05, -0.02, 0.0, 0.0};
    const double angle = i * M_PI / 3;
    frame.camera_to_world.R = Eigen::AngleAxisd(angle, Eigen::Vector3d::UnitY()).toRotationMatrix();
    frame.camera_to_world.t = Eigen::Vector3d(std::cos(angle), 0, std::sin(angle));
    frame.split = Split::kMapping;
    scene.frames.push_back(frame);
  }
  return scene;
}

const LoadedModel& tinyRandomModel() {
  static const LoadedModel model = [] {
    setTorchThreadCount(1);
    return loadModel("random:tiny:5");
  }();
  return model;
}

// The textured scene's every frame mapped with the tiny random model.
MapFile mapOf(const Scene& scene) {
  MappingOptions mapping;
  mapping.long_side = kLongSide;
  mapping.quiet = true;
  MapFile map = emptyMap(tinyRandomModel(), scene.metric);
  addToMap(map, tinyRandomModel(), scene, scene.mappingIndices(), mapping);
  return map;
}

TEST(QueryDescriptor, AMappingImageAsQueryRetrievesItselfFirst) {
  const Scene scene = texturedScene(testing::makeTempDir("ffloc_query_descriptor"));
  const LoadedModel& model = tinyRandomModel();
  const MapFile map = mapOf(scene);
  ASSERT_EQ(map.images.size(), scene.frames.size());

  std::vector<std::vector<float>> database;
  std::vector<Pose> poses;
  for (const MapImage& image : map.images) {
    database.push_back(image.descriptor);
    poses.push_back(image.camera_to_world);
  }
  std::vector<std::vector<float>> queries;
  for (size_t i = 0; i < scene.frames.size(); ++i) {
    const Frame& frame = scene.frames[i];
    const std::vector<float> descriptor =
        queryDescriptor(*model.model, readImageRgb(frame.image_path), frame.intrinsics, frame.name, kLongSide);
    // Same preparation, encoder and pooling as the mapper: the same numbers, not just close ones.
    EXPECT_EQ(descriptor, map.images[i].descriptor) << frame.name;
    EXPECT_EQ(topKBySimilarity(database, descriptor, 1), std::vector<size_t>{i}) << frame.name;
    queries.push_back(descriptor);
  }
  const RetrievalRecall recall = measureRetrievalRecall(poses, poses, database, queries);
  EXPECT_DOUBLE_EQ(recall.recall[0].retrieval, 1.0);
  EXPECT_DOUBLE_EQ(recall.median_rank, 1.0);

  // The localizer ranks the map with the same descriptor: its selection for a query equals the
  // ranking by queryDescriptor.
  LocalizeOptions options;
  options.long_side = kLongSide;
  options.top_k = map.images.size();
  options.num_features = 64;
  options.retrieval = FastForwardRetrieval::kEncoder;
  const Frame& probe = scene.frames[3];
  const cv::Mat rgb = readImageRgb(probe.image_path);
  const FastForwardLocalizer localizer(*model.model, map);
  EXPECT_EQ(localizer.predictCoordinates(rgb, probe.intrinsics, probe.name, options).selected,
            topKBySimilarity(database, queryDescriptor(*model.model, rgb, probe.intrinsics, probe.name, kLongSide),
                             map.images.size()));
}

// The token VLAD (the default retrieval) learns its vocabulary from the map: a mapping image as
// query finds itself first, and the localizer's selection is the ranking by the same VLAD.
TEST(QueryDescriptor, TokenVladOfAMappingImageRetrievesItselfFirst) {
  const Scene scene = texturedScene(testing::makeTempDir("ffloc_token_vlad"));
  const LoadedModel& model = tinyRandomModel();
  const MapFile map = mapOf(scene);
  const TokenVlad vlad(map);
  ASSERT_EQ(vlad.imageDescriptors().size(), map.images.size());
  std::vector<Eigen::VectorXf> queries;
  for (size_t i = 0; i < scene.frames.size(); ++i) {
    const Frame& frame = scene.frames[i];
    const Dust3rEncoding encoding =
        queryEncoding(*model.model, readImageRgb(frame.image_path), frame.intrinsics, frame.name, kLongSide);
    queries.push_back(vlad.describe(encoding.tokens));
    EXPECT_NEAR(queries.back().norm(), 1.0, 1e-5);
    EXPECT_EQ(rankBySimilarity(vlad.imageDescriptors(), queries.back()).front(), i) << frame.name;
  }

  LocalizeOptions options;
  options.long_side = kLongSide;
  options.top_k = map.images.size();
  options.num_features = 64;
  const Frame& probe = scene.frames[2];
  const FastForwardLocalizer localizer(*model.model, map);
  EXPECT_EQ(localizer.predictCoordinates(readImageRgb(probe.image_path), probe.intrinsics, probe.name, options).selected,
            rankBySimilarity(vlad.imageDescriptors(), queries[2]));
}

TEST(QueryDescriptor, BadQueryNamesTheImage) {
  const LoadedModel& model = tinyRandomModel();
  Intrinsics intrinsics;
  intrinsics.fx = intrinsics.fy = 100;
  intrinsics.cx = 31.5;
  intrinsics.cy = 23.5;
  intrinsics.width = 64;
  intrinsics.height = 48;
  const cv::Mat wrong_size(40, 64, CV_8UC3, cv::Scalar::all(128));
  try {
    queryDescriptor(*model.model, wrong_size, intrinsics, "query.png", kLongSide);
    FAIL() << "no InputError for an image that does not fit its intrinsics";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("query.png"), std::string::npos) << e.what();
  }
  EXPECT_THROW(queryDescriptor(*model.model, cv::Mat(), intrinsics, "empty.png", kLongSide), InputError);
}

}  // namespace
}  // namespace ffloc
