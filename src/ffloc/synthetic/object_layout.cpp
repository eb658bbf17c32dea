#include <cmath>

#include "ffloc/synthetic/det_math.h"
#include "ffloc/synthetic/layouts.h"
#include "ffloc/synthetic/palette.h"
#include "ffloc/synthetic/props.h"
#include "ffloc/synthetic/room.h"

namespace ffloc::synthetic {
namespace {

Material smallScale(Material m, double scale) {
  m.period *= scale;
  return m;
}

// A composite object of about `size`: a base part with a few parts stacked on and around it,
// each in its own material (a toy, a vase with fruit, a gadget).
void addCentrepiece(Prop& prop, World& world, Rng& rng, double size) {
  auto material = [&]() {
    const int family = rng.index(5);
    if (family == 0) return world.addMaterial(smallScale(marbleMaterial(rng), 0.3));
    if (family == 1) return world.addMaterial(smallScale(woodMaterial(rng), 0.3));
    if (family == 2) return world.addMaterial(fabricMaterial(rng, 0.4));
    if (family == 3) return world.addMaterial(posterMaterial(rng, 0.3));
    return world.addMaterial(plasticMaterial(rng, 1.0));
  };
  const ShapeKind kinds[] = {ShapeKind::kBox, ShapeKind::kCylinder, ShapeKind::kEllipsoid,
                             ShapeKind::kCone, ShapeKind::kWedge};
  const Vec3 base_half{size * rng.uniform(0.3, 0.5), size * rng.uniform(0.3, 0.5),
                       size * rng.uniform(0.2, 0.35)};
  const ShapeKind base_kind = rng.chance(0.5) ? ShapeKind::kBox : ShapeKind::kCylinder;
  const int base_material = material();
  prop.add(base_kind, {0, 0, base_half.z}, base_half, base_material);
  double top = 2.0 * base_half.z;
  const int parts = 2 + rng.index(4);
  for (int i = 0; i < parts; ++i) {
    const ShapeKind kind = kinds[rng.index(5)];
    const Vec3 half{size * rng.uniform(0.1, 0.3), size * rng.uniform(0.1, 0.3),
                    size * rng.uniform(0.1, 0.3)};
    const bool stacked = rng.chance(0.6);
    const Vec3 offset{rng.uniform(-0.6, 0.6) * base_half.x, rng.uniform(-0.6, 0.6) * base_half.y, 0.0};
    const double yaw = rng.uniform(0.0, 2.0 * kPi);
    const int part_material = material();
    const double z = stacked ? top + half.z : half.z;
    const Vec3 side = stacked ? Vec3{0, 0, 0}
                              : Vec3{(offset.x >= 0 ? 1.0 : -1.0) * (base_half.x + half.x), 0, 0};
    prop.add(kind, offset + side + Vec3{0, 0, z}, half, part_material, yawRotation(yaw));
    if (stacked) top += 2.0 * half.z * 0.8;
  }
}

}  // namespace

Layout buildObjectLayout(Rng& rng, const Intrinsics& camera, int mapping_frames,
                         int query_frames) {
  Layout layout;
  World& world = layout.world;
  const double length = rng.uniform(3.8, 6.0);
  const double width = rng.uniform(3.5, 5.5);
  const double height = rng.uniform(2.5, 3.0);
  addRoomShell(world, rng, length, width, height);
  const double table_h = rng.uniform(0.7, 0.8);
  const double table_w = rng.uniform(1.2, 1.8), table_d = rng.uniform(0.8, 1.1);
  {
    Prop table({0, 0, 0}, rng.uniform(0.0, kPi));
    addTable(table, world, rng, table_w, table_d, table_h, false);
    commit(world, table);
  }
  const double size = rng.uniform(0.12, 0.35);
  {
    Prop piece({0, 0, table_h}, rng.uniform(0.0, 2.0 * kPi));
    addCentrepiece(piece, world, rng, size);
    commit(world, piece);
  }
  const int clutter = 2 + rng.index(4);
  for (int i = 0; i < clutter; ++i) {
    const double angle = rng.uniform(0.0, 2.0 * kPi);
    const double r = rng.uniform(size * 0.9 + 0.08, std::fmin(table_d / 2 - 0.05, size * 2.0 + 0.15));
    Prop item({r * detCos(angle), r * detSin(angle), table_h}, 0.0);
    const double item_size = rng.uniform(0.04, 0.12);
    addSmallObject(item, world, rng, {0, 0, 0}, item_size);
    commit(world, item);
  }

  // The scan: an orbit around the object, looking at it, rising and dipping a little.
  const Vec3 target{0, 0, table_h + size * 0.4};
  const double orbit = size * rng.uniform(2.2, 3.2) + 0.2;
  const double elevation = degrees(rng.uniform(22.0, 40.0));
  const double start = rng.uniform(0.0, 2.0 * kPi);
  for (int i = 0; i < mapping_frames; ++i) {
    const double phi = start + 2.0 * kPi * i / mapping_frames;
    const double e = elevation + degrees(8.0) * detSin(2.0 * phi);
    CameraState c;
    c.position = target + direction(phi, e) * orbit;
    const Vec3 aim = target + Vec3{0.02 * detSin(3.0 * phi), 0.02 * detCos(5.0 * phi), 0.0};
    c.forward = normalized(aim - c.position);
    c.roll = 0.04 * detSin(3.0 * phi);
    layout.mapping.push_back(c);
  }
  FloorPlan plan;
  plan.taken.push_back(Aabb{{-table_w, -table_w, 0.0}, {table_w, table_w, 2.0}});
  for (const auto& c : layout.mapping) plan.keep_clear.push_back(c.position);
  plan.keep_clear_radius = 0.3;
  furnishWalls(world, rng, plan, length, width, height, 24);
  world.buildBvh();

  layout.mapping_lighting = roomLighting(rng, length * 0.5, width * 0.5, height);
  QuerySampling sampling;
  sampling.near_translation = orbit * 0.12;
  sampling.near_rotation = 0.1;
  sampling.requirements = {0.03, 0.08, 0.15, 0.95};
  sampling.far_candidate = [=](Rng& r) {
    const double phi = r.uniform(0.0, 2.0 * kPi);
    const bool high = r.chance(0.5);
    const double e = degrees(high ? r.uniform(55.0, 70.0) : r.uniform(8.0, 15.0));
    const double distance = orbit * r.uniform(1.5, 2.4);
    CameraState c;
    c.position = target + direction(phi, e) * distance;
    // Stay inside the room: pull the camera in towards the object until it is.
    for (double pull = 0.9; std::fabs(c.position.x) > length / 2 - 0.3 ||
                            std::fabs(c.position.y) > width / 2 - 0.3 ||
                            c.position.z > height - 0.3;
         pull *= 0.9)
      c.position = target + direction(phi, e) * (distance * pull);
    c.forward = normalized(target - c.position);
    return c;
  };
  layout.queries = sampleQueries(rng, world, camera, layout.mapping, query_frames, sampling);
  for (int q = 0; q < query_frames; ++q)
    layout.query_lighting.push_back(relight(rng, layout.mapping_lighting, length * 0.5, width * 0.5, height));
  return layout;
}

}  // namespace ffloc::synthetic
