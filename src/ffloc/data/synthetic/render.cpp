#include "ffloc/data/synthetic/render.h"

#include <cmath>

#include "ffloc/data/synthetic/noise.h"
#include "ffloc/data/synthetic/random.h"

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

Vec3 shade(const World& world, const Lighting& light, const Ray& ray, const Hit& hit,
           double pixel_angle) {
  const Shape& shape = world.shapes[hit.shape];
  const Material& material = world.materials[shape.material];
  const Vec3 p = ray.origin + ray.direction * hit.t;
  const Vec3 view = normalized(ray.direction);
  Vec3 n = normalized(shape.rotation * hit.local_normal);
  if (dot(n, view) > 0.0) n = -n;
  const double facing = -dot(n, view);
  const double distance = hit.t * norm(ray.direction);
  const double footprint = distance * pixel_angle / (facing > 0.25 ? facing : 0.25);
  const Vec3 local_p = shape.rotation.transposeTimes(p - shape.centre);
  const Vec3 base = albedo(material, local_p, hit.local_normal, footprint);

  Vec3 diffuse = lerp(light.ground_ambient, light.sky_ambient, 0.5 + 0.5 * n.z);
  Vec3 highlight;
  const Vec3 origin = p + n * (1e-5 + 1e-5 * distance);
  auto addLight = [&](const Vec3& towards, const Vec3& colour, double shadow_limit) {
    const double len = norm(towards);
    const Vec3 l = towards / len;
    const double ndl = dot(n, l);
    if (ndl <= 0.0) return;
    if (light.shadows && shadow_limit > 0.0 &&
        world.bvh.occluded(world.shapes, {origin, towards}, 0.0, shadow_limit))
      return;
    diffuse = diffuse + colour * ndl;
    if (material.specular > 0.0) {
      const double nh = dot(n, normalized(l - view));
      if (nh > 0.0)
        highlight = highlight + colour * (material.specular * powerOfTwoPower(nh, material.shininess));
    }
  };
  if (light.sun_colour.x + light.sun_colour.y + light.sun_colour.z > 0.0)
    addLight(light.sun_direction, light.sun_colour, 1e4);
  // The first lamp is the key light and casts shadows; the others fill without them, which
  // halves the rays per pixel with little visible difference.
  for (size_t i = 0; i < light.lamps.size(); ++i) {
    const Vec3 towards = light.lamps[i].position - p;
    const double d2 = dot(towards, towards);
    addLight(towards, light.lamps[i].colour / d2, i == 0 ? 1.0 - 1e-6 : -1.0);
  }
  Vec3 c = mul(base, diffuse) + highlight;
  if (light.fog_distance > 0.0) {
    const double haze = distance / (distance + light.fog_distance);
    c = lerp(c, light.sky_horizon * 1.1, haze);
  }
  return c;
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
  RenderedView view;
  view.rgb.create(camera.height, camera.width);
  view.depth.create(camera.height, camera.width);
  const double pixel_angle = 1.0 / camera.fx;
  Rng noise(options.noise_seed);
  for (int v = 0; v < camera.height; ++v) {
    cv::Vec3b* rgb_row = view.rgb.ptr<cv::Vec3b>(v);
    float* depth_row = view.depth.ptr<float>(v);
    for (int u = 0; u < camera.width; ++u) {
      const Ray ray = rays.ray(u, v);
      Hit hit;
      Vec3 c;
      if (world.closestHit(ray, 0.0, options.max_depth, hit)) {
        depth_row[u] = static_cast<float>(hit.t);
        c = shade(world, lighting, ray, hit, pixel_angle);
      } else {
        depth_row[u] = 0.0f;
        c = skyColour(lighting, ray.direction);
      }
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
