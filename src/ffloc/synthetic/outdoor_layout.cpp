#include <algorithm>
#include <cmath>

#include "ffloc/synthetic/det_math.h"
#include "ffloc/synthetic/layouts.h"
#include "ffloc/synthetic/palette.h"
#include "ffloc/synthetic/props.h"
#include "ffloc/synthetic/room.h"

namespace ffloc::synthetic {

Layout buildOutdoorLayout(Rng& rng, const Intrinsics& camera, int mapping_frames,
                          int query_frames) {
  Layout layout;
  World& world = layout.world;
  const double radius = rng.uniform(12.0, 30.0);
  const int ground = world.addMaterial(groundMaterial(rng));
  world.addShape({ShapeKind::kBox, Mat3(), {0, 0, -0.5}, {600, 600, 0.5}, ground});
  const int paving = world.addMaterial(rng.chance(0.5) ? tileMaterial(rng, 3.0) : brickMaterial(rng, 6.0));
  world.addShape({ShapeKind::kCylinder, Mat3(), {0, 0, 0.0}, {radius + 4.0, radius + 4.0, 0.02}, paving});

  // The scan: a walk around the plaza looking at the facades, with the camera swinging
  // left and right.
  const double a = radius * rng.uniform(0.55, 0.7);
  const double b = a * rng.uniform(0.75, 1.0);
  const double start = rng.uniform(0.0, 2.0 * kPi);
  const double sweep_phase = rng.uniform(0.0, 2.0 * kPi);
  for (int i = 0; i < mapping_frames; ++i) {
    const double theta = start + 2.0 * kPi * i / mapping_frames;
    CameraState c;
    c.position = {a * detCos(theta), b * detSin(theta), 1.6 + 0.05 * detSin(9.0 * theta)};
    const Vec3 outward = normalized(Vec3{c.position.x / a, c.position.y / b, 0.0});
    c.forward = turn(outward, 0.7 * detSin(2.0 * theta + sweep_phase),
                     0.1 + 0.05 * detSin(4.0 * theta));
    c.roll = 0.02 * detSin(5.0 * theta);
    layout.mapping.push_back(c);
  }
  FloorPlan plan;
  for (const auto& c : layout.mapping) plan.keep_clear.push_back(c.position);
  plan.keep_clear_radius = 1.5;

  // Buildings around the plaza, fronts facing its centre.
  const int buildings = std::max(8, std::min(20, static_cast<int>(2.0 * kPi * (radius + 10.0) / 16.0)));
  const double arc = 2.0 * kPi / buildings;
  for (int i = 0; i < buildings; ++i) {
    const double angle = i * arc + rng.uniform(-0.15, 0.15) * arc;
    const double depth = rng.uniform(8.0, 18.0);
    const double distance = radius + rng.uniform(4.0, 9.0) + depth / 2;
    const double width = std::fmax(6.0, rng.uniform(0.65, 0.95) * arc * (distance - depth / 2));
    const double height = rng.uniform(6.0, 12.0 + radius);
    Prop building({distance * detCos(angle), distance * detSin(angle), 0.0}, angle + kPi / 2);
    addBuilding(building, world, rng, width, depth, height);
    commit(world, building);
  }
  {
    const double size = rng.uniform(5.0, std::fmin(14.0, 1.6 * (std::fmin(a, b) - 2.0)));
    Prop landmark({0, 0, 0}, rng.uniform(0.0, 2.0 * kPi));
    addLandmark(landmark, world, rng, size);
    plan.taken.push_back(landmark.bounds());
    commit(world, landmark);
  }
  // Street furniture and trees inside the plaza and along its edge; cars on the road.
  for (int attempt = 0; attempt < 45; ++attempt) {
    const double angle = rng.uniform(0.0, 2.0 * kPi);
    const int kind = rng.index(5);
    const double r = kind == 4 ? radius + rng.uniform(1.0, 3.0) : radius * rng.uniform(0.25, 1.05);
    const double yaw = kind == 4 ? angle + kPi / 2 : rng.uniform(0.0, 2.0 * kPi);
    Prop prop({r * detCos(angle), r * detSin(angle), 0.0}, yaw);
    switch (kind) {
      case 0:
      case 1: {
        const double h = rng.uniform(4.0, 11.0);
        addTree(prop, world, rng, h);
        break;
      }
      case 2: addLampPost(prop, world, rng); break;
      case 3: addBench(prop, world, rng); break;
      default: addCar(prop, world, rng); break;
    }
    const Aabb box = prop.bounds();
    if (!plan.fits(box)) continue;
    plan.taken.push_back(box);
    commit(world, prop);
  }
  world.buildBvh();

  layout.mapping_lighting = daylight(rng, radius);
  QuerySampling sampling;
  sampling.near_translation = 0.6;
  sampling.near_rotation = 0.12;
  sampling.requirements = {0.6, 2.0, 0.15, 0.35};
  sampling.far_candidate = [=](Rng& r) {
    CameraState c;
    const double angle = r.uniform(0.0, 2.0 * kPi);
    const double dist = radius * r.uniform(0.1, 1.0);
    c.position = {dist * detCos(angle), dist * detSin(angle), r.uniform(1.4, 1.9)};
    c.forward = direction(r.uniform(0.0, 2.0 * kPi), r.uniform(0.0, 0.2));
    return c;
  };
  layout.queries = sampleQueries(rng, world, camera, layout.mapping, query_frames, sampling);
  for (int q = 0; q < query_frames; ++q)
    layout.query_lighting.push_back(relight(rng, layout.mapping_lighting, 0, 0, 0));
  return layout;
}

}  // namespace ffloc::synthetic
