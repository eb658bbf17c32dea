#include "ffloc/synthetic/bvh.h"

#include <algorithm>
#include <cmath>

namespace ffloc::synthetic {
namespace {

constexpr int kLeafSize = 1;
// Traversal keeps at most one pending node per level, so the build stops splitting here.
constexpr int kMaxDepth = 60;

struct RayBoxTest {
  double origin[3], inverse[3];
  int near[3], far[3];  // per axis: which entry of Node::bounds the ray meets first and last

  explicit RayBoxTest(const Ray& ray)
      : origin{ray.origin.x, ray.origin.y, ray.origin.z},
        inverse{1.0 / ray.direction.x, 1.0 / ray.direction.y, 1.0 / ray.direction.z} {
    for (int a = 0; a < 3; ++a) {
      near[a] = inverse[a] < 0.0 ? a + 3 : a;
      far[a] = inverse[a] < 0.0 ? a : a + 3;
    }
  }

  // Whether the ray meets the box within (t_min, t_max), and where it enters. One branch,
  // on the answer: per-axis early exits cost more in mispredictions than the arithmetic
  // they skip.
  bool enters(const double* bounds, double t_min, double t_max, double& enter) const {
    const double x0 = (bounds[near[0]] - origin[0]) * inverse[0];
    const double x1 = (bounds[far[0]] - origin[0]) * inverse[0];
    const double y0 = (bounds[near[1]] - origin[1]) * inverse[1];
    const double y1 = (bounds[far[1]] - origin[1]) * inverse[1];
    const double z0 = (bounds[near[2]] - origin[2]) * inverse[2];
    const double z1 = (bounds[far[2]] - origin[2]) * inverse[2];
    // NaN (0 * inf for a ray in a box face) compares false and leaves the bound untouched.
    double lo = x0 > t_min ? x0 : t_min, hi = x1 < t_max ? x1 : t_max;
    lo = y0 > lo ? y0 : lo;
    hi = y1 < hi ? y1 : hi;
    lo = z0 > lo ? z0 : lo;
    hi = z1 < hi ? z1 : hi;
    enter = lo;
    return lo <= hi;
  }
};

// Whether the box lies wholly on the far side of the plane: even its corner lowest along the
// normal is above the offset.
bool outside(const double* bounds, const Plane& plane) {
  const Vec3& n = plane.normal;
  const double lowest = n.x * (n.x > 0.0 ? bounds[0] : bounds[3]) +
                        n.y * (n.y > 0.0 ? bounds[1] : bounds[4]) +
                        n.z * (n.z > 0.0 ? bounds[2] : bounds[5]);
  return lowest > plane.offset;
}

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
  for (int a = 0; a < 3; ++a) {
    nodes_[index].bounds[a] = box.lo[a];
    nodes_[index].bounds[a + 3] = box.hi[a];
  }
  const int count = end - begin;
  auto makeLeaf = [&]() {
    nodes_[index].first = begin;
    nodes_[index].count = count;
    return index;
  };
  if (count <= kLeafSize || depth >= kMaxDepth) return makeLeaf();

  constexpr int kBins = 16;
  constexpr double kTraversalCost = 1.0;
  // Always split, even where the heuristic prices a leaf lower: it assumes rays come from
  // outside the box, but cameras stand inside the room or plaza, where every ray enters the
  // box of the walls and a leaf of walls would cost every ray all of their intersections.
  double best_cost = 1e300;
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
  } else {
    // All centres coincide: halve in index order.
    mid = begin + count / 2;
  }
  build(items, begin, mid, boxes, depth + 1);  // lands at index + 1
  const int right = build(items, mid, end, boxes, depth + 1);
  nodes_[index].first = right;
  nodes_[index].count = 0;
  return index;
}

bool Bvh::closestHit(const std::vector<Shape>& shapes, const Ray& ray, double t_min,
                     double t_max, Hit& hit) const {
  double best = t_max, enter;
  const RayBoxTest test(ray);
  if (nodes_.empty() || !test.enters(nodes_[0].bounds, t_min, best, enter)) return false;
  bool found = false;
  // Depth first, nearer child first; the nearer child stays in registers and only the farther
  // one is stacked, with its entry distance, so it can be dropped unvisited once a hit nearer
  // than its box has been found. Node and distance live in separate arrays: a pop then reads
  // exactly what a push wrote, which the processor can forward from the store.
  int pending_node[kMaxDepth + 2];
  double pending_enter[kMaxDepth + 2];
  int top = 0;
  int current = 0;
  for (;;) {
    const Node& node = nodes_[current];
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
    } else {
      const int left = current + 1, right = node.first;
      double tl, tr;
      const bool enters_left = test.enters(nodes_[left].bounds, t_min, best, tl);
      const bool enters_right = test.enters(nodes_[right].bounds, t_min, best, tr);
      if (enters_left && enters_right) {
        const bool left_first = tl <= tr;
        pending_node[top] = left_first ? right : left;
        pending_enter[top] = left_first ? tr : tl;
        ++top;
        current = left_first ? left : right;
        continue;
      }
      if (enters_left || enters_right) {
        current = enters_left ? left : right;
        continue;
      }
    }
    do {
      if (top == 0) return found;
      --top;
    } while (pending_enter[top] > best);
    current = pending_node[top];
  }
}

int Bvh::occluder(const std::vector<Shape>& shapes, const Ray& ray, double t_min,
                  double t_max, int ignore) const {
  double enter;
  const RayBoxTest test(ray);
  if (nodes_.empty() || !test.enters(nodes_[0].bounds, t_min, t_max, enter)) return -1;
  // Any hit ends the search, so the order does not matter; as in closestHit, one child is
  // carried in a register and only a second one is stacked.
  int pending[kMaxDepth + 2];
  int top = 0;
  int current = 0;
  for (;;) {
    const Node& node = nodes_[current];
    if (node.count > 0) {
      for (int i = node.first; i < node.first + node.count; ++i) {
        const int s = order_[i];
        double t;
        Vec3 n;
        if (s != ignore && intersect(shapes[s], ray, t_min, t_max, t, n)) return s;
      }
    } else {
      const int left = current + 1, right = node.first;
      const bool enters_left = test.enters(nodes_[left].bounds, t_min, t_max, enter);
      const bool enters_right = test.enters(nodes_[right].bounds, t_min, t_max, enter);
      if (enters_left && enters_right) pending[top++] = right;
      if (enters_left || enters_right) {
        current = enters_left ? left : right;
        continue;
      }
    }
    if (top == 0) return -1;
    current = pending[--top];
  }
}

void Bvh::collect(const Plane* planes, int count, std::vector<BoxedShape>& out) const {
  if (nodes_.empty()) return;
  int pending[kMaxDepth + 2];
  int top = 0;
  pending[top++] = 0;
  while (top > 0) {
    const int index = pending[--top];
    const Node& node = nodes_[index];
    bool culled = false;
    for (int p = 0; p < count && !culled; ++p) culled = outside(node.bounds, planes[p]);
    if (culled) continue;
    if (node.count > 0) {
      for (int i = node.first; i < node.first + node.count; ++i) {
        BoxedShape entry;
        for (int k = 0; k < 6; ++k) entry.bounds[k] = node.bounds[k];
        entry.shape = order_[i];
        out.push_back(entry);
      }
      continue;
    }
    // Right first, so the left subtree is listed first.
    pending[top++] = node.first;
    pending[top++] = index + 1;
  }
}

bool closestHitAmong(const std::vector<Shape>& shapes, const std::vector<BoxedShape>& list,
                     const Ray& ray, double t_min, double t_max, Hit& hit) {
  const RayBoxTest test(ray);
  double best = t_max, enter;
  bool found = false;
  for (const BoxedShape& entry : list) {
    if (!test.enters(entry.bounds, t_min, best, enter)) continue;
    double t;
    Vec3 n;
    if (!intersect(shapes[entry.shape], ray, t_min, best, t, n)) continue;
    best = t;
    hit.t = t;
    hit.shape = entry.shape;
    hit.local_normal = n;
    found = true;
  }
  return found;
}

int occluderAmong(const std::vector<Shape>& shapes, const std::vector<BoxedShape>& list,
                  const Ray& ray, double t_min, double t_max, int ignore) {
  const RayBoxTest test(ray);
  double enter, t;
  Vec3 n;
  for (const BoxedShape& entry : list) {
    if (entry.shape == ignore || !test.enters(entry.bounds, t_min, t_max, enter)) continue;
    if (intersect(shapes[entry.shape], ray, t_min, t_max, t, n)) return entry.shape;
  }
  return -1;
}

}  // namespace ffloc::synthetic
