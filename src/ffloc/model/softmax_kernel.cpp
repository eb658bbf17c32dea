#include "ffloc/model/softmax_kernel.h"

#include <ATen/Parallel.h>
#include <ATen/ops/_softmax.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

#include "ffloc/model/op_profile.h"

#if defined(__x86_64__) && defined(__GNUC__)
// GCC 12 flags the intrinsics' own internal "undefined" vectors as maybe-uninitialised.
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#include <immintrin.h>
#define FFLOC_SOFTMAX_AVX512 1
#else
#define FFLOC_SOFTMAX_AVX512 0
#endif

namespace ffloc {

#if FFLOC_SOFTMAX_AVX512
namespace {

#define FFLOC_AVX512 __attribute__((target("avx512f,avx512bw,avx512vl")))

// exp(x) for x <= 0: x = n ln2 + r with |r| <= ln2 / 2, exp(r) by its degree-6 Taylor polynomial
// (relative error < 3e-7 on that interval), times 2^n by scalef. Below -87 the result is 0 or a
// denormal, where the clamp keeps it finite; softmax never needs those digits.
FFLOC_AVX512 inline __m512 expNonPositive(__m512 x) {
  x = _mm512_max_ps(x, _mm512_set1_ps(-87.0f));
  const __m512 n = _mm512_roundscale_ps(_mm512_mul_ps(x, _mm512_set1_ps(1.44269504088896341f)),
                                        _MM_FROUND_TO_NEAREST_INT | _MM_FROUND_NO_EXC);
  __m512 r = _mm512_fnmadd_ps(n, _mm512_set1_ps(0.693359375f), x);
  r = _mm512_fnmadd_ps(n, _mm512_set1_ps(-2.12194440e-4f), r);
  __m512 p = _mm512_set1_ps(1.0f / 720.0f);
  p = _mm512_fmadd_ps(p, r, _mm512_set1_ps(1.0f / 120.0f));
  p = _mm512_fmadd_ps(p, r, _mm512_set1_ps(1.0f / 24.0f));
  p = _mm512_fmadd_ps(p, r, _mm512_set1_ps(1.0f / 6.0f));
  p = _mm512_fmadd_ps(p, r, _mm512_set1_ps(0.5f));
  p = _mm512_fmadd_ps(p, r, _mm512_set1_ps(1.0f));
  p = _mm512_fmadd_ps(p, r, _mm512_set1_ps(1.0f));
  return _mm512_scalef_ps(p, n);
}

FFLOC_AVX512 inline __m512 load(const float* data, __mmask16 mask) { return _mm512_maskz_loadu_ps(mask, data); }

FFLOC_AVX512 inline __m512 load(const c10::BFloat16* data, __mmask16 mask) {
  const __m256i bits = _mm256_maskz_loadu_epi16(mask, data);
  return _mm512_castsi512_ps(_mm512_slli_epi32(_mm512_cvtepu16_epi32(bits), 16));
}

FFLOC_AVX512 inline void store(float* data, __m512 value, __mmask16 mask) { _mm512_mask_storeu_ps(data, mask, value); }

// Round to nearest even, as ATen's float -> bfloat16 conversion (inputs here are finite).
FFLOC_AVX512 inline void store(c10::BFloat16* data, __m512 value, __mmask16 mask) {
  const __m512i bits = _mm512_castps_si512(value);
  const __m512i lsb = _mm512_and_si512(_mm512_srli_epi32(bits, 16), _mm512_set1_epi32(1));
  const __m512i rounded = _mm512_add_epi32(bits, _mm512_add_epi32(lsb, _mm512_set1_epi32(0x7fff)));
  _mm256_mask_storeu_epi16(data, mask, _mm512_cvtepi32_epi16(_mm512_srli_epi32(rounded, 16)));
}

FFLOC_AVX512 inline __mmask16 tailMask(int64_t remaining) {
  return remaining >= 16 ? static_cast<__mmask16>(0xffff) : static_cast<__mmask16>((1u << remaining) - 1u);
}

// One row: exp(x - max) into `scratch` while summing, then scaled by 1 / sum into the row.
template <typename T>
FFLOC_AVX512 void softmaxRow(T* row, int64_t length, float* scratch) {
  __m512 max = _mm512_set1_ps(-INFINITY);
  for (int64_t i = 0; i < length; i += 16) {
    const __mmask16 mask = tailMask(length - i);
    max = _mm512_mask_max_ps(max, mask, max, load(row + i, mask));
  }
  const __m512 row_max = _mm512_set1_ps(_mm512_reduce_max_ps(max));
  __m512 sum = _mm512_setzero_ps();
  for (int64_t i = 0; i < length; i += 16) {
    const __mmask16 mask = tailMask(length - i);
    const __m512 e = expNonPositive(_mm512_sub_ps(load(row + i, mask), row_max));
    sum = _mm512_mask_add_ps(sum, mask, sum, e);
    _mm512_mask_storeu_ps(scratch + i, mask, e);
  }
  const __m512 inverse = _mm512_set1_ps(1.0f / _mm512_reduce_add_ps(sum));
  for (int64_t i = 0; i < length; i += 16) {
    const __mmask16 mask = tailMask(length - i);
    store(row + i, _mm512_mul_ps(_mm512_maskz_loadu_ps(mask, scratch + i), inverse), mask);
  }
}

template <typename T>
void softmaxRows(T* data, int64_t rows, int64_t length) {
  // ~64k scores per task: large enough to amortise the thread hand-off.
  const int64_t grain = std::max<int64_t>(1, 65536 / std::max<int64_t>(length, 1));
  at::parallel_for(0, rows, grain, [&](int64_t begin, int64_t end) {
    std::vector<float> scratch(static_cast<size_t>(length));
    for (int64_t r = begin; r < end; ++r) softmaxRow(data + r * length, length, scratch.data());
  });
}

}  // namespace
#endif

bool vectorizedSoftmaxAvailable() {
#if FFLOC_SOFTMAX_AVX512
  static const bool available = __builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512bw") &&
                                __builtin_cpu_supports("avx512vl");
  return available;
#else
  return false;
#endif
}

void softmaxLastDimInPlace(at::Tensor& scores) {
  const OpScope scope(OpKind::kSoftmax);
#if FFLOC_SOFTMAX_AVX512
  const bool supported_dtype = scores.scalar_type() == at::kFloat || scores.scalar_type() == at::kBFloat16;
  if (vectorizedSoftmaxAvailable() && scores.is_cpu() && scores.is_contiguous() && supported_dtype &&
      scores.dim() > 0 && scores.numel() > 0 && !scores.requires_grad()) {
    const int64_t length = scores.size(-1);
    const int64_t rows = scores.numel() / length;
    if (scores.scalar_type() == at::kFloat) {
      softmaxRows(scores.data_ptr<float>(), rows, length);
    } else {
      softmaxRows(scores.data_ptr<c10::BFloat16>(), rows, length);
    }
    return;
  }
#endif
  at::_softmax_out(scores, scores, -1, /*half_to_float=*/false);
}

}  // namespace ffloc
