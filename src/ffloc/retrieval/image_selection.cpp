#include "ffloc/retrieval/image_selection.h"

#include <algorithm>
#include <limits>
#include <numeric>

#include "ffloc/core/error.h"
#include "ffloc/core/random.h"
#include "ffloc/retrieval/global_descriptor.h"

namespace ffloc {

const char* toString(ImageSelection selection) {
  switch (selection) {
    case ImageSelection::kRetrieval: return "retrieval";
    case ImageSelection::kUniform: return "uniform";
    case ImageSelection::kRandom: return "random";
  }
  return "retrieval";
}

ImageSelection parseImageSelection(const std::string& name) {
  if (name == "retrieval") return ImageSelection::kRetrieval;
  if (name == "uniform") return ImageSelection::kUniform;
  if (name == "random") return ImageSelection::kRandom;
  throw InputError("selection: unknown strategy '" + name + "' (known: retrieval, uniform, random)");
}

std::vector<size_t> topKBySimilarity(const std::vector<std::vector<float>>& database,
                                     const std::vector<float>& query, size_t k) {
  std::vector<float> similarity(database.size());
  for (size_t i = 0; i < database.size(); ++i) similarity[i] = cosineSimilarity(database[i], query);
  std::vector<size_t> order(database.size());
  std::iota(order.begin(), order.end(), 0);
  const size_t keep = std::min(k, order.size());
  std::partial_sort(order.begin(), order.begin() + keep, order.end(), [&](size_t a, size_t b) {
    return similarity[a] > similarity[b] || (similarity[a] == similarity[b] && a < b);
  });
  order.resize(keep);
  return order;
}

std::vector<size_t> uniformSelection(size_t count, size_t k) {
  std::vector<size_t> out;
  if (count == 0 || k == 0) return out;
  if (k >= count) {
    out.resize(count);
    std::iota(out.begin(), out.end(), 0);
    return out;
  }
  for (size_t i = 0; i < k; ++i) out.push_back(i * count / k);
  return out;
}

std::vector<size_t> randomSelection(size_t count, size_t k, uint64_t seed) {
  std::vector<size_t> all(count);
  std::iota(all.begin(), all.end(), 0);
  if (k >= count) return all;
  // A partial Fisher-Yates shuffle.
  Rng rng(seed);
  for (size_t i = 0; i < k; ++i) std::swap(all[i], all[i + rng.below(count - i)]);
  all.resize(k);
  std::sort(all.begin(), all.end());
  return all;
}

size_t nearestMappingCamera(const std::vector<Pose>& mapping, const Pose& query, double max_angle_deg) {
  size_t best_close = mapping.size(), best_angle_index = 0;
  double best_distance = std::numeric_limits<double>::infinity();
  double best_angle = std::numeric_limits<double>::infinity();
  for (size_t i = 0; i < mapping.size(); ++i) {
    const double angle = rotationErrorDeg(mapping[i], query);
    const double distance = translationError(mapping[i], query);
    if (angle <= max_angle_deg && distance < best_distance) {
      best_distance = distance;
      best_close = i;
    }
    if (angle < best_angle) {
      best_angle = angle;
      best_angle_index = i;
    }
  }
  return best_close < mapping.size() ? best_close : best_angle_index;
}

}  // namespace ffloc
