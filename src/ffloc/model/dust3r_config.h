#pragma once

#include <array>
#include <cstdint>
#include <string>

#include "ffloc/io/tensor_archive.h"

namespace ffloc {

// Channel sizes of one DPT head (DUSt3R's DPTOutputAdapter_fix).
struct DptHeadConfig {
  std::array<int64_t, 4> layer_dims = {96, 192, 384, 768};
  int64_t feature_dim = 256;
  int64_t last_dim = 128;
  int64_t num_channels = 4;  // x, y, z, confidence logit
};

// The DUSt3R network (AsymmetricCroCo3DStereo with RoPE100, PatchEmbedDust3R, DPT heads, pts3d
// output with exp depth and exp confidence). Defaults are the official ViT-L encoder / ViT-B
// decoder / DPT-512 model.
struct Dust3rConfig {
  int64_t patch_size = 16;
  int64_t enc_dim = 1024;
  int64_t enc_depth = 24;
  int64_t enc_heads = 16;
  int64_t dec_dim = 768;
  int64_t dec_depth = 12;
  int64_t dec_heads = 12;
  int64_t mlp_ratio = 4;
  double rope_base = 100.0;
  double layer_norm_eps = 1e-6;
  DptHeadConfig head;

  // Indices into [encoder output, decoder layer 1..d] that feed the DPT: [0, 2d/4, 3d/4, d].
  std::array<int64_t, 4> dptHooks() const;
  // InputError naming the field when the sizes cannot form a model (e.g. heads not dividing the
  // width, a head dim RoPE2D cannot split into four equal parts).
  // InputError naming `origin` (a file's metadata, say) and the field.
  void validate(const std::string& origin = "Dust3rConfig") const;

  // "large" (the official model), "small" (the size of the shipped model, for training on small
  // hardware) or "tiny" (the fixture model in shared/fixtures/dust3r).
  static Dust3rConfig preset(const std::string& name);
};

// Sizes from the tensor shapes of a DUSt3R checkpoint: widths, depths, MLP ratio, patch size and
// the DPT channel sizes. Head counts are not visible in shapes, so they come from the head dims
// (64 in the official model).
struct Dust3rConfigInference {
  int64_t enc_head_dim = 64;
  int64_t dec_head_dim = 64;
};
Dust3rConfig inferDust3rConfig(const TensorArchive& archive,
                               const Dust3rConfigInference& options = {});

}  // namespace ffloc
