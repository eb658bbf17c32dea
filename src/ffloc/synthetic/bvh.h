#pragma once

#include <vector>

#include "ffloc/synthetic/shapes.h"

namespace ffloc::synthetic {

// The closest intersection of a ray with a set of shapes.
struct Hit {
  double t = 0;
  int shape = -1;
  Vec3 local_normal;
};

// The half-space {x : dot(normal, x) <= offset}.
struct Plane {
  Vec3 normal;
  double offset = 0;
};

// A shape with a box around it (its leaf's), for testing rays against a short list of shapes
// without walking the tree.
struct BoxedShape {
  double bounds[6];  // lo.x, lo.y, lo.z, hi.x, hi.y, hi.z
  int shape;
};

// A bounding-volume hierarchy over shapes (binary, binned surface-area heuristic, one shape
// per leaf). The build uses only stable partitions, so the tree is the same whatever the
// standard library.
class Bvh {
 public:
  Bvh() = default;
  explicit Bvh(const std::vector<Shape>& shapes);

  // Closest hit with t in (t_min, t_max).
  bool closestHit(const std::vector<Shape>& shapes, const Ray& ray, double t_min, double t_max,
                  Hit& hit) const;
  // A shape other than `ignore` (-1: none) that lies on the ray within (t_min, t_max), or -1:
  // the first one found, not necessarily the nearest.
  int occluder(const std::vector<Shape>& shapes, const Ray& ray, double t_min, double t_max,
               int ignore = -1) const;

  // Appends, in tree order, every shape whose box is not wholly outside one of the planes: a
  // superset of the shapes that meet the convex region the planes bound. Renderers collect
  // once for a bundle of rays (a tile of pixels, their shadow rays) and then test each ray
  // against the short list.
  void collect(const Plane* planes, int count, std::vector<BoxedShape>& out) const;

 private:
  // One cache line: the box as {lo.x, lo.y, lo.z, hi.x, hi.y, hi.z}, so a ray picks its near
  // and far face per axis by index instead of by branch.
  struct alignas(64) Node {
    double bounds[6];
    int first = 0;  // leaf: first entry in order_; inner: index of the right child
    int count = 0;  // leaf: number of shapes; inner: 0 (the left child follows the node)
  };
  int build(std::vector<int>& items, int begin, int end, const std::vector<Aabb>& boxes,
            int depth);

  std::vector<Node> nodes_;
  std::vector<int> order_;
};

// closestHit and occluder over a list of shapes, for rays that lie wholly in the region the
// list was collected for; the same answers as the tree gives, apart from which of two shapes
// at exactly the same distance is reported.
bool closestHitAmong(const std::vector<Shape>& shapes, const std::vector<BoxedShape>& list,
                     const Ray& ray, double t_min, double t_max, Hit& hit);
int occluderAmong(const std::vector<Shape>& shapes, const std::vector<BoxedShape>& list,
                  const Ray& ray, double t_min, double t_max, int ignore = -1);

}  // namespace ffloc::synthetic
