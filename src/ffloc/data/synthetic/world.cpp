#include "ffloc/data/synthetic/world.h"

namespace ffloc::synthetic {

int World::addMaterial(const Material& material) {
  materials.push_back(material);
  return static_cast<int>(materials.size()) - 1;
}

int World::addShape(const Shape& shape) {
  shapes.push_back(shape);
  return static_cast<int>(shapes.size()) - 1;
}

bool World::nearAnyShape(const Vec3& p, double margin) const {
  for (const auto& s : shapes)
    if (bounds(s).contains(p, margin)) return true;
  return false;
}

}  // namespace ffloc::synthetic
