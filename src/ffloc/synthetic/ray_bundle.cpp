#include "ffloc/synthetic/ray_bundle.h"

#include <cmath>

namespace ffloc::synthetic {
namespace {

// Longer lists cost more to test than walking the tree.
constexpr size_t kMaxListed = 24;

double maxAbs(const Vec3& v) {
  return std::fmax(std::fabs(v.x), std::fmax(std::fabs(v.y), std::fabs(v.z)));
}

Vec3 boxCorner(const Aabb& box, int i) {
  return {(i & 1) ? box.hi.x : box.lo.x, (i & 2) ? box.hi.y : box.lo.y,
          (i & 4) ? box.hi.z : box.lo.z};
}

void collect(const World& world, const Plane* planes, int count, RayBundle& bundle) {
  bundle.list.clear();
  world.bvh.collect(planes, count, bundle.list);
  bundle.listed = bundle.list.size() <= kMaxListed;
}

}  // namespace

void collectFromPoint(const World& world, const Vec3& apex, const Vec3 corners[4],
                      double max_length, RayBundle& bundle) {
  const Vec3 inward = corners[0] + corners[1] + corners[2] + corners[3];
  Plane planes[4];
  for (int i = 0; i < 4; ++i) {
    Vec3 n = cross(corners[i], corners[(i + 1) % 4]);
    if (dot(n, inward) > 0.0) n = -n;
    // A camera ray's direction is rounded on its own, not interpolated between the corners;
    // the slack is orders of magnitude above that rounding and still a hair next to a pixel.
    const double slack = 1e-9 * norm(n) * (1.0 + maxAbs(apex) + max_length);
    planes[i] = {n, dot(n, apex) + slack};
  }
  collect(world, planes, 4, bundle);
}

// The rays lie in the pyramid from the light through the box, on the face of a cube around
// the light that the box lies in front of; no list when the box straddles that face's plane.
// (A shadow ray runs from the offset surface point by light - surface point, so it ends
// within the offset of the light, not at it.)
void collectTowardsPoint(const World& world, const Aabb& origins, const Vec3& light,
                         double end_offset, RayBundle& bundle) {
  bundle.listed = false;
  const Vec3 centre = origins.centre() - light;
  const int k = std::fabs(centre.x) >= std::fabs(centre.y)
                    ? (std::fabs(centre.x) >= std::fabs(centre.z) ? 0 : 2)
                    : (std::fabs(centre.y) >= std::fabs(centre.z) ? 1 : 2);
  const int a = (k + 1) % 3, b = (k + 2) % 3;
  const double sign = centre[k] >= 0.0 ? 1.0 : -1.0;
  double u_lo = 1e300, u_hi = -1e300, v_lo = 1e300, v_hi = -1e300, w_hi = 0.0;
  for (int i = 0; i < 8; ++i) {
    const Vec3 corner = boxCorner(origins, i);
    const Vec3 q = corner - light;
    const double w = sign * q[k];
    if (!(w > 0.0)) return;
    const double u = q[a] / w, v = q[b] / w;
    u_lo = std::fmin(u_lo, u);
    u_hi = std::fmax(u_hi, u);
    v_lo = std::fmin(v_lo, v);
    v_hi = std::fmax(v_hi, v);
    w_hi = std::fmax(w_hi, w);
  }
  // In coordinates q = x - light: q_a <= u_hi w, q_a >= u_lo w, the same for b, and w <= w_hi.
  Vec3 normals[5];
  normals[0][a] = 1.0;
  normals[0][k] = -u_hi * sign;
  normals[1][a] = -1.0;
  normals[1][k] = u_lo * sign;
  normals[2][b] = 1.0;
  normals[2][k] = -v_hi * sign;
  normals[3][b] = -1.0;
  normals[3][k] = v_lo * sign;
  normals[4][k] = sign;
  const double extent = std::fmax(std::fmax(std::fabs(u_lo), std::fabs(u_hi)),
                                  std::fmax(std::fabs(v_lo), std::fabs(v_hi)));
  const double scale = 1.0 + maxAbs(light) + maxAbs(origins.lo) + maxAbs(origins.hi) +
                       w_hi * (1.0 + extent);
  Plane planes[5];
  for (int i = 0; i < 5; ++i) {
    const double slack = norm(normals[i]) * (2.0 * end_offset + 1e-9 * scale);
    planes[i] = {normals[i], dot(normals[i], light) + (i == 4 ? w_hi : 0.0) + slack};
  }
  collect(world, planes, 5, bundle);
}

// The rays lie in the box swept along the direction.
void collectAlong(const World& world, const Aabb& origins, const Vec3& direction, double length,
                  RayBundle& bundle) {
  const double ax = std::fabs(direction.x), ay = std::fabs(direction.y),
               az = std::fabs(direction.z);
  const Vec3 helper =
      ax <= ay && ax <= az ? Vec3{1, 0, 0} : (ay <= az ? Vec3{0, 1, 0} : Vec3{0, 0, 1});
  const Vec3 e1 = normalized(cross(direction, helper));
  const Vec3 e2 = cross(direction, e1);
  double lo1 = 1e300, hi1 = -1e300, lo2 = 1e300, hi2 = -1e300, lo3 = 1e300;
  for (int i = 0; i < 8; ++i) {
    const Vec3 corner = boxCorner(origins, i);
    const double d1 = dot(e1, corner), d2 = dot(e2, corner), d3 = dot(direction, corner);
    lo1 = std::fmin(lo1, d1);
    hi1 = std::fmax(hi1, d1);
    lo2 = std::fmin(lo2, d2);
    hi2 = std::fmax(hi2, d2);
    lo3 = std::fmin(lo3, d3);
  }
  const double slack = 1e-9 * (1.0 + maxAbs(origins.lo) + maxAbs(origins.hi) + length);
  const Plane planes[5] = {{e1, hi1 + slack}, {-e1, -lo1 + slack}, {e2, hi2 + slack},
                           {-e2, -lo2 + slack}, {-direction, -lo3 + slack}};
  collect(world, planes, 5, bundle);
}

}  // namespace ffloc::synthetic
