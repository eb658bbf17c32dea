#include "ffloc/geometry/preprocess.h"
#include "ffloc/io/map_file.h"

#include <gtest/gtest.h>

#include <fstream>
#include <functional>
#include <iterator>
#include <random>

#include "ffloc/core/error.h"
#include "ffloc/core/hash.h"
#include "ffloc/core/testing/shared_data.h"
#include "ffloc/io/half.h"
#include "ffloc/io/testing/safetensors_edit.h"

namespace ffloc {
namespace {

MapFile smallMap(int images = 3) {
  std::mt19937 rng(7);
  std::normal_distribution<float> n(0.f, 1.f);
  MapFile map;
  map.model_id = "tiny-1234abcd";
  map.token_dim = 8;
  map.metric = true;
  for (int i = 0; i < images; ++i) {
    MapImage image;
    image.name = "frame-" + std::to_string(i) + ".png";
    image.camera_to_world.R = Eigen::AngleAxisd(0.3 * i, Eigen::Vector3d::UnitY()).toRotationMatrix();
    image.camera_to_world.t = Eigen::Vector3d(0.1 * i, 0.2, -0.3 * i);
    image.intrinsics = {400.5, 401.25, 255.5, 191.5, 512, 384, {}};
    image.geometry = preprocessGeometry(640, 480);
    image.grid_rows = 3;
    image.grid_cols = 4;
    std::vector<uint16_t> tokens;
    for (size_t t = 0; t < image.tokenCount() * map.token_dim; ++t) tokens.push_back(floatToHalf(n(rng)));
    image.tokens = StoredTokens(std::move(tokens));
    for (int d = 0; d < 16; ++d) image.descriptor.push_back(n(rng));
    map.images.push_back(image);
  }
  return map;
}

TEST(MapFile, RoundTripIsExact) {
  const auto dir = testing::makeTempDir("ffloc-map");
  const MapFile map = smallMap();
  writeMapFile(map, dir / "scene.ffmap");
  const MapFile back = readMapFile(dir / "scene.ffmap", "tiny-1234abcd");
  EXPECT_EQ(back.model_id, map.model_id);
  EXPECT_EQ(back.token_dim, map.token_dim);
  ASSERT_EQ(back.images.size(), map.images.size());
  for (size_t i = 0; i < map.images.size(); ++i) {
    const MapImage &a = map.images[i], &b = back.images[i];
    EXPECT_EQ(a.name, b.name);
    EXPECT_EQ(a.camera_to_world.matrix(), b.camera_to_world.matrix());
    EXPECT_EQ(a.intrinsics.fx, b.intrinsics.fx);
    EXPECT_EQ(a.intrinsics.cy, b.intrinsics.cy);
    EXPECT_EQ(a.geometry.crop_y, b.geometry.crop_y);
    EXPECT_EQ(a.geometry.resized_width, b.geometry.resized_width);
    EXPECT_EQ(a.tokens, b.tokens);
    EXPECT_EQ(a.descriptor, b.descriptor);
  }
  // No temporary file is left behind.
  size_t files = 0;
  for (const auto& entry : std::filesystem::directory_iterator(dir)) files += entry.is_regular_file();
  EXPECT_EQ(files, 1u);
}

// The token vocabulary is optional (maps written before 5 Dec 2026 have none) and, stored, comes
// back exactly; one of another width than the tokens is refused when written and when read, and
// one of more words than any map holds when read.
TEST(MapFile, TheTokenVocabularyRoundTripsAndItsShapeIsChecked) {
  const auto dir = testing::makeTempDir("ffloc-map-vocabulary");
  MapFile map = smallMap();
  writeMapFile(map, dir / "none.ffmap");
  EXPECT_TRUE(readMapFile(dir / "none.ffmap").token_vocabulary.empty());
  for (int v = 0; v < 5 * map.token_dim; ++v) map.token_vocabulary.push_back(0.25f * v - 3);
  writeMapFile(map, dir / "five.ffmap");
  EXPECT_EQ(readMapFile(dir / "five.ffmap").token_vocabulary, map.token_vocabulary);

  map.token_vocabulary.pop_back();
  try {
    writeMapFile(map, dir / "bad.ffmap");
    FAIL() << "a vocabulary of 39 values for 8-wide tokens was written";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("token vocabulary of 39 values is not words x 8"), std::string::npos) << e.what();
  }
  EXPECT_FALSE(std::filesystem::exists(dir / "bad.ffmap"));
  map.token_vocabulary.push_back(1);
  map.token_dim = 4;  // written 4-wide, then the description edited to say 8: the vocabulary is 10 x 4
  for (MapImage& image : map.images) image.grid_cols *= 2;
  writeMapFile(map, dir / "narrow.ffmap");
  testing::editMetadata(dir / "narrow.ffmap", [](nlohmann::json& metadata) {
    nlohmann::json description = nlohmann::json::parse(metadata[kMapMetadataKey].get<std::string>());
    description["token_dim"] = 8;
    for (const auto& [key, value] : mapMetadataEntries(description, "narrow.ffmap")) metadata[key] = value;
  });
  try {
    readMapFile(dir / "narrow.ffmap");
    FAIL() << "a 4-wide vocabulary was read for 8-wide tokens";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("tensor 'token_vocabulary' has shape (10, 4) F32, expected (words, 8) F32 "
                                         "with 1 to 1024 words"),
              std::string::npos)
        << e.what();
  }
  // Each image's descriptor holds words x width floats: 20 000 words took a query to 1.5 GB.
  map = smallMap();
  map.token_vocabulary.assign(1025 * map.token_dim, 0.5f);
  for (size_t v = 0; v < map.token_vocabulary.size(); v += 9) map.token_vocabulary[v] = static_cast<float>(v);
  writeMapFile(map, dir / "many.ffmap");
  try {
    readMapFile(dir / "many.ffmap");
    FAIL() << "a vocabulary of 1025 words was read";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("has shape (1025, 8) F32, expected (words, 8) F32 with 1 to 1024 words"),
              std::string::npos)
        << e.what();
  }
}

// Tokens are views into one snapshot of the file, not per-image copies (a 150-image
// large-configuration map held 236 MB of those). The snapshot keeps the map read intact whatever
// happens to the file: replaced by atomic rename, as `ffloc map` writes, deleted, or written over
// in place and cut short, which under the file's own mapping changed the tokens of a served map or
// ended the server with SIGBUS at its next query (found by an outside probe).
TEST(MapFile, TokensAreViewsOfASnapshotThatOutlivesAnyChangeToTheFile) {
  const auto dir = testing::makeTempDir("ffloc-map");
  const MapFile written = smallMap();
  writeMapFile(written, dir / "scene.ffmap");
  const MapFile read = readMapFile(dir / "scene.ffmap");
  ASSERT_EQ(read.images.size(), written.images.size());
  for (const MapImage& image : read.images) EXPECT_TRUE(image.tokens.mapped()) << image.name;

  MapFile other = smallMap(2);
  other.images[0].tokens = StoredTokens(std::vector<uint16_t>(other.images[0].tokens.size(), 0x3c00));
  writeMapFile(other, dir / "scene.ffmap");
  for (size_t i = 0; i < written.images.size(); ++i) EXPECT_EQ(read.images[i].tokens, written.images[i].tokens) << i;
  EXPECT_EQ(readMapFile(dir / "scene.ffmap").images[0].tokens, other.images[0].tokens);
  std::filesystem::remove(dir / "scene.ffmap");
  for (size_t i = 0; i < written.images.size(); ++i) EXPECT_EQ(read.images[i].tokens, written.images[i].tokens) << i;
  // Copies of a read map share the mapping; the last one to go unmaps it.
  MapFile copy = read;
  EXPECT_EQ(copy.images[1].tokens, written.images[1].tokens);

  // Written over in place (the same inode, as `cp` does), then cut short.
  writeMapFile(written, dir / "served.ffmap");
  const MapFile served = readMapFile(dir / "served.ffmap");
  writeMapFile(other, dir / "other.ffmap");
  std::filesystem::copy_file(dir / "other.ffmap", dir / "served.ffmap", std::filesystem::copy_options::overwrite_existing);
  for (size_t i = 0; i < written.images.size(); ++i) EXPECT_EQ(served.images[i].tokens, written.images[i].tokens) << i;
  std::filesystem::resize_file(dir / "served.ffmap", 64);
  for (size_t i = 0; i < written.images.size(); ++i) EXPECT_EQ(served.images[i].tokens, written.images[i].tokens) << i;
}

TEST(MapFile, RefusesAMapBuiltWithAnotherModel) {
  const auto dir = testing::makeTempDir("ffloc-map");
  writeMapFile(smallMap(), dir / "scene.ffmap");
  try {
    readMapFile(dir / "scene.ffmap", "large-99999999");
    FAIL();
  } catch (const InputError& e) {
    const std::string message = e.what();
    EXPECT_NE(message.find("tiny-1234abcd"), std::string::npos) << message;
    EXPECT_NE(message.find("large-99999999"), std::string::npos) << message;
  }
}

TEST(MapFile, DetectsCorruptionAndTruncation) {
  const auto dir = testing::makeTempDir("ffloc-map");
  const auto path = dir / "scene.ffmap";
  writeMapFile(smallMap(), path);
  const auto size = std::filesystem::file_size(path);
  {
    // Flip one byte near the end (inside the token data).
    std::fstream f(path, std::ios::in | std::ios::out | std::ios::binary);
    f.seekg(static_cast<std::streamoff>(size - 100));
    char c;
    f.read(&c, 1);
    c = static_cast<char>(c ^ 0x5a);
    f.seekp(static_cast<std::streamoff>(size - 100));
    f.write(&c, 1);
  }
  try {
    readMapFile(path);
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("checksum"), std::string::npos) << e.what();
  }
  // One bit flipped in an optional tensor's name (its points): the map loaded without them, and
  // an append then dropped their checksum too.
  MapFile with_points = smallMap();
  with_points.images[1].token_points.assign(3 * with_points.images[1].tokenCount(), 0.5f);
  writeMapFile(with_points, path);
  {
    std::fstream f(path, std::ios::in | std::ios::out | std::ios::binary);
    const std::string bytes((std::istreambuf_iterator<char>(f)), {});
    const size_t at = bytes.find("\"points.1\":{");
    ASSERT_NE(at, std::string::npos);
    f.seekp(static_cast<std::streamoff>(at + 6));
    f.put('r');
  }
  try {
    readMapFile(path);
    FAIL() << "a map without a tensor it records was read";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("tensor 'points.1': checksum recorded, but the file has no such tensor"),
              std::string::npos)
        << e.what();
  }
  writeMapFile(smallMap(), path);
  std::filesystem::resize_file(path, size / 2);
  EXPECT_THROW(readMapFile(path), InputError);
  std::ofstream(dir / "empty.ffmap").close();
  EXPECT_THROW(readMapFile(dir / "empty.ffmap"), InputError);
  // Another file given as the map: what it is not comes first, the reason after.
  std::ofstream(dir / "manifest.json") << R"({"format": "ffloc-manifest", "version": 1, "frames": []})";
  try {
    readMapHeader(dir / "manifest.json");
    FAIL();
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()).rfind((dir / "manifest.json").string() + ": not an ffloc map, or a damaged one: header length", 0), 0u)
        << e.what();
  }
  // A mistyped path is that, not a damaged map.
  try {
    readMapHeader(dir / "typo.ffmap");
    FAIL();
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()), (dir / "typo.ffmap").string() + ": map file not found");
  }
}

TEST(MapFile, RejectsInconsistentImages) {
  const auto dir = testing::makeTempDir("ffloc-map");
  MapFile map = smallMap();
  map.images[1].tokens = StoredTokens(std::vector<uint16_t>(map.images[1].tokens.size() - 1));
  try {
    writeMapFile(map, dir / "bad.ffmap");
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("frame-1.png"), std::string::npos) << e.what();
  }
  EXPECT_FALSE(std::filesystem::exists(dir / "bad.ffmap"));
}

TEST(MapFile, EmptyMapRoundTrips) {
  const auto dir = testing::makeTempDir("ffloc-map");
  writeMapFile(smallMap(0), dir / "empty.ffmap");
  EXPECT_TRUE(readMapFile(dir / "empty.ffmap").images.empty());
}

// Rewrites a map with its metadata (and, when given, its descriptors) edited and every checksum
// made right again, as a damaged map whose damage the checksums do not catch would be.
void rewriteSealed(const std::filesystem::path& path, const std::function<void(nlohmann::json&)>& edit,
                   const std::vector<float>& descriptors = {}) {
  std::vector<std::vector<uint8_t>> copies;
  std::vector<TensorView> tensors;
  nlohmann::json description;
  {
    const auto archive = openSafetensors(path);
    description = readMapMetadata(*archive, path.string());
    for (const std::string& name : archive->names()) {
      TensorView view = archive->at(name);
      if (name == "descriptors" && !descriptors.empty())
        view.data = reinterpret_cast<const uint8_t*>(descriptors.data());
      copies.emplace_back(view.data, view.data + view.nbytes);
      view.data = copies.back().data();
      description["checksums"][name] = hex64(fnv1a64(view.data, view.nbytes));
      tensors.push_back(view);
    }
  }
  edit(description);
  writeSafetensors(path, tensors, mapMetadataEntries(description, path.string()));
}

std::string readError(const std::filesystem::path& path) {
  try {
    readMapFile(path);
  } catch (const InputError& e) {
    return e.what();
  }
  return "(read without an error)";
}

// The outside probe's findings: each of these loaded before the reader checked them.
TEST(MapFile, RefusesMetadataThatNoMapWouldHold) {
  const auto dir = testing::makeTempDir("ffloc-map");
  const auto path = dir / "scene.ffmap";
  struct Case {
    std::function<void(nlohmann::json&)> edit;
    std::string expected;
  };
  const std::vector<Case> cases = {
      {[](nlohmann::json& m) { m["images"][1]["preprocess"]["height"] = -84; }, "images[1].preprocess.height"},
      {[](nlohmann::json& m) { m["images"][0]["camera_to_world"][0][1] = 1000; }, "not orthonormal"},
      {[](nlohmann::json& m) { m["images"][0]["intrinsics"]["fx"] = -351; }, "images[0].intrinsics.fx': must be positive"},
      {[](nlohmann::json& m) { m["images"][2]["intrinsics"]["fy"] = 0; }, "images[2].intrinsics.fy': must be positive"},
      {[](nlohmann::json& m) { m["images"][0]["preprocess"]["crop_x"] = -1e5; }, "images[0].preprocess.crop_x"},
      {[](nlohmann::json& m) { m["images"][0]["preprocess"]["crop_y"] = 1000; }, "images[0].preprocess.crop_y"},
      {[](nlohmann::json& m) { m["images"][0]["preprocess"]["original_width"] = 0; }, "preprocess.original_width"},
      {[](nlohmann::json& m) { m["images"][0]["intrinsics"]["width"] = 500; }, "intrinsics are of a 500x384 image"},
      {[](nlohmann::json& m) { m["images"][2]["name"] = "frame-0.png"; }, "duplicate image name 'frame-0.png'"},
      {[](nlohmann::json& m) { m["images"][0]["grid"] = {3.5, 4}; }, "images[0].grid"},
      {[](nlohmann::json& m) { m["version"] = 1e30; }, "'version' must be a small non-negative integer"},
      {[](nlohmann::json& m) { m["token_dim"] = 1e30; }, "field 'token_dim'"},
      {[](nlohmann::json& m) { m["images"][0]["intrinsics"]["height"] = 4294967680.0; }, "intrinsics.height"},
  };
  for (const Case& bad : cases) {
    writeMapFile(smallMap(), path);
    rewriteSealed(path, bad.edit);
    const std::string message = readError(path);
    EXPECT_NE(message.find(bad.expected), std::string::npos) << message;
    EXPECT_NE(message.find(path.string()), std::string::npos) << message;
  }
  writeMapFile(smallMap(), path);
  std::vector<float> descriptors(3 * 16, 0.5f);
  descriptors[17] = std::nanf("");
  rewriteSealed(path, [](nlohmann::json&) {}, descriptors);
  EXPECT_NE(readError(path).find("'descriptors' holds NaN"), std::string::npos) << readError(path);
}

// Version 2 identifies the model by its architecture too: a version 1 map's identity matches no
// model of this build, and "load the model the map was built with" would mislead.
TEST(MapFile, AVersionOneMapIsToldToBeRebuilt) {
  const auto dir = testing::makeTempDir("ffloc-map");
  const auto path = dir / "old.ffmap";
  writeMapFile(smallMap(), path);
  testing::editMetadata(path, [](nlohmann::json& metadata) {
    nlohmann::json description = nlohmann::json::parse(metadata[kMapMetadataKey].get<std::string>());
    description["version"] = 1;
    for (const auto& [key, value] : mapMetadataEntries(description, "old.ffmap")) metadata[key] = value;
  });
  EXPECT_NE(readError(path).find("map version 1 identifies its model by the weights alone"), std::string::npos)
      << readError(path);
}

TEST(MapFile, MetadataChecksumCatchesAChangedPose) {
  const auto dir = testing::makeTempDir("ffloc-map");
  const auto path = dir / "scene.ffmap";
  writeMapFile(smallMap(), path);
  std::string bytes;
  {
    std::ifstream in(path, std::ios::binary);
    bytes.assign(std::istreambuf_iterator<char>(in), {});
  }
  // Two digits of the first translation (0.2, escaped inside the header's JSON string): another
  // valid pose, which only the metadata checksum can tell from the written one.
  const size_t at = bytes.find("0.2]");
  ASSERT_NE(at, std::string::npos);
  bytes.replace(at, 3, "0.7");
  std::ofstream(path, std::ios::binary) << bytes;
  EXPECT_NE(readError(path).find("map metadata checksum mismatch"), std::string::npos) << readError(path);
}

}  // namespace
}  // namespace ffloc
