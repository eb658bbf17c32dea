#pragma once

#include <Eigen/Core>
#include <array>
#include <filesystem>
#include <string>
#include <vector>

#include "ffloc/eval/metrics.h"
#include "ffloc/geometry/camera.h"
#include "ffloc/geometry/pose.h"

namespace ffloc {

// Why `name` cannot be the first field of a pose list line, empty when it can. The lists are
// split on whitespace by every reader (hloc's, the map-free benchmark's), so a name with
// whitespace would be read as another name and numbers, and one with a newline as two lines:
// such names, names with other control characters, empty names and names that are not UTF-8 are
// refused rather than escaped, as no reader would undo an escape.
std::string poseListNameProblem(const std::string& name);

// hloc / Cambridge pose list: one line per succeeded frame, `name qw qx qy qz tx ty tz`, the
// world-to-camera rotation (Hamilton, scalar first) and translation. Failed frames are left out,
// as hloc's readers expect. InputError "poses: frame '<name>': ..." for a name the list cannot
// hold (poseListNameProblem); callers check their names before the work that makes the poses.
std::string hlocPoseList(const std::vector<FrameResult>& frames);

// Map-free relocalisation submission lines: `name qw qx qy qz tx ty tz confidence`, world-to-camera,
// confidence = inlier count. Failed frames are left out; names are refused as hlocPoseList does.
std::string mapFreeSubmission(const std::vector<FrameResult>& frames);

// A coloured point cloud with camera frusta, as ASCII PLY, for MeshLab or CloudCompare.
class PlyWriter {
 public:
  using Colour = std::array<uint8_t, 3>;
  static constexpr Colour kGrey{150, 150, 150}, kGreen{40, 200, 40}, kBlue{40, 90, 230}, kRed{220, 50, 50};

  void addPoint(const Eigen::Vector3d& point, Colour colour);
  // A pyramid with its apex at the camera centre and its base `size` units along the optical axis,
  // with the aspect of the image.
  void addCamera(const Pose& camera_to_world, const Intrinsics& intrinsics, double size, Colour colour);
  std::string str() const;
  // Atomic write; InputError naming the file on failure.
  void write(const std::filesystem::path& path) const;

 private:
  struct Vertex {
    Eigen::Vector3d position;
    Colour colour;
  };
  std::vector<Vertex> vertices_;
  std::vector<std::array<int, 3>> faces_;
};

}  // namespace ffloc
