#include "ffloc/model/rope2d.h"

#include <ATen/TensorOperators.h>
#include <ATen/core/grad_mode.h>
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
#include "ffloc/model/torch_threads.h"

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

bool ropeInPlaceApplies(const at::Tensor& token_rows, const RopeFactors& factors) {
  if (at::GradMode::is_enabled() && token_rows.requires_grad()) return false;
  return token_rows.is_cpu() && token_rows.scalar_type() == at::kFloat && token_rows.dim() == 3 &&
         token_rows.stride(2) == 1 && factors.cos.scalar_type() == at::kFloat && factors.cos.is_contiguous() &&
         factors.signed_sin.is_contiguous() && factors.cos.size(2) == token_rows.size(1) &&
         (factors.cos.size(0) == token_rows.size(0) || factors.cos.size(0) == 1) &&
         token_rows.size(2) % factors.cos.size(3) == 0;
}

void applyRopeInPlace(const at::Tensor& token_rows, const RopeFactors& factors) {
  const OpScope scope(OpKind::kRope);
  const int64_t batch = token_rows.size(0), tokens = token_rows.size(1);
  const int64_t head_dim = factors.cos.size(3), heads = token_rows.size(2) / head_dim;
  const int64_t quarter = head_dim / 4;
  const int64_t factor_batch = factors.cos.size(0);
  const int64_t batch_stride = token_rows.stride(0), row_stride = token_rows.stride(1);
  float* data = token_rows.data_ptr<float>();
  const float* cos = factors.cos.data_ptr<float>();
  const float* sin = factors.signed_sin.data_ptr<float>();
  parallelFor(0, batch * tokens, 256, [&](int64_t first, int64_t last) {
    std::vector<float> original(static_cast<size_t>(head_dim));
    for (int64_t index = first; index < last; ++index) {
      const int64_t b = index / tokens, n = index % tokens;
      float* row = data + b * batch_stride + n * row_stride;
      const int64_t factor_row = ((b % factor_batch) * tokens + n) * head_dim;
      const float* c = cos + factor_row;
      const float* s = sin + factor_row;
      for (int64_t h = 0; h < heads; ++h) {
        float* t = row + h * head_dim;
        std::copy(t, t + head_dim, original.begin());
        // Each half pairs its two quarters: out = t * cos + (t with the quarters swapped) * signed_sin.
        for (int64_t half = 0; half < head_dim; half += 2 * quarter) {
          for (int64_t j = half; j < half + quarter; ++j) {
            t[j] = original[j] * c[j] + original[j + quarter] * s[j];
            t[j + quarter] = original[j + quarter] * c[j + quarter] + original[j] * s[j + quarter];
          }
        }
      }
    }
  });
}

}  // namespace ffloc
