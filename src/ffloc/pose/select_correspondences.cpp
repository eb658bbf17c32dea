#include "ffloc/pose/select_correspondences.h"

#include <algorithm>

namespace ffloc {

std::vector<int> selectCorrespondences(const Correspondences& correspondences,
                                       float confidence_threshold, size_t max_count,
                                       std::mt19937_64* rng) {
  std::vector<int> selected;
  selected.reserve(correspondences.size());
  for (size_t i = 0; i < correspondences.size(); ++i) {
    if (!(correspondences.confidences[i] >= confidence_threshold)) continue;
    if (!correspondences.pixels[i].allFinite() || !correspondences.points[i].allFinite()) continue;
    selected.push_back(static_cast<int>(i));
  }
  if (selected.size() <= max_count) return selected;
  // Partial Fisher-Yates: the first max_count slots become a uniform random subset.
  for (size_t i = 0; i < max_count; ++i) {
    std::uniform_int_distribution<size_t> pick(i, selected.size() - 1);
    std::swap(selected[i], selected[pick(*rng)]);
  }
  selected.resize(max_count);
  std::sort(selected.begin(), selected.end());
  return selected;
}

}  // namespace ffloc
