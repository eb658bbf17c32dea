#include "ffloc/pose/select_correspondences.h"

#include <algorithm>

namespace ffloc {

std::vector<int> selectCorrespondences(const Correspondences& correspondences, float confidence_threshold,
                                       size_t max_count, Rng* rng, size_t min_count) {
  std::vector<int> finite, selected;
  finite.reserve(correspondences.size());
  selected.reserve(correspondences.size());
  for (size_t i = 0; i < correspondences.size(); ++i) {
    if (!correspondences.pixels[i].allFinite() || !correspondences.points[i].allFinite()) continue;
    if (!(correspondences.confidences[i] == correspondences.confidences[i])) continue;  // NaN
    finite.push_back(static_cast<int>(i));
    if (correspondences.confidences[i] >= confidence_threshold) selected.push_back(static_cast<int>(i));
  }
  if (selected.size() < min_count && finite.size() > selected.size()) {
    const size_t keep = std::min(min_count, finite.size());
    const auto more_confident = [&](int a, int b) {
      const float ca = correspondences.confidences[a], cb = correspondences.confidences[b];
      return ca != cb ? ca > cb : a < b;
    };
    std::nth_element(finite.begin(), finite.begin() + static_cast<std::ptrdiff_t>(keep - 1), finite.end(),
                     more_confident);
    selected.assign(finite.begin(), finite.begin() + static_cast<std::ptrdiff_t>(keep));
    std::sort(selected.begin(), selected.end());
  }
  if (selected.size() <= max_count) return selected;
  // Partial Fisher-Yates: the first max_count slots become a uniform random subset.
  for (size_t i = 0; i < max_count; ++i) std::swap(selected[i], selected[i + rng->below(selected.size() - i)]);
  selected.resize(max_count);
  std::sort(selected.begin(), selected.end());
  return selected;
}

}  // namespace ffloc
