#include "ffloc/model/dust3r_config.h"

#include "ffloc/core/error.h"

namespace ffloc {

std::array<int64_t, 4> Dust3rConfig::dptHooks() const {
  return {0, dec_depth * 2 / 4, dec_depth * 3 / 4, dec_depth};
}

void Dust3rConfig::validate(const std::string& origin) const {
  const auto fail = [&](const std::string& field, const std::string& what) {
    throwInputError(origin, 0, "field '" + field + "': " + what);
  };
  if (patch_size <= 0) fail("patch_size", "must be positive");
  // No encoder block is a valid network: a frozen classical encoder feeds the decoder directly.
  if (enc_dim <= 0) fail("enc_dim", "must be positive");
  if (enc_depth < 0) fail("enc_depth", "must not be negative");
  if (enc_heads <= 0) fail("enc_heads", "must be positive");
  if (dec_dim <= 0) fail("dec_dim", "must be positive");
  if (dec_heads <= 0) fail("dec_heads", "must be positive");
  // Fewer layers would make two DPT hooks read the same decoder layer.
  if (dec_depth < 4) fail("dec_depth", "must be at least 4 for the DPT hooks");
  if (mlp_ratio <= 0) fail("mlp_ratio", "must be positive");
  if (enc_dim % enc_heads != 0) fail("enc_heads", "must divide enc_dim");
  if (dec_dim % dec_heads != 0) fail("dec_heads", "must divide dec_dim");
  // RoPE2D halves each head (y, x) and rotates each half in two quarters.
  if ((enc_dim / enc_heads) % 4 != 0) fail("enc_heads", "head dim must be a multiple of 4");
  if ((dec_dim / dec_heads) % 4 != 0) fail("dec_heads", "head dim must be a multiple of 4");
  for (int64_t dim : head.layer_dims) {
    if (dim <= 0) fail("head.layer_dims", "must be positive");
  }
  if (head.feature_dim <= 0 || head.feature_dim % 2 != 0) {
    fail("head.feature_dim", "must be positive and even");
  }
  if (head.last_dim <= 0) fail("head.last_dim", "must be positive");
  if (head.num_channels != 4) fail("head.num_channels", "must be 4 (x, y, z, confidence)");
}

Dust3rConfig Dust3rConfig::preset(const std::string& name) {
  Dust3rConfig config;
  if (name == "large") return config;
  if (name == "tiny") {
    config.enc_dim = 64;
    config.enc_depth = 3;
    config.enc_heads = 4;
    config.dec_dim = 48;
    config.dec_depth = 10;
    config.dec_heads = 4;
    config.head.layer_dims = {16, 24, 32, 40};
    config.head.feature_dim = 32;
    config.head.last_dim = 24;
    return config;
  }
  if (name == "small") {
    config.enc_dim = 192;
    config.enc_depth = 6;
    config.enc_heads = 3;
    config.dec_dim = 192;
    config.dec_depth = 6;
    config.dec_heads = 3;
    config.head.layer_dims = {48, 96, 192, 192};
    config.head.feature_dim = 64;
    config.head.last_dim = 32;
    return config;
  }
  throwInputError("Dust3rConfig", 0, "unknown preset '" + name + "' (expected large, small or tiny)");
}

namespace {

const TensorView& tensorOfRank(const TensorArchive& archive, const std::string& name, size_t rank) {
  const TensorView& view = archive.at(name);
  if (view.shape.size() != rank) {
    throwInputError(archive.path().string(), 0,
                    "tensor '" + name + "': expected " + std::to_string(rank) + " dimensions, got " +
                        view.shapeString());
  }
  return view;
}

int64_t countBlocks(const TensorArchive& archive, const std::string& prefix) {
  int64_t count = 0;
  while (archive.contains(prefix + std::to_string(count) + ".norm1.weight")) ++count;
  return count;
}

int64_t headDivisor(const TensorArchive& archive, int64_t dim, int64_t head_dim, const std::string& what) {
  if (head_dim <= 0 || dim % head_dim != 0) {
    throwInputError(archive.path().string(), 0,
                    what + " width " + std::to_string(dim) + " is not a multiple of head dim " +
                        std::to_string(head_dim));
  }
  return dim / head_dim;
}

}  // namespace

Dust3rConfig inferDust3rConfig(const TensorArchive& archive, const Dust3rConfigInference& options) {
  Dust3rConfig config;
  // A copy: bound by reference beside temporary arguments, GCC 13 warns of a dangling one.
  const TensorView patch = tensorOfRank(archive, "patch_embed.proj.weight", 4);
  config.enc_dim = patch.shape[0];
  config.patch_size = patch.shape[2];
  config.enc_depth = countBlocks(archive, "enc_blocks.");
  config.dec_dim = tensorOfRank(archive, "decoder_embed.weight", 2).shape[0];
  config.dec_depth = countBlocks(archive, "dec_blocks.");
  config.enc_heads = headDivisor(archive, config.enc_dim, options.enc_head_dim, "encoder");
  config.dec_heads = headDivisor(archive, config.dec_dim, options.dec_head_dim, "decoder");
  const int64_t hidden = tensorOfRank(archive, "enc_blocks.0.mlp.fc1.weight", 2).shape[0];
  if (hidden % config.enc_dim != 0) {
    throwInputError(archive.path().string(), 0,
                    "tensor 'enc_blocks.0.mlp.fc1.weight': hidden width " + std::to_string(hidden) +
                        " is not a multiple of the encoder width " + std::to_string(config.enc_dim));
  }
  config.mlp_ratio = hidden / config.enc_dim;

  const std::string dpt = "downstream_head1.dpt.";
  for (size_t i = 0; i < 4; ++i) {
    config.head.layer_dims[i] =
        tensorOfRank(archive, dpt + "act_postprocess." + std::to_string(i) + ".0.weight", 4).shape[0];
  }
  // The two names of one tensor; safetensors files keep only the first.
  const std::string rn = archive.contains(dpt + "scratch.layer1_rn.weight")
                             ? dpt + "scratch.layer1_rn.weight"
                             : dpt + "scratch.layer_rn.0.weight";
  config.head.feature_dim = tensorOfRank(archive, rn, 4).shape[0];
  config.head.last_dim = tensorOfRank(archive, dpt + "head.2.weight", 4).shape[0];
  config.head.num_channels = tensorOfRank(archive, dpt + "head.4.weight", 4).shape[0];
  config.validate();
  return config;
}

}  // namespace ffloc
