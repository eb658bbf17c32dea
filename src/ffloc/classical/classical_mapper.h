#pragma once

#include <vector>

#include "ffloc/classical/classical_map.h"
#include "ffloc/data/scene.h"

namespace ffloc {

// How a classical map is built (`ffloc map --method classical`).
struct ClassicalMappingOptions {
  SiftOptions sift;
  float ratio = 0.8f;  // Lowe's ratio test on RootSIFT distances
  VladOptions vocabulary;
  int map_neighbours = 6;  // most similar mapping images each new image is linked with
  // Mapping frames with depth get their points by lifting each keypoint with its depth and pose;
  // others (and this set to false) by triangulating the keypoint's links.
  bool use_depth = true;
  // A lifted point is kept only where the depth around its keypoint (3x3) agrees within this
  // fraction of the depth: keypoints sit on edges, where a pixel of offset between the colour and
  // the depth image jumps to the background.
  double max_depth_spread = 0.03;
  // Triangulation and the check of a point against the other views, in working-resolution
  // pixels, so they mean the same at any image size.
  double max_reprojection_error_px = 4.0;
  double min_triangulation_angle_deg = 1.5;
  size_t max_track_views = 16;
  bool quiet = false;  // no progress bar

  // InputError naming the field for a value out of range or NaN.
  void check() const;
};

struct ClassicalMappingReport {
  size_t added = 0;
  size_t skipped_duplicates = 0;      // names already in the map
  std::vector<std::string> featureless;  // the names of images left out with fewer than two keypoints
  size_t points = 0;                  // over the added images
  size_t points_from_depth = 0;       // of them, lifted with the frame's depth; the others triangulated
  size_t links = 0;                   // new links, both directions
  double seconds = 0;
};

// An empty map that will be described with these options.
ClassicalMap emptyClassicalMap(bool metric, const ClassicalMappingOptions& options);

// Adds `frames` (indices into scene.frames) to `map`. The images already there keep their
// keypoints, descriptors and points; they gain links to the new images. The vocabulary is
// trained by the first call and kept after. InputError when the map is in other units, when a
// frame's image does not fit its intrinsics, or when no image of the map has usable features.
ClassicalMappingReport addToClassicalMap(ClassicalMap& map, const Scene& scene, const std::vector<size_t>& frames,
                                         const ClassicalMappingOptions& options = {});

}  // namespace ffloc
