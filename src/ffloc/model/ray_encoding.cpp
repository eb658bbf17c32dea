#include "ffloc/model/ray_encoding.h"

#include <ATen/TensorOperators.h>
#include <ATen/ops/cat.h>
#include <ATen/ops/cos.h>
#include <ATen/ops/empty.h>
#include <ATen/ops/gelu.h>
#include <ATen/ops/sin.h>

#include <cmath>

#include "ffloc/core/error.h"

namespace ffloc {

at::Tensor fourierFeatures(const at::Tensor& x, int64_t num_frequencies, bool include_input) {
  const at::Tensor input = x.to(at::kFloat);
  std::vector<at::Tensor> parts;
  if (include_input) parts.push_back(input);
  for (int64_t l = 0; l < num_frequencies; ++l) {
    const at::Tensor scaled = input * (std::ldexp(1.0, static_cast<int>(l)) * M_PI);
    parts.push_back(at::sin(scaled));
    parts.push_back(at::cos(scaled));
  }
  return at::cat(parts, -1);
}

int64_t RayEncoderConfig::inputDim() const {
  const int64_t identity = include_input ? 1 : 0;
  return 3 * (identity + 2 * origin_frequencies) + 3 * (identity + 2 * direction_frequencies);
}

RayEncoder::RayEncoder(const RayEncoderConfig& config, int64_t out_dim)
    : config(config),
      fc1(config.inputDim(), config.hidden_dim > 0 ? config.hidden_dim : out_dim),
      fc2(config.hidden_dim > 0 ? config.hidden_dim : out_dim, out_dim) {}

void RayEncoder::registerIn(ParameterTable& table, const std::string& prefix) {
  fc1.registerIn(table, prefix + ".fc1");
  fc2.registerIn(table, prefix + ".fc2");
}

at::Tensor RayEncoder::forward(const at::Tensor& rays) const {
  if (rays.dim() < 1 || rays.size(-1) != 6) {
    throwInputError("map rays", 0, "expected (..., 6) origin + direction, got " + std::to_string(rays.dim()) + " dims");
  }
  const at::Tensor encoded = at::cat({fourierFeatures(rays.narrow(-1, 0, 3), config.origin_frequencies, config.include_input),
                                      fourierFeatures(rays.narrow(-1, 3, 3), config.direction_frequencies, config.include_input)},
                                     -1);
  return fc2.forward(at::gelu(fc1.forward(encoded.to(fc1.weight.scalar_type()))));
}

at::Tensor rayTensor(const std::vector<Ray>& rays) {
  at::Tensor out = at::empty({1, static_cast<int64_t>(rays.size()), 6}, at::TensorOptions().dtype(at::kFloat));
  float* data = out.data_ptr<float>();
  for (size_t i = 0; i < rays.size(); ++i) {
    for (int j = 0; j < 3; ++j) {
      data[6 * i + j] = static_cast<float>(rays[i].origin[j]);
      data[6 * i + 3 + j] = static_cast<float>(rays[i].direction[j]);
    }
  }
  return out;
}

}  // namespace ffloc
