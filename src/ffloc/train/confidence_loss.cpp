#include "ffloc/train/confidence_loss.h"

#include <ATen/TensorOperators.h>
#include <ATen/ops/linalg_vector_norm.h>
#include <ATen/ops/zeros.h>

#include <stdexcept>
#include <vector>

namespace ffloc {

ConfidenceLossTerm confidenceLoss(const at::Tensor& points, const at::Tensor& confidence, const at::Tensor& truth,
                                  const at::Tensor& valid, double alpha) {
  if (points.sizes() != truth.sizes() || points.size(-1) != 3 ||
      confidence.sizes() != points.sizes().slice(0, points.dim() - 1) || valid.sizes() != confidence.sizes()) {
    throw std::invalid_argument("confidenceLoss: points/truth (..., 3) and confidence/valid (...) must agree");
  }
  ConfidenceLossTerm term;
  const at::Tensor mask = valid.to(points.device(), at::kBool);
  term.valid = mask.sum().item<int64_t>();
  if (term.valid == 0) {
    term.loss = (points.sum() * 0.0);  // keeps the graph connected, contributes nothing
    term.error = at::zeros({}, points.options().requires_grad(false));
    return term;
  }
  const std::vector<int64_t> last = {-1};
  const at::Tensor distance =
      at::linalg_vector_norm(points - truth.to(points.device(), points.scalar_type()), 2, at::IntArrayRef(last));
  const at::Tensor d = distance.masked_select(mask);
  const at::Tensor c = confidence.masked_select(mask);
  term.loss = (c * d - alpha * c.log()).mean();
  term.error = d.mean().detach();
  return term;
}

}  // namespace ffloc
