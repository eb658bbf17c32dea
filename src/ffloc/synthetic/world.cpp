#include "ffloc/synthetic/world.h"

namespace ffloc::synthetic {

int World::addMaterial(const Material& material) {
  materials.push_back(material);
  return static_cast<int>(materials.size()) - 1;
}

int World::addShape(const Shape& shape) {
  shapes.push_back(shape);
  return static_cast<int>(shapes.size()) - 1;
}

}  // namespace ffloc::synthetic
