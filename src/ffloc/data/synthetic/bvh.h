#pragma once

#include <vector>

#include "ffloc/data/synthetic/shapes.h"

namespace ffloc::synthetic {

// The closest intersection of a ray with a set of shapes.
struct Hit {
  double t = 0;
  int shape = -1;
  Vec3 local_normal;
};

// A bounding-volume hierarchy over shapes (binary, binned surface-area heuristic). The build
// uses only stable partitions, so the tree is the same whatever the standard library.
class Bvh {
 public:
  Bvh() = default;
  explicit Bvh(const std::vector<Shape>& shapes);

  // Closest hit with t in (t_min, t_max).
  bool closestHit(const std::vector<Shape>& shapes, const Ray& ray, double t_min, double t_max,
                  Hit& hit) const;
  // Whether anything lies on the ray within (t_min, t_max).
  bool occluded(const std::vector<Shape>& shapes, const Ray& ray, double t_min,
                double t_max) const;

 private:
  struct Node {
    Aabb box;
    int first = 0;  // leaf: first entry in order_; inner: index of the right child
    int count = 0;  // leaf: number of shapes; inner: 0 (the left child follows the node)
  };
  int build(std::vector<int>& items, int begin, int end, const std::vector<Aabb>& boxes,
            int depth);

  std::vector<Node> nodes_;
  std::vector<int> order_;
};

}  // namespace ffloc::synthetic
