#pragma once

#include <string>

#include "ffloc/geometry/camera.h"
#include "ffloc/geometry/pose.h"

namespace ffloc {

// A mapping image as every method and the map assembly know it.
struct MapCamera {
  std::string name;
  Pose camera_to_world;
  Intrinsics intrinsics;  // of the image the method works on
};

}  // namespace ffloc
