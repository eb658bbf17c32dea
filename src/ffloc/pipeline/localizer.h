#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "ffloc/geometry/normalization.h"
#include "ffloc/io/map_file.h"
#include "ffloc/model/fastforward_model.h"
#include "ffloc/pose/pnp.h"
#include "ffloc/retrieval/global_descriptor.h"
#include "ffloc/retrieval/image_selection.h"

namespace ffloc {

// Localisation of one query against a map (paper, section 3 and appendix "Inference").
struct LocalizeOptions {
  size_t top_k = 10;            // K mapping images behind the map representation
  int64_t num_features = 1500;  // N map tokens sampled from them
  uint64_t seed = 0;            // token sampling (and random image selection)
  ImageSelection selection = ImageSelection::kRetrieval;
  int long_side = 0;                   // of the preprocessed query, as MappingOptions
  GlobalDescriptorOptions descriptor;  // must match the mapper's
  PnpOptions pnp;

  // The paper's settings: "indoor" K = 10, N = 1500; "outdoor" K = 20, N = 3000. InputError for
  // other names.
  static LocalizeOptions preset(const std::string& name);
};

// Wall-clock seconds of each stage of one query.
struct QueryTimings {
  double preprocessing = 0;  // undistortion, resize, crop
  double retrieval = 0;      // query descriptor and image selection
  double encoding = 0;       // the query's encoder pass
  double decoding = 0;       // map assembly (tokens, rays), decoder and heads, back to world
  double pnp = 0;
  double total() const { return preprocessing + retrieval + encoding + decoding + pnp; }
};

struct QueryPrediction {
  // One pair per pixel of the preprocessed query: the pixel in `camera`'s grid (the undistorted
  // full-size query), the predicted point in world coordinates, the network's confidence.
  Correspondences correspondences;
  Intrinsics camera;
  std::vector<size_t> selected;  // map image indices; the first is the reference P_0
  SceneNormalization normalization;
  QueryTimings timings;
};

struct LocalizationResult {
  QueryPrediction prediction;
  PnpResult pnp;
  // Fraction of the pairs given to PnP that are inliers of the pose: 0 when it failed.
  double confidence() const;
};

class Localizer {
 public:
  // InputError when the map has no images or its token width differs from the model's.
  Localizer(const FastForwardModel& model, MapFile map);

  const MapFile& map() const { return map_; }

  // Map images behind the map representation of a query with this global descriptor.
  std::vector<size_t> selectImages(const std::vector<float>& query_descriptor, const LocalizeOptions& options) const;

  // Query 3D coordinates in the world frame. `intrinsics` describe `rgb` (distortion allowed).
  QueryPrediction predict(const cv::Mat& rgb, const Intrinsics& intrinsics, const std::string& name,
                          const LocalizeOptions& options) const;

  // predict() then the confidence filter and PnP-RANSAC.
  LocalizationResult localize(const cv::Mat& rgb, const Intrinsics& intrinsics, const std::string& name,
                              const LocalizeOptions& options) const;

 private:
  const FastForwardModel& model_;
  MapFile map_;
  std::vector<std::vector<float>> descriptors_;
};

}  // namespace ffloc
