#pragma once

#include <vector>

#include "ffloc/core/random.h"
#include "ffloc/pose/correspondences.h"

namespace ffloc {

// Indices of the pairs PnP should use, in increasing order: those with finite pixel and point
// and a confidence >= confidence_threshold (NaN never passes), then, when more than max_count
// remain, a uniformly random subset of max_count of them drawn with `rng`.
// When fewer than min_count pass the threshold, the min_count most confident finite pairs are
// used instead (ties by index): a weakly trained network can sit below the paper's threshold
// everywhere, and RANSAC, not the threshold, is what rejects wrong points.
std::vector<int> selectCorrespondences(const Correspondences& correspondences, float confidence_threshold,
                                       size_t max_count, Rng* rng, size_t min_count = 0);

}  // namespace ffloc
