#include "ffloc/retrieval/global_descriptor.h"

#include <cmath>
#include <stdexcept>

namespace ffloc {

std::vector<float> globalDescriptor(const float* tokens, int64_t count, int64_t dim,
                                    const GlobalDescriptorOptions& options) {
  std::vector<double> positive(dim, 0.0), negative(dim, 0.0);
  for (int64_t t = 0; t < count; ++t) {
    const float* row = tokens + t * dim;
    for (int64_t c = 0; c < dim; ++c) {
      const double v = row[c];
      if (v > 0)
        positive[c] += std::pow(v, options.p);
      else
        negative[c] += std::pow(-v, options.p);
    }
  }
  std::vector<float> descriptor(2 * dim);
  double norm2 = 0;
  for (int64_t c = 0; c < dim; ++c) {
    const double pos = count ? std::pow(positive[c] / count, 1.0 / options.p) : 0.0;
    const double neg = count ? std::pow(negative[c] / count, 1.0 / options.p) : 0.0;
    descriptor[c] = static_cast<float>(pos);
    descriptor[dim + c] = static_cast<float>(neg);
    norm2 += pos * pos + neg * neg;
  }
  if (norm2 > 0) {
    const double inv = 1.0 / std::sqrt(norm2);
    for (float& v : descriptor) v = static_cast<float>(v * inv);
  }
  return descriptor;
}

float cosineSimilarity(const std::vector<float>& a, const std::vector<float>& b) {
  if (a.size() != b.size())
    throw std::invalid_argument("cosineSimilarity: descriptors of different lengths (" + std::to_string(a.size()) +
                                " and " + std::to_string(b.size()) + ")");
  double dot = 0, na = 0, nb = 0;
  for (size_t i = 0; i < a.size(); ++i) {
    dot += static_cast<double>(a[i]) * b[i];
    na += static_cast<double>(a[i]) * a[i];
    nb += static_cast<double>(b[i]) * b[i];
  }
  if (na == 0 || nb == 0) return 0.0f;
  return static_cast<float>(dot / std::sqrt(na * nb));
}

}  // namespace ffloc
