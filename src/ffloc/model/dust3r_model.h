#pragma once

#include <ATen/core/Tensor.h>

#include <array>
#include <string>
#include <vector>

#include "ffloc/io/tensor_archive.h"
#include "ffloc/model/dpt_head.h"
#include "ffloc/model/dust3r_config.h"
#include "ffloc/model/layers.h"
#include "ffloc/model/parameter_table.h"

namespace ffloc {

// Tokens of one or more same-sized images after the encoder (enc_norm applied).
struct Dust3rEncoding {
  at::Tensor tokens;     // (B, N, enc_dim), backbone dtype
  at::Tensor positions;  // (B, N, 2) int64 patch (row, col)
  int64_t height = 0, width = 0;
};

// DUSt3R's pts3d output of one view: exp depth mode and 1 + exp confidence.
struct Dust3rPointMap {
  at::Tensor pts3d;  // (B, H, W, 3) float32, in the first view's camera frame
  at::Tensor conf;   // (B, H, W) float32, >= 1
};

struct Dust3rPairPrediction {
  Dust3rPointMap view1;
  Dust3rPointMap view2;  // pts3d_in_other_view
};

// DUSt3R's post-processing of (..., 4) channels-last head outputs: points xyz / |xyz| *
// expm1(|xyz|) (..., 3) and confidence 1 + exp(c) (...).
Dust3rPointMap pointsFromRaw(const at::Tensor& channels_last);

// The same for a (B, 4, H, W) DPT output: (B, H, W, 3) points, (B, H, W) confidence.
Dust3rPointMap pointMapFromRaw(const at::Tensor& raw);

// Which DPT heads a model holds. FastForward keeps only the first (the query head), or none
// when another head predicts the query's points.
enum class Dust3rHeads { kBoth, kFirstOnly, kNone };

// Which decoder outputs of a view decode() returns: the DPT head's inputs (Dust3rConfig::dptHooks,
// the last output among them), or the last output only (a view that no DPT head reads).
enum class DecoderOutputs { kHeadInputs, kLast };

// Patch (row, col) positions of an image of rows x cols patches, row-major: (batch, rows*cols, 2)
// int64.
at::Tensor patchPositions(int64_t batch, int64_t rows, int64_t cols, at::Device device);

// The DUSt3R network (AsymmetricCroCo3DStereo) as functional libtorch code with the reference's
// parameter names. Built with undefined tensors; loadWeights() fills them.
//
// Precision: the backbone (patch embedding, encoder, decoder) runs in the chosen dtype (float32
// or bfloat16). The DPT heads run in float32 by default, as the reference does on CUDA, or in
// bfloat16, as the reference does on CPU under autocast; their last 1x1 projection and the
// post-processing always run in float32.
class Dust3rModel {
 public:
  explicit Dust3rModel(const Dust3rConfig& config);

  const Dust3rConfig& config() const { return config_; }
  at::ScalarType backboneDtype() const { return backbone_dtype_; }
  at::ScalarType headDtype() const { return head_dtype_; }
  at::Device device() const { return device_; }

  // The state_dict (1009 keys for the large config), pointing into this model: rebuild it after
  // the model is moved. Without the encoder (a model fed by another tokeniser) the table starts
  // at decoder_embed.
  ParameterTable parameterTable(Dust3rHeads heads = Dust3rHeads::kBoth, bool with_encoder = true);
  // Strict load (see loadParameters); the tensors then get the current dtype and device.
  void loadWeights(const TensorArchive& archive);
  // Moves every tensor to `device`, casting the backbone to `backbone_dtype` and the heads to
  // `head_dtype` (each kFloat or kBFloat16).
  void to(at::Device device, at::ScalarType backbone_dtype, at::ScalarType head_dtype = at::kFloat);

  // images: (B, 3, H, W) normalised (see normalizedImageTensor), H and W multiples of the patch
  // size. Trace names "<view>.patch_embed.x", "<view>.enc.block<i>", "<view>.enc.out", ...
  Dust3rEncoding encode(const at::Tensor& images, TensorTrace* trace = nullptr,
                        const std::string& view = "view1") const;

  // Decoder of both views: per view the d + 1 outputs [encoder tokens, layer 1, ..., layer d - 1,
  // dec_norm(layer d)], of which only those `keep` names are defined; the others are dropped as
  // soon as the next layer has read them (all d + 1 of a pair at 768 tokens are 54 MiB in
  // float32, a FastForward map stream of 1500 tokens alone 57 MiB).
  std::array<std::vector<at::Tensor>, 2> decode(const Dust3rEncoding& view1, const Dust3rEncoding& view2,
                                                TensorTrace* trace = nullptr,
                                                std::array<DecoderOutputs, 2> keep = {DecoderOutputs::kHeadInputs,
                                                                                      DecoderOutputs::kHeadInputs}) const;

  // DPT head `index` (0 for view 1, 1 for view 2) on a decoder output list; raw (B, 4, H, W).
  at::Tensor headForward(size_t index, const std::vector<at::Tensor>& decoded, int64_t height,
                         int64_t width, TensorTrace* trace = nullptr, const std::string& view = "") const;

  // The full pair forward. Same-sized views are encoded as one batch, like the reference.
  Dust3rPairPrediction forward(const at::Tensor& images1, const at::Tensor& images2,
                               TensorTrace* trace = nullptr) const;

 private:
  void registerBackbone(ParameterTable& table, bool with_encoder);
  void registerHeads(ParameterTable& table, Dust3rHeads heads);

  Dust3rConfig config_;
  at::ScalarType backbone_dtype_ = at::kFloat;
  at::ScalarType head_dtype_ = at::kFloat;
  at::Device device_ = at::kCPU;
  at::Tensor mask_token_;  // in the checkpoint, unused at inference
  nn::Conv2d patch_embed_;
  std::vector<nn::EncoderBlock> enc_blocks_;
  nn::LayerNorm enc_norm_;
  nn::Linear decoder_embed_;
  std::vector<nn::DecoderBlock> dec_blocks_, dec_blocks2_;
  nn::LayerNorm dec_norm_;
  std::array<DptHead, 2> heads_;
};

}  // namespace ffloc
