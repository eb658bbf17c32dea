#include "ffloc/pipeline/mapper.h"

#include <ATen/core/Tensor.h>

#include <algorithm>
#include <chrono>
#include <cstring>
#include <map>
#include <optional>

#include "ffloc/classical/sift_features.h"
#include "ffloc/classical/vlad.h"
#include "ffloc/core/clock.h"
#include "ffloc/core/error.h"
#include "ffloc/core/ordered_parallel.h"
#include "ffloc/core/progress.h"
#include "ffloc/data/depth.h"
#include "ffloc/data/pose_check.h"
#include "ffloc/geometry/preprocess.h"
#include "ffloc/geometry/rays.h"
#include "ffloc/model/torch_threads.h"
#include "ffloc/pipeline/prepared_image.h"
#include "ffloc/pipeline/query_descriptor.h"
#include "ffloc/pipeline/token_vlad.h"

namespace ffloc {

MapImage encodeMappingImage(const FastForwardModel& model, const Frame& frame, const MappingOptions& options) {
  const PreparedImage prepared = prepareImage(readImageRgb(frame.image_path), frame.intrinsics, frame.name,
                                              preprocessOptionsFor(model, options.long_side));
  const Dust3rEncoding encoding = encodeImage(model, prepared);
  const int64_t patch = model.config().dust3r.patch_size;

  MapImage image;
  image.name = frame.name;
  image.camera_to_world = frame.camera_to_world;
  image.intrinsics = prepared.preprocessed.intrinsics;
  image.geometry = prepared.preprocessed.geometry;
  image.grid_rows = static_cast<int>(encoding.height / patch);
  image.grid_cols = static_cast<int>(encoding.width / patch);

  const at::Tensor tokens = encoding.tokens[0].to(at::kFloat).contiguous();  // (T, D)
  const at::Tensor half = tokens.to(at::kHalf).contiguous();
  std::vector<uint16_t> bits(static_cast<size_t>(half.numel()));
  std::memcpy(bits.data(), half.data_ptr(), bits.size() * sizeof(uint16_t));
  image.tokens = StoredTokens(std::move(bits));
  image.descriptor = encodingDescriptor(encoding, options.descriptor);
  const FastForwardConfig& config = model.config();
  if (frame.depth && config.usesTokenPoints()) {
    const cv::Mat1f depth = preprocessDepthNearest(readDepthMetres(frame), prepared.preprocessed.geometry);
    const std::vector<Eigen::Vector3d> points =
        patchCentrePoints(depth, image.intrinsics, frame.camera_to_world, static_cast<int>(patch));
    image.token_points.reserve(3 * points.size());
    for (const Eigen::Vector3d& point : points) {
      for (int c = 0; c < 3; ++c) image.token_points.push_back(static_cast<float>(point[c]));
    }
  }
  return image;
}

namespace {

int frameWorkers(const FastForwardModel& model, const MappingOptions& options) {
  if (options.frame_workers < 0) {
    throwInputError("mapping options", 0, "field 'frame_workers': must be at least 0 (0: chosen for the encoder)");
  }
  if (options.frame_workers > 0) return options.frame_workers;
  return model.config().encoder == TokenEncoderKind::kDenseSift ? torchThreadCount() : 1;
}

}  // namespace

MapFile emptyMap(const LoadedModel& model, bool metric) {
  MapFile map;
  map.model_id = model.id;
  map.token_dim = static_cast<int>(model.model->config().dust3r.enc_dim);
  map.metric = metric;
  return map;
}

MappingReport addToMap(MapFile& map, const LoadedModel& model, const Scene& scene, const std::vector<size_t>& frames,
                       const MappingOptions& options) {
  if (map.model_id != model.id)
    throw InputError("map: built with model '" + map.model_id + "', but the loaded model is '" + model.id +
                     "'; images encoded by different models cannot share a map");
  if (map.token_dim != model.model->config().dust3r.enc_dim)
    throw InputError("map: token width " + std::to_string(map.token_dim) + " differs from the model's " +
                     std::to_string(model.model->config().dust3r.enc_dim));
  if (!map.images.empty() && map.metric != scene.metric)
    throw InputError(scene.root.string() + ": dataset units (" + (scene.metric ? "metric" : "non-metric") +
                     ") differ from the map's (" + (map.metric ? "metric" : "non-metric") + ")");
  if (map.images.empty()) map.metric = scene.metric;
  // Found after every new image was encoded, and blamed on the first old image.
  if (options.vlad && map.vlad_centres.empty() && !map.images.empty())
    throw InputError("map: was built without VLAD descriptors, which an append cannot add to the images already in "
                     "it; rebuild it with MappingOptions::vlad");

  if (model.model->config().usesTokenPoints()) {
    const bool any_depth =
        std::any_of(frames.begin(), frames.end(), [&](size_t f) { return f < scene.frames.size() && scene.frames[f].depth; });
    if (!any_depth)
      throw InputError(scene.root.string() + ": the model (" + model.description +
                       ") places queries on its map tokens' 3D points, which come from the mapping frames' depth, and "
                       "no mapping frame of this dataset has depth: map it with the classical method");
  }
  std::map<std::string, Pose> mapped;
  std::map<std::string, const MapImage*> previous;  // the map's images before this append, by name
  for (const MapImage& image : map.images) {
    mapped.emplace(image.name, image.camera_to_world);
    previous.emplace(image.name, &image);
  }
  MappingReport report;
  std::vector<const Frame*> to_add;
  for (const size_t f : frames) {
    if (f >= scene.frames.size()) throw InputError("mapping: frame index " + std::to_string(f) + " out of range");
    const Frame& frame = scene.frames[f];
    if (const auto [found, added] = mapped.emplace(frame.name, frame.camera_to_world); added) {
      to_add.push_back(&frame);
    } else {
      requireSamePoseAsMapped(scene.root, frame.name, found->second, frame.camera_to_world);
      if (const auto image = previous.find(frame.name); image != previous.end()) {
        // The map holds the preprocessed camera and the size it was preprocessed from: the
        // frame's camera is compared through the same preprocessing.
        const PreprocessGeometry& geometry = image->second->geometry;
        Intrinsics stored = image->second->intrinsics;
        stored.width = geometry.original_width;
        stored.height = geometry.original_height;
        Intrinsics now = geometry.apply(frame.intrinsics.undistorted());
        now.width = frame.intrinsics.width;  // 0 where the reader does not know it
        now.height = frame.intrinsics.height;
        requireSameCameraAsMapped(scene.root, frame.name, stored, now);
      }
      ++report.skipped_duplicates;
    }
  }
  const auto start = std::chrono::steady_clock::now();
  ProgressBar progress("mapping " + scene.name, to_add.size(), options.quiet);
  const FastForwardModel& network = *model.model;
  const int workers = frameWorkers(network, options);
  forEachInOrder<MapImage>(
      to_add.size(), workers,
      [&](size_t i) {
        std::optional<SingleThreadedKernels> one_thread_per_frame;
        if (workers > 1) one_thread_per_frame.emplace();
        return encodeMappingImage(network, *to_add[i], options);
      },
      [&](size_t i, MapImage&& image) {
        if (network.config().usesTokenPoints() && image.token_points.empty()) ++report.added_without_points;
        map.images.push_back(std::move(image));
        ++report.added;
        progress.update(i + 1);
      });
  progress.finish();
  // Learnt once here rather than by every process's first query (1.5 s for redkitchen); an
  // append keeps it, as the classical map keeps its own.
  if (map.token_vocabulary.empty() && !map.images.empty()) map.token_vocabulary = TokenVlad::learnVocabulary(map);
  if (options.vlad || !map.vlad_centres.empty()) addVladRetrieval(map, scene, options.quiet);
  report.seconds = secondsSince(start);
  return report;
}

void addVladRetrieval(MapFile& map, const Scene& scene, bool quiet) {
  const bool appending = !map.vlad_centres.empty();
  if (!appending && !map.images.empty() && !map.images.front().vlad_descriptor.empty())
    throw InputError("map: has VLAD descriptors but no vocabulary");
  std::vector<size_t> missing;
  for (size_t i = 0; i < map.images.size(); ++i)
    if (map.images[i].vlad_descriptor.empty()) missing.push_back(i);
  if (appending && missing.size() == map.images.size()) return;
  if (!appending && missing.size() != map.images.size())
    throw InputError("map: was built without VLAD descriptors; rebuild it with MappingOptions::vlad to add VLAD retrieval");

  std::map<std::string, const Frame*> frames;
  for (const Frame& frame : scene.frames) frames[frame.name] = &frame;
  std::vector<cv::Mat> descriptors(missing.size());
  ProgressBar progress("VLAD features", missing.size(), quiet);
  for (size_t m = 0; m < missing.size(); ++m) {
    const auto frame = frames.find(map.images[missing[m]].name);
    if (frame == frames.end())
      throw InputError("map image '" + map.images[missing[m]].name + "': not in the dataset, so no VLAD descriptor");
    descriptors[m] = extractSiftFeatures(*frame->second).descriptors;
    progress.update(m + 1);
  }
  progress.finish();
  VladVocabulary vocabulary;
  if (appending) {
    VladVocabulary::RowMatrixXf centres =
        Eigen::Map<const VladVocabulary::RowMatrixXf>(map.vlad_centres.data(), map.vlad_centres.size() / 128, 128);
    vocabulary = VladVocabulary(std::move(centres));
  } else {
    std::vector<const cv::Mat*> training;
    for (const cv::Mat& d : descriptors) training.push_back(&d);
    vocabulary = VladVocabulary::train(training);
    if (vocabulary.empty()) throw InputError(scene.root.string() + ": no mapping image has SIFT features for VLAD");
    map.vlad_centres.assign(vocabulary.centres().data(), vocabulary.centres().data() + vocabulary.centres().size());
  }
  for (size_t m = 0; m < missing.size(); ++m) {
    const Eigen::VectorXf v = vocabulary.describe(descriptors[m]);
    map.images[missing[m]].vlad_descriptor.assign(v.data(), v.data() + v.size());
  }
}

}  // namespace ffloc
