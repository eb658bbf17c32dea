#include "ffloc/pipeline/localizer.h"

#include <ATen/core/Tensor.h>
#include <ATen/ops/from_blob.h>
#include <c10/core/InferenceMode.h>

#include <chrono>
#include <cmath>

#include "ffloc/core/error.h"
#include "ffloc/geometry/rays.h"
#include "ffloc/model/ray_encoding.h"
#include "ffloc/pipeline/prepared_image.h"
#include "ffloc/pipeline/query_descriptor.h"

namespace ffloc {
namespace {

using Clock = std::chrono::steady_clock;

double secondsSince(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

}  // namespace

LocalizeOptions LocalizeOptions::preset(const std::string& name) {
  LocalizeOptions options;
  if (name == "indoor") return options;
  if (name == "outdoor") {
    options.top_k = 20;
    options.num_features = 3000;
    return options;
  }
  throwInputError("--preset", 0, "unknown preset '" + name + "' (expected indoor or outdoor)");
}

double LocalizationResult::confidence() const {
  if (!pnp.ok() || pnp.used_correspondences <= 0) return 0;
  return static_cast<double>(pnp.inliers) / pnp.used_correspondences;
}

Localizer::Localizer(const FastForwardModel& model, MapFile map) : model_(model), map_(std::move(map)) {
  if (map_.images.empty()) throw InputError("map: holds no images (build one with 'ffloc map')");
  const int64_t dim = model_.config().dust3r.enc_dim;
  if (map_.token_dim != dim)
    throw InputError("map: token width " + std::to_string(map_.token_dim) + " differs from the model's " +
                     std::to_string(dim) + " (built with another model)");
  const int patch = static_cast<int>(model_.config().dust3r.patch_size);
  for (const MapImage& image : map_.images) {
    if (image.grid_rows * patch != image.intrinsics.height || image.grid_cols * patch != image.intrinsics.width)
      throw InputError("map image '" + image.name + "': token grid " + std::to_string(image.grid_rows) + "x" +
                       std::to_string(image.grid_cols) + " does not match its " + std::to_string(image.intrinsics.width) +
                       "x" + std::to_string(image.intrinsics.height) + " preprocessed image at patch size " +
                       std::to_string(patch));
    descriptors_.push_back(image.descriptor);
  }
}

std::vector<size_t> Localizer::selectImages(const std::vector<float>& query_descriptor,
                                            const LocalizeOptions& options) const {
  switch (options.selection) {
    case ImageSelection::kRetrieval:
      return topKBySimilarity(descriptors_, query_descriptor, options.top_k);
    case ImageSelection::kUniform:
      return uniformSelection(map_.images.size(), options.top_k);
    case ImageSelection::kRandom:
      return randomSelection(map_.images.size(), options.top_k, options.seed);
  }
  return {};
}

QueryPrediction Localizer::predict(const cv::Mat& rgb, const Intrinsics& intrinsics, const std::string& name,
                                   const LocalizeOptions& options) const {
  if (options.top_k == 0) throw InputError("--top-k: must be positive");
  if (options.num_features <= 0) throw InputError("--features: must be positive");
  c10::InferenceMode inference;
  QueryPrediction out;

  auto start = Clock::now();
  const PreparedImage query = prepareImage(rgb, intrinsics, name, preprocessOptionsFor(model_, options.long_side));
  out.camera = query.camera;
  out.timings.preprocessing = secondsSince(start);

  start = Clock::now();
  const Dust3rEncoding encoding = encodeImage(model_, query);
  out.timings.encoding = secondsSince(start);

  start = Clock::now();
  const std::vector<float> descriptor = encodingDescriptor(encoding, options.descriptor);
  out.selected = selectImages(descriptor, options);
  out.timings.retrieval = secondsSince(start);

  start = Clock::now();
  std::vector<Pose> poses;
  std::vector<std::string> names;
  for (size_t index : out.selected) {
    poses.push_back(map_.images[index].camera_to_world);
    names.push_back(map_.images[index].name);
  }
  // The best-ranked image is P_0: the normalised frame is then centred where the query most
  // likely is.
  out.normalization = SceneNormalization::fromMappingPoses(poses, 0, names);

  const int patch = static_cast<int>(model_.config().dust3r.patch_size);
  const at::ScalarType dtype = model_.dust3r().backboneDtype();
  std::vector<Dust3rEncoding> images;
  std::vector<at::Tensor> rays;
  std::vector<int64_t> tokens_per_image;
  for (size_t index : out.selected) {
    const MapImage& image = map_.images[index];
    const int64_t count = static_cast<int64_t>(image.tokenCount());
    Dust3rEncoding encoded;
    encoded.tokens = at::from_blob(const_cast<uint16_t*>(image.tokens.data()), {1, count, map_.token_dim},
                                   at::TensorOptions().dtype(at::kHalf))
                         .to(dtype);
    encoded.positions = patchPositions(1, image.grid_rows, image.grid_cols, at::kCPU);
    encoded.height = static_cast<int64_t>(image.grid_rows) * patch;
    encoded.width = static_cast<int64_t>(image.grid_cols) * patch;
    images.push_back(std::move(encoded));
    rays.push_back(rayTensor(patchRays(image.intrinsics, out.normalization.normalize(image.camera_to_world), patch)));
    tokens_per_image.push_back(count);
  }
  const MapTokens map_tokens =
      gatherMapTokens(images, rays, sampleMapTokenIndices(tokens_per_image, options.num_features, options.seed));
  const FastForwardPrediction prediction = model_.forward(encoding, map_tokens);

  const at::Tensor points = prediction.query.pts3d[0].to(at::kDouble).contiguous();  // (H, W, 3)
  const at::Tensor confidence = prediction.query.conf[0].to(at::kFloat).contiguous();  // (H, W)
  const int64_t height = points.size(0), width = points.size(1);
  const double* xyz = points.data_ptr<double>();
  const float* conf = confidence.data_ptr<float>();
  const PreprocessGeometry& geometry = query.preprocessed.geometry;
  out.correspondences.reserve(static_cast<size_t>(height * width));
  for (int64_t y = 0; y < height; ++y) {
    for (int64_t x = 0; x < width; ++x) {
      const int64_t i = y * width + x;
      const Eigen::Vector3d normalized(xyz[3 * i], xyz[3 * i + 1], xyz[3 * i + 2]);
      if (!normalized.allFinite() || !std::isfinite(conf[i])) continue;
      out.correspondences.add(geometry.toOriginal(Eigen::Vector2d(static_cast<double>(x), static_cast<double>(y))),
                              out.normalization.toWorld(normalized), conf[i]);
    }
  }
  out.timings.decoding = secondsSince(start);
  return out;
}

LocalizationResult Localizer::localize(const cv::Mat& rgb, const Intrinsics& intrinsics, const std::string& name,
                                       const LocalizeOptions& options) const {
  LocalizationResult result;
  result.prediction = predict(rgb, intrinsics, name, options);
  result.pnp = estimatePose(result.prediction.correspondences, result.prediction.camera, options.pnp);
  result.prediction.timings.pnp = result.pnp.seconds;
  return result;
}

}  // namespace ffloc
