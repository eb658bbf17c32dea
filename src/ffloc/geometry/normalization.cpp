#include "ffloc/geometry/normalization.h"

#include <algorithm>
#include <cmath>

#include "ffloc/core/error.h"

namespace ffloc {

SceneNormalization SceneNormalization::fromMappingPoses(const std::vector<Pose>& mapping_poses,
                                                        size_t reference_index,
                                                        const std::vector<std::string>& names) {
  if (mapping_poses.empty()) throw InputError("scene normalisation: no mapping poses");
  if (reference_index >= mapping_poses.size())
    throw InputError("scene normalisation: reference index " + std::to_string(reference_index) +
                     " out of range (" + std::to_string(mapping_poses.size()) + " mapping poses)");
  for (size_t k = 0; k < mapping_poses.size(); ++k) {
    if (!mapping_poses[k].isFinite()) {
      const std::string name = k < names.size() ? names[k] : "mapping pose #" + std::to_string(k);
      throw InputError(name + ": pose: non-finite value in camera-to-world pose");
    }
  }
  SceneNormalization n;
  n.reference = mapping_poses[reference_index];
  const Pose reference_inverse = n.reference.inverse();
  double largest = 0;
  for (const Pose& pose : mapping_poses)
    largest = std::max(largest, (reference_inverse * pose).t.cwiseAbs().maxCoeff());
  n.scale = largest > kDegenerateScale ? largest : 1.0;
  return n;
}

Pose SceneNormalization::normalize(const Pose& world_pose) const {
  Pose p = reference.inverse() * world_pose;
  p.t /= scale;
  return p;
}

Pose SceneNormalization::denormalize(const Pose& normalized_pose) const {
  Pose p = normalized_pose;
  p.t *= scale;
  return reference * p;
}

Eigen::Vector3d SceneNormalization::normalize(const Eigen::Vector3d& world_point) const {
  return (reference.inverse() * world_point) / scale;
}

Eigen::Vector3d SceneNormalization::toWorld(const Eigen::Vector3d& normalized_point) const {
  return reference * (normalized_point * scale);
}

}  // namespace ffloc
