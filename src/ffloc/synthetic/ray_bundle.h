#pragma once

#include <vector>

#include "ffloc/synthetic/bvh.h"
#include "ffloc/synthetic/world.h"

namespace ffloc::synthetic {

// The shapes a bundle of rays may meet, collected with one walk of the tree for the whole
// bundle (a tile of camera rays, or their shadow rays towards one light), so each ray tests a
// short list of boxes instead of walking the tree itself. The regions are conservative, with
// slack far above floating-point rounding, so a listed search returns the same hits as the
// tree. `listed` false: the list came out longer than a tree walk costs; use the tree.
struct RayBundle {
  std::vector<BoxedShape> list;
  bool listed = false;
};

// Rays from `apex` with directions in the pyramid spanned by the four `corners` (in order
// around it), out to `max_length` times their direction.
void collectFromPoint(const World& world, const Vec3& apex, const Vec3 corners[4],
                      double max_length, RayBundle& bundle);

// Rays from origins inside `origins` towards the point `light`, each ending within
// `end_offset` of it. Not listed when `origins` is not wholly on one side of the light along
// some axis.
void collectTowardsPoint(const World& world, const Aabb& origins, const Vec3& light,
                         double end_offset, RayBundle& bundle);

// Rays from origins inside `origins` along the unit vector `direction`, out to `length`.
void collectAlong(const World& world, const Aabb& origins, const Vec3& direction, double length,
                  RayBundle& bundle);

}  // namespace ffloc::synthetic
