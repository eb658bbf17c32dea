#include "ffloc/synthetic/room.h"

#include <cmath>

#include "ffloc/synthetic/det_math.h"
#include "ffloc/synthetic/palette.h"
#include "ffloc/synthetic/props.h"

namespace ffloc::synthetic {
namespace {

// Wall k's inner face: its centre, the yaw that turns a prop's local +y into the room, and
// its length.
struct Wall {
  Vec3 centre;
  double yaw;
  double length;
};

Wall wall(int k, double length, double width) {
  switch (k) {
    case 0: return {{0, -width / 2, 0}, 0.0, length};
    case 1: return {{length / 2, 0, 0}, kPi / 2, width};
    case 2: return {{0, width / 2, 0}, kPi, length};
    default: return {{-length / 2, 0, 0}, -kPi / 2, width};
  }
}

Vec3 along(const Wall& w) { return {detCos(w.yaw), detSin(w.yaw), 0.0}; }

double horizontalDistance(const Aabb& box, const Vec3& p) {
  const double dx = std::fmax(0.0, std::fmax(box.lo.x - p.x, p.x - box.hi.x));
  const double dy = std::fmax(0.0, std::fmax(box.lo.y - p.y, p.y - box.hi.y));
  return std::sqrt(dx * dx + dy * dy);
}

bool overlaps(const Aabb& a, const Aabb& b) {
  return a.lo.x < b.hi.x && b.lo.x < a.hi.x && a.lo.y < b.hi.y && b.lo.y < a.hi.y &&
         a.lo.z < b.hi.z && b.lo.z < a.hi.z;
}

}  // namespace

bool FloorPlan::fits(const Aabb& box) const {
  for (const auto& t : taken)
    if (overlaps(box, t)) return false;
  for (const auto& p : keep_clear)
    if (horizontalDistance(box, p) < keep_clear_radius) return false;
  return true;
}

void addRoomShell(World& world, Rng& rng, double length, double width, double height) {
  const double t = 0.1;
  const int floor_kind = rng.index(3);
  Material floor_m = floor_kind == 0   ? woodMaterial(rng, 1.5)
                     : floor_kind == 1 ? tileMaterial(rng)
                                       : fabricMaterial(rng, 0.5);
  if (floor_kind == 2) floor_m.pattern = Pattern::kStone;  // carpet
  const int floor = world.addMaterial(floor_m);
  const int ceiling = world.addMaterial(paintMaterial(rng));
  const int paint = world.addMaterial(paintMaterial(rng));
  const int feature_kind = rng.index(4);
  const int feature = world.addMaterial(feature_kind == 0   ? wallpaperMaterial(rng)
                                        : feature_kind == 1 ? brickMaterial(rng)
                                        : feature_kind == 2 ? tileMaterial(rng, 0.4)
                                                            : paintMaterial(rng));
  const int feature_wall = rng.index(4);
  world.addShape({ShapeKind::kBox, Mat3(), {0, 0, -t}, {length / 2 + t, width / 2 + t, t}, floor});
  world.addShape({ShapeKind::kBox, Mat3(), {0, 0, height + t}, {length / 2 + t, width / 2 + t, t}, ceiling});
  const int skirting = world.addMaterial(paintMaterial(rng));
  for (int k = 0; k < 4; ++k) {
    const Wall w = wall(k, length, width);
    Prop prop(w.centre, w.yaw);
    prop.box({0, -t, height / 2}, {w.length / 2 + 2 * t, t, height / 2}, k == feature_wall ? feature : paint);
    prop.box({0, 0.01, 0.05}, {w.length / 2, 0.01, 0.05}, skirting);
    commit(world, prop);
  }
  const Wall door_wall = wall(rng.index(4), length, width);
  if (door_wall.length > 2.0) {
    const double s = rng.uniform(-door_wall.length / 2 + 0.8, door_wall.length / 2 - 0.8);
    Prop door(door_wall.centre + along(door_wall) * s, door_wall.yaw);
    const int wood = world.addMaterial(woodMaterial(rng));
    const int handle = world.addMaterial(metalMaterial(rng));
    door.box({0, 0.02, 1.03}, {0.45, 0.02, 1.03}, wood);
    door.add(ShapeKind::kEllipsoid, {0.35, 0.06, 1.0}, {0.03, 0.03, 0.03}, handle);
    commit(world, door);
  }
}

void furnishWalls(World& world, Rng& rng, FloorPlan& plan, double length, double width,
                  double height, int attempts) {
  for (int attempt = 0; attempt < attempts; ++attempt) {
    const Wall w = wall(rng.index(4), length, width);
    const int kind = rng.index(11);
    double span = 0.0, depth = 0.0;
    switch (kind) {
      case 0: span = rng.uniform(0.6, 1.4); depth = rng.uniform(0.25, 0.4); break;   // shelf
      case 1: span = rng.uniform(0.6, 1.6); depth = rng.uniform(0.4, 0.6); break;    // cabinet
      case 2: span = rng.uniform(1.5, 2.2); depth = rng.uniform(0.8, 1.0); break;    // sofa
      case 3: span = rng.uniform(0.9, 1.8); depth = 2.0; break;                       // bed
      case 4: span = rng.uniform(0.8, 1.5); depth = rng.uniform(0.5, 0.8); break;    // desk
      case 5: span = 0.5; depth = 0.5; break;                                         // plant
      case 6: span = 0.5; depth = 0.5; break;                                         // lamp
      default: span = rng.uniform(0.4, 1.2); depth = 0.05; break;                    // picture
    }
    if (span > w.length - 0.4) continue;
    const double s = rng.uniform(-w.length / 2 + span / 2 + 0.1, w.length / 2 - span / 2 - 0.1);
    Prop prop(w.centre + along(w) * s, w.yaw);
    switch (kind) {
      case 0: {
        const double h = rng.uniform(1.2, std::fmin(2.2, height - 0.3));
        addShelf(prop, world, rng, span, depth, h);
        break;
      }
      case 1: {
        const double h = rng.uniform(0.7, 1.2);
        addCabinet(prop, world, rng, span, depth, h);
        break;
      }
      case 2: addSofa(prop, world, rng, span, depth); break;
      case 3: addBed(prop, world, rng, span, depth); break;
      case 4: {
        Prop desk(prop.toWorld({0, depth / 2, 0}), w.yaw);
        addTable(desk, world, rng, span, depth, 0.74, true);
        prop = desk;
        break;
      }
      case 5: {
        Prop plant(prop.toWorld({0, 0.3, 0}), w.yaw);
        const double h = rng.uniform(0.5, 1.4);
        addPlant(plant, world, rng, h);
        prop = plant;
        break;
      }
      case 6: {
        Prop lamp(prop.toWorld({0, 0.3, 0}), w.yaw);
        addFloorLamp(lamp, world, rng);
        prop = lamp;
        break;
      }
      default: {
        const double h = rng.uniform(0.3, 0.9);
        const double z = rng.uniform(1.2, std::fmin(1.8, height - h / 2 - 0.2));
        addPicture(prop, world, rng, span, h, z);
        break;
      }
    }
    const Aabb box = prop.bounds();
    if (!plan.fits(box)) continue;
    plan.taken.push_back(box);
    commit(world, prop);
  }
}

Lighting roomLighting(Rng& rng, double length, double width, double height) {
  Lighting light;
  light.sun_colour = {0, 0, 0};
  const double ambient = rng.uniform(0.18, 0.3);
  light.sky_ambient = Vec3{1.0, 0.98, 0.95} * ambient;
  light.ground_ambient = Vec3{0.6, 0.55, 0.5} * ambient;
  const int lamps = 1 + rng.index(3);
  const double warmth = rng.uniform(0.0, 1.0);
  const Vec3 tint = lerp(Vec3{0.95, 0.97, 1.0}, Vec3{1.0, 0.82, 0.6}, warmth);
  const double power = rng.uniform(2.5, 4.5) * (height / 2.8) * (height / 2.8) * 3.0 / lamps;
  for (int i = 0; i < lamps; ++i) {
    PointLight lamp;
    lamp.position = {rng.uniform(-0.35, 0.35) * length, rng.uniform(-0.35, 0.35) * width,
                     height - 0.35};
    lamp.colour = tint * power;
    light.lamps.push_back(lamp);
  }
  light.cloudiness = 0.0;
  light.exposure = rng.uniform(0.9, 1.15);
  return light;
}

Lighting daylight(Rng& rng, double scale) {
  Lighting light;
  const double azimuth = rng.uniform(0.0, 2.0 * kPi);
  const double elevation = degrees(rng.uniform(20.0, 65.0));
  light.sun_direction = direction(azimuth, elevation);
  light.sun_colour = Vec3{1.0, 0.95, 0.86} * rng.uniform(2.0, 2.8);
  light.sky_ambient = Vec3{0.38, 0.45, 0.58} * rng.uniform(0.8, 1.1);
  light.ground_ambient = {0.2, 0.18, 0.15};
  light.sky_zenith = {0.22, 0.42, 0.85};
  light.sky_horizon = {0.72, 0.8, 0.9};
  light.cloudiness = rng.uniform(0.1, 0.5);
  light.fog_distance = 200.0 + 8.0 * scale;
  light.exposure = rng.uniform(0.75, 0.95);
  return light;
}

Lighting relight(Rng& rng, const Lighting& base, double length, double width, double height) {
  Lighting light = base;
  light.exposure = base.exposure * rng.uniform(0.75, 1.3);
  if (!base.lamps.empty()) {
    const double warmth = rng.uniform(0.0, 1.0);
    const Vec3 tint = lerp(Vec3{0.85, 0.93, 1.1}, Vec3{1.05, 0.8, 0.55}, warmth);
    for (auto& lamp : light.lamps) {
      lamp.position = {rng.uniform(-0.4, 0.4) * length, rng.uniform(-0.4, 0.4) * width,
                       height - rng.uniform(0.3, 0.6)};
      lamp.colour = tint * (norm(lamp.colour) / norm(Vec3{1, 1, 1}) * rng.uniform(0.5, 1.6));
    }
    // Daylight through unseen windows: a brighter, bluer fill.
    if (rng.chance(0.4)) {
      light.sky_ambient = mul(light.sky_ambient, Vec3{1.2, 1.35, 1.6});
      light.lamps.resize(light.lamps.size() > 1 ? light.lamps.size() - 1 : 1);
    }
    return light;
  }
  const double mood = rng.uniform();
  const double azimuth = rng.uniform(0.0, 2.0 * kPi);
  if (mood < 0.3) {  // overcast
    light.sun_direction = direction(azimuth, degrees(50.0));
    light.sun_colour = base.sun_colour * 0.15;
    light.sky_ambient = Vec3{0.75, 0.78, 0.82} * rng.uniform(0.9, 1.2);
    light.sky_zenith = {0.55, 0.58, 0.62};
    light.sky_horizon = {0.75, 0.76, 0.78};
    light.cloudiness = 1.0;
  } else if (mood < 0.55) {  // low evening sun
    light.sun_direction = direction(azimuth, degrees(rng.uniform(7.0, 18.0)));
    light.sun_colour = Vec3{1.0, 0.62, 0.32} * rng.uniform(1.8, 2.6);
    light.sky_ambient = Vec3{0.32, 0.3, 0.38} * rng.uniform(0.8, 1.1);
    light.sky_zenith = {0.2, 0.28, 0.55};
    light.sky_horizon = {0.95, 0.65, 0.4};
    light.exposure *= 1.15;
  } else {  // another time of day
    light.sun_direction = direction(azimuth, degrees(rng.uniform(20.0, 70.0)));
    light.sun_colour = base.sun_colour * rng.uniform(0.8, 1.2);
    light.cloudiness = rng.uniform(0.0, 0.7);
  }
  return light;
}

}  // namespace ffloc::synthetic
