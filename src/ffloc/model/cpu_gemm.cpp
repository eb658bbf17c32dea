#include "ffloc/model/cpu_gemm.h"

#include <ATen/Parallel.h>
#include <ATen/core/grad_mode.h>
#include <ATen/ops/empty.h>
#include <cblas.h>

#include <algorithm>
#include <cstring>
#include <mutex>
#include <vector>

#include "ffloc/core/threads.h"
#include "ffloc/model/torch_threads.h"

namespace ffloc {
namespace {

std::mutex g_blas_mutex;
int g_blas_holders = 0;
int g_blas_saved_threads = 0;

// Columns per piece are a multiple of this: whole register tiles of OpenBLAS's AVX2 kernel.
constexpr int64_t kColumnAlign = 16;

}  // namespace

// Under another BLAS blasThreadCount() is 0 and its threads are left alone.
SingleThreadedBlas::SingleThreadedBlas() {
  std::lock_guard<std::mutex> lock(g_blas_mutex);
  if (g_blas_holders++ == 0) {
    g_blas_saved_threads = blasThreadCount();
    if (g_blas_saved_threads > 1) setBlasThreadCount(1);
  }
}

SingleThreadedBlas::~SingleThreadedBlas() {
  std::lock_guard<std::mutex> lock(g_blas_mutex);
  if (--g_blas_holders == 0 && g_blas_saved_threads > 1) setBlasThreadCount(g_blas_saved_threads);
}

bool cpuGemmApplies(const at::Tensor& x, const at::Tensor& weight) {
  const bool needs_grad = at::GradMode::is_enabled() && (x.requires_grad() || weight.requires_grad());
  return !needs_grad && x.is_cpu() && weight.is_cpu() && x.scalar_type() == at::kFloat &&
         weight.scalar_type() == at::kFloat && weight.dim() == 2 && weight.is_contiguous();
}

void sgemmOnThisThread(bool b_transposed, int64_t m, int64_t n, int64_t k, float alpha, const float* a,
                       int64_t lda, const float* b, int64_t ldb, float beta, float* c, int64_t ldc) {
  cblas_sgemm(CblasRowMajor, CblasNoTrans, b_transposed ? CblasTrans : CblasNoTrans, static_cast<int>(m),
              static_cast<int>(n), static_cast<int>(k), alpha, a, static_cast<int>(lda), b, static_cast<int>(ldb),
              beta, c, static_cast<int>(ldc));
}

at::Tensor cpuLinear(const at::Tensor& x, const at::Tensor& weight, const at::Tensor& bias,
                     const at::Tensor& residual) {
  const at::Tensor input = x.contiguous();
  const int64_t in = weight.size(1), out = weight.size(0);
  const int64_t rows = input.numel() / in;
  std::vector<int64_t> shape = x.sizes().vec();
  shape.back() = out;
  at::Tensor y = at::empty(shape, x.options().memory_format(at::MemoryFormat::Contiguous));
  const at::Tensor res = residual.defined() ? residual.contiguous() : residual;
  const float* a = input.data_ptr<float>();
  const float* w = weight.data_ptr<float>();
  const float* b = bias.defined() ? bias.data_ptr<float>() : nullptr;
  const float* r = res.defined() ? res.data_ptr<float>() : nullptr;
  float* c = y.data_ptr<float>();
  const bool accumulate = b || r;

  // One piece per thread. Splitting the output columns gives each thread its own share of the
  // weights, which are the larger operand for the network's token counts; splitting rows makes
  // every thread read all of them, so rows are split only when there are more rows than columns.
  const int64_t threads = std::max<int64_t>(1, at::get_num_threads());
  const bool split_columns = out >= rows;
  const int64_t extent = split_columns ? out : rows;
  int64_t step = (extent + threads - 1) / threads;
  if (split_columns) step = (step + kColumnAlign - 1) / kColumnAlign * kColumnAlign;
  const int64_t pieces = std::max<int64_t>(1, (extent + step - 1) / step);

  const SingleThreadedBlas single_threaded;
  parallelFor(0, pieces, 1, [&](int64_t first, int64_t last) {
    for (int64_t piece = first; piece < last; ++piece) {
      const int64_t begin = piece * step, end = std::min(extent, begin + step);
      const int64_t row0 = split_columns ? 0 : begin, row1 = split_columns ? rows : end;
      const int64_t col0 = split_columns ? begin : 0, col1 = split_columns ? end : out;
      // The bias and the residual go into the output first; the product then adds to them
      // (beta = 1), which saves a pass over the output for each.
      if (accumulate) {
        for (int64_t i = row0; i < row1; ++i) {
          float* dst = c + i * out;
          const float* src = r ? r + i * out : nullptr;
          for (int64_t j = col0; j < col1; ++j) dst[j] = (src ? src[j] : 0.0f) + (b ? b[j] : 0.0f);
        }
      }
      sgemmOnThisThread(true, row1 - row0, col1 - col0, in, 1.0f, a + row0 * in, in, w + col0 * in, in,
                        accumulate ? 1.0f : 0.0f, c + row0 * out + col0, out);
    }
  });
  return y;
}

}  // namespace ffloc
