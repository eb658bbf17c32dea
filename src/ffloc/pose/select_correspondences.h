#pragma once

#include <random>
#include <vector>

#include "ffloc/pose/correspondences.h"

namespace ffloc {

// Indices of the pairs PnP should use, in increasing order: those with finite pixel and point
// and a confidence >= confidence_threshold (NaN never passes), then, when more than max_count
// remain, a uniformly random subset of max_count of them drawn with `rng`.
std::vector<int> selectCorrespondences(const Correspondences& correspondences,
                                       float confidence_threshold, size_t max_count,
                                       std::mt19937_64* rng);

}  // namespace ffloc
