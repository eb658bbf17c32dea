#pragma once

#include <cstdint>

#include "ffloc/eval/coordinate_source.h"

namespace ffloc {

// The upper bound of any coordinate regressor: scene coordinates from the query's own depth map
// and ground-truth pose, optionally corrupted, to test the solver and the harness.
struct OracleDepthOptions {
  int stride = 4;                 // use every stride-th pixel in x and y
  double pixel_noise_px = 0.0;    // zero-mean unit-variance bell noise (core/random.h) times this, on the 2D side
  double outlier_fraction = 0.0;  // fraction of pairs whose 3D point is replaced at random
  double point_noise = 0.0;       // the same noise on the other 3D points (scene units), like a regressor's error
  uint64_t seed = 0;
};

class OracleDepthSource : public CoordinateSource {
 public:
  explicit OracleDepthSource(OracleDepthOptions options = {}) : options_(options) {}
  std::string name() const override { return "oracle-depth"; }
  // Throws InputError naming the scene when a query frame has no depth map.
  void prepare(const Scene& scene) override;
  Correspondences correspondences(const Scene& scene, size_t query_index) override;

 private:
  OracleDepthOptions options_;
};

}  // namespace ffloc
