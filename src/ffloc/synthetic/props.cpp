#include "ffloc/synthetic/props.h"

#include <cmath>

#include "ffloc/synthetic/det_math.h"
#include "ffloc/synthetic/palette.h"

namespace ffloc::synthetic {

// As in palette.cpp, random draws are separate statements or braced lists, never two in one
// function call, whose argument order C++ leaves unspecified.

Mat3 yawRotation(double yaw) {
  const double c = detCos(yaw), s = detSin(yaw);
  Mat3 r;
  r.c0 = {c, s, 0};
  r.c1 = {-s, c, 0};
  r.c2 = {0, 0, 1};
  return r;
}

Mat3 axisRotation(const Vec3& axis) {
  const Vec3 z = normalized(axis);
  const Vec3 helper = std::fabs(z.z) < 0.9 ? Vec3{0, 0, 1} : Vec3{1, 0, 0};
  const Vec3 x = normalized(cross(helper, z));
  Mat3 r;
  r.c0 = x;
  r.c1 = cross(z, x);
  r.c2 = z;
  return r;
}

void Prop::add(ShapeKind kind, const Vec3& centre, const Vec3& half, int material,
               const Mat3& local_rotation) {
  Shape s;
  s.kind = kind;
  s.rotation = rotation_ * local_rotation;
  s.centre = toWorld(centre);
  s.half = half;
  s.material = material;
  shapes_.push_back(s);
}

Aabb Prop::bounds() const {
  Aabb box;
  for (const auto& s : shapes_) box.grow(synthetic::bounds(s));
  return box;
}

void commit(World& world, const Prop& prop) {
  for (const auto& s : prop.shapes()) world.addShape(s);
}

void addTable(Prop& prop, World& world, Rng& rng, double width, double depth, double height,
              bool with_clutter) {
  const int top = world.addMaterial(rng.chance(0.25) ? marbleMaterial(rng, 0.5) : woodMaterial(rng));
  const int legs = rng.chance(0.5) ? top : world.addMaterial(metalMaterial(rng));
  prop.box({0, 0, height - 0.02}, {width / 2, depth / 2, 0.02}, top);
  const double leg_half = (height - 0.04) / 2;
  for (int i = 0; i < 4; ++i) {
    const double x = (i & 1) ? width / 2 - 0.05 : -width / 2 + 0.05;
    const double y = (i & 2) ? depth / 2 - 0.05 : -depth / 2 + 0.05;
    prop.box({x, y, leg_half}, {0.025, 0.025, leg_half}, legs);
  }
  if (!with_clutter) return;
  const int count = 1 + rng.index(5);
  for (int i = 0; i < count; ++i) {
    const double x = rng.uniform(-width / 2 + 0.1, width / 2 - 0.1);
    const double y = rng.uniform(-depth / 2 + 0.1, depth / 2 - 0.1);
    const double size = rng.uniform(0.06, 0.2);
    addSmallObject(prop, world, rng, {x, y, height}, size);
  }
}

void addShelf(Prop& prop, World& world, Rng& rng, double width, double depth, double height) {
  const int wood = world.addMaterial(woodMaterial(rng));
  const double t = 0.02;
  prop.box({-width / 2 + t / 2, depth / 2, height / 2}, {t / 2, depth / 2, height / 2}, wood);
  prop.box({width / 2 - t / 2, depth / 2, height / 2}, {t / 2, depth / 2, height / 2}, wood);
  prop.box({0, t / 2, height / 2}, {width / 2, t / 2, height / 2}, wood);
  const int boards = 2 + static_cast<int>(height / 0.4);
  const double spacing = (height - t) / (boards - 1);
  int book_materials[4];
  for (int& m : book_materials) m = world.addMaterial(fabricMaterial(rng, 0.3));
  for (int b = 0; b < boards; ++b) {
    const double z = t / 2 + b * spacing;
    prop.box({0, depth / 2, z}, {width / 2 - t, depth / 2, t / 2}, wood);
    if (b == boards - 1) break;
    double x = -width / 2 + t + 0.01;
    while (x < width / 2 - 0.08) {
      const double kind = rng.uniform();
      if (kind < 0.7) {
        const double thick = rng.uniform(0.015, 0.05);
        const double tall = rng.uniform(0.5, 0.85) * (spacing - t);
        const double deep = rng.uniform(0.6, 0.9) * depth;
        const int material = book_materials[rng.index(4)];
        prop.box({x + thick / 2, deep / 2 + t, z + t / 2 + tall / 2}, {thick / 2, deep / 2, tall / 2},
                 material);
        x += thick + 0.002;
      } else if (kind < 0.85) {
        const double size = rng.uniform(0.06, 0.12);
        addSmallObject(prop, world, rng, {x + size / 2, depth / 2, z + t / 2}, size);
        x += size + 0.02;
      } else {
        x += rng.uniform(0.05, 0.2);
      }
    }
  }
}

void addCabinet(Prop& prop, World& world, Rng& rng, double width, double depth, double height) {
  const int body = world.addMaterial(rng.chance(0.5) ? woodMaterial(rng) : paintMaterial(rng));
  const int doors = rng.chance(0.5) ? body : world.addMaterial(paintMaterial(rng));
  const int knobs = world.addMaterial(metalMaterial(rng));
  prop.box({0, depth / 2, height / 2}, {width / 2, depth / 2, height / 2}, body);
  const int count = width > 0.9 ? 3 : 2;
  const double door_w = (width - 0.04) / count;
  for (int i = 0; i < count; ++i) {
    const double x = -width / 2 + 0.02 + door_w * (i + 0.5);
    prop.box({x, depth + 0.008, height / 2}, {door_w / 2 - 0.008, 0.008, height / 2 - 0.04}, doors);
    prop.add(ShapeKind::kEllipsoid, {x + door_w * 0.35, depth + 0.025, height * 0.6},
             {0.015, 0.015, 0.015}, knobs);
  }
  if (rng.chance(0.7)) {
    const int count_top = 1 + rng.index(3);
    for (int i = 0; i < count_top; ++i) {
      const double x = rng.uniform(-width / 2 + 0.1, width / 2 - 0.1);
      const double y = rng.uniform(0.1, depth - 0.1);
      const double size = rng.uniform(0.08, 0.25);
      addSmallObject(prop, world, rng, {x, y, height}, size);
    }
  }
}

void addSofa(Prop& prop, World& world, Rng& rng, double width, double depth) {
  const int fabric = world.addMaterial(fabricMaterial(rng));
  const int cushions = world.addMaterial(fabricMaterial(rng, 0.5));
  prop.box({0, depth / 2, 0.22}, {width / 2, depth / 2, 0.22}, fabric);
  prop.box({0, 0.1, 0.6}, {width / 2, 0.1, 0.2}, fabric);
  prop.box({-width / 2 + 0.1, depth / 2, 0.52}, {0.1, depth / 2, 0.1}, fabric);
  prop.box({width / 2 - 0.1, depth / 2, 0.52}, {0.1, depth / 2, 0.1}, fabric);
  const int count = 2 + rng.index(2);
  for (int i = 0; i < count; ++i) {
    const double x = -width / 2 + 0.3 + (width - 0.6) * (i + 0.5) / count;
    prop.add(ShapeKind::kEllipsoid, {x, 0.3, 0.6}, {0.2, 0.08, 0.18}, cushions);
  }
}

void addBed(Prop& prop, World& world, Rng& rng, double width, double length) {
  const int frame = world.addMaterial(woodMaterial(rng));
  const int sheet = world.addMaterial(fabricMaterial(rng, 0.3));
  const int blanket = world.addMaterial(fabricMaterial(rng));
  prop.box({0, length / 2, 0.15}, {width / 2, length / 2, 0.15}, frame);
  prop.box({0, 0.03, 0.5}, {width / 2, 0.03, 0.5}, frame);
  prop.box({0, length / 2, 0.38}, {width / 2 - 0.03, length / 2 - 0.03, 0.09}, sheet);
  prop.box({0, length * 0.62, 0.49}, {width / 2 - 0.01, length * 0.36, 0.03}, blanket);
  const int pillows = width > 1.2 ? 2 : 1;
  for (int i = 0; i < pillows; ++i) {
    const double x = pillows == 1 ? 0.0 : (i == 0 ? -width / 4 : width / 4);
    prop.add(ShapeKind::kEllipsoid, {x, 0.25, 0.5}, {width / (2.5 * pillows), 0.14, 0.07}, sheet);
  }
}

void addPlant(Prop& prop, World& world, Rng& rng, double height) {
  const int pot = world.addMaterial(rng.chance(0.5) ? plasticMaterial(rng) : stoneMaterial(rng, 0.2));
  Material leaves = foliageMaterial(rng);
  leaves.period *= 0.3;
  const int foliage = world.addMaterial(leaves);
  const double pot_r = height * 0.15;
  prop.add(ShapeKind::kCylinder, {0, 0, pot_r}, {pot_r, pot_r, pot_r}, pot);
  const int blobs = 2 + rng.index(3);
  for (int i = 0; i < blobs; ++i) {
    const Vec3 offset{rng.uniform(-0.3, 0.3) * height * 0.3, rng.uniform(-0.3, 0.3) * height * 0.3,
                      rng.uniform(0.45, 0.75) * height};
    const double r = rng.uniform(0.18, 0.3) * height;
    prop.add(ShapeKind::kEllipsoid, offset, {r, r, r * 1.2}, foliage);
  }
}

void addChair(Prop& prop, World& world, Rng& rng, double height) {
  const int wood = world.addMaterial(rng.chance(0.6) ? woodMaterial(rng) : plasticMaterial(rng));
  const double seat = height * 0.5;
  prop.box({0, 0, seat}, {0.22, 0.22, 0.025}, wood);
  for (int i = 0; i < 4; ++i) {
    const double x = (i & 1) ? 0.19 : -0.19, y = (i & 2) ? 0.19 : -0.19;
    prop.box({x, y, seat / 2}, {0.02, 0.02, seat / 2}, wood);
  }
  prop.box({0, -0.2, seat + (height - seat) / 2}, {0.22, 0.02, (height - seat) / 2}, wood);
}

void addFloorLamp(Prop& prop, World& world, Rng& rng) {
  const int metal = world.addMaterial(metalMaterial(rng));
  const int shade = world.addMaterial(fabricMaterial(rng, 0.5));
  const double height = rng.uniform(1.3, 1.7);
  prop.add(ShapeKind::kCylinder, {0, 0, 0.02}, {0.15, 0.15, 0.02}, metal);
  prop.add(ShapeKind::kCylinder, {0, 0, height / 2}, {0.015, 0.015, height / 2}, metal);
  prop.add(ShapeKind::kCone, {0, 0, height + 0.05}, {0.22, 0.22, 0.18}, shade);
}

void addPicture(Prop& prop, World& world, Rng& rng, double width, double height, double centre_z) {
  const int frame = world.addMaterial(rng.chance(0.5) ? woodMaterial(rng, 0.3) : metalMaterial(rng));
  const int canvas = world.addMaterial(posterMaterial(rng));
  prop.box({0, 0.015, centre_z}, {width / 2 + 0.03, 0.015, height / 2 + 0.03}, frame);
  prop.box({0, 0.032, centre_z}, {width / 2, 0.003, height / 2}, canvas);
}

void addSmallObject(Prop& prop, World& world, Rng& rng, const Vec3& base, double size) {
  const int kind = rng.index(7);
  const int material = world.addMaterial(kind == 6 ? fabricMaterial(rng, 0.3)
                                                   : (rng.chance(0.3) ? marbleMaterial(rng, 0.2)
                                                                      : plasticMaterial(rng)));
  const double yaw = rng.uniform(0.0, 2.0 * kPi);
  const Mat3 turn = yawRotation(yaw);
  switch (kind) {
    case 0: {
      const Vec3 half{size * rng.uniform(0.25, 0.5), size * rng.uniform(0.25, 0.5),
                      size * rng.uniform(0.2, 0.5)};
      prop.add(ShapeKind::kBox, base + Vec3{0, 0, half.z}, half, material, turn);
      break;
    }
    case 1: prop.add(ShapeKind::kEllipsoid, base + Vec3{0, 0, size / 2}, {size / 2, size / 2, size / 2}, material); break;
    case 2: prop.add(ShapeKind::kCylinder, base + Vec3{0, 0, size * 0.4}, {size * 0.3, size * 0.3, size * 0.4}, material); break;
    case 3: {
      const double body = size * 0.55;
      prop.add(ShapeKind::kCylinder, base + Vec3{0, 0, body}, {size * 0.2, size * 0.2, body}, material);
      prop.add(ShapeKind::kCone, base + Vec3{0, 0, 2 * body + size * 0.2}, {size * 0.2, size * 0.2, size * 0.2}, material);
      break;
    }
    case 4: prop.add(ShapeKind::kEllipsoid, base, {size * 0.5, size * 0.5, size * 0.3}, material); break;
    case 5: prop.add(ShapeKind::kCone, base + Vec3{0, 0, size / 2}, {size * 0.35, size * 0.35, size / 2}, material); break;
    default: {
      const int books = 2 + rng.index(3);
      double z = base.z;
      for (int i = 0; i < books; ++i) {
        const double thick = size * rng.uniform(0.1, 0.2);
        const double book_yaw = yaw + rng.uniform(-0.3, 0.3);
        const Vec3 half{size * 0.5, size * 0.35, thick / 2};
        prop.add(ShapeKind::kBox, {base.x, base.y, z + thick / 2}, half, material, yawRotation(book_yaw));
        z += thick;
      }
      break;
    }
  }
}

void addBuilding(Prop& prop, World& world, Rng& rng, double width, double depth, double height) {
  const int facade = world.addMaterial(facadeMaterial(rng));
  prop.box({0, 0, height / 2}, {width / 2, depth / 2, height / 2}, facade);
  if (rng.chance(0.7)) {
    Material shop = rng.chance(0.5) ? facadeMaterial(rng) : stoneMaterial(rng, 2.0);
    shop.period *= 1.6;
    const int shop_id = world.addMaterial(shop);
    prop.box({0, 0, 1.9}, {width / 2 + 0.15, depth / 2 + 0.15, 1.9}, shop_id);
  }
  const int roof_style = rng.index(3);
  Material roof_material = tileMaterial(rng, 0.8);
  roof_material.base = rng.chance(0.5) ? Vec3{0.35, 0.12, 0.08} : Vec3{0.18, 0.19, 0.21};
  roof_material.accent = roof_material.base * 0.8;
  const int roof = world.addMaterial(roof_material);
  if (roof_style == 0) {
    const double rise = rng.uniform(0.25, 0.5) * std::fmin(width, depth);
    prop.add(ShapeKind::kWedge, {0, 0, height + rise / 2}, {width / 2 + 0.3, depth / 2 + 0.3, rise / 2},
             roof);
  } else if (roof_style == 1) {
    const int cornice = world.addMaterial(stoneMaterial(rng, 1.0));
    prop.box({0, 0, height + 0.2}, {width / 2 + 0.3, depth / 2 + 0.3, 0.2}, cornice);
    const int units = rng.index(4);
    for (int i = 0; i < units; ++i) {
      const Vec3 c{rng.uniform(-0.35, 0.35) * width, rng.uniform(-0.35, 0.35) * depth, height + 0.9};
      prop.box(c, {rng.uniform(0.5, 1.5), rng.uniform(0.5, 1.5), 0.5}, cornice);
    }
  } else {
    const double spire = rng.uniform(0.4, 1.0) * std::fmin(width, depth);
    prop.add(ShapeKind::kCone, {0, 0, height + spire / 2},
             {width / 2 * 0.75, depth / 2 * 0.75, spire / 2}, roof);
  }
  if (rng.chance(0.5)) {
    const int balcony = world.addMaterial(metalMaterial(rng));
    const double floor_h = world.materials[facade].period * 1.25;
    for (double z = floor_h * 2; z < height - floor_h; z += floor_h) {
      prop.box({0, depth / 2 + 0.4, z + 0.1}, {width * 0.3, 0.4, 0.06}, balcony);
    }
  }
}

void addTree(Prop& prop, World& world, Rng& rng, double height) {
  const int bark = world.addMaterial(stoneMaterial(rng, 0.2));
  const int leaves = world.addMaterial(foliageMaterial(rng));
  const double trunk_r = height * rng.uniform(0.025, 0.04);
  const double trunk_h = height * 0.5;
  prop.add(ShapeKind::kCylinder, {0, 0, trunk_h / 2}, {trunk_r, trunk_r, trunk_h / 2}, bark);
  if (rng.chance(0.3)) {
    prop.add(ShapeKind::kCone, {0, 0, height * 0.6}, {height * 0.22, height * 0.22, height * 0.4}, leaves);
    return;
  }
  const int blobs = 1 + rng.index(3);
  for (int i = 0; i < blobs; ++i) {
    const Vec3 c{rng.uniform(-0.12, 0.12) * height, rng.uniform(-0.12, 0.12) * height,
                 rng.uniform(0.62, 0.75) * height};
    const double r = rng.uniform(0.2, 0.3) * height;
    prop.add(ShapeKind::kEllipsoid, c, {r, r, r * 0.9}, leaves);
  }
}

void addLampPost(Prop& prop, World& world, Rng& rng) {
  const int metal = world.addMaterial(metalMaterial(rng));
  const double h = rng.uniform(3.5, 5.0);
  prop.add(ShapeKind::kCylinder, {0, 0, h / 2}, {0.07, 0.07, h / 2}, metal);
  prop.add(ShapeKind::kEllipsoid, {0, 0, h + 0.15}, {0.22, 0.22, 0.2}, metal);
}

void addBench(Prop& prop, World& world, Rng& rng) {
  const int wood = world.addMaterial(woodMaterial(rng, 0.5));
  const int metal = world.addMaterial(metalMaterial(rng));
  for (int i = 0; i < 3; ++i) prop.box({0, -0.15 + 0.15 * i, 0.45}, {0.9, 0.06, 0.02}, wood);
  prop.box({0, -0.25, 0.75}, {0.9, 0.02, 0.12}, wood);
  for (double x : {-0.75, 0.75}) prop.box({x, 0, 0.22}, {0.03, 0.22, 0.22}, metal);
}

void addCar(Prop& prop, World& world, Rng& rng) {
  Material paint = plasticMaterial(rng, 5.0);
  paint.pattern = Pattern::kGrain;
  paint.specular = 0.6;
  paint.shininess = 64;
  const int body = world.addMaterial(paint);
  Material glass_m;
  glass_m.base = {0.05, 0.07, 0.09};
  glass_m.specular = 0.8;
  glass_m.shininess = 64;
  const int glass = world.addMaterial(glass_m);
  Material tyre_m;
  tyre_m.base = {0.03, 0.03, 0.03};
  const int tyre = world.addMaterial(tyre_m);
  const double length = rng.uniform(1.9, 2.4);
  prop.box({0, 0, 0.65}, {length, 0.9, 0.32}, body);
  prop.box({-0.15, 0, 1.22}, {length * 0.5, 0.8, 0.26}, glass);
  const Mat3 wheel_axis = axisRotation({0, 1, 0});
  for (int i = 0; i < 4; ++i) {
    const double x = (i & 1) ? length * 0.65 : -length * 0.65, y = (i & 2) ? 0.82 : -0.82;
    prop.add(ShapeKind::kCylinder, {x, y, 0.34}, {0.34, 0.34, 0.12}, tyre, wheel_axis);
  }
}

void addLandmark(Prop& prop, World& world, Rng& rng, double size) {
  const int stone = world.addMaterial(rng.chance(0.5) ? marbleMaterial(rng, 3.0) : stoneMaterial(rng, 1.0));
  const int accent = world.addMaterial(rng.chance(0.5) ? brickMaterial(rng, 2.0) : metalMaterial(rng));
  const int kind = rng.index(4);
  if (kind == 0) {  // obelisk
    prop.box({0, 0, 0.6}, {size * 0.3, size * 0.3, 0.6}, accent);
    prop.box({0, 0, 1.2 + size * 0.5}, {size * 0.08, size * 0.08, size * 0.5}, stone);
    prop.add(ShapeKind::kCone, {0, 0, 1.2 + size + size * 0.06}, {size * 0.09, size * 0.09, size * 0.06}, stone);
  } else if (kind == 1) {  // statue on a pedestal
    prop.box({0, 0, size * 0.2}, {size * 0.2, size * 0.2, size * 0.2}, stone);
    prop.add(ShapeKind::kCylinder, {0, 0, size * 0.55}, {size * 0.08, size * 0.06, size * 0.15}, accent);
    prop.add(ShapeKind::kEllipsoid, {0, 0, size * 0.78}, {size * 0.1, size * 0.08, size * 0.12}, accent);
    prop.add(ShapeKind::kEllipsoid, {0, 0, size * 0.96}, {size * 0.05, size * 0.05, size * 0.06}, accent);
  } else if (kind == 2) {  // domed pavilion on columns
    const double r = size * 0.35;
    prop.add(ShapeKind::kCylinder, {0, 0, 0.3}, {r * 1.2, r * 1.2, 0.3}, stone);
    const int columns = 6 + 2 * rng.index(3);
    for (int i = 0; i < columns; ++i) {
      const double a = 2.0 * kPi * i / columns;
      prop.add(ShapeKind::kCylinder, {r * detCos(a), r * detSin(a), 0.6 + size * 0.25},
               {size * 0.03, size * 0.03, size * 0.25}, stone);
    }
    prop.add(ShapeKind::kCylinder, {0, 0, 0.6 + size * 0.53}, {r * 1.1, r * 1.1, size * 0.03}, stone);
    prop.add(ShapeKind::kEllipsoid, {0, 0, 0.6 + size * 0.56}, {r, r, r * 0.8}, accent);
  } else {  // clock tower
    const int facade = world.addMaterial(facadeMaterial(rng));
    const double w = size * 0.18;
    prop.box({0, 0, size * 0.5}, {w, w, size * 0.5}, facade);
    prop.add(ShapeKind::kWedge, {0, 0, size + w * 0.5}, {w * 1.1, w * 1.1, w * 0.5}, accent);
    const Mat3 face_axis = axisRotation({0, 1, 0});
    prop.add(ShapeKind::kCylinder, {0, w + 0.02, size * 0.85}, {w * 0.6, w * 0.6, 0.02}, stone, face_axis);
    prop.add(ShapeKind::kCylinder, {0, -w - 0.02, size * 0.85}, {w * 0.6, w * 0.6, 0.02}, stone, face_axis);
  }
}

}  // namespace ffloc::synthetic
