#pragma once

#include <optional>
#include <string>
#include <vector>

#include "ffloc/geometry/camera.h"

// COLMAP's camera models, which kapture uses under the same names and parameter orders.
namespace ffloc {

// "SIMPLE_PINHOLE, PINHOLE, SIMPLE_RADIAL, RADIAL, OPENCV, FULL_OPENCV", for error messages.
extern const char* const kSupportedColmapModels;

// How many parameters (after width and height) `model` takes; nullopt for a model ffloc does not
// read (the fisheye and FOV models, UNKNOWN_CAMERA).
std::optional<size_t> colmapModelParameterCount(const std::string& model);

// The intrinsics of a supported model, width and height left at 0. COLMAP puts the top-left
// pixel's centre at (0.5, 0.5), OpenCV at (0, 0): principal points are shifted by -0.5. All-zero
// distortion is dropped.
Intrinsics colmapIntrinsics(const std::string& model, const std::vector<double>& parameters);

// The inverse: PINHOLE without distortion, OPENCV with 4 coefficients, FULL_OPENCV with more (5
// are padded with zeros), principal point shifted by +0.5.
struct ColmapCamera {
  std::string model;
  std::vector<double> parameters;
};
ColmapCamera colmapCamera(const Intrinsics& intrinsics);

}  // namespace ffloc
