#pragma once

#ifdef FFLOC_WITH_TORCH

#include <cstdint>

#include "ffloc/model/fastforward_model.h"

namespace ffloc::cli {

// Analytic FLOP counts of the network, batch 1, for `ffloc bench model`. Convention of the
// Python reference timing (fixtures/dust3r/python_reference_timing.txt, counted there by hooks):
// a multiply-add is 2 FLOPs, and only the matrix products count: Linear layers, the two attention
// products (q k^T and attention x v) and (transposed) convolutions. Norms, softmax, GELU, RoPE,
// biases, resizing and post-processing are left out (together well under 1 %). Formulas:
// docs/benchmarks.md.

// Patch embedding + all encoder blocks of one height x width image.
double encoderFlops(const Dust3rConfig& config, int64_t height, int64_t width);

// decoder_embed of both streams + every decoder block of both streams, with tokens1 tokens in the
// first stream and tokens2 in the second.
double decoderFlops(const Dust3rConfig& config, int64_t tokens1, int64_t tokens2);

// One DPT head producing a height x width map.
double dptHeadFlops(const Dust3rConfig& config, int64_t height, int64_t width);

// FastForwardModel::forward for a height x width query and map_tokens map tokens: ray MLP,
// decoder, the query DPT head and the map head.
double fastForwardFlops(const FastForwardConfig& config, int64_t height, int64_t width, int64_t map_tokens);

}  // namespace ffloc::cli

#endif  // FFLOC_WITH_TORCH
