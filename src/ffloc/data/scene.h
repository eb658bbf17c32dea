#pragma once

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "ffloc/geometry/camera.h"
#include "ffloc/geometry/pose.h"

namespace ffloc {

enum class Split { kMapping, kQuery, kUnassigned };
const char* toString(Split split);

// Where a frame's depth map lives and how to read it. Depth is z-depth along the optical axis,
// in the image's own pixel grid (same width and height, same intrinsics).
struct DepthSource {
  std::filesystem::path path;
  // Stored value times this gives scene units (7-Scenes uint16 millimetres: 0.001).
  double scale = 0.001;
  // Stored values that mean "no depth" (7-Scenes: 0 and 65535). NaN and non-positive values
  // are always invalid.
  std::vector<double> invalid_values = {0.0, 65535.0};
  // The depth camera's pinhole intrinsics, when they are not the colour image's (an RGB-D
  // sensor whose depth is not registered to colour; same pose assumed): readDepthMetres then
  // resamples the depth into the colour image's pixel grid.
  std::optional<Intrinsics> camera;
};

// One posed image. Every reader produces these; everything else consumes them.
struct Frame {
  std::string name;  // path of the image relative to the scene root; unique within a scene
  std::filesystem::path image_path;
  Intrinsics intrinsics;
  Pose camera_to_world;  // OpenCV axes, scene units
  std::optional<DepthSource> depth;
  Split split = Split::kUnassigned;
};

// An optional sparse point with its observations (COLMAP points3D.txt).
struct ScenePoint {
  Eigen::Vector3d position = Eigen::Vector3d::Zero();
  struct Observation {
    size_t frame_index;
    Eigen::Vector2d pixel;  // OpenCV convention (pixel centre at integers)
  };
  std::vector<Observation> observations;
};

struct Scene {
  std::string name;
  std::filesystem::path root;
  std::string format;  // the reader that produced it: "7scenes", "nerf", "colmap", ...
  bool metric = true;  // translations in metres; false for SfM/arbitrary scale
  std::vector<Frame> frames;
  std::vector<ScenePoint> points;

  std::vector<size_t> indices(Split split) const;
  std::vector<size_t> mappingIndices() const { return indices(Split::kMapping); }
  std::vector<size_t> queryIndices() const { return indices(Split::kQuery); }
};

}  // namespace ffloc
