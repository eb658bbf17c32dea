#pragma once

#include <cstdint>

#include "ffloc/synthetic/vec3.h"

namespace ffloc::synthetic {

// A ray o + t d. d need not be unit length: camera rays use d = R * (x, y, 1), so that t is
// the z-depth directly and the stored depth equals the intersection parameter.
struct Ray {
  Vec3 origin;
  Vec3 direction;
};

// The primitives the scenes are built from. Each lives in its own local frame (a rotation and
// a centre) with half-extents `half`; local z is the shape's up axis.
enum class ShapeKind : uint8_t {
  kBox,        // [-half, half]
  kEllipsoid,  // semi-axes half
  kCylinder,   // elliptic, axis z, caps at z = +-half.z
  kCone,       // base at z = -half.z with radii half.x, half.y; apex at z = +half.z
  kWedge,      // a roof prism: base rectangle at z = -half.z, ridge along y at z = +half.z
};

struct Shape {
  ShapeKind kind = ShapeKind::kBox;
  Mat3 rotation;  // local to world
  Vec3 centre;
  Vec3 half{0.5, 0.5, 0.5};
  int material = 0;
};

struct Aabb {
  Vec3 lo{1e300, 1e300, 1e300};
  Vec3 hi{-1e300, -1e300, -1e300};

  void grow(const Vec3& p) { lo = min(lo, p); hi = max(hi, p); }
  void grow(const Aabb& b) { lo = min(lo, b.lo); hi = max(hi, b.hi); }
  Vec3 centre() const { return (lo + hi) * 0.5; }
};

Aabb bounds(const Shape& shape);

// The nearest intersection with t in (t_min, t_max); on success writes t and the local-frame
// outward normal (not normalised).
bool intersect(const Shape& shape, const Ray& ray, double t_min, double t_max, double& t,
               Vec3& local_normal);

}  // namespace ffloc::synthetic
