#include "ffloc/train/matching_loss.h"

#include <ATen/TensorOperators.h>
#include <ATen/ops/argmax.h>
#include <ATen/ops/cdist.h>
#include <ATen/ops/full_like.h>
#include <ATen/ops/log_softmax.h>
#include <ATen/ops/nll_loss.h>
#include <ATen/ops/where.h>
#include <ATen/ops/zeros.h>

#include <limits>
#include <stdexcept>

namespace ffloc {

PatchGroundTruth patchCentreGroundTruth(const at::Tensor& pixel_points, const at::Tensor& pixel_valid, int64_t patch_size) {
  if (pixel_points.dim() != 4 || pixel_points.size(3) != 3 || pixel_valid.dim() != 3 || patch_size < 2 ||
      pixel_points.size(1) % patch_size != 0 || pixel_points.size(2) % patch_size != 0) {
    throw std::invalid_argument("patchCentreGroundTruth: expected (B, H, W, 3) points on a whole patch grid");
  }
  const int64_t batch = pixel_points.size(0), rows = pixel_points.size(1) / patch_size,
                cols = pixel_points.size(2) / patch_size, first = patch_size / 2 - 1;
  const at::Tensor points = pixel_points.reshape({batch, rows, patch_size, cols, patch_size, 3})
                                .narrow(2, first, 2)
                                .narrow(4, first, 2);
  const at::Tensor valid = pixel_valid.reshape({batch, rows, patch_size, cols, patch_size})
                               .narrow(2, first, 2)
                               .narrow(4, first, 2);
  PatchGroundTruth out;
  out.points = points.mean({2, 4});
  out.valid = valid.all(4).all(2);
  return out;
}

at::Tensor matchingTargets(const at::Tensor& patch_points, const at::Tensor& patch_valid, const at::Tensor& map_points,
                           const at::Tensor& map_valid, const at::Tensor& radius) {
  const int64_t tokens = map_points.size(0);
  const at::Tensor distances = at::cdist(patch_points.to(at::kFloat).unsqueeze(0), map_points.to(at::kFloat).unsqueeze(0)).squeeze(0);
  const at::Tensor usable = at::where(map_valid.unsqueeze(0), distances,
                                      at::full_like(distances, std::numeric_limits<float>::infinity()));
  const auto [nearest, index] = usable.min(1);
  at::Tensor targets = at::where(nearest <= radius.to(at::kFloat), index, at::full_like(index, tokens));
  return at::where(patch_valid, targets, at::full_like(targets, -1));
}

MatchingLossTerm matchingLoss(const at::Tensor& logits, const at::Tensor& targets) {
  MatchingLossTerm out;
  const at::Tensor labelled = targets >= 0;
  out.patches = labelled.sum().item<int64_t>();
  if (out.patches == 0) {
    out.loss = (logits * 0).sum();
    return out;
  }
  out.loss = at::nll_loss(at::log_softmax(logits.to(at::kFloat), -1), targets.to(logits.device()), {},
                          at::Reduction::Mean, -1);
  const at::Tensor correct = (at::argmax(logits, -1) == targets) & labelled;
  out.accuracy = correct.sum().item<double>() / static_cast<double>(out.patches);
  return out;
}

}  // namespace ffloc
