#pragma once

#include <array>
#include <cstddef>
#include <cstdint>

namespace ffloc {

// Where the network's time goes, per kind of operation: `ffloc bench model --profile`.
//
// The model code opens an OpScope around each piece of work. Scopes nest and time is exclusive:
// while an inner scope runs, the outer one does not count, so the kinds add up to the time
// spent inside scopes. Only the thread that runs the model opens scopes; the intra-op workers
// run inside them. Collection is off unless a profile is started, and then a scope costs one
// relaxed atomic load.
enum class OpKind {
  kGemm,         // Linear layers (matrix products with weights)
  kAttention,    // q k^T and the weighted sum of v, with what the attention does around them
  kSoftmax,      // the attention softmax
  kLayerNorm,
  kGelu,
  kRope,
  kLayout,       // copies and layout changes: head split/merge, contiguous(), casts
  kConvolution,  // the DPT heads' (and the patch embedding's) convolutions
  kElementwise,  // residual adds, ReLU, bilinear upsampling, post-processing
  kCount
};

const char* opKindName(OpKind kind);

struct OpTotals {
  double seconds = 0.0;
  double flops = 0.0;  // multiply-add = 2, as flop_count.h counts them
  int64_t calls = 0;
};
using OpProfile = std::array<OpTotals, static_cast<std::size_t>(OpKind::kCount)>;

// Clears the totals and starts collecting on every thread's scopes.
void startOpProfile();
// Stops collecting and returns the totals since startOpProfile().
OpProfile stopOpProfile();

class OpScope {
 public:
  explicit OpScope(OpKind kind, double flops = 0.0);
  ~OpScope();
  OpScope(const OpScope&) = delete;
  OpScope& operator=(const OpScope&) = delete;

 private:
  OpKind kind_;
  bool active_;
  OpScope* outer_ = nullptr;
  int64_t resumed_ns_ = 0;  // when this scope last became the innermost one
};

}  // namespace ffloc
