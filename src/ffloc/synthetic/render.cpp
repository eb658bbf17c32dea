#include "ffloc/synthetic/render.h"

#include <algorithm>
#include <cmath>
#include <vector>

#include "ffloc/synthetic/noise.h"
#include "ffloc/core/random.h"
#include "ffloc/synthetic/ray_bundle.h"

namespace ffloc::synthetic {
namespace {

struct CameraRays {
  Vec3 centre;
  Mat3 rotation;
  double fx, fy, cx, cy;

  CameraRays(const Intrinsics& camera, const Pose& pose)
      : centre(pose.t.x(), pose.t.y(), pose.t.z()),
        fx(camera.fx), fy(camera.fy), cx(camera.cx), cy(camera.cy) {
    rotation.c0 = {pose.R(0, 0), pose.R(1, 0), pose.R(2, 0)};
    rotation.c1 = {pose.R(0, 1), pose.R(1, 1), pose.R(2, 1)};
    rotation.c2 = {pose.R(0, 2), pose.R(1, 2), pose.R(2, 2)};
  }

  // The ray through (u, v) with direction R * ((u - cx) / fx, (v - cy) / fy, 1), so the ray
  // parameter of a hit is its z-depth in this camera.
  Ray ray(double u, double v) const {
    return {centre, rotation * Vec3{(u - cx) / fx, (v - cy) / fy, 1.0}};
  }
};

double clamp01(double x) { return x < 0.0 ? 0.0 : (x > 1.0 ? 1.0 : x); }

double powerOfTwoPower(double x, int exponent) {
  for (int e = exponent; e > 1; e >>= 1) x *= x;
  return x;
}

Vec3 skyColour(const Lighting& light, const Vec3& direction) {
  const Vec3 d = normalized(direction);
  const double elevation = d.z;
  Vec3 c = lerp(light.sky_horizon, light.sky_zenith, clamp01(elevation * 1.6));
  if (elevation < 0.0) c = light.sky_horizon * (0.8 + 0.2 * (1.0 + elevation));
  if (elevation > 0.02 && light.cloudiness > 0.0) {
    const double inv = 1.0 / (elevation + 0.15);
    const Vec3 q{d.x * inv * 1.5, d.y * inv * 1.5, 0.0};
    const double v = fractalNoise(q, 4, 0.0, 4242u);
    const double threshold = 0.62 - 0.25 * light.cloudiness;
    const double cloud = clamp01((v - threshold) * 4.0);
    c = lerp(c, Vec3{0.92, 0.92, 0.95}, cloud * clamp01(elevation * 6.0));
  }
  const double toward_sun = dot(d, light.sun_direction);
  if (toward_sun > 0.0) {
    c = c + light.sun_colour * (0.08 * powerOfTwoPower(toward_sun, 8) +
                                0.6 * powerOfTwoPower(toward_sun, 256));
  }
  return c;
}

// Rays are handled in tiles of kTile x kTile pixels: per tile the camera rays, and the shadow
// rays towards each shadow-casting light, are tested against lists of the shapes they may
// meet (ray_bundle.h) instead of walking the tree one ray at a time.
constexpr int kTile = 16;

// One shadow-casting light (sun or key lamp) within a tile: the shapes its rays may meet, and
// the last shape found to cast a shadow, which is tested first since shadows are coherent.
struct ShadowLight {
  RayBundle bundle;
  int cached = -1;
};

// Whether something other than `self` lies on the ray within (0, limit).
bool inShadow(const World& world, const Ray& ray, double limit, int self, ShadowLight& light) {
  double t;
  Vec3 n;
  if (light.cached >= 0 && light.cached != self &&
      intersect(world.shapes[light.cached], ray, 0.0, limit, t, n))
    return true;
  // Shapes are convex, so a ray leaving a shape's outer surface cannot meet it again.
  const int occluder =
      light.bundle.listed ? occluderAmong(world.shapes, light.bundle.list, ray, 0.0, limit, self)
                          : world.bvh.occluder(world.shapes, ray, 0.0, limit, self);
  if (occluder < 0) return false;
  light.cached = occluder;
  return true;
}

constexpr double kSunShadowLength = 1e4;

// The offset of a shadow ray's origin from the surface point, so it does not start inside.
double shadowOffset(double distance) { return 1e-5 + 1e-5 * distance; }

Vec3 shade(const World& world, const Lighting& light, const Ray& ray, const Hit& hit,
           double pixel_angle, ShadowLight* shadow_lights) {
  const Shape& shape = world.shapes[hit.shape];
  const Material& material = world.materials[shape.material];
  const Vec3 p = ray.origin + ray.direction * hit.t;
  const Vec3 view = normalized(ray.direction);
  Vec3 n = normalized(shape.rotation * hit.local_normal);
  const bool inside = dot(n, view) > 0.0;  // seen from within: only if a camera were inside
  if (inside) n = -n;
  const int self = inside ? -1 : hit.shape;
  const double facing = -dot(n, view);
  const double distance = hit.t * norm(ray.direction);
  const double footprint = distance * pixel_angle / (facing > 0.25 ? facing : 0.25);
  const Vec3 local_p = shape.rotation.transposeTimes(p - shape.centre);
  const Vec3 base = albedo(material, local_p, hit.local_normal, footprint);

  Vec3 diffuse = lerp(light.ground_ambient, light.sky_ambient, 0.5 + 0.5 * n.z);
  Vec3 highlight;
  const Vec3 origin = p + n * shadowOffset(distance);
  auto addLight = [&](const Vec3& towards, const Vec3& colour, double shadow_limit,
                      ShadowLight* shadow) {
    const double len = norm(towards);
    const Vec3 l = towards / len;
    const double ndl = dot(n, l);
    if (ndl <= 0.0) return;
    if (light.shadows && shadow &&
        inShadow(world, {origin, towards}, shadow_limit, self, *shadow))
      return;
    diffuse = diffuse + colour * ndl;
    if (material.specular > 0.0) {
      const double nh = dot(n, normalized(l - view));
      if (nh > 0.0)
        highlight = highlight + colour * (material.specular * powerOfTwoPower(nh, material.shininess));
    }
  };
  if (light.sun_colour.x + light.sun_colour.y + light.sun_colour.z > 0.0)
    addLight(light.sun_direction, light.sun_colour, kSunShadowLength, &shadow_lights[0]);
  // The first lamp is the key light and casts shadows; the others fill without them, which
  // halves the rays per pixel with little visible difference.
  for (size_t i = 0; i < light.lamps.size(); ++i) {
    const Vec3 towards = light.lamps[i].position - p;
    const double d2 = dot(towards, towards);
    addLight(towards, light.lamps[i].colour / d2, 1.0 - 1e-6, i == 0 ? &shadow_lights[1] : nullptr);
  }
  Vec3 c = mul(base, diffuse) + highlight;
  if (light.fog_distance > 0.0) {
    const double haze = distance / (distance + light.fog_distance);
    c = lerp(c, light.sky_horizon * 1.1, haze);
  }
  return c;
}

// The closest hit among the bundle's shapes (or the tree's), trying first `guess`, the shape
// the previous pixel of the tile row hit: its distance bounds the search from the start, so
// boxes behind that surface are skipped. The distance found is the same either way (a shape's
// intersection does not depend on the bound); of two shapes at exactly the same distance the
// guess wins.
bool closestHitFrom(const World& world, const RayBundle& bundle, const Ray& ray, double t_max,
                    int guess, Hit& hit) {
  auto search = [&](double bound) {
    return bundle.listed ? closestHitAmong(world.shapes, bundle.list, ray, 0.0, bound, hit)
                         : world.closestHit(ray, 0.0, bound, hit);
  };
  if (guess >= 0) {
    double t;
    Vec3 n;
    if (intersect(world.shapes[guess], ray, 0.0, t_max, t, n)) {
      if (!search(t)) {
        hit.t = t;
        hit.shape = guess;
        hit.local_normal = n;
      }
      return true;
    }
  }
  return search(t_max);
}

// Extended Reinhard with white point 2, then gamma 2 (a square root, exact in IEEE 754).
double toDisplay(double linear, double exposure) {
  const double x = linear * exposure;
  const double y = x * (1.0 + x * 0.25) / (1.0 + x);
  return std::sqrt(clamp01(y));
}

uint8_t quantise(double value) {
  const double v = std::floor(value * 255.0 + 0.5);
  return static_cast<uint8_t>(v < 0.0 ? 0.0 : (v > 255.0 ? 255.0 : v));
}

}  // namespace

RenderedView renderView(const World& world, const Lighting& lighting, const Intrinsics& camera,
                        const Pose& camera_to_world, const RenderOptions& options) {
  const CameraRays rays(camera, camera_to_world);
  const int width = camera.width, height = camera.height;
  RenderedView view;
  view.rgb.create(height, width);
  view.depth.create(height, width);
  const double pixel_angle = 1.0 / camera.fx;
  const Vec3& sun = lighting.sun_colour;
  const bool sun_shadows = lighting.shadows && sun.x + sun.y + sun.z > 0.0;
  const bool lamp_shadows = lighting.shadows && !lighting.lamps.empty();
  std::vector<Vec3> linear(static_cast<size_t>(width) * height);
  RayBundle camera_bundle;
  ShadowLight shadow_lights[2];  // sun, key lamp
  struct TilePixel {
    Hit hit;
    bool found = false;
  };
  TilePixel tile[kTile * kTile];
  for (int v0 = 0; v0 < height; v0 += kTile) {
    const int v1 = std::min(v0 + kTile, height) - 1;
    for (int u0 = 0; u0 < width; u0 += kTile) {
      const int u1 = std::min(u0 + kTile, width) - 1;
      // Every camera ray of the tile lies in the pyramid of its corner rays.
      const Vec3 corners[4] = {rays.ray(u0, v0).direction, rays.ray(u1, v0).direction,
                               rays.ray(u1, v1).direction, rays.ray(u0, v1).direction};
      collectFromPoint(world, rays.centre, corners, options.max_depth, camera_bundle);
      Aabb origins;
      double max_offset = 0.0;
      for (int v = v0; v <= v1; ++v) {
        int previous = -1;
        float* depth_row = view.depth.ptr<float>(v);
        for (int u = u0; u <= u1; ++u) {
          TilePixel& pixel = tile[(v - v0) * kTile + (u - u0)];
          const Ray ray = rays.ray(u, v);
          pixel.hit = Hit();
          pixel.found = closestHitFrom(world, camera_bundle, ray, options.max_depth, previous,
                                       pixel.hit);
          depth_row[u] = pixel.found ? static_cast<float>(pixel.hit.t) : 0.0f;
          previous = pixel.found ? pixel.hit.shape : -1;
          if (!pixel.found) continue;
          // Where shade() starts this pixel's shadow rays: within the offset of this point.
          const Vec3 p = ray.origin + ray.direction * pixel.hit.t;
          const double offset = shadowOffset(pixel.hit.t * norm(ray.direction)) * 1.01;
          origins.grow(p - Vec3{offset, offset, offset});
          origins.grow(p + Vec3{offset, offset, offset});
          max_offset = std::fmax(max_offset, offset);
        }
      }
      const bool any_surface = origins.lo.x <= origins.hi.x;
      shadow_lights[0].bundle.listed = shadow_lights[1].bundle.listed = false;
      if (any_surface && sun_shadows)
        collectAlong(world, origins, lighting.sun_direction, kSunShadowLength,
                     shadow_lights[0].bundle);
      if (any_surface && lamp_shadows)
        collectTowardsPoint(world, origins, lighting.lamps[0].position, max_offset,
                            shadow_lights[1].bundle);
      shadow_lights[0].cached = shadow_lights[1].cached = -1;
      for (int v = v0; v <= v1; ++v) {
        for (int u = u0; u <= u1; ++u) {
          const TilePixel& pixel = tile[(v - v0) * kTile + (u - u0)];
          const Ray ray = rays.ray(u, v);
          linear[static_cast<size_t>(v) * width + u] =
              pixel.found ? shade(world, lighting, ray, pixel.hit, pixel_angle, shadow_lights)
                          : skyColour(lighting, ray.direction);
        }
      }
    }
  }
  // In raster order, so the pixel noise draws do not depend on the tiling.
  Rng noise(options.noise_seed);
  for (int v = 0; v < height; ++v) {
    cv::Vec3b* rgb_row = view.rgb.ptr<cv::Vec3b>(v);
    for (int u = 0; u < width; ++u) {
      const Vec3& c = linear[static_cast<size_t>(v) * width + u];
      for (int k = 0; k < 3; ++k) {
        double value = toDisplay(c[k], lighting.exposure);
        if (options.image_noise > 0.0) value += options.image_noise / 255.0 * noise.normal();
        rgb_row[u][k] = quantise(value);
      }
    }
  }
  return view;
}

double castDepth(const World& world, const Intrinsics& camera, const Pose& camera_to_world,
                 double u, double v, double max_depth) {
  const CameraRays rays(camera, camera_to_world);
  Hit hit;
  return world.closestHit(rays.ray(u, v), 0.0, max_depth, hit) ? hit.t : 0.0;
}

}  // namespace ffloc::synthetic
