#include "bench_model_rows.h"

#ifdef FFLOC_WITH_TORCH

#include <ATen/TensorOperators.h>
#include <ATen/ops/rand.h>
#include <ATen/ops/randn.h>

#include <algorithm>
#include <chrono>
#include <string>
#include <vector>

#include "ffloc/core/clock.h"
#include "ffloc/model/fastforward_model.h"
#include "ffloc/model/map_assembly.h"
#include "ffloc/model/model_loader.h"
#include "ffloc/model/model_options.h"
#include "ffloc/model/op_profile.h"
#include "flop_count.h"

namespace ffloc::cli {
namespace {

// One more call of a row, untimed by the row, with the per-kind profile switched on.
void profileCall(const BenchReport& report, const std::string& dtype, const std::string& what,
                 const std::function<void()>& call) {
  startOpProfile();
  const auto start = std::chrono::steady_clock::now();
  call();
  const double seconds = secondsSince(start);
  report.profile(dtype, what, seconds, stopOpProfile());
}

// `count` map tokens assembled as localisation and training assemble them (map_assembly.h), from
// mapping cameras on a circle looking inwards and random encoder tokens.
MapTokens randomMapTokens(const Dust3rConfig& config, int64_t rows, int64_t cols, int64_t count,
                          at::ScalarType dtype, uint64_t seed) {
  const int64_t per_image = rows * cols;
  // At least a handful of images, as after retrieval, and enough to hold all N tokens.
  const int64_t images = std::max<int64_t>(8, (count + per_image - 1) / per_image);
  const int patch = static_cast<int>(config.patch_size);
  std::vector<MapCamera> cameras;
  std::vector<Dust3rEncoding> encodings;
  for (int64_t k = 0; k < images; ++k) {
    MapCamera camera;
    camera.intrinsics.width = static_cast<int>(cols) * patch;
    camera.intrinsics.height = static_cast<int>(rows) * patch;
    camera.intrinsics.fx = camera.intrinsics.fy = 0.8 * camera.intrinsics.width;
    camera.intrinsics.cx = 0.5 * (camera.intrinsics.width - 1);
    camera.intrinsics.cy = 0.5 * (camera.intrinsics.height - 1);
    const double angle = 2.0 * 3.141592653589793 * static_cast<double>(k) / static_cast<double>(images);
    camera.camera_to_world.R = Eigen::AngleAxisd(-angle, Eigen::Vector3d::UnitY()).toRotationMatrix();
    camera.camera_to_world.t = -2.0 * (camera.camera_to_world.R * Eigen::Vector3d::UnitZ());
    camera.name = "bench_" + std::to_string(k);
    cameras.push_back(camera);
    Dust3rEncoding encoding;
    encoding.tokens = at::randn({1, per_image, config.enc_dim}).to(dtype);
    encoding.positions = patchPositions(1, rows, cols, at::kCPU);
    encoding.height = rows * patch;
    encoding.width = cols * patch;
    encodings.push_back(encoding);
  }
  return assembleMapTokens(planMap(cameras, patch, count, seed), encodings);
}

}  // namespace

// Encoder on one image and DUSt3R's decoder + both DPT heads (with post-processing) on a pair:
// the two measurements of the Python reference.
void benchDust3r(const BenchModelArguments& args, const BenchReport& report, const std::string& dtype_name) {
  const at::ScalarType dtype = parseNetworkDtype(dtype_name);
  at::manual_seed(args.seed);
  Dust3rModel model(Dust3rConfig::preset(args.config));
  randomizeParameters(model.parameterTable(), args.seed, dtype);
  model.to(at::kCPU, dtype, dtype);
  MemoryReport memory = startMemoryWindow();
  const Dust3rConfig& config = model.config();
  const at::Tensor image1 = at::rand({1, 3, args.height, args.width}) * 2 - 1;
  const at::Tensor image2 = at::rand({1, 3, args.height, args.width}) * 2 - 1;

  const auto encode = [&] { model.encode(image1); };
  const Timing encoder = timeCalls(args.warmup, args.repeats, encode);
  report.row(dtype_name, "encoder, 1 image", encoder, encoderFlops(config, args.height, args.width),
             report.encoderReference());
  if (args.profile) profileCall(report, dtype_name, "encoder, 1 image", encode);

  const Dust3rEncoding view1 = model.encode(image1), view2 = model.encode(image2);
  const auto decode_pair = [&] {
    const auto decoded = model.decode(view1, view2);
    pointMapFromRaw(model.headForward(0, decoded[0], args.height, args.width));
    pointMapFromRaw(model.headForward(1, decoded[1], args.height, args.width));
  };
  const Timing pair = timeCalls(args.warmup, args.repeats, decode_pair);
  const int64_t tokens = view1.tokens.size(1);
  report.row(dtype_name, "DUSt3R decoder + 2 DPT heads, pair", pair,
             decoderFlops(config, tokens, tokens) + 2 * dptHeadFlops(config, args.height, args.width),
             report.pairReference());
  if (args.profile) profileCall(report, dtype_name, "DUSt3R decoder + 2 DPT heads, pair", decode_pair);
  closeMemoryWindow(memory);
  report.memory(dtype_name, "DUSt3R", memory);
}

// FastForwardModel::forward for one query against N map tokens: ray MLP, decoder, query DPT
// head (with post-processing) and map head.
void benchFastForward(const BenchModelArguments& args, const BenchReport& report, const std::string& dtype_name) {
  const at::ScalarType dtype = parseNetworkDtype(dtype_name);
  at::manual_seed(args.seed);
  FastForwardConfig ff_config;
  ff_config.dust3r = Dust3rConfig::preset(args.config);
  FastForwardModel model(ff_config);
  randomizeParameters(model.parameterTable(), args.seed, dtype);
  model.to(at::kCPU, dtype, dtype);
  MemoryReport memory = startMemoryWindow();
  const Dust3rConfig& config = model.config().dust3r;
  const Dust3rEncoding query = model.encode(at::rand({1, 3, args.height, args.width}) * 2 - 1);
  for (const int64_t count : args.map_tokens) {
    const MapTokens map = randomMapTokens(config, args.height / config.patch_size, args.width / config.patch_size,
                                          count, dtype, args.seed);
    const auto forward_call = [&] { model.forward(query, map); };
    const std::string what = "FastForward decoder + query head, N=" + std::to_string(count);
    const Timing forward = timeCalls(args.warmup, args.repeats, forward_call);
    report.row(dtype_name, what, forward, fastForwardFlops(model.config(), args.height, args.width, count), nullptr);
    if (args.profile) profileCall(report, dtype_name, what, forward_call);
  }
  closeMemoryWindow(memory);
  report.memory(dtype_name, "FastForward", memory);
}

}  // namespace ffloc::cli

#endif  // FFLOC_WITH_TORCH
