#ifdef FFLOC_WITH_TORCH

#include "flop_count.h"

namespace ffloc::cli {
namespace {

double linear(int64_t tokens, int64_t in, int64_t out) { return 2.0 * tokens * in * out; }

// q k^T and (attention weights) v over all heads: each tokens_q x tokens_k x dim multiply-adds.
double attention(int64_t tokens_q, int64_t tokens_k, int64_t dim) { return 4.0 * tokens_q * tokens_k * dim; }

struct Size {
  int64_t rows = 0, cols = 0;
  int64_t pixels() const { return rows * cols; }
  Size twice() const { return {2 * rows, 2 * cols}; }
};

double conv(int64_t in, int64_t out, int64_t kernel, Size output) {
  return 2.0 * in * out * kernel * kernel * output.pixels();
}

// A transposed convolution does its multiply-adds per input pixel.
double convTranspose(int64_t in, int64_t out, int64_t kernel, Size input) {
  return 2.0 * in * out * kernel * kernel * input.pixels();
}

double mlp(int64_t tokens, int64_t dim, int64_t ratio) {
  return linear(tokens, dim, ratio * dim) + linear(tokens, ratio * dim, dim);
}

// One decoder block of the stream with `tokens` tokens attending to `other` tokens.
double decoderBlock(const Dust3rConfig& c, int64_t tokens, int64_t other) {
  const int64_t d = c.dec_dim;
  const double self_attention = linear(tokens, d, 3 * d) + attention(tokens, tokens, d) + linear(tokens, d, d);
  const double cross_attention = linear(tokens, d, d) + 2 * linear(other, d, d) + attention(tokens, other, d) +
                                 linear(tokens, d, d);
  return self_attention + cross_attention + mlp(tokens, d, c.mlp_ratio);
}

}  // namespace

double encoderFlops(const Dust3rConfig& c, int64_t height, int64_t width) {
  const Size grid{height / c.patch_size, width / c.patch_size};
  const int64_t tokens = grid.pixels(), d = c.enc_dim;
  const double block =
      linear(tokens, d, 3 * d) + attention(tokens, tokens, d) + linear(tokens, d, d) + mlp(tokens, d, c.mlp_ratio);
  return conv(3, d, c.patch_size, grid) + c.enc_depth * block;
}

double decoderFlops(const Dust3rConfig& c, int64_t tokens1, int64_t tokens2) {
  const double embed = linear(tokens1 + tokens2, c.enc_dim, c.dec_dim);
  return embed + c.dec_depth * (decoderBlock(c, tokens1, tokens2) + decoderBlock(c, tokens2, tokens1));
}

double dptHeadFlops(const Dust3rConfig& c, int64_t height, int64_t width) {
  const DptHeadConfig& h = c.head;
  const std::array<int64_t, 4> token_dims = {c.enc_dim, c.dec_dim, c.dec_dim, c.dec_dim};
  const Size grid{height / c.patch_size, width / c.patch_size};
  // Resolutions after act_postprocess: x4, x2, x1 and x1/2 (3x3, stride 2, padding 1) the grid.
  const std::array<Size, 4> levels = {Size{4 * grid.rows, 4 * grid.cols}, grid.twice(), grid,
                                      Size{(grid.rows + 1) / 2, (grid.cols + 1) / 2}};
  const int64_t f = h.feature_dim;
  double total = 0.0;
  for (size_t i = 0; i < 4; ++i) {
    total += conv(token_dims[i], h.layer_dims[i], 1, grid);
    total += conv(h.layer_dims[i], f, 3, levels[i]);  // layer_rn
  }
  total += convTranspose(h.layer_dims[0], h.layer_dims[0], 4, grid);
  total += convTranspose(h.layer_dims[1], h.layer_dims[1], 2, grid);
  total += conv(h.layer_dims[3], h.layer_dims[3], 3, levels[3]);
  // Refinenets: two 3x3 convs per residual unit (the coarsest has only its second unit), then a
  // 1x1 conv after the x2 upsampling. The coarsest output is cropped to the next level after
  // its out_conv, so that conv runs on the uncropped map.
  const double unit = 2 * conv(f, f, 3, Size{1, 1});
  total += 1 * unit * levels[3].pixels() + conv(f, f, 1, levels[3].twice());
  for (size_t i = 0; i < 3; ++i) total += 2 * unit * levels[i].pixels() + conv(f, f, 1, levels[i].twice());
  const Size finest = levels[0].twice();
  total += conv(f, f / 2, 3, finest);
  total += conv(f / 2, h.last_dim, 3, finest.twice()) + conv(h.last_dim, h.num_channels, 1, finest.twice());
  return total;
}

double fastForwardFlops(const FastForwardConfig& config, int64_t height, int64_t width, int64_t map_tokens) {
  const Dust3rConfig& c = config.dust3r;
  const int64_t query_tokens = (height / c.patch_size) * (width / c.patch_size);
  const int64_t hidden = config.rays.hidden_dim > 0 ? config.rays.hidden_dim : c.enc_dim;
  const double rays = linear(map_tokens, config.rays.inputDim(), hidden) + linear(map_tokens, hidden, c.enc_dim);
  const double map_head = linear(map_tokens, c.dec_dim, c.head.num_channels);
  return rays + decoderFlops(c, query_tokens, map_tokens) + dptHeadFlops(c, height, width) + map_head;
}

}  // namespace ffloc::cli

#endif  // FFLOC_WITH_TORCH
