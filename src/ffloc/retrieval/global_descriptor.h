#pragma once

#include <cstdint>
#include <vector>

namespace ffloc {

// A global image descriptor pooled from the encoder's own tokens, so retrieval ships no second
// network: generalised-mean (GeM) pooling of each channel over the image's tokens, then L2
// normalisation. Encoder tokens come out of a LayerNorm and take both signs, so GeM pools the
// positive and the negative parts of each channel separately (2 * dim values); with p = 1 this is
// the plain mean of each part, and large p tends to the max.
struct GlobalDescriptorOptions {
  double p = 3.0;
};

// tokens: `count` rows of `dim` floats, row-major. Returns 2 * dim values with unit L2 norm (all
// zero for an all-zero input).
std::vector<float> globalDescriptor(const float* tokens, int64_t count, int64_t dim,
                                    const GlobalDescriptorOptions& options = {});

float cosineSimilarity(const std::vector<float>& a, const std::vector<float>& b);

}  // namespace ffloc
