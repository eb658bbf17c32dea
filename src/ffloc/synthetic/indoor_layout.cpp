#include <cmath>

#include "ffloc/synthetic/det_math.h"
#include "ffloc/synthetic/layouts.h"
#include "ffloc/synthetic/palette.h"
#include "ffloc/synthetic/props.h"
#include "ffloc/synthetic/room.h"

namespace ffloc::synthetic {

Layout buildIndoorLayout(Rng& rng, const Intrinsics& camera, int mapping_frames,
                         int query_frames) {
  Layout layout;
  World& world = layout.world;
  const double length = rng.uniform(4.5, 9.0);
  const double width = rng.uniform(3.5, 7.0);
  const double height = rng.uniform(2.5, 3.2);
  addRoomShell(world, rng, length, width, height);

  // The scan: one loop around the room, holding the phone at chest height and sweeping it
  // across the walls, as someone mapping a room does.
  const double a = std::fmax(0.6, length / 2 - 1.7), b = std::fmax(0.5, width / 2 - 1.6);
  const double start = rng.uniform(0.0, 2.0 * kPi);
  const double sweep_phase = rng.uniform(0.0, 2.0 * kPi);
  const double eye = rng.uniform(1.3, 1.6);
  const double tilt = -rng.uniform(0.12, 0.3);
  for (int i = 0; i < mapping_frames; ++i) {
    const double theta = start + 2.0 * kPi * i / mapping_frames;
    CameraState c;
    c.position = {a * detCos(theta), b * detSin(theta), eye + 0.06 * detSin(3.0 * theta)};
    const Vec3 outward = normalized(Vec3{c.position.x / a, c.position.y / b, 0.0});
    c.forward = turn(outward, 0.6 * detSin(2.0 * theta + sweep_phase),
                     tilt + 0.08 * detSin(5.0 * theta));
    c.roll = 0.03 * detSin(7.0 * theta);
    layout.mapping.push_back(c);
  }

  FloorPlan plan;
  for (const auto& c : layout.mapping) plan.keep_clear.push_back(c.position);
  plan.keep_clear_radius = 0.55;
  furnishWalls(world, rng, plan, length, width, height, 60);
  // A table in the middle when the loop leaves room for one.
  if (rng.chance(0.7)) {
    const double tw = rng.uniform(0.8, 1.6), td = rng.uniform(0.6, 1.0);
    const double yaw = rng.uniform(0.0, kPi);
    Prop table({rng.uniform(-0.2, 0.2), rng.uniform(-0.2, 0.2), 0.0}, yaw);
    addTable(table, world, rng, tw, td, 0.75, true);
    if (plan.fits(table.bounds())) {
      plan.taken.push_back(table.bounds());
      commit(world, table);
    }
  }
  // A rug under the loop is fine: it is flat.
  if (rng.chance(0.6)) {
    Prop rug({0, 0, 0}, rng.uniform(0.0, kPi));
    const int fabric = world.addMaterial(fabricMaterial(rng));
    rug.box({0, 0, 0.005}, {std::fmin(a + 0.8, 2.0), std::fmin(b + 0.6, 1.5), 0.005}, fabric);
    commit(world, rug);
  }
  world.buildBvh();

  layout.mapping_lighting = roomLighting(rng, length, width, height);
  QuerySampling sampling;
  sampling.near_translation = 0.2;
  sampling.requirements = {0.3, 0.35, 0.15, 0.95};
  sampling.far_candidate = [=](Rng& r) {
    CameraState c;
    c.position = {r.uniform(-0.4, 0.4) * length, r.uniform(-0.4, 0.4) * width,
                  r.uniform(0.6, 1.9)};
    c.forward = direction(r.uniform(0.0, 2.0 * kPi), -r.uniform(0.0, 0.35));
    return c;
  };
  layout.queries = sampleQueries(rng, world, camera, layout.mapping, query_frames, sampling);
  for (int q = 0; q < query_frames; ++q)
    layout.query_lighting.push_back(relight(rng, layout.mapping_lighting, length, width, height));
  return layout;
}

}  // namespace ffloc::synthetic
