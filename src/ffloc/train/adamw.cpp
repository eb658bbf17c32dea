#include "ffloc/train/adamw.h"

#include <ATen/TensorOperators.h>
#include <ATen/ops/zeros_like.h>
#include <c10/core/GradMode.h>

#include <cmath>
#include <map>

#include "ffloc/core/error.h"
#include "ffloc/model/parameter_table.h"

namespace ffloc {

AdamW::AdamW(std::vector<std::pair<std::string, at::Tensor>> parameters, const AdamWOptions& options)
    : parameters_(std::move(parameters)), options_(options) {
  for (const auto& entry : parameters_) {
    exp_avg_.push_back(at::zeros_like(entry.second, at::MemoryFormat::Contiguous));
    exp_avg_sq_.push_back(at::zeros_like(entry.second, at::MemoryFormat::Contiguous));
  }
}

void AdamW::zeroGrad() {
  for (auto& entry : parameters_) {
    if (entry.second.mutable_grad().defined()) entry.second.mutable_grad().zero_();
  }
}

void AdamW::step(double lr) {
  at::NoGradGuard no_grad;
  ++step_count_;
  const double correction1 = 1 - std::pow(options_.beta1, static_cast<double>(step_count_));
  const double correction2 = 1 - std::pow(options_.beta2, static_cast<double>(step_count_));
  for (size_t i = 0; i < parameters_.size(); ++i) {
    at::Tensor& p = parameters_[i].second;
    const at::Tensor& g = p.grad();
    if (!g.defined()) continue;
    if (p.dim() >= 2) p.mul_(1 - lr * options_.weight_decay);
    exp_avg_[i].mul_(options_.beta1).add_(g, 1 - options_.beta1);
    exp_avg_sq_[i].mul_(options_.beta2).addcmul_(g, g, 1 - options_.beta2);
    const at::Tensor denom = (exp_avg_sq_[i].sqrt() / std::sqrt(correction2)).add_(options_.epsilon);
    p.addcdiv_(exp_avg_[i], denom, -lr / correction1);
  }
  zeroGrad();
}

std::vector<std::pair<std::string, at::Tensor>> AdamW::state() const {
  std::vector<std::pair<std::string, at::Tensor>> out;
  for (size_t i = 0; i < parameters_.size(); ++i) {
    out.emplace_back("exp_avg." + parameters_[i].first, exp_avg_[i]);
    out.emplace_back("exp_avg_sq." + parameters_[i].first, exp_avg_sq_[i]);
  }
  return out;
}

void AdamW::loadState(const std::vector<std::pair<std::string, at::Tensor>>& state, int64_t step_count,
                      const std::string& origin) {
  std::map<std::string, at::Tensor> by_name(state.begin(), state.end());
  const auto fetch = [&](const std::string& name, const at::Tensor& like) {
    const auto found = by_name.find(name);
    if (found == by_name.end()) throwInputError(origin, 0, "tensor '" + name + "': missing");
    if (found->second.sizes() != like.sizes()) {
      throwInputError(origin, 0, "tensor '" + name + "': shape " + shapeString(found->second.sizes()) +
                                     ", expected " + shapeString(like.sizes()));
    }
    return found->second.to(like.device(), like.scalar_type()).contiguous();
  };
  for (size_t i = 0; i < parameters_.size(); ++i) {
    exp_avg_[i] = fetch("exp_avg." + parameters_[i].first, exp_avg_[i]);
    exp_avg_sq_[i] = fetch("exp_avg_sq." + parameters_[i].first, exp_avg_sq_[i]);
  }
  step_count_ = step_count;
}

double clipGradientNorm(const std::vector<std::pair<std::string, at::Tensor>>& parameters, double max_norm) {
  at::NoGradGuard no_grad;
  double sum_sq = 0;
  for (const auto& entry : parameters) {
    const at::Tensor& g = entry.second.grad();
    if (g.defined()) sum_sq += g.to(at::kDouble).pow(2).sum().item<double>();
  }
  const double norm = std::sqrt(sum_sq);
  if (max_norm > 0) {
    const double factor = max_norm / (norm + 1e-6);
    if (factor < 1) {
      for (const auto& entry : parameters) {
        at::Tensor g = entry.second.grad();
        if (g.defined()) g.mul_(factor);
      }
    }
  }
  return norm;
}

double cosineLearningRate(int64_t step, int64_t total, int64_t warmup, double peak, double min_lr) {
  if (step < warmup) return peak * static_cast<double>(step + 1) / static_cast<double>(warmup);
  const int64_t decay = std::max<int64_t>(total - warmup, 1);
  const double progress = std::min(1.0, static_cast<double>(step - warmup) / static_cast<double>(decay));
  return min_lr + 0.5 * (peak - min_lr) * (1 + std::cos(M_PI * progress));
}

}  // namespace ffloc
