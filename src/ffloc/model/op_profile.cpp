#include "ffloc/model/op_profile.h"

#include <atomic>
#include <chrono>
#include <mutex>

namespace ffloc {
namespace {

std::atomic<bool> g_enabled{false};
std::mutex g_mutex;
OpProfile g_totals;
thread_local OpScope* t_innermost = nullptr;

int64_t nowNs() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

}  // namespace

const char* opKindName(OpKind kind) {
  switch (kind) {
    case OpKind::kGemm: return "GEMM (Linear)";
    case OpKind::kAttention: return "attention products";
    case OpKind::kSoftmax: return "softmax";
    case OpKind::kLayerNorm: return "layer norm";
    case OpKind::kGelu: return "GELU";
    case OpKind::kRope: return "RoPE";
    case OpKind::kLayout: return "copies / layout";
    case OpKind::kConvolution: return "convolutions";
    case OpKind::kElementwise: return "other element-wise";
    case OpKind::kCount: break;
  }
  return "?";
}

void startOpProfile() {
  std::lock_guard<std::mutex> lock(g_mutex);
  g_totals = OpProfile{};
  g_enabled.store(true, std::memory_order_relaxed);
}

OpProfile stopOpProfile() {
  std::lock_guard<std::mutex> lock(g_mutex);
  g_enabled.store(false, std::memory_order_relaxed);
  return g_totals;
}

OpScope::OpScope(OpKind kind, double flops) : kind_(kind), active_(g_enabled.load(std::memory_order_relaxed)) {
  if (!active_) return;
  const int64_t now = nowNs();
  outer_ = t_innermost;
  {
    std::lock_guard<std::mutex> lock(g_mutex);
    OpTotals& totals = g_totals[static_cast<size_t>(kind)];
    totals.flops += flops;
    ++totals.calls;
    if (outer_) g_totals[static_cast<size_t>(outer_->kind_)].seconds += 1e-9 * static_cast<double>(now - outer_->resumed_ns_);
  }
  t_innermost = this;
  resumed_ns_ = now;
}

OpScope::~OpScope() {
  if (!active_) return;
  const int64_t now = nowNs();
  {
    std::lock_guard<std::mutex> lock(g_mutex);
    g_totals[static_cast<size_t>(kind_)].seconds += 1e-9 * static_cast<double>(now - resumed_ns_);
  }
  t_innermost = outer_;
  if (outer_) outer_->resumed_ns_ = now;
}

}  // namespace ffloc
