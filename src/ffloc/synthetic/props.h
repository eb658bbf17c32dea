#pragma once

#include <vector>

#include "ffloc/core/random.h"
#include "ffloc/synthetic/world.h"

namespace ffloc::synthetic {

Mat3 yawRotation(double yaw);
// A frame whose local z (a cylinder's axis) points along `axis`.
Mat3 axisRotation(const Vec3& axis);

// Collects the parts of one object in the object's own frame (origin on the floor, z up,
// local +y its front) and places them in the world; a layout checks the bounds before
// committing, so objects do not overlap each other or the camera path.
class Prop {
 public:
  Prop(const Vec3& origin, double yaw) : origin_(origin), rotation_(yawRotation(yaw)) {}

  void add(ShapeKind kind, const Vec3& centre, const Vec3& half, int material,
           const Mat3& local_rotation = Mat3());
  void box(const Vec3& centre, const Vec3& half, int material) {
    add(ShapeKind::kBox, centre, half, material);
  }
  Aabb bounds() const;
  const std::vector<Shape>& shapes() const { return shapes_; }
  // Where a point of the object's frame lands in the world.
  Vec3 toWorld(const Vec3& local) const { return origin_ + rotation_ * local; }

 private:
  Vec3 origin_;
  Mat3 rotation_;
  std::vector<Shape> shapes_;
};

// Appends the prop's shapes to the world.
void commit(World& world, const Prop& prop);

// Indoor furniture. Dimensions in metres; each draws its own materials.
void addTable(Prop& prop, World& world, Rng& rng, double width, double depth, double height,
              bool with_clutter);
void addShelf(Prop& prop, World& world, Rng& rng, double width, double depth, double height);
void addCabinet(Prop& prop, World& world, Rng& rng, double width, double depth, double height);
void addSofa(Prop& prop, World& world, Rng& rng, double width, double depth);
void addBed(Prop& prop, World& world, Rng& rng, double width, double length);
void addPlant(Prop& prop, World& world, Rng& rng, double height);
void addChair(Prop& prop, World& world, Rng& rng, double height);
void addFloorLamp(Prop& prop, World& world, Rng& rng);
// A framed picture on a wall: the prop's origin is on the wall, local +y out of it.
void addPicture(Prop& prop, World& world, Rng& rng, double width, double height, double centre_z);

// A small object of size about `size` standing at `base` in the prop's frame (boxes, balls,
// cans, bottles, bowls, cones, book stacks): the clutter of desks and shelves.
void addSmallObject(Prop& prop, World& world, Rng& rng, const Vec3& base, double size);

// Outdoor props.
void addBuilding(Prop& prop, World& world, Rng& rng, double width, double depth, double height);
void addTree(Prop& prop, World& world, Rng& rng, double height);
void addLampPost(Prop& prop, World& world, Rng& rng);
void addBench(Prop& prop, World& world, Rng& rng);
void addCar(Prop& prop, World& world, Rng& rng);
void addLandmark(Prop& prop, World& world, Rng& rng, double size);

}  // namespace ffloc::synthetic
