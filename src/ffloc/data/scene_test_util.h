#pragma once

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <string>

#include "ffloc/core/error.h"
#include "ffloc/data/scene.h"

namespace ffloc::testing {

inline void writeTextFile(const std::filesystem::path& path, const std::string& text) {
  if (path.has_parent_path()) std::filesystem::create_directories(path.parent_path());
  std::ofstream(path, std::ios::binary) << text;
}

inline void expectSameIntrinsics(const Intrinsics& a, const Intrinsics& b) {
  EXPECT_EQ(a.width, b.width);
  EXPECT_EQ(a.height, b.height);
  EXPECT_EQ(a.fx, b.fx);
  EXPECT_EQ(a.fy, b.fy);
  EXPECT_EQ(a.cx, b.cx);
  EXPECT_EQ(a.cy, b.cy);
  EXPECT_EQ(a.distortion, b.distortion);
}

// Bit-exact equality of everything a frame holds.
inline void expectSameFrame(const Frame& a, const Frame& b) {
  SCOPED_TRACE(a.name);
  EXPECT_EQ(a.name, b.name);
  EXPECT_EQ(a.image_path, b.image_path);
  expectSameIntrinsics(a.intrinsics, b.intrinsics);
  EXPECT_TRUE(a.camera_to_world.matrix() == b.camera_to_world.matrix())
      << toString(a.camera_to_world) << "\nvs\n" << toString(b.camera_to_world);
  ASSERT_EQ(a.depth.has_value(), b.depth.has_value());
  if (a.depth) {
    EXPECT_EQ(a.depth->path, b.depth->path);
    EXPECT_EQ(a.depth->scale, b.depth->scale);
    EXPECT_EQ(a.depth->invalid_values, b.depth->invalid_values);
    ASSERT_EQ(a.depth->camera.has_value(), b.depth->camera.has_value());
    if (a.depth->camera) expectSameIntrinsics(*a.depth->camera, *b.depth->camera);
  }
  EXPECT_EQ(a.split, b.split);
}

// Runs `load` and expects an InputError whose message contains every one of `parts`.
template <typename Load>
void expectInputError(Load&& load, const std::vector<std::string>& parts) {
  try {
    load();
    ADD_FAILURE() << "expected an InputError mentioning '" << parts.front() << "'";
  } catch (const InputError& e) {
    for (const auto& part : parts)
      EXPECT_NE(std::string(e.what()).find(part), std::string::npos)
          << "message '" << e.what() << "' lacks '" << part << "'";
  }
}

}  // namespace ffloc::testing
