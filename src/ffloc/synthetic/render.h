#pragma once

#include <cstdint>
#include <opencv2/core.hpp>

#include "ffloc/synthetic/world.h"
#include "ffloc/geometry/camera.h"
#include "ffloc/geometry/pose.h"

namespace ffloc::synthetic {

struct RenderOptions {
  // Standard deviation of additive pixel noise, in 8-bit levels; 0 renders clean images.
  double image_noise = 0.0;
  uint64_t noise_seed = 0;
  double max_depth = 5000.0;  // rays that hit nothing nearer (the sky) get depth 0
};

struct RenderedView {
  cv::Mat3b rgb;     // 8-bit, RGB channel order
  cv::Mat1f depth;   // z-depth in metres at each pixel centre; 0 where the ray hits nothing
};

// Casts one ray through the centre of every pixel of a pinhole camera (no distortion). Colour
// and depth come from the same ray, so they agree exactly.
RenderedView renderView(const World& world, const Lighting& lighting, const Intrinsics& camera,
                        const Pose& camera_to_world, const RenderOptions& options = {});

// The z-depth of the surface seen at the (sub)pixel position (u, v), 0 when none: the same ray
// renderView casts at integer positions. Tests use it to check depth maps against geometry.
double castDepth(const World& world, const Intrinsics& camera, const Pose& camera_to_world,
                 double u, double v, double max_depth = 5000.0);

}  // namespace ffloc::synthetic
