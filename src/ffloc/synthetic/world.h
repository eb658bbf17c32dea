#pragma once

#include <vector>

#include "ffloc/synthetic/bvh.h"
#include "ffloc/synthetic/material.h"
#include "ffloc/synthetic/shapes.h"

namespace ffloc::synthetic {

// The scene's geometry and materials. World axes: z up, metres.
struct World {
  std::vector<Shape> shapes;
  std::vector<Material> materials;
  Bvh bvh;  // over `shapes`; call buildBvh() after the last shape is added

  int addMaterial(const Material& material);
  int addShape(const Shape& shape);
  void buildBvh() { bvh = Bvh(shapes); }
  bool closestHit(const Ray& ray, double t_min, double t_max, Hit& hit) const {
    return bvh.closestHit(shapes, ray, t_min, t_max, hit);
  }
};

struct PointLight {
  Vec3 position;
  Vec3 colour{1, 1, 1};  // intensity at 1 m, linear RGB
};

// One illumination condition. Mapping frames share one; queries get others, so a query sees
// the same geometry under a different sun, lamp set or exposure.
struct Lighting {
  Vec3 sun_direction{0, 0, 1};  // towards the sun, unit length
  Vec3 sun_colour{0, 0, 0};     // zero: no sun (indoors)
  Vec3 sky_ambient{0.3, 0.3, 0.35};
  Vec3 ground_ambient{0.15, 0.13, 0.1};
  std::vector<PointLight> lamps;
  Vec3 sky_zenith{0.25, 0.45, 0.85};
  Vec3 sky_horizon{0.75, 0.82, 0.9};
  double cloudiness = 0.3;
  double fog_distance = 0.0;  // metres at which haze reaches half strength; 0: none
  double exposure = 1.0;
  bool shadows = true;
};

}  // namespace ffloc::synthetic
