#include "ffloc/synthetic/shapes.h"

#include <cmath>
#include <initializer_list>
#include <utility>

namespace ffloc::synthetic {
namespace {

// The convex solid {p : n_i . p <= offset_i}: clips the ray against each half-space.
struct HalfSpace {
  Vec3 normal;
  double offset;
};

bool intersectConvex(const HalfSpace* planes, int count, const Vec3& o, const Vec3& d,
                     double t_min, double t_max, double& t, Vec3& normal) {
  double enter = -1e300, leave = 1e300;
  Vec3 enter_normal, leave_normal;
  for (int i = 0; i < count; ++i) {
    const double denom = dot(planes[i].normal, d);
    const double dist = planes[i].offset - dot(planes[i].normal, o);
    if (denom == 0.0) {
      if (dist < 0.0) return false;
      continue;
    }
    const double s = dist / denom;
    if (denom < 0.0) {
      if (s > enter) { enter = s; enter_normal = planes[i].normal; }
    } else if (s < leave) {
      leave = s;
      leave_normal = planes[i].normal;
    }
  }
  if (enter > leave) return false;
  if (enter > t_min && enter < t_max) {
    t = enter;
    normal = enter_normal;
    return true;
  }
  // Seen from inside (a camera should never be, but stay correct): the exit face.
  if (enter <= t_min && leave > t_min && leave < t_max) {
    t = leave;
    normal = -leave_normal;
    return true;
  }
  return false;
}

bool intersectBox(const Vec3& h, const Vec3& o, const Vec3& d, double t_min, double t_max,
                  double& t, Vec3& normal) {
  double enter = -1e300, leave = 1e300;
  int enter_axis = 0, leave_axis = 0;
  double enter_sign = 1, leave_sign = 1;
  for (int a = 0; a < 3; ++a) {
    if (d[a] == 0.0) {
      if (o[a] < -h[a] || o[a] > h[a]) return false;
      continue;
    }
    const double inv = 1.0 / d[a];
    double t0 = (-h[a] - o[a]) * inv, t1 = (h[a] - o[a]) * inv;
    double s0 = -1, s1 = 1;
    if (t0 > t1) { std::swap(t0, t1); std::swap(s0, s1); }
    if (t0 > enter) { enter = t0; enter_axis = a; enter_sign = s0; }
    if (t1 < leave) { leave = t1; leave_axis = a; leave_sign = s1; }
  }
  if (enter > leave) return false;
  normal = Vec3();
  if (enter > t_min && enter < t_max) {
    t = enter;
    normal[enter_axis] = enter_sign;
    return true;
  }
  if (enter <= t_min && leave > t_min && leave < t_max) {
    t = leave;
    normal[leave_axis] = -leave_sign;
    return true;
  }
  return false;
}

// The smaller root of a t^2 + 2 b t + c = 0 above t_min (and the larger as fallback).
bool quadraticRoots(double a, double b, double c, double& r0, double& r1) {
  const double disc = b * b - a * c;
  if (disc < 0.0 || a == 0.0) return false;
  const double s = std::sqrt(disc);
  // The numerically stable pair: q = -(b + sign(b) s); roots q / a and c / q.
  const double q = b >= 0.0 ? -(b + s) : -(b - s);
  r0 = q / a;
  r1 = q != 0.0 ? c / q : r0;
  if (r0 > r1) std::swap(r0, r1);
  return true;
}

bool intersectEllipsoid(const Vec3& h, const Vec3& o, const Vec3& d, double t_min,
                        double t_max, double& t, Vec3& normal) {
  const Vec3 os = div(o, h), ds = div(d, h);
  double r0, r1;
  if (!quadraticRoots(dot(ds, ds), dot(os, ds), dot(os, os) - 1.0, r0, r1)) return false;
  const double root = r0 > t_min ? r0 : r1;
  if (root <= t_min || root >= t_max) return false;
  t = root;
  const Vec3 p = o + d * t;
  normal = div(p, mul(h, h));
  if (r0 <= t_min) normal = -normal;
  return true;
}

bool intersectCylinder(const Vec3& h, const Vec3& o, const Vec3& d, double t_min,
                       double t_max, double& t, Vec3& normal) {
  bool found = false;
  double best = t_max;
  const double ox = o.x / h.x, oy = o.y / h.y, dx = d.x / h.x, dy = d.y / h.y;
  double r0, r1;
  if (quadraticRoots(dx * dx + dy * dy, ox * dx + oy * dy, ox * ox + oy * oy - 1.0, r0, r1)) {
    for (double root : {r0, r1}) {
      if (root <= t_min || root >= best) continue;
      const double z = o.z + d.z * root;
      if (z < -h.z || z > h.z) continue;
      best = root;
      found = true;
      const Vec3 p = o + d * root;
      normal = {p.x / (h.x * h.x), p.y / (h.y * h.y), 0.0};
      if (ox * ox + oy * oy < 1.0) normal = -normal;
      break;
    }
  }
  if (d.z != 0.0) {
    for (double cap : {-h.z, h.z}) {
      const double root = (cap - o.z) / d.z;
      if (root <= t_min || root >= best) continue;
      const double x = (o.x + d.x * root) / h.x, y = (o.y + d.y * root) / h.y;
      if (x * x + y * y > 1.0) continue;
      best = root;
      found = true;
      normal = {0.0, 0.0, cap > 0 ? 1.0 : -1.0};
      if (o.z > -h.z && o.z < h.z && ox * ox + oy * oy < 1.0) normal = -normal;
    }
  }
  if (found) t = best;
  return found;
}

bool intersectCone(const Vec3& h, const Vec3& o, const Vec3& d, double t_min, double t_max,
                   double& t, Vec3& normal) {
  // Scaled so the base is the unit disc: x^2 + y^2 = k^2 (apex - z)^2, k = 1 / (2 half.z).
  const double k = 1.0 / (2.0 * h.z), k2 = k * k;
  const double ox = o.x / h.x, oy = o.y / h.y, dx = d.x / h.x, dy = d.y / h.y;
  const double oz = h.z - o.z, dz = -d.z;  // height below the apex
  bool found = false;
  double best = t_max;
  double r0, r1;
  if (quadraticRoots(dx * dx + dy * dy - k2 * dz * dz, ox * dx + oy * dy - k2 * oz * dz,
                     ox * ox + oy * oy - k2 * oz * oz, r0, r1)) {
    for (double root : {r0, r1}) {
      if (root <= t_min || root >= best) continue;
      const double z = o.z + d.z * root;
      if (z < -h.z || z > h.z) continue;  // the mirrored nappe or below the base
      best = root;
      found = true;
      const Vec3 p = o + d * root;
      const double below_apex = h.z - p.z;
      normal = {p.x / (h.x * h.x), p.y / (h.y * h.y), k2 * below_apex};
      break;
    }
  }
  if (d.z != 0.0) {
    const double root = (-h.z - o.z) / d.z;
    if (root > t_min && root < best) {
      const double x = (o.x + d.x * root) / h.x, y = (o.y + d.y * root) / h.y;
      if (x * x + y * y <= 1.0) {
        best = root;
        found = true;
        normal = {0.0, 0.0, -1.0};
      }
    }
  }
  if (found) t = best;
  return found;
}

bool intersectWedge(const Vec3& h, const Vec3& o, const Vec3& d, double t_min, double t_max,
                    double& t, Vec3& normal) {
  // Slopes: z <= half.z - 2 half.z |x| / half.x, i.e. (2 hz / hx) |x| + z <= hz.
  const double slope = 2.0 * h.z / h.x;
  const HalfSpace planes[5] = {
      {{0, 1, 0}, h.y}, {{0, -1, 0}, h.y}, {{0, 0, -1}, h.z},
      {{slope, 0, 1}, h.z}, {{-slope, 0, 1}, h.z}};
  return intersectConvex(planes, 5, o, d, t_min, t_max, t, normal);
}

}  // namespace

Aabb bounds(const Shape& shape) {
  Aabb box;
  for (int i = 0; i < 8; ++i) {
    const Vec3 corner{(i & 1) ? shape.half.x : -shape.half.x,
                      (i & 2) ? shape.half.y : -shape.half.y,
                      (i & 4) ? shape.half.z : -shape.half.z};
    box.grow(shape.centre + shape.rotation * corner);
  }
  return box;
}

bool intersect(const Shape& shape, const Ray& ray, double t_min, double t_max, double& t,
               Vec3& local_normal) {
  const Vec3 o = shape.rotation.transposeTimes(ray.origin - shape.centre);
  const Vec3 d = shape.rotation.transposeTimes(ray.direction);
  switch (shape.kind) {
    case ShapeKind::kBox: return intersectBox(shape.half, o, d, t_min, t_max, t, local_normal);
    case ShapeKind::kEllipsoid:
      return intersectEllipsoid(shape.half, o, d, t_min, t_max, t, local_normal);
    case ShapeKind::kCylinder:
      return intersectCylinder(shape.half, o, d, t_min, t_max, t, local_normal);
    case ShapeKind::kCone: return intersectCone(shape.half, o, d, t_min, t_max, t, local_normal);
    case ShapeKind::kWedge:
      return intersectWedge(shape.half, o, d, t_min, t_max, t, local_normal);
  }
  return false;
}

}  // namespace ffloc::synthetic
