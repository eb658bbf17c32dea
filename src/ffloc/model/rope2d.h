#pragma once

#include <ATen/core/Tensor.h>

namespace ffloc {

// croco's RoPE2D ("RoPE100"): the first half of each head vector is rotated by the token's row
// (y), the second half by its column (x). Inside a half of length D, element j pairs with
// j + D/2 ("rotate half") at angle pos * base^(-2 (j mod D/2) / D).
//
// The angle table is built in float32 (float32 position times float32 inverse frequency) as
// in the reference, so that float32 results match it to the last bits.

// cos and sin tables of shape (num_positions, D), row p for position p; columns j and j + D/2
// hold the same frequency. float32.
struct RopeTables {
  at::Tensor cos;
  at::Tensor sin;
};
RopeTables ropeTables(int64_t half_dim, int64_t num_positions, double base = 100.0);

// The per-token factors of one attention input, ready to apply to (B, heads, N, head_dim)
// tensors: out = t * cos + swap_quarters(t) * signed_sin, with the sign of the rotate-half
// convention folded into signed_sin (negating a factor is exact, so this equals the reference).
struct RopeFactors {
  at::Tensor cos;         // (B, 1, N, head_dim)
  at::Tensor signed_sin;  // (B, 1, N, head_dim)
};

// positions: (B, N, 2) int64 (y, x). Factors in `dtype`.
RopeFactors ropeFactors(const at::Tensor& positions, int64_t head_dim, at::ScalarType dtype,
                        double base = 100.0);

// tokens: (B, heads, N, head_dim).
at::Tensor applyRope(const at::Tensor& tokens, const RopeFactors& factors);

// The same rotation in place on float32 CPU token rows (B, N, heads * head_dim) with unit
// channel stride, e.g. the q or k column range of a qkv product: no head split, no copies. The
// arithmetic is applyRope's, element for element. Float32 factors only.
void applyRopeInPlace(const at::Tensor& token_rows, const RopeFactors& factors);

// Whether applyRopeInPlace serves these token rows.
bool ropeInPlaceApplies(const at::Tensor& token_rows, const RopeFactors& factors);

}  // namespace ffloc
