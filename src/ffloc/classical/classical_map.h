#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "ffloc/classical/descriptor_matching.h"
#include "ffloc/classical/sift_features.h"
#include "ffloc/classical/vlad.h"
#include "ffloc/geometry/camera.h"
#include "ffloc/geometry/pose.h"

namespace ffloc {

// A keypoint of one mapping image matched to a keypoint of another.
struct KeypointLink {
  uint32_t keypoint = 0;
  uint32_t other_image = 0;
  uint32_t other_keypoint = 0;
};

// One mapping image of a classical map: everything a query needs, so that no mapping image is
// read again after mapping.
struct ClassicalMapImage {
  std::string name;
  Pose camera_to_world;
  Intrinsics camera;  // undistorted, original resolution: the keypoints' pixel grid
  double working_scale = 1;             // SIFT's working-resolution pixels per original pixel
  std::vector<Eigen::Vector2d> keypoints;
  cv::Mat descriptors;                  // CV_8U, quantised RootSIFT, one row per keypoint
  // Per keypoint: its world point and the number of views that agree on it (0: no point).
  std::vector<Eigen::Vector3d> points;
  std::vector<uint8_t> point_views;
  std::vector<KeypointLink> links;
  Eigen::VectorXf global_descriptor;    // VLAD over the map's vocabulary
  bool depth_lifted = false;            // points lifted from the frame's depth (else triangulated)

  size_t pointCount() const;
};

// A classical map (`ffloc map --method classical`): one versioned safetensors file whose
// tensors hold keypoints, descriptors, points, links, the vocabulary and the global
// descriptors, each checksummed, and whose JSON metadata (checksummed too) holds the names,
// poses, cameras and the options the map was built with.
struct ClassicalMap {
  static constexpr int kVersion = 1;

  bool metric = true;
  SiftOptions sift;    // queries are described with the same options
  float ratio = 0.8f;  // Lowe's ratio test, for the links and the queries' matches
  VladVocabulary vocabulary;
  std::vector<ClassicalMapImage> images;
};

// Atomic (temporary file, then rename). InputError naming the image for inconsistent sizes.
void writeClassicalMap(const ClassicalMap& map, const std::filesystem::path& path);

// Validates the container, method, version, every checksum, size and value. InputError naming
// the file and the field or tensor at fault.
ClassicalMap readClassicalMap(const std::filesystem::path& path);

}  // namespace ffloc
