#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <memory>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "ffloc/classical/descriptor_matching.h"
#include "ffloc/classical/sift_features.h"
#include "ffloc/classical/vlad.h"
#include "ffloc/eval/coordinate_source.h"
#include "ffloc/geometry/triangulation.h"

namespace ffloc {

// The classical structure-based comparator: SIFT features, image retrieval, ratio-test matching
// and triangulation from the posed mapping images. No network, no depth. See
// docs/sift_baseline.md for the design and measured numbers.
//
// prepare() matches every mapping frame with its most similar mapping frames, which links each
// mapping keypoint to its matches elsewhere in the map. A query keypoint matched to mapping
// keypoints then gets a track made of those keypoints and their links, and its 3D point is
// triangulated from the mapping poses. Points are made per query, so no global map (and no
// track merging) is needed.
struct SiftBaselineOptions {
  SiftOptions sift = {1600, 8000};  // the settings its numbers in docs/sift_baseline.md were measured with
  MatchingOptions matching;
  VladOptions vocabulary;
  // Mapping frames matched per query (the paper's indoor setting uses 10); every mapping frame
  // when the scene has no more than this.
  int retrieval_top_k = 10;
  // Mapping frames each mapping frame is matched with in prepare(), the most similar first.
  int map_neighbours = 6;
  // Triangulation checks; the reprojection threshold is in working-resolution pixels, so it
  // means the same at any image size.
  double max_reprojection_error_px = 4.0;
  double min_triangulation_angle_deg = 1.5;
  size_t max_track_views = 16;  // longer tracks are cut, direct query matches kept first
  uint64_t seed = 0;
};

// Confidence of a pair: 1 + the number of mapping views its point was triangulated from, so
// every pair (>= 3) passes the paper's tau = 1.5 and a higher --confidence-threshold keeps only
// points seen in more views.
class SiftBaselineSource : public CoordinateSource {
 public:
  explicit SiftBaselineSource(SiftBaselineOptions options = {});
  ~SiftBaselineSource() override;
  std::string name() const override { return "sift-baseline"; }
  // Extracts and indexes the mapping frames' features and trains the retrieval vocabulary.
  void prepare(const Scene& scene) override;
  Correspondences correspondences(const Scene& scene, size_t query_index) override;

  // Every usable mapping frame (scene frame indices), most similar to the query first; the first
  // retrieval_top_k are the ones correspondences() matches against.
  std::vector<size_t> rankMappingFrames(const Scene& scene, size_t query_index);

 private:
  struct MappingFrame;

  void ensurePrepared(const Scene& scene);
  std::vector<size_t> rank(const Eigen::VectorXf& global) const;
  Eigen::VectorXf describe(const SiftFeatures& features) const;
  void linkMappingFrames();
  MatchingOptions matchingOptions() const;

  SiftBaselineOptions options_;
  const Scene* prepared_scene_ = nullptr;
  std::vector<MappingFrame> mapping_;
  VladVocabulary vocabulary_;
};

}  // namespace ffloc
