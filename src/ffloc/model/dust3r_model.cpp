#include "ffloc/model/dust3r_model.h"

#include <ATen/TensorOperators.h>
#include <ATen/ops/arange.h>
#include <ATen/ops/cat.h>
#include <ATen/ops/exp.h>
#include <ATen/ops/expm1.h>
#include <ATen/ops/linalg_vector_norm.h>
#include <ATen/ops/stack.h>

#include <algorithm>

#include "ffloc/core/error.h"
#include "ffloc/model/op_profile.h"
#include "ffloc/model/rope2d.h"

namespace ffloc {

namespace {

void record(TensorTrace* trace, const std::string& name, const at::Tensor& value) {
  if (trace) (*trace)[name] = value;
}

void checkImages(const at::Tensor& images, int64_t patch, const std::string& what) {
  if (!images.defined() || images.dim() != 4 || images.size(1) != 3) {
    throwInputError(what, 0, "expected a (B, 3, H, W) image tensor");
  }
  if (images.size(2) % patch != 0 || images.size(3) % patch != 0 || images.size(2) == 0 ||
      images.size(3) == 0) {
    throwInputError(what, 0, "image size " + std::to_string(images.size(3)) + "x" +
                                 std::to_string(images.size(2)) + " (WxH) is not a positive multiple of " +
                                 std::to_string(patch));
  }
}

}  // namespace

Dust3rPointMap pointMapFromRaw(const at::Tensor& raw) { return pointsFromRaw(raw.permute({0, 2, 3, 1})); }

Dust3rPointMap pointsFromRaw(const at::Tensor& raw) {
  const OpScope scope(OpKind::kElementwise);
  // float32 whatever produced `raw` (under mixed precision a bf16 layer may have): exp would
  // otherwise carry bf16's 8-bit mantissa into depth and confidence.
  const at::Tensor fmap = raw.to(at::kFloat);
  const at::Tensor xyz = fmap.narrow(-1, 0, 3);
  const std::vector<int64_t> last = {-1};
  const at::Tensor d = at::linalg_vector_norm(xyz, 2, at::IntArrayRef(last), /*keepdim=*/true);
  Dust3rPointMap out;
  out.pts3d = xyz / d.clamp_min(1e-8) * at::expm1(d);
  out.conf = at::exp(fmap.select(-1, 3)) + 1;
  return out;
}

at::Tensor patchPositions(int64_t batch, int64_t rows, int64_t cols, at::Device device) {
  const at::TensorOptions options = at::TensorOptions().dtype(at::kLong).device(device);
  const at::Tensor y = at::arange(rows, options).view({rows, 1}).expand({rows, cols});
  const at::Tensor x = at::arange(cols, options).view({1, cols}).expand({rows, cols});
  return at::stack({y, x}, -1).reshape({1, rows * cols, 2}).expand({batch, rows * cols, 2}).contiguous();
}

Dust3rModel::Dust3rModel(const Dust3rConfig& config) : config_(config) {
  config_.validate();
  const Dust3rConfig& c = config_;
  const double eps = c.layer_norm_eps;
  patch_embed_ = nn::Conv2d(3, c.enc_dim, c.patch_size, c.patch_size, 0);
  for (int64_t i = 0; i < c.enc_depth; ++i) enc_blocks_.emplace_back(c.enc_dim, c.enc_heads, c.mlp_ratio, eps);
  enc_norm_ = nn::LayerNorm(c.enc_dim, eps);
  decoder_embed_ = nn::Linear(c.enc_dim, c.dec_dim);
  for (int64_t i = 0; i < c.dec_depth; ++i) {
    dec_blocks_.emplace_back(c.dec_dim, c.dec_heads, c.mlp_ratio, eps);
    dec_blocks2_.emplace_back(c.dec_dim, c.dec_heads, c.mlp_ratio, eps);
  }
  dec_norm_ = nn::LayerNorm(c.dec_dim, eps);
  const std::array<int64_t, 4> dim_tokens = {c.enc_dim, c.dec_dim, c.dec_dim, c.dec_dim};
  heads_[0] = DptHead(c.head, dim_tokens);
  heads_[1] = DptHead(c.head, dim_tokens);
}

void Dust3rModel::registerBackbone(ParameterTable& table, bool with_encoder) {
  if (with_encoder) {
    table.add("mask_token", {1, 1, config_.dec_dim}, &mask_token_);
    patch_embed_.registerIn(table, "patch_embed.proj");
    for (size_t i = 0; i < enc_blocks_.size(); ++i) enc_blocks_[i].registerIn(table, "enc_blocks." + std::to_string(i));
    enc_norm_.registerIn(table, "enc_norm");
  }
  decoder_embed_.registerIn(table, "decoder_embed");
  for (size_t i = 0; i < dec_blocks_.size(); ++i) dec_blocks_[i].registerIn(table, "dec_blocks." + std::to_string(i));
  dec_norm_.registerIn(table, "dec_norm");
  for (size_t i = 0; i < dec_blocks2_.size(); ++i) dec_blocks2_[i].registerIn(table, "dec_blocks2." + std::to_string(i));
}

void Dust3rModel::registerHeads(ParameterTable& table, Dust3rHeads heads) {
  if (heads == Dust3rHeads::kNone) return;
  heads_[0].registerIn(table, "downstream_head1.dpt");
  if (heads == Dust3rHeads::kBoth) heads_[1].registerIn(table, "downstream_head2.dpt");
}

ParameterTable Dust3rModel::parameterTable(Dust3rHeads heads, bool with_encoder) {
  ParameterTable table;
  registerBackbone(table, with_encoder);
  registerHeads(table, heads);
  return table;
}

void Dust3rModel::loadWeights(const TensorArchive& archive) {
  loadParameters(parameterTable(), archive);
  to(device_, backbone_dtype_, head_dtype_);
}

void Dust3rModel::to(at::Device device, at::ScalarType backbone_dtype, at::ScalarType head_dtype) {
  for (const at::ScalarType dtype : {backbone_dtype, head_dtype}) {
    if (dtype != at::kFloat && dtype != at::kBFloat16) {
      throw std::invalid_argument("Dust3rModel::to: dtypes must be float32 or bfloat16");
    }
  }
  ParameterTable backbone, heads;
  registerBackbone(backbone, true);
  registerHeads(heads, Dust3rHeads::kBoth);
  for (const auto& entry : backbone.entries()) {
    if (entry.tensor->defined()) *entry.tensor = entry.tensor->to(device, backbone_dtype);
  }
  for (const auto& entry : heads.entries()) {
    if (!entry.tensor->defined()) continue;
    const bool output_projection = entry.name.find(".head.4.") != std::string::npos;
    *entry.tensor = entry.tensor->to(device, output_projection ? at::kFloat : head_dtype);
  }
  backbone_dtype_ = backbone_dtype;
  head_dtype_ = head_dtype;
  device_ = device;
}

Dust3rEncoding Dust3rModel::encode(const at::Tensor& images, TensorTrace* trace, const std::string& view) const {
  if (!patch_embed_.weight.defined()) throw std::logic_error("Dust3rModel: weights are not loaded");
  checkImages(images, config_.patch_size, view + " image");
  const int64_t batch = images.size(0);
  const int64_t rows = images.size(2) / config_.patch_size, cols = images.size(3) / config_.patch_size;
  Dust3rEncoding out;
  out.height = images.size(2);
  out.width = images.size(3);
  const at::Tensor pixels = images.to(device(), backbone_dtype_);
  // (B, C, rows, cols) -> (B, N, C), row-major.
  at::Tensor x = patch_embed_.forward(pixels).flatten(2).transpose(1, 2);
  out.positions = patchPositions(batch, rows, cols, device());
  record(trace, view + ".patch_embed.x", x);
  record(trace, view + ".patch_embed.pos", out.positions);
  const RopeFactors rope =
      ropeFactors(out.positions, config_.enc_dim / config_.enc_heads, backbone_dtype_, config_.rope_base);
  for (size_t i = 0; i < enc_blocks_.size(); ++i) {
    x = enc_blocks_[i].forward(x, rope);
    record(trace, view + ".enc.block" + std::to_string(i), x);
  }
  out.tokens = enc_norm_.forward(x);
  record(trace, view + ".enc.out", out.tokens);
  return out;
}

std::array<std::vector<at::Tensor>, 2> Dust3rModel::decode(const Dust3rEncoding& view1, const Dust3rEncoding& view2,
                                                           TensorTrace* trace, std::array<DecoderOutputs, 2> keep) const {
  for (const Dust3rEncoding* view : {&view1, &view2}) {
    if (!view->tokens.defined() || view->tokens.dim() != 3 || view->tokens.size(2) != config_.enc_dim ||
        !view->positions.defined() || view->positions.sizes() != at::IntArrayRef({view->tokens.size(0), view->tokens.size(1), 2})) {
      throwInputError("decoder input", 0, "expected (B, N, " + std::to_string(config_.enc_dim) +
                                              ") tokens with (B, N, 2) positions");
    }
  }
  if (view1.tokens.size(0) != view2.tokens.size(0)) {
    throwInputError("decoder input", 0, "the two streams have different batch sizes");
  }
  const int64_t head_dim = config_.dec_dim / config_.dec_heads;
  const RopeFactors rope1 = ropeFactors(view1.positions, head_dim, backbone_dtype_, config_.rope_base);
  const RopeFactors rope2 = ropeFactors(view2.positions, head_dim, backbone_dtype_, config_.rope_base);
  const std::array<int64_t, 4> hooks = config_.dptHooks();
  // Output `layer` < d of view `v` (0: the encoder tokens) when the caller reads it, else undefined.
  const auto kept = [&](size_t v, int64_t layer, const at::Tensor& value) {
    const bool is_hook = std::find(hooks.begin(), hooks.end(), layer) != hooks.end();
    return keep[v] == DecoderOutputs::kHeadInputs && is_hook ? value : at::Tensor();
  };
  std::array<std::vector<at::Tensor>, 2> outputs;
  outputs[0].push_back(kept(0, 0, view1.tokens));
  outputs[1].push_back(kept(1, 0, view2.tokens));
  at::Tensor f1 = decoder_embed_.forward(view1.tokens);
  at::Tensor f2 = decoder_embed_.forward(view2.tokens);
  record(trace, "view1.dec.embed", f1);
  record(trace, "view2.dec.embed", f2);
  for (size_t i = 0; i < dec_blocks_.size(); ++i) {
    // Both views read the other's tokens of the previous layer.
    const at::Tensor next1 = dec_blocks_[i].forward(f1, f2, rope1, rope2);
    const at::Tensor next2 = dec_blocks2_[i].forward(f2, f1, rope2, rope1);
    f1 = next1;
    f2 = next2;
    record(trace, "view1.dec.block" + std::to_string(i), f1);
    record(trace, "view2.dec.block" + std::to_string(i), f2);
    if (i + 1 < dec_blocks_.size()) {
      const int64_t layer = static_cast<int64_t>(i) + 1;
      outputs[0].push_back(kept(0, layer, f1));
      outputs[1].push_back(kept(1, layer, f2));
    }
  }
  outputs[0].push_back(dec_norm_.forward(f1));
  outputs[1].push_back(dec_norm_.forward(f2));
  record(trace, "view1.dec.out", outputs[0].back());
  record(trace, "view2.dec.out", outputs[1].back());
  return outputs;
}

at::Tensor Dust3rModel::headForward(size_t index, const std::vector<at::Tensor>& decoded, int64_t height,
                                    int64_t width, TensorTrace* trace, const std::string& view) const {
  const std::array<int64_t, 4> hooks = config_.dptHooks();
  std::array<at::Tensor, 4> tokens;
  for (size_t i = 0; i < 4; ++i) {
    const at::Tensor& layer = decoded.at(hooks[i]);
    if (!layer.defined()) throw std::logic_error("Dust3rModel::headForward: decode() kept only the last output");
    tokens[i] = layer.to(head_dtype_);
  }
  return heads_.at(index).forward(tokens, height, width, config_.patch_size, trace, view + ".head");
}

Dust3rPairPrediction Dust3rModel::forward(const at::Tensor& images1, const at::Tensor& images2,
                                          TensorTrace* trace) const {
  checkImages(images1, config_.patch_size, "view1 image");
  checkImages(images2, config_.patch_size, "view2 image");
  if (images1.size(0) != images2.size(0)) {
    throwInputError("view2 image", 0, "batch size differs from view 1");
  }
  Dust3rEncoding enc1, enc2;
  if (images1.sizes() == images2.sizes()) {
    TensorTrace batch_trace;
    const Dust3rEncoding both = encode(at::cat({images1, images2}, 0), trace ? &batch_trace : nullptr, "pair");
    const int64_t batch = images1.size(0);
    enc1 = {both.tokens.narrow(0, 0, batch), both.positions.narrow(0, 0, batch), both.height, both.width};
    enc2 = {both.tokens.narrow(0, batch, batch), both.positions.narrow(0, batch, batch), both.height, both.width};
    for (const auto& [name, value] : batch_trace) {
      const std::string what = name.substr(std::string("pair").size());
      record(trace, "view1" + what, value.narrow(0, 0, batch));
      record(trace, "view2" + what, value.narrow(0, batch, batch));
    }
  } else {
    enc1 = encode(images1, trace, "view1");
    enc2 = encode(images2, trace, "view2");
  }
  const auto decoded = decode(enc1, enc2, trace);
  Dust3rPairPrediction out;
  out.view1 = pointMapFromRaw(headForward(0, decoded[0], enc1.height, enc1.width, trace, "view1"));
  out.view2 = pointMapFromRaw(headForward(1, decoded[1], enc2.height, enc2.width, trace, "view2"));
  record(trace, "view1.pts3d", out.view1.pts3d);
  record(trace, "view1.conf", out.view1.conf);
  record(trace, "view2.pts3d_in_other_view", out.view2.pts3d);
  record(trace, "view2.conf", out.view2.conf);
  return out;
}

}  // namespace ffloc
