#include "ffloc/model/rope2d.h"

#include <ATen/TensorOperators.h>
#include <ATen/ops/arange.h>
#include <ATen/ops/cat.h>
#include <ATen/ops/cos.h>
#include <ATen/ops/embedding.h>
#include <ATen/ops/ones_like.h>
#include <ATen/ops/outer.h>
#include <ATen/ops/pow.h>
#include <ATen/ops/reciprocal.h>
#include <ATen/ops/sin.h>

#include <stdexcept>

#include "ffloc/model/op_profile.h"

namespace ffloc {

RopeTables ropeTables(int64_t half_dim, int64_t num_positions, double base) {
  if (half_dim <= 0 || half_dim % 2 != 0) {
    throw std::invalid_argument("ropeTables: half_dim must be positive and even");
  }
  const at::TensorOptions f32 = at::TensorOptions().dtype(at::kFloat);
  // 1 / base^(2i / D) with the exponent and the power in float32, as the reference does.
  const at::Tensor exponent = at::arange(0, half_dim, 2, f32) / static_cast<double>(half_dim);
  const at::Tensor inv_freq = at::reciprocal(at::pow(base, exponent));
  const at::Tensor angles = at::outer(at::arange(num_positions, f32), inv_freq);
  const at::Tensor both = at::cat({angles, angles}, -1);
  return {at::cos(both), at::sin(both)};
}

RopeFactors ropeFactors(const at::Tensor& positions, int64_t head_dim, at::ScalarType dtype,
                        double base) {
  const OpScope scope(OpKind::kRope);
  if (positions.dim() != 3 || positions.size(2) != 2) {
    throw std::invalid_argument("ropeFactors: positions must be (B, N, 2)");
  }
  const int64_t half = head_dim / 2;
  const int64_t num_positions = positions.numel() == 0 ? 1 : positions.max().item<int64_t>() + 1;
  RopeTables tables = ropeTables(half, num_positions, base);
  const at::Tensor cos = tables.cos.to(positions.device());
  const at::Tensor sin = tables.sin.to(positions.device());
  // Negate the first quarter of each half: rotate_half(t) = (-t2, t1).
  const at::Tensor sign =
      at::cat({-at::ones_like(sin.narrow(1, 0, half / 2)), at::ones_like(sin.narrow(1, half / 2, half / 2))}, 1);
  const at::Tensor signed_sin = sin * sign;
  const at::Tensor y = positions.select(2, 0);
  const at::Tensor x = positions.select(2, 1);
  RopeFactors factors;
  factors.cos = at::cat({at::embedding(cos, y), at::embedding(cos, x)}, -1).unsqueeze(1).to(dtype);
  factors.signed_sin =
      at::cat({at::embedding(signed_sin, y), at::embedding(signed_sin, x)}, -1).unsqueeze(1).to(dtype);
  return factors;
}

at::Tensor applyRope(const at::Tensor& tokens, const RopeFactors& factors) {
  const OpScope scope(OpKind::kRope);
  const int64_t head_dim = tokens.size(-1);
  const int64_t quarter = head_dim / 4;
  // Swap the two quarters inside each half: (t1, t2, t3, t4) -> (t2, t1, t4, t3).
  std::vector<int64_t> split = tokens.sizes().vec();
  split.back() = 2;
  split.push_back(2);
  split.push_back(quarter);
  const at::Tensor swapped = tokens.reshape(split).flip({-2}).reshape(tokens.sizes());
  return tokens * factors.cos + swapped * factors.signed_sin;
}

}  // namespace ffloc
