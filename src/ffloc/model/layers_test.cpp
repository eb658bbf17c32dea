#include "ffloc/model/layers.h"

#include "ffloc/model/bfloat16_kernels.h"
#include "ffloc/model/cpu_attention.h"
#include "ffloc/model/cpu_conv.h"
#include "ffloc/model/cpu_gemm.h"
#include "ffloc/model/softmax_kernel.h"

#include <ATen/ATen.h>
#include <gtest/gtest.h>

namespace ffloc::nn {
namespace {

// out[o, i*k + di, j*k + dj] = bias[o] + sum_c x[c, i, j] * w[c, o, di, dj], written out directly.
at::Tensor transposedConvByDefinition(const at::Tensor& x, const at::Tensor& w, const at::Tensor& b, int64_t k) {
  const int64_t in = x.size(1), rows = x.size(2), cols = x.size(3), out = w.size(1);
  at::Tensor result = at::zeros({1, out, rows * k, cols * k}, at::kDouble);
  const at::Tensor xd = x.to(at::kDouble), wd = w.to(at::kDouble), bd = b.to(at::kDouble);
  auto r = result.accessor<double, 4>();
  auto xa = xd.accessor<double, 4>();
  auto wa = wd.accessor<double, 4>();
  auto ba = bd.accessor<double, 1>();
  for (int64_t o = 0; o < out; ++o)
    for (int64_t i = 0; i < rows; ++i)
      for (int64_t j = 0; j < cols; ++j)
        for (int64_t di = 0; di < k; ++di)
          for (int64_t dj = 0; dj < k; ++dj) {
            double sum = ba[o];
            for (int64_t c = 0; c < in; ++c) sum += xa[0][c][i][j] * wa[c][o][di][dj];
            r[0][o][i * k + di][j * k + dj] = sum;
          }
  return result;
}

// The DPT head's x4 and x2 resampling: stride = kernel, no padding. Covers an input smaller than
// the kernel (which libtorch 1.13's conv_transpose2d refuses) and bfloat16 (where it returns wrong
// shapes).
TEST(Conv2d, StrideEqualsKernelTransposedConvMatchesDefinition) {
  at::manual_seed(3);
  for (const int64_t kernel : {2, 4}) {
    for (const auto& [rows, cols] : {std::pair<int64_t, int64_t>{1, 1}, {3, 5}}) {
      Conv2d conv(6, 5, kernel, kernel, 0, /*has_bias=*/true, /*transposed=*/true);
      conv.weight = at::randn({6, 5, kernel, kernel});
      conv.bias = at::randn({5});
      const at::Tensor x = at::randn({1, 6, rows, cols});
      const at::Tensor expected = transposedConvByDefinition(x, conv.weight, conv.bias, kernel);

      const at::Tensor fp32 = conv.forward(x);
      ASSERT_EQ(fp32.sizes(), expected.sizes());
      EXPECT_LT((fp32.to(at::kDouble) - expected).abs().max().item<double>(), 1e-5);

      Conv2d half = conv;
      half.weight = conv.weight.to(at::kBFloat16);
      half.bias = conv.bias.to(at::kBFloat16);
      const at::Tensor bf16 = half.forward(x.to(at::kBFloat16));
      ASSERT_EQ(bf16.sizes(), expected.sizes());
      const double scale = expected.abs().max().item<double>();
      EXPECT_LT((bf16.to(at::kDouble) - expected).abs().max().item<double>(), 0.05 * scale);
    }
  }
}

// The float32 kernels that serve bf16 layers where the CPU has no native bf16, against the same
// layer in double precision on the same bf16 values: the exact sums rounded once to bf16, so
// within a step of bf16 (8 significant bits: 2^-8 of the output's magnitude) plus float32's
// rounding, and never farther from exact than libtorch's own bf16 kernels, which round on the
// way (measured here: a 3x3 convolution 0.026 of its magnitude off). Run on every CPU.
TEST(Bfloat16Kernels, Float32KernelsRoundTheExactResultOnce) {
  at::manual_seed(11);
  constexpr double kBfloat16Step = 1.0 / 256;
  const auto bf16 = [](const at::Tensor& t) { return t.to(at::kBFloat16); };
  const auto dbl = [](const at::Tensor& t) { return t.to(at::kDouble); };
  const auto check = [](const std::string& what, const auto& run_bf16, const at::Tensor& exact, double steps) {
    at::Tensor wide, aten;
    {
      const ScopedBfloat16Kernels kernels(Bfloat16Kernels::kFloat32);
      wide = run_bf16();
    }
    {
      const ScopedBfloat16Kernels kernels(Bfloat16Kernels::kLibtorch);
      aten = run_bf16();
    }
    ASSERT_EQ(wide.scalar_type(), at::kBFloat16) << what;
    ASSERT_EQ(wide.sizes(), exact.sizes()) << what;
    const double scale = exact.abs().max().item<double>();
    const double wide_error = (wide.to(at::kDouble) - exact).abs().max().item<double>() / scale;
    const double aten_error = (aten.to(at::kDouble) - exact).abs().max().item<double>() / scale;
    EXPECT_LE(wide_error, steps * kBfloat16Step) << what;
    EXPECT_LE(wide_error, aten_error + kBfloat16Step) << what << ": libtorch's bf16 kernels " << aten_error;
  };

  Linear linear(64, 96);
  linear.weight = bf16(at::randn({96, 64}) * 0.1);
  linear.bias = bf16(at::randn({96}));
  const at::Tensor tokens = bf16(at::randn({2, 50, 64}));
  const at::Tensor residual = bf16(at::randn({2, 50, 96}));
  Linear linear_exact = linear;
  linear_exact.weight = dbl(linear.weight);
  linear_exact.bias = dbl(linear.bias);
  check("linear", [&] { return linear.forward(tokens, residual); }, linear_exact.forward(dbl(tokens), dbl(residual)), 1);

  for (const int64_t kernel : {1, 3}) {
    Conv2d conv(16, 24, kernel, 1, kernel / 2);
    conv.weight = bf16(at::randn({24, 16, kernel, kernel}) * 0.2);
    conv.bias = bf16(at::randn({24}));
    Conv2d conv_exact = conv;
    conv_exact.weight = dbl(conv.weight);
    conv_exact.bias = dbl(conv.bias);
    const at::Tensor image = bf16(at::randn({1, 16, 9, 13}));
    check(std::to_string(kernel) + "x" + std::to_string(kernel) + " convolution", [&] { return conv.forward(image); },
          conv_exact.forward(dbl(image)), 1);
  }

  Attention attention(64, 4);
  Attention attention_exact(64, 4);
  for (auto [layer, exact_layer, out] : {std::tuple{&attention.qkv, &attention_exact.qkv, 192},
                                        std::tuple{&attention.proj, &attention_exact.proj, 64}}) {
    layer->weight = bf16(at::randn({out, 64}) * 0.1);
    layer->bias = bf16(at::randn({out}) * 0.1);
    exact_layer->weight = dbl(layer->weight);
    exact_layer->bias = dbl(layer->bias);
  }
  const at::Tensor positions =
      at::stack({at::div(at::arange(50), 10, "floor"), at::arange(50) % 10}, -1).unsqueeze(0).expand({2, 50, 2}).contiguous();
  const RopeFactors rope = ropeFactors(positions, 16, at::kBFloat16);
  // The float32 path rounds only the attention's output; in double, q, k and v are not rounded to
  // bf16 after the projection either, so the two differ by the projection's roundings too.
  check("attention", [&] { return attention.forward(tokens, rope, tokens); },
        attention_exact.forward(dbl(tokens), {dbl(rope.cos), dbl(rope.signed_sin)}, dbl(tokens)), 2);
}

// Rows of several lengths (a multiple of the vector width, a tail, shorter than one vector) and a
// wide value range, against ATen's softmax in double precision.
TEST(Softmax, InPlaceKernelMatchesReference) {
  if (!vectorizedSoftmaxAvailable()) GTEST_SKIP() << "no AVX-512 on this CPU: the kernel falls back to ATen";
  at::manual_seed(5);
  for (const int64_t length : {1, 7, 16, 100, 768}) {
    const at::Tensor input = at::randn({3, 5, length}) * 20;
    const at::Tensor expected = at::softmax(input.to(at::kDouble), -1);
    at::Tensor fp32 = input.clone();
    softmaxLastDimInPlace(fp32);
    EXPECT_LT((fp32.to(at::kDouble) - expected).abs().max().item<double>(), 1e-6) << "length " << length;
    at::Tensor bf16 = input.to(at::kBFloat16);
    const at::Tensor aten = at::softmax(bf16, -1);
    softmaxLastDimInPlace(bf16);
    // Both round float32 values to bfloat16 (8 significant bits): at most one step apart.
    EXPECT_LE((bf16.to(at::kDouble) - aten.to(at::kDouble)).abs().max().item<double>(), 4e-3) << "length " << length;
    EXPECT_NEAR(bf16.to(at::kDouble).sum(-1).mean().item<double>(), 1.0, 1e-2);
  }
}

// The single-thread row kernel of the fused attention (AVX-512, AVX2 or plain C++, whichever this
// CPU runs), on lengths around the vector widths.
TEST(Softmax, RowsOnThisThreadMatchReference) {
  at::manual_seed(6);
  for (const int64_t length : {1, 7, 8, 9, 17, 100, 768}) {
    const at::Tensor input = at::randn({4, length}) * 20;
    const at::Tensor expected = at::softmax(input.to(at::kDouble), -1);
    at::Tensor rows = input.clone();
    softmaxRowsOnThisThread(rows.data_ptr<float>(), rows.size(0), length);
    EXPECT_LT((rows.to(at::kDouble) - expected).abs().max().item<double>(), 1e-6) << "length " << length;
  }
}

// Fused attention against the composition of ATen ops in double: q, k and v as column ranges of
// one wider product (as the qkv Linear gives them), key and query counts that differ, several
// query blocks with a short last one, batch 2.
TEST(CpuAttention, MatchesComposedReference) {
  at::manual_seed(7);
  const int64_t batch = 2, queries = 300, keys = 700, heads = 3, head_dim = 12, width = heads * head_dim;
  const at::Tensor q_source = at::randn({batch, queries, 3 * width});
  const at::Tensor kv_source = at::randn({batch, keys, 2 * width});
  const at::Tensor q = q_source.narrow(2, width, width);
  const at::Tensor k = kv_source.narrow(2, 0, width), v = kv_source.narrow(2, width, width);
  ASSERT_TRUE(cpuAttentionApplies(q, k, v));
  const at::Tensor out = cpuAttention(q, k, v, heads);

  const auto split = [&](const at::Tensor& t) {
    return t.to(at::kDouble).reshape({batch, t.size(1), heads, head_dim}).permute({0, 2, 1, 3});
  };
  const at::Tensor scores = at::matmul(split(q), split(k).transpose(-2, -1)) / std::sqrt(static_cast<double>(head_dim));
  const at::Tensor expected =
      at::matmul(at::softmax(scores, -1), split(v)).permute({0, 2, 1, 3}).reshape({batch, queries, width});
  ASSERT_EQ(out.sizes(), expected.sizes());
  EXPECT_LT((out.to(at::kDouble) - expected).abs().max().item<double>(), 1e-5);
}

// The DPT heads' 3x3 (padding 1) and 1x1 convolutions as products, against libtorch's own, on
// images down to one pixel wide (where every horizontal tap but the centre one falls off the
// row), batch 2, channels-last and contiguous inputs.
TEST(CpuConvolution, MatchesLibtorchConvolution) {
  at::manual_seed(9);
  for (const int64_t kernel : {3, 1}) {
    for (const auto& [rows, cols] : {std::pair<int64_t, int64_t>{5, 7}, {3, 1}, {1, 2}}) {
      const at::Tensor weight = at::randn({6, 5, kernel, kernel}), bias = at::randn({6});
      const int64_t padding = kernel / 2;
      for (const bool channels_last : {true, false}) {
        at::Tensor x = at::randn({2, 5, rows, cols});
        if (channels_last) x = x.contiguous(at::MemoryFormat::ChannelsLast);
        ASSERT_TRUE(cpuConvolutionApplies(x, weight, 1, padding));
        const at::Tensor expected = at::conv2d(x, weight, bias, 1, padding);
        EXPECT_LT((cpuConvolution(x, weight, bias) - expected).abs().max().item<double>(), 1e-5)
            << kernel << "x" << kernel << " on " << rows << "x" << cols;
        EXPECT_LT((cpuConvolution(x, weight, {}) - at::conv2d(x, weight, {}, 1, padding)).abs().max().item<double>(), 1e-5);
      }
    }
  }
  EXPECT_FALSE(cpuConvolutionApplies(at::randn({1, 5, 4, 4}), at::randn({6, 5, 3, 3}), 2, 1));
}

// The threaded Linear with its bias and residual folded in, for both ways of splitting the
// work (more output columns than rows, and the reverse).
TEST(CpuLinear, MatchesLinearPlusResidual) {
  at::manual_seed(8);
  for (const auto& [rows, out] : {std::pair<int64_t, int64_t>{10, 70}, {150, 40}}) {
    const at::Tensor x = at::randn({1, rows, 33});
    const at::Tensor weight = at::randn({out, 33}), bias = at::randn({out});
    const at::Tensor residual = at::randn({1, rows, out});
    ASSERT_TRUE(cpuGemmApplies(x, weight));
    const at::Tensor expected = at::linear(x.to(at::kDouble), weight.to(at::kDouble), bias.to(at::kDouble));
    EXPECT_LT((cpuLinear(x, weight, bias, residual).to(at::kDouble) - expected - residual.to(at::kDouble))
                  .abs().max().item<double>(), 1e-4);
    EXPECT_LT((cpuLinear(x, weight, {}, {}).to(at::kDouble) - (expected - bias.to(at::kDouble))).abs().max().item<double>(),
              1e-4);
  }
}

}  // namespace
}  // namespace ffloc::nn
