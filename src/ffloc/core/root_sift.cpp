#include "ffloc/core/root_sift.h"

#include <cmath>

namespace ffloc {

void toRootSift(cv::Mat& descriptors) {
  for (int r = 0; r < descriptors.rows; ++r) {
    float* row = descriptors.ptr<float>(r);
    double l1 = 0;
    for (int c = 0; c < descriptors.cols; ++c) l1 += std::abs(row[c]);
    const double inv = l1 > 0 ? 1.0 / l1 : 0.0;
    for (int c = 0; c < descriptors.cols; ++c) row[c] = static_cast<float>(std::sqrt(std::abs(row[c]) * inv));
  }
}

}  // namespace ffloc
