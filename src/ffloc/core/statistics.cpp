#include "ffloc/core/statistics.h"

#include <algorithm>
#include <cmath>

namespace ffloc {

double median(std::vector<double> values) {
  if (values.empty()) return 0;
  const size_t upper = values.size() / 2;
  std::nth_element(values.begin(), values.begin() + static_cast<std::ptrdiff_t>(upper), values.end());
  if (values.size() % 2 == 1) return values[upper];
  const double lower = *std::max_element(values.begin(), values.begin() + static_cast<std::ptrdiff_t>(upper));
  return 0.5 * (lower + values[upper]);
}

double percentile(std::vector<double> values, double q) {
  if (values.empty()) return 0;
  std::sort(values.begin(), values.end());
  const double rank = std::ceil(std::clamp(q, 0.0, 1.0) * values.size());
  const size_t index = rank < 1 ? 0 : static_cast<size_t>(rank) - 1;
  return values[std::min(index, values.size() - 1)];
}

}  // namespace ffloc
