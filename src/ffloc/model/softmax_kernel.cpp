#include "ffloc/model/softmax_kernel.h"

#include <ATen/ops/_softmax.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

#include "ffloc/model/op_profile.h"
#include "ffloc/model/torch_threads.h"

#if defined(__x86_64__) && defined(__GNUC__)
// GCC 12 flags the intrinsics' own internal "undefined" vectors as maybe-uninitialised.
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#include <immintrin.h>
#define FFLOC_SOFTMAX_X86 1
#else
#define FFLOC_SOFTMAX_X86 0
#endif

namespace ffloc {

#if FFLOC_SOFTMAX_X86
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
  parallelFor(0, rows, grain, [&](int64_t begin, int64_t end) {
    std::vector<float> scratch(static_cast<size_t>(length));
    for (int64_t r = begin; r < end; ++r) softmaxRow(data + r * length, length, scratch.data());
  });
}

}  // namespace

namespace {

#define FFLOC_AVX2 __attribute__((target("avx2,fma")))

// The AVX-512 kernel's exp for CPUs with AVX2 only (AMD Zen 3): the same reduction and
// polynomial; 2^n is built in the exponent bits, exact for the n >= -126 the clamp allows.
FFLOC_AVX2 inline __m256 expNonPositive8(__m256 x) {
  x = _mm256_max_ps(x, _mm256_set1_ps(-87.0f));
  const __m256 n = _mm256_round_ps(_mm256_mul_ps(x, _mm256_set1_ps(1.44269504088896341f)),
                                   _MM_FROUND_TO_NEAREST_INT | _MM_FROUND_NO_EXC);
  __m256 r = _mm256_fnmadd_ps(n, _mm256_set1_ps(0.693359375f), x);
  r = _mm256_fnmadd_ps(n, _mm256_set1_ps(-2.12194440e-4f), r);
  __m256 p = _mm256_set1_ps(1.0f / 720.0f);
  p = _mm256_fmadd_ps(p, r, _mm256_set1_ps(1.0f / 120.0f));
  p = _mm256_fmadd_ps(p, r, _mm256_set1_ps(1.0f / 24.0f));
  p = _mm256_fmadd_ps(p, r, _mm256_set1_ps(1.0f / 6.0f));
  p = _mm256_fmadd_ps(p, r, _mm256_set1_ps(0.5f));
  p = _mm256_fmadd_ps(p, r, _mm256_set1_ps(1.0f));
  p = _mm256_fmadd_ps(p, r, _mm256_set1_ps(1.0f));
  const __m256i bits = _mm256_slli_epi32(_mm256_add_epi32(_mm256_cvtps_epi32(n), _mm256_set1_epi32(127)), 23);
  return _mm256_mul_ps(p, _mm256_castsi256_ps(bits));
}

FFLOC_AVX2 inline float horizontalMax(__m256 v) {
  __m128 m = _mm_max_ps(_mm256_castps256_ps128(v), _mm256_extractf128_ps(v, 1));
  m = _mm_max_ps(m, _mm_movehl_ps(m, m));
  m = _mm_max_ss(m, _mm_shuffle_ps(m, m, 1));
  return _mm_cvtss_f32(m);
}

FFLOC_AVX2 inline float horizontalSum(__m256 v) {
  __m128 s = _mm_add_ps(_mm256_castps256_ps128(v), _mm256_extractf128_ps(v, 1));
  s = _mm_add_ps(s, _mm_movehl_ps(s, s));
  s = _mm_add_ss(s, _mm_shuffle_ps(s, s, 1));
  return _mm_cvtss_f32(s);
}

// One float32 row in place: max, then exp(x - max) written back while summing, then the scale.
// The tail (length % 8) goes through a zero-padded 8-lane buffer so that every lane of every
// vector is a real score or excluded.
FFLOC_AVX2 void softmaxRowAvx2(float* row, int64_t length) {
  const int64_t body = length / 8 * 8;
  __m256 max = _mm256_set1_ps(-INFINITY);
  for (int64_t i = 0; i < body; i += 8) max = _mm256_max_ps(max, _mm256_loadu_ps(row + i));
  float row_max = horizontalMax(max);
  for (int64_t i = body; i < length; ++i) row_max = std::max(row_max, row[i]);
  const __m256 vmax = _mm256_set1_ps(row_max);
  __m256 sum = _mm256_setzero_ps();
  for (int64_t i = 0; i < body; i += 8) {
    const __m256 e = expNonPositive8(_mm256_sub_ps(_mm256_loadu_ps(row + i), vmax));
    sum = _mm256_add_ps(sum, e);
    _mm256_storeu_ps(row + i, e);
  }
  float total = horizontalSum(sum);
  if (body < length) {
    alignas(32) float tail[8];
    for (int64_t i = 0; i < 8; ++i) tail[i] = body + i < length ? row[body + i] - row_max : -INFINITY;
    _mm256_store_ps(tail, expNonPositive8(_mm256_load_ps(tail)));
    for (int64_t i = body; i < length; ++i) {
      row[i] = tail[i - body];
      total += row[i];
    }
  }
  const __m256 inverse = _mm256_set1_ps(1.0f / total);
  for (int64_t i = 0; i < body; i += 8) _mm256_storeu_ps(row + i, _mm256_mul_ps(_mm256_loadu_ps(row + i), inverse));
  for (int64_t i = body; i < length; ++i) row[i] *= 1.0f / total;
}

bool avx2Available() {
  static const bool available = __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma");
  return available;
}

}  // namespace
#endif

bool vectorizedSoftmaxAvailable() {
#if FFLOC_SOFTMAX_X86
  static const bool available = __builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512bw") &&
                                __builtin_cpu_supports("avx512vl");
  return available;
#else
  return false;
#endif
}

void softmaxRowsOnThisThread(float* data, int64_t rows, int64_t length) {
#if FFLOC_SOFTMAX_X86
  if (vectorizedSoftmaxAvailable()) {
    std::vector<float> scratch(static_cast<size_t>(length));
    for (int64_t r = 0; r < rows; ++r) softmaxRow(data + r * length, length, scratch.data());
    return;
  }
  if (avx2Available()) {
    for (int64_t r = 0; r < rows; ++r) softmaxRowAvx2(data + r * length, length);
    return;
  }
#endif
  for (int64_t r = 0; r < rows; ++r) {
    float* row = data + r * length;
    const float row_max = *std::max_element(row, row + length);
    float total = 0.0f;
    for (int64_t i = 0; i < length; ++i) total += row[i] = std::exp(row[i] - row_max);
    for (int64_t i = 0; i < length; ++i) row[i] /= total;
  }
}

void softmaxLastDimInPlace(at::Tensor& scores) {
  const OpScope scope(OpKind::kSoftmax);
#if FFLOC_SOFTMAX_X86
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
  if (avx2Available() && scores.is_cpu() && scores.is_contiguous() && scores.scalar_type() == at::kFloat &&
      scores.dim() > 0 && scores.numel() > 0 && !scores.requires_grad()) {
    const int64_t length = scores.size(-1);
    float* data = scores.data_ptr<float>();
    parallelFor(0, scores.numel() / length, std::max<int64_t>(1, 65536 / length), [&](int64_t begin, int64_t end) {
      softmaxRowsOnThisThread(data + begin * length, end - begin, length);
    });
    return;
  }
#endif
  at::_softmax_out(scores, scores, -1, /*half_to_float=*/false);
}

}  // namespace ffloc
