#pragma once

#include <string>
#include <vector>

#include "ffloc/geometry/pose.h"

namespace ffloc {

// Scene and scale normalisation (FastForward paper, section 3.1). A reference mapping camera P_0
// becomes the origin: every mapping pose becomes P_0^-1 P_k. The scale s is the largest |x|,
// |y| or |z| over the normalised mapping translations; normalised translations are divided by
// s. Network outputs live in this normalised frame; toWorld() maps them back (times s, then
// P_0).
//
// Degenerate cases, by rule rather than by division by zero:
// - one mapping camera, or all mapping cameras at one position (s would be 0): s = 1, so the
//   normalised frame keeps the world's units. The network then sees translations of 0, which is
//   what those inputs really are.
// - a non-finite pose: InputError naming the frame.
struct SceneNormalization {
  Pose reference;    // P_0, camera-to-world of the reference mapping camera
  double scale = 1;  // s, always > 0

  // Builds the normalisation of `mapping_poses` (camera-to-world) with mapping_poses[reference_index]
  // as P_0. `names` (same length, may be empty) name the frames in errors.
  static SceneNormalization fromMappingPoses(const std::vector<Pose>& mapping_poses,
                                             size_t reference_index = 0,
                                             const std::vector<std::string>& names = {});

  // World camera-to-world pose -> normalised camera-to-world pose (rotation P_0^-1 R, translation / s).
  Pose normalize(const Pose& world_pose) const;
  Pose denormalize(const Pose& normalized_pose) const;
  // World point -> normalised point and back.
  Eigen::Vector3d normalize(const Eigen::Vector3d& world_point) const;
  Eigen::Vector3d toWorld(const Eigen::Vector3d& normalized_point) const;
};

// Translations below this magnitude count as "all cameras at one position".
inline constexpr double kDegenerateScale = 1e-9;

}  // namespace ffloc
