#include "ffloc/model/point_encoding.h"

#include <ATen/TensorOperators.h>
#include <ATen/ops/clamp_min.h>
#include <ATen/ops/gelu.h>
#include <ATen/ops/where.h>
#include <ATen/ops/zeros_like.h>

#include "ffloc/core/error.h"
#include "ffloc/model/ray_encoding.h"

namespace ffloc {

at::Tensor contractPoints(const at::Tensor& points) {
  const at::Tensor x = points.to(at::kFloat);
  const at::Tensor norm = x.norm(2, -1, true).clamp_min(1e-12);
  const at::Tensor folded = (2.0 - 1.0 / norm) * (x / norm);
  return at::where(norm <= 1.0, x, folded) * 0.5;
}

PointEncoder::PointEncoder(const PointEncoderConfig& config, int64_t out_dim)
    : config(config),
      fc1(config.inputDim(), config.hidden_dim > 0 ? config.hidden_dim : out_dim),
      fc2(config.hidden_dim > 0 ? config.hidden_dim : out_dim, out_dim) {}

void PointEncoder::registerIn(ParameterTable& table, const std::string& prefix) {
  fc1.registerIn(table, prefix + ".fc1");
  fc2.registerIn(table, prefix + ".fc2");
}

at::Tensor PointEncoder::forward(const at::Tensor& points, const at::Tensor& valid) const {
  if (points.dim() < 1 || points.size(-1) != 3 || valid.sizes() != points.sizes().slice(0, points.dim() - 1)) {
    throwInputError("map points", 0, "expected (..., 3) points with a (...) validity mask");
  }
  // Invalid points may hold anything (NaN included); they are zeroed before the encoding so that
  // no NaN reaches the gradient through the masked branch.
  const at::Tensor mask = valid.unsqueeze(-1);
  const at::Tensor safe = at::where(mask, points.to(at::kFloat), at::zeros_like(points, at::kFloat));
  const at::Tensor encoded = fourierFeatures(contractPoints(safe), config.frequencies, true);
  const at::Tensor out = fc2.forward(at::gelu(fc1.forward(encoded.to(fc1.weight.scalar_type()))));
  return out * mask.to(out.scalar_type());
}

}  // namespace ffloc
