#pragma once

#include <vector>

#include "ffloc/synthetic/capture.h"
#include "ffloc/core/random.h"
#include "ffloc/synthetic/world.h"

namespace ffloc::synthetic {

// A generated scene before rendering: geometry, the capture (a mapping scan and queries) and
// the illumination of each.
struct Layout {
  World world;  // BVH built
  std::vector<CameraState> mapping;
  QueryPlan queries;
  Lighting mapping_lighting;
  std::vector<Lighting> query_lighting;  // one per query
};

// A furnished room (4.5-9 m x 3.5-7 m) scanned by walking a loop and looking at the walls.
Layout buildIndoorLayout(Rng& rng, const Intrinsics& camera, int mapping_frames, int query_frames);
// A plaza (12-30 m radius) ringed by buildings, with a landmark, trees, cars and benches,
// scanned by walking around it.
Layout buildOutdoorLayout(Rng& rng, const Intrinsics& camera, int mapping_frames, int query_frames);
// A desk-scale object (0.12-0.35 m) on a table in a room, scanned by orbiting it.
Layout buildObjectLayout(Rng& rng, const Intrinsics& camera, int mapping_frames, int query_frames);

}  // namespace ffloc::synthetic
