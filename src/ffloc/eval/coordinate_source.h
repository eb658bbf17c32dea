#pragma once

#include <memory>
#include <string>

#include "ffloc/data/scene.h"
#include "ffloc/pose/correspondences.h"

namespace ffloc {

// The seam every localisation method plugs into: for a query frame of a scene, produce 2D-3D
// pairs with confidences. Pixels are in the query's undistorted pixel grid
// (frame.intrinsics.undistorted()), points in the scene's world frame. Evaluation and PnP are
// written once, on top of this.
class CoordinateSource {
 public:
  virtual ~CoordinateSource() = default;
  virtual std::string name() const = 0;
  // Called once per scene before its queries (build a map, cache mapping data).
  virtual void prepare(const Scene& /*scene*/) {}
  virtual Correspondences correspondences(const Scene& scene, size_t query_index) = 0;
};

}  // namespace ffloc
