#pragma once

#include <functional>
#include <vector>

#include "ffloc/core/random.h"
#include "ffloc/synthetic/world.h"
#include "ffloc/geometry/camera.h"
#include "ffloc/geometry/pose.h"

namespace ffloc::synthetic {

// A camera as the layouts think of it: where it is, where it looks (unit vector), and the roll
// about that direction. World up is +z.
struct CameraState {
  Vec3 position;
  Vec3 forward{1, 0, 0};
  double roll = 0.0;  // radians
};

// Camera-to-world pose with OpenCV axes (x right, y down, z forward).
Pose toPose(const CameraState& camera);

// forward rotated by `yaw` about world up, then by `pitch` towards up.
Vec3 turn(const Vec3& forward, double yaw, double pitch);
// Horizontal direction at angle `yaw` from +x, tilted by `pitch` (radians).
Vec3 direction(double yaw, double pitch);

// How queries relate to the mapping scan: the paper's easy and hard cases.
enum class QueryKind { kNear, kFar, kOpposite };
const char* toString(QueryKind kind);

struct ViewRequirements {
  double clearance = 0.3;            // the camera centre keeps this far from every shape's box
  double min_depth = 0.3;            // sampled rays nearer than this count as blocked
  double max_blocked_fraction = 0.15;
  double min_hit_fraction = 0.9;     // outdoors less: the sky has no depth
};

// Whether a camera sees a usable view: not inside or against geometry, enough surface.
bool viewIsUsable(const World& world, const Intrinsics& camera, const CameraState& state,
                  const ViewRequirements& requirements);

struct QueryPlan {
  std::vector<CameraState> cameras;
  std::vector<QueryKind> kinds;
};

struct QuerySampling {
  double near_translation = 0.2;  // scene units, std-dev per horizontal axis
  double near_rotation = 0.14;    // radians, std-dev of yaw
  // Draws a candidate far view; the sampler keeps the one farthest from the mapping scan.
  std::function<CameraState(Rng&)> far_candidate;
  ViewRequirements requirements;
};

// Queries cycling near / far / opposite. Near: a mapping camera moved and turned a little.
// Far: the candidate (of several) farthest from every mapping camera. Opposite: a mapping
// camera turned around (180 deg +- 20). Every query passes viewIsUsable.
QueryPlan sampleQueries(Rng& rng, const World& world, const Intrinsics& camera,
                        const std::vector<CameraState>& mapping, int count,
                        const QuerySampling& sampling);

}  // namespace ffloc::synthetic
