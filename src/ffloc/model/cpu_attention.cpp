#include "ffloc/model/cpu_attention.h"

#include <ATen/core/grad_mode.h>
#include <ATen/ops/empty.h>

#include <algorithm>
#include <cmath>
#include <vector>

#include "ffloc/model/cpu_gemm.h"
#include "ffloc/model/softmax_kernel.h"
#include "ffloc/model/torch_threads.h"

namespace ffloc {
namespace {

// Scores of one task: up to 128 K floats (512 KB, a Zen 3 core's L2) and 32 to 256 query rows.
// Measured on the 2-core Zen 3 machine with 768 and 1500 keys, head_dim 64: blocks of 128-256
// rows ran the two products 10-30 % faster than blocks of 16-64 (q k^T has only head_dim = 64
// to accumulate over, so short blocks spend their time packing k).
constexpr int64_t kScoreBudget = 131072;
constexpr int64_t kMinQueryBlock = 32, kMaxQueryBlock = 256;

bool tokenRows(const at::Tensor& t) { return t.dim() == 3 && t.stride(2) == 1 && t.stride(0) == t.size(1) * t.stride(1); }

}  // namespace

bool cpuAttentionApplies(const at::Tensor& q, const at::Tensor& k, const at::Tensor& v) {
  for (const at::Tensor* t : {&q, &k, &v}) {
    if (!t->is_cpu() || t->scalar_type() != at::kFloat || !tokenRows(*t)) return false;
    if (at::GradMode::is_enabled() && t->requires_grad()) return false;
  }
  return q.size(0) == k.size(0) && k.sizes() == v.sizes() && q.size(2) == k.size(2);
}

at::Tensor cpuAttention(const at::Tensor& q, const at::Tensor& k, const at::Tensor& v, int64_t num_heads) {
  const int64_t batch = q.size(0), queries = q.size(1), keys = k.size(1), width = q.size(2);
  const int64_t head_dim = width / num_heads;
  const float scale = static_cast<float>(std::pow(static_cast<double>(head_dim), -0.5));
  at::Tensor out = at::empty({batch, queries, width}, q.options().memory_format(at::MemoryFormat::Contiguous));
  const int64_t block = std::clamp(kScoreBudget / std::max<int64_t>(keys, 1), kMinQueryBlock, kMaxQueryBlock);
  const int64_t blocks = (queries + block - 1) / block;
  const float* q_data = q.data_ptr<float>();
  const float* k_data = k.data_ptr<float>();
  const float* v_data = v.data_ptr<float>();
  float* o_data = out.data_ptr<float>();
  const int64_t q_stride = q.stride(1), k_stride = k.stride(1), v_stride = v.stride(1);

  const SingleThreadedBlas single_threaded;
  parallelFor(0, batch * num_heads * blocks, 1, [&](int64_t first, int64_t last) {
    std::vector<float> scores(static_cast<size_t>(std::min(block, queries) * keys));
    for (int64_t task = first; task < last; ++task) {
      const int64_t b = task / (num_heads * blocks);
      const int64_t h = task / blocks % num_heads;
      const int64_t row0 = task % blocks * block;
      const int64_t rows = std::min(block, queries - row0);
      const float* q_block = q_data + (b * queries + row0) * q_stride + h * head_dim;
      const float* k_head = k_data + b * keys * k_stride + h * head_dim;
      const float* v_head = v_data + b * keys * v_stride + h * head_dim;
      sgemmOnThisThread(true, rows, keys, head_dim, scale, q_block, q_stride, k_head, k_stride, 0.0f, scores.data(),
                        keys);
      softmaxRowsOnThisThread(scores.data(), rows, keys);
      sgemmOnThisThread(false, rows, head_dim, keys, 1.0f, scores.data(), keys, v_head, v_stride, 0.0f,
                        o_data + (b * queries + row0) * width + h * head_dim, width);
    }
  });
  return out;
}

}  // namespace ffloc
