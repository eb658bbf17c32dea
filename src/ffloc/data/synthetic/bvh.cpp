#include "ffloc/data/synthetic/bvh.h"

#include <algorithm>
#include <cmath>

namespace ffloc::synthetic {
namespace {

constexpr int kLeafSize = 1;
// Traversal keeps at most one pending node per level, so the build stops splitting here.
constexpr int kMaxDepth = 60;

struct RayBoxTest {
  Vec3 origin, inverse;
  bool negative[3];  // per axis: the ray meets the box's upper face first

  explicit RayBoxTest(const Ray& ray)
      : origin(ray.origin),
        inverse(1.0 / ray.direction.x, 1.0 / ray.direction.y, 1.0 / ray.direction.z),
        negative{inverse.x < 0.0, inverse.y < 0.0, inverse.z < 0.0} {}

  // Entry distance into the box, or 1e300 when the ray misses it within (t_min, t_max).
  double enter(const Aabb& box, double t_min, double t_max) const {
    double lo = t_min, hi = t_max;
    for (int a = 0; a < 3; ++a) {
      const double t0 = ((negative[a] ? box.hi[a] : box.lo[a]) - origin[a]) * inverse[a];
      const double t1 = ((negative[a] ? box.lo[a] : box.hi[a]) - origin[a]) * inverse[a];
      // NaN (0 * inf for a ray in a box face) compares false and leaves the bound untouched.
      if (t0 > lo) lo = t0;
      if (t1 < hi) hi = t1;
      if (lo > hi) return 1e300;
    }
    return lo;
  }
};

}  // namespace

namespace {

double surfaceArea(const Aabb& box) {
  const Vec3 e = box.hi - box.lo;
  if (e.x < 0.0) return 0.0;
  return 2.0 * (e.x * e.y + e.y * e.z + e.z * e.x);
}

}  // namespace

Bvh::Bvh(const std::vector<Shape>& shapes) {
  std::vector<Aabb> boxes;
  boxes.reserve(shapes.size());
  for (const auto& s : shapes) boxes.push_back(bounds(s));
  for (size_t i = 0; i < shapes.size(); ++i) order_.push_back(static_cast<int>(i));
  nodes_.reserve(2 * order_.size() + 1);
  if (!order_.empty()) build(order_, 0, static_cast<int>(order_.size()), boxes, 0);
}

// Binned surface-area heuristic: rooms and streets mix a few huge shapes (floor, walls,
// ground) with many small ones (books, clutter); a median split would scatter the huge boxes
// into leaves all over the tree, and every ray would visit them.
int Bvh::build(std::vector<int>& items, int begin, int end, const std::vector<Aabb>& boxes,
               int depth) {
  const int index = static_cast<int>(nodes_.size());
  nodes_.push_back({});
  Aabb box, centres;
  for (int i = begin; i < end; ++i) {
    box.grow(boxes[items[i]]);
    centres.grow(boxes[items[i]].centre());
  }
  nodes_[index].box = box;
  const int count = end - begin;
  auto makeLeaf = [&]() {
    nodes_[index].first = begin;
    nodes_[index].count = count;
    return index;
  };
  if (count <= kLeafSize || depth >= kMaxDepth) return makeLeaf();

  constexpr int kBins = 16;
  constexpr double kTraversalCost = 1.0;
  double best_cost = count * surfaceArea(box);  // cost of a leaf, in intersection tests
  int best_axis = -1, best_split = 0;
  for (int axis = 0; axis < 3; ++axis) {
    const double lo = centres.lo[axis], extent = centres.hi[axis] - lo;
    if (extent <= 0.0) continue;
    Aabb bin_box[kBins];
    int bin_count[kBins] = {};
    for (int i = begin; i < end; ++i) {
      int b = static_cast<int>((boxes[items[i]].centre()[axis] - lo) / extent * kBins);
      b = b < 0 ? 0 : (b >= kBins ? kBins - 1 : b);
      bin_box[b].grow(boxes[items[i]]);
      ++bin_count[b];
    }
    double right_area[kBins];
    int right_count[kBins];
    Aabb accumulated;
    int n = 0;
    for (int b = kBins - 1; b > 0; --b) {
      accumulated.grow(bin_box[b]);
      n += bin_count[b];
      right_area[b] = surfaceArea(accumulated);
      right_count[b] = n;
    }
    Aabb left;
    int left_n = 0;
    for (int split = 1; split < kBins; ++split) {
      left.grow(bin_box[split - 1]);
      left_n += bin_count[split - 1];
      if (left_n == 0 || right_count[split] == 0) continue;
      const double cost = kTraversalCost * surfaceArea(box) + left_n * surfaceArea(left) +
                          right_count[split] * right_area[split];
      if (cost < best_cost) {
        best_cost = cost;
        best_axis = axis;
        best_split = split;
      }
    }
  }
  int mid = begin;
  if (best_axis >= 0) {
    const double lo = centres.lo[best_axis], extent = centres.hi[best_axis] - lo;
    // Stable, so the order of shapes (and so the tree) is fully determined.
    mid = static_cast<int>(
        std::stable_partition(items.begin() + begin, items.begin() + end,
                              [&](int item) {
                                int b = static_cast<int>(
                                    (boxes[item].centre()[best_axis] - lo) / extent * kBins);
                                b = b < 0 ? 0 : (b >= kBins ? kBins - 1 : b);
                                return b < best_split;
                              }) -
        items.begin());
  } else if (count > 8) {
    // No split pays off by area, but a long leaf is slow: halve it in index order.
    mid = begin + count / 2;
  } else {
    return makeLeaf();
  }
  build(items, begin, mid, boxes, depth + 1);  // lands at index + 1
  const int right = build(items, mid, end, boxes, depth + 1);
  nodes_[index].first = right;
  nodes_[index].count = 0;
  return index;
}

bool Bvh::closestHit(const std::vector<Shape>& shapes, const Ray& ray, double t_min,
                     double t_max, Hit& hit) const {
  if (nodes_.empty()) return false;
  bool found = false;
  double best = t_max;
  const RayBoxTest test(ray);
  // Each pending node carries its entry distance, so a node is box-tested once, when its
  // parent is visited, and dropped on the pop if a nearer hit has been found since.
  struct Pending {
    int node;
    double enter;
  };
  Pending stack[kMaxDepth + 2];
  int top = 0;
  const double root_enter = test.enter(nodes_[0].box, t_min, best);
  if (root_enter > best) return found;
  stack[top++] = {0, root_enter};
  while (top > 0) {
    const Pending pending = stack[--top];
    if (pending.enter > best) continue;
    const Node& node = nodes_[pending.node];
    if (node.count > 0) {
      for (int i = node.first; i < node.first + node.count; ++i) {
        const int s = order_[i];
        double t;
        Vec3 n;
        // Strictly nearer than the best so far: of two hits at the same distance the first
        // found wins, which the fixed tree and traversal order make deterministic.
        if (!intersect(shapes[s], ray, t_min, best, t, n)) continue;
        best = t;
        hit.t = t;
        hit.shape = s;
        hit.local_normal = n;
        found = true;
      }
      continue;
    }
    // Visit the nearer child first so the far one is often culled by the shrunken bound.
    const int left = pending.node + 1, right = node.first;
    const double tl = test.enter(nodes_[left].box, t_min, best);
    const double tr = test.enter(nodes_[right].box, t_min, best);
    if (tl <= tr) {
      if (tr <= best) stack[top++] = {right, tr};
      if (tl <= best) stack[top++] = {left, tl};
    } else {
      if (tl <= best) stack[top++] = {left, tl};
      if (tr <= best) stack[top++] = {right, tr};
    }
  }
  return found;
}

bool Bvh::occluded(const std::vector<Shape>& shapes, const Ray& ray, double t_min,
                   double t_max) const {
  if (nodes_.empty()) return false;
  double t;
  Vec3 n;
  const RayBoxTest test(ray);
  int stack[kMaxDepth + 2];
  int top = 0;
  stack[top++] = 0;
  while (top > 0) {
    const Node& node = nodes_[stack[--top]];
    if (test.enter(node.box, t_min, t_max) > t_max) continue;
    if (node.count > 0) {
      for (int i = node.first; i < node.first + node.count; ++i) {
        if (intersect(shapes[order_[i]], ray, t_min, t_max, t, n)) return true;
      }
      continue;
    }
    stack[top++] = static_cast<int>(&node - nodes_.data()) + 1;
    stack[top++] = node.first;
  }
  return false;
}

}  // namespace ffloc::synthetic
