#pragma once

#include <vector>

namespace ffloc {

// The median as numpy and the papers' evaluation scripts give it: the middle value, or the mean
// of the two middle values for an even count (so with half the values infinite, as failed poses
// are counted, it is infinite). Empty input gives 0.
double median(std::vector<double> values);

// Nearest-rank percentile, q in [0, 1]. Empty input gives 0.
double percentile(std::vector<double> values, double q);

}  // namespace ffloc
