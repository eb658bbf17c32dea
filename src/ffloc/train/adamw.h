#pragma once

#include <ATen/core/Tensor.h>

#include <cstdint>
#include <string>
#include <utility>
#include <vector>

namespace ffloc {

struct AdamWOptions {
  double beta1 = 0.9;
  double beta2 = 0.95;
  double epsilon = 1e-8;
  double weight_decay = 0.05;
};

// AdamW (Loshchilov & Hutter) with torch.optim.AdamW's update order (decoupled decay first,
// bias-corrected moments, epsilon added after the square root). As in DUSt3R's training (timm's
// param_groups_weight_decay), biases and norm weights (tensors of fewer than 2 dimensions) get
// no weight decay. Written out rather than taken
// from torch::optim so that its whole state is two named tensors per parameter plus a step
// count: checkpoints store it in safetensors and resume bit-exactly on any libtorch version.
class AdamW {
 public:
  AdamW(std::vector<std::pair<std::string, at::Tensor>> parameters, const AdamWOptions& options);

  // One update with learning rate `lr` from the parameters' current gradients (parameters
  // without a gradient are left alone); then clears the gradients.
  void step(double lr);
  void zeroGrad();

  int64_t stepCount() const { return step_count_; }
  const std::vector<std::pair<std::string, at::Tensor>>& parameters() const { return parameters_; }

  // "exp_avg.<name>" and "exp_avg_sq.<name>" for every parameter.
  std::vector<std::pair<std::string, at::Tensor>> state() const;
  // Restores state() and the step count; InputError naming `origin` and the tensor for a
  // missing tensor or a shape mismatch.
  void loadState(const std::vector<std::pair<std::string, at::Tensor>>& state, int64_t step_count,
                 const std::string& origin);

 private:
  std::vector<std::pair<std::string, at::Tensor>> parameters_;
  std::vector<at::Tensor> exp_avg_, exp_avg_sq_;
  AdamWOptions options_;
  int64_t step_count_ = 0;
};

// Scales all gradients so their joint L2 norm is at most max_norm (torch's clip_grad_norm_ with
// its 1e-6 guard) and returns the norm before clipping; max_norm 0 only measures.
double clipGradientNorm(const std::vector<std::pair<std::string, at::Tensor>>& parameters, double max_norm);

// Linear warm-up from lr/warmup to the peak over `warmup` steps, then a half cosine down to
// min_lr at `total` steps. `step` is 0-based.
double cosineLearningRate(int64_t step, int64_t total, int64_t warmup, double peak, double min_lr);

}  // namespace ffloc
