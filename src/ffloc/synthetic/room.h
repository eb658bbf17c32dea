#pragma once

#include <vector>

#include "ffloc/synthetic/capture.h"
#include "ffloc/core/random.h"
#include "ffloc/synthetic/world.h"

namespace ffloc::synthetic {

// Floor, ceiling, four walls (one possibly papered, tiled or brick), skirting boards and a
// door, around the rectangle [-length/2, length/2] x [-width/2, width/2], floor at z = 0.
void addRoomShell(World& world, Rng& rng, double length, double width, double height);

// Space already taken, so props neither overlap each other nor the camera path.
struct FloorPlan {
  std::vector<Aabb> taken;
  std::vector<Vec3> keep_clear;  // camera positions
  double keep_clear_radius = 0.5;

  bool fits(const Aabb& box) const;
};

// Furniture against the walls (shelves, cabinets, sofas, beds, plants, lamps, desks) and
// pictures on them.
void furnishWalls(World& world, Rng& rng, FloorPlan& plan, double length, double width,
                  double height, int attempts);

// Ceiling lamps over the room.
Lighting roomLighting(Rng& rng, double length, double width, double height);
// The sun and sky over an outdoor scene, `scale` being its size in metres (sets the haze).
Lighting daylight(Rng& rng, double scale);
// The same place under other light: lamps moved, dimmed or recoloured, another time of day,
// an overcast sky, a different exposure.
Lighting relight(Rng& rng, const Lighting& base, double length, double width, double height);

}  // namespace ffloc::synthetic
