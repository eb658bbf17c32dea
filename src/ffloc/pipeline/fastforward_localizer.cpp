#include "ffloc/geometry/preprocess.h"
#include "ffloc/pipeline/fastforward_localizer.h"

#include <ATen/core/Tensor.h>
#include <ATen/ops/empty.h>
#include <ATen/ops/from_blob.h>
#include <ATen/ops/full.h>
#include <c10/core/InferenceMode.h>

#include <chrono>
#include <cmath>
#include <future>

#include "ffloc/classical/sift_features.h"
#include "ffloc/core/clock.h"
#include "ffloc/core/error.h"
#include "ffloc/model/map_assembly.h"
#include "ffloc/model/torch_threads.h"
#include "ffloc/pipeline/prepared_image.h"
#include "ffloc/pipeline/query_descriptor.h"

namespace ffloc {
namespace {

using Clock = std::chrono::steady_clock;

}  // namespace

struct EncodedQuery {
  PreparedImage image;
  Dust3rEncoding encoding;
  std::vector<size_t> ranked;  // map images by retrieval, best first
};

FastForwardLocalizer::FastForwardLocalizer(const FastForwardModel& model, MapFile map) : model_(model), map_(std::move(map)) {
  if (map_.images.empty()) throw InputError("map: holds no images");
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
    cameras_.push_back({image.name, image.camera_to_world, image.intrinsics});
  }
  if (!map_.vlad_centres.empty()) {
    vlad_ = VladVocabulary(Eigen::Map<const VladVocabulary::RowMatrixXf>(map_.vlad_centres.data(),
                                                                          map_.vlad_centres.size() / 128, 128));
    for (const MapImage& image : map_.images)
      vlad_descriptors_.push_back(Eigen::Map<const Eigen::VectorXf>(image.vlad_descriptor.data(), image.vlad_descriptor.size()));
  }
}

FastForwardLocalizer::~FastForwardLocalizer() = default;

std::vector<size_t> FastForwardLocalizer::selectImages(const std::vector<float>& query_descriptor,
                                                       const LocalizeOptions& options,
                                                       const std::vector<size_t>* vlad_ranking) const {
  switch (options.selection) {
    case ImageSelection::kRetrieval:
      if (vlad_ranking) {
        std::vector<size_t> top(*vlad_ranking);
        if (top.size() > options.top_k) top.resize(options.top_k);
        return top;
      }
      return topKBySimilarity(descriptors_, query_descriptor, options.top_k);
    case ImageSelection::kUniform:
      return uniformSelection(map_.images.size(), options.top_k);
    case ImageSelection::kRandom:
      return randomSelection(map_.images.size(), options.top_k, options.seed);
  }
  return {};
}

EncodedQuery FastForwardLocalizer::encode(const cv::Mat& rgb, const Intrinsics& intrinsics, const std::string& name,
                                          const LocalizeOptions& options, QueryTimings& timings) const {
  auto start = Clock::now();
  EncodedQuery query{prepareImage(rgb, intrinsics, name, preprocessOptionsFor(model_, options.long_side)), {}, {}};
  timings.preprocessing = secondsSince(start);

  start = Clock::now();
  query.encoding = encodeImage(model_, query.image);
  timings.features = secondsSince(start);

  start = Clock::now();
  const std::vector<float> descriptor = encodingDescriptor(query.encoding, options.descriptor);
  if (options.retrieval == FastForwardRetrieval::kVlad) {
    if (vlad_.empty()) throw InputError("retrieval: the map has no VLAD descriptors (build it with MappingOptions::vlad)");
    const std::vector<size_t> ranking =
        rankBySimilarity(vlad_descriptors_, vlad_.describe(extractSiftFeatures(rgb, intrinsics, name).descriptors));
    query.ranked = selectImages(descriptor, options, &ranking);
  } else if (options.retrieval == FastForwardRetrieval::kTokenVlad) {
    std::call_once(token_vlad_learned_, [this] { token_vlad_.emplace(map_); });
    const std::vector<size_t> ranking =
        rankBySimilarity(token_vlad_->imageDescriptors(), token_vlad_->describe(query.encoding.tokens));
    query.ranked = selectImages(descriptor, options, &ranking);
  } else {
    query.ranked = selectImages(descriptor, options);
  }
  timings.retrieval = secondsSince(start);
  return query;
}

namespace {

// A map image's token points in the query's normalised frame, (1, T, 3) with NaN where a token has
// none (all NaN for an image mapped without depth).
at::Tensor normalizedTokenPoints(const MapImage& image, const SceneNormalization& normalization) {
  const int64_t count = static_cast<int64_t>(image.tokenCount());
  if (image.token_points.empty()) return at::full({1, count, 3}, NAN, at::kFloat);
  at::Tensor out = at::empty({1, count, 3}, at::kFloat);
  float* data = out.data_ptr<float>();
  for (int64_t i = 0; i < count; ++i) {
    const Eigen::Vector3d world(image.token_points[3 * i], image.token_points[3 * i + 1], image.token_points[3 * i + 2]);
    const Eigen::Vector3d point = world.allFinite() ? normalization.normalize(world) : world;
    for (int c = 0; c < 3; ++c) data[3 * i + c] = static_cast<float>(point[c]);
  }
  return out;
}

}  // namespace

void FastForwardLocalizer::decode(const EncodedQuery& query, const std::vector<size_t>& selected, uint64_t seed,
                                  const LocalizeOptions& options, QueryPrediction& out) const {
  out.camera = query.image.camera;
  out.selected = selected;
  std::vector<MapCamera> cameras;
  for (size_t index : selected) {
    const MapImage& image = map_.images[index];
    cameras.push_back({image.name, image.camera_to_world, image.intrinsics});
  }
  const int patch = static_cast<int>(model_.config().dust3r.patch_size);
  // The first image is P_0: the normalised frame is then centred where the query most likely is.
  const MapLayout layout = planMap(cameras, patch, options.num_features, seed);
  out.normalization = layout.normalization;

  const at::ScalarType dtype = model_.dust3r().backboneDtype();
  std::vector<Dust3rEncoding> images;
  const bool uses_points = model_.config().usesTokenPoints();
  std::vector<at::Tensor> points;  // per image, normalised, for a model that reads them
  for (size_t index : selected) {
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
    if (uses_points) points.push_back(normalizedTokenPoints(image, layout.normalization));
  }
  const MapTokens map_tokens = assembleMapTokens(layout, images, points);
  // A sample of a few tokens (num_features 5) may hold none with a point, though the map has
  // depth: the matching head then places nothing, and the query has no pairs (failed) rather
  // than the map being called one without depth.
  if (model_.config().query_head == QueryHeadKind::kMatching && !map_tokens.point_valid.any().item<bool>()) return;
  const FastForwardPrediction prediction =
      model_.forward(query.encoding, map_tokens, nullptr, FastForwardOutputs::kQuery);
  out.correspondences = queryCorrespondences(prediction.query, 0, out.normalization, model_.config().queryGridStride(),
                                             &query.image.preprocessed.geometry);
}

QueryPrediction FastForwardLocalizer::predictCoordinates(const cv::Mat& rgb, const Intrinsics& intrinsics,
                                                         const std::string& name, const LocalizeOptions& options) const {
  options.check();
  c10::InferenceMode inference;
  QueryPrediction out;
  const EncodedQuery query = encode(rgb, intrinsics, name, options, out.timings);
  stopIfRequested(options, "after the encoder");
  const auto start = Clock::now();
  decode(query, query.ranked, options.seed, options, out);
  out.timings.matching = secondsSince(start);
  return out;
}

void FastForwardLocalizer::predict(const cv::Mat& rgb, const Intrinsics& intrinsics, const std::string& name,
                                   const LocalizeOptions& options, LocalizationResult& result,
                                   std::optional<PnpResult>& second_estimate, PoseGuidedLooks& /*pose_guided*/) const {
  c10::InferenceMode inference;
  QueryPrediction first;
  const EncodedQuery query = encode(rgb, intrinsics, name, options, first.timings);
  stopIfRequested(options, "after the encoder");
  const bool verify = options.verify_with_second_reference && query.ranked.size() >= 2;
  // The second pass (the verdict's reference: P_0 and P_1 swapped, its own PnP) does not depend on
  // the first. With two or more threads the two run side by side, each on one thread: their
  // products are too small to gain much from a second thread (one pass: 1.35x), two passes at once
  // nearly 2x.
  const bool side_by_side = verify && torchThreadCount() >= 2;
  const auto secondEstimate = [&] {
    c10::InferenceMode inference_on_this_thread;
    std::optional<SingleThreadedKernels> one_thread_for_this_pass;
    if (side_by_side) one_thread_for_this_pass.emplace();
    std::vector<size_t> swapped = query.ranked;
    std::swap(swapped[0], swapped[1]);
    QueryPrediction other;
    decode(query, swapped, options.seed + 1, options, other);
    PnpOptions pnp = options.pnp;
    pnp.seed = options.pnp.seed + 1;
    return estimatePose(other.correspondences, other.camera, pnp);
  };
  std::optional<SingleThreadedKernels> one_thread_for_the_first_pass;
  if (side_by_side) one_thread_for_the_first_pass.emplace();
  const auto start = Clock::now();
  std::future<PnpResult> beside;
  if (side_by_side) beside = std::async(std::launch::async, secondEstimate);
  decode(query, query.ranked, options.seed, options, first);
  first.timings.matching = secondsSince(start);
  if (side_by_side) {
    second_estimate = beside.get();
  } else if (verify) {
    stopIfRequested(options, "after the first network pass");
    second_estimate = secondEstimate();
  }
  // What verification added to the query's time, so that the stages still sum to it.
  if (verify) first.timings.verification = secondsSince(start) - first.timings.matching;
  result.correspondences = std::move(first.correspondences);
  result.camera = first.camera;
  result.selected = first.selected;
  result.timings = first.timings;
}

}  // namespace ffloc
