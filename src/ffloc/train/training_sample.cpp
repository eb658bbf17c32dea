#include "ffloc/train/training_sample.h"

#include <ATen/ops/from_blob.h>
#include <ATen/ops/zeros.h>

#include <algorithm>
#include <cmath>
#include <numeric>
#include <set>

#include "ffloc/core/error.h"
#include "ffloc/core/number_text.h"
#include "ffloc/core/random.h"
#include "ffloc/data/depth.h"
#include "ffloc/data/overlap.h"
#include "ffloc/geometry/preprocess.h"
#include "ffloc/geometry/rays.h"
#include "ffloc/model/map_assembly.h"
#include "ffloc/model/image_tensor.h"

namespace ffloc {

namespace {

// Brightness, contrast and saturation factors in [1 - strength, 1 + strength], in that order.
cv::Mat jitterColour(const cv::Mat& rgb, double strength, Rng& rng) {
  if (strength <= 0) return rgb;
  const double brightness = 1 + strength * (2 * rng.uniform() - 1);
  const double contrast = 1 + strength * (2 * rng.uniform() - 1);
  const double saturation = 1 + strength * (2 * rng.uniform() - 1);
  cv::Mat3f image;
  rgb.convertTo(image, CV_32FC3, brightness);
  const cv::Scalar mean = cv::mean(image);
  const float grey_mean = static_cast<float>((mean[0] + mean[1] + mean[2]) / 3);
  for (int y = 0; y < image.rows; ++y) {
    for (int x = 0; x < image.cols; ++x) {
      cv::Vec3f& p = image(y, x);
      for (int c = 0; c < 3; ++c) p[c] = static_cast<float>((p[c] - grey_mean) * contrast + grey_mean);
      const float grey = (p[0] + p[1] + p[2]) / 3;
      for (int c = 0; c < 3; ++c) p[c] = static_cast<float>((p[c] - grey) * saturation + grey);
    }
  }
  cv::Mat out;
  image.convertTo(out, CV_8UC3);  // saturating
  return out;
}

Eigen::Vector3d normalizedPoint(const Frame& frame, const SceneNormalization& normalization, double u, double v,
                                double depth) {
  return normalization.normalize(frame.camera_to_world * frame.intrinsics.backproject({u, v}, depth));
}

// The preprocessed size of a width x height image; none when it holds no whole patch.
std::optional<PreprocessGeometry> preprocessedSize(int width, int height, int long_side, int patch_size) {
  PreprocessOptions preprocess;
  preprocess.long_side = long_side;
  preprocess.patch_size = patch_size;
  try {
    return preprocessGeometry(width, height, preprocess);
  } catch (const InputError&) {
    return std::nullopt;
  }
}

}  // namespace

TrainingSampler::TrainingSampler(std::vector<Scene> scenes, const SampleOptions& options, std::string name)
    : scenes_(std::move(scenes)), options_(options), name_(std::move(name)) {
  size_t total = 0;
  for (const Scene& scene : scenes_) {
    std::vector<size_t> with_depth;
    for (size_t i = 0; i < scene.frames.size(); ++i) {
      const Frame& frame = scene.frames[i];
      if (!frame.depth) continue;
      if (frame.intrinsics.hasDistortion()) {
        throwInputError(scene.root.string(), 0, "frame '" + frame.name +
                                                    "': training needs undistorted images and depth");
      }
      with_depth.push_back(i);
    }
    // A scene without depth beside one with it was never drawn, without a word (found by an
    // outside probe); alone it was refused.
    if (with_depth.empty())
      throwInputError(scene.root.string(), 0, "no frame has depth, which training needs; leave the dataset out");
    // A scene whose depth holds no valid value was skipped by every draw, without a word, while
    // other scenes trained: three frames across it are read now.
    {
      bool any_valid = false;
      std::string read;
      // A set: a scene of one or two frames with depth has each read once.
      for (const size_t i : std::set<size_t>{with_depth.front(), with_depth[with_depth.size() / 2], with_depth.back()}) {
        const cv::Mat1f depth = readDepthMetres(scene.frames[i]);
        any_valid = any_valid || cv::countNonZero(depth > 0) > 0;
        read += (read.empty() ? "" : ", ") + scene.frames[i].name;
      }
      if (!any_valid) {
        throwInputError(scene.root.string(), 0, "the depth of its frames holds no valid value (read: " + read +
                                                    "); training needs depth");
      }
    }
    // Found at the first draw, the error named neither the field nor the dataset.
    const Intrinsics& first = scene.frames[with_depth.front()].intrinsics;
    if (first.width > 0 && first.height > 0) {
      const auto size = preprocessedSize(first.width, first.height, options_.long_side, options_.patch_size);
      if (!size) {
        int enough = options_.long_side;
        while (enough < 100000 && !preprocessedSize(first.width, first.height, enough, options_.patch_size)) ++enough;
        throwInputError(scene.root.string(), 0, "field 'long_side': " + std::to_string(options_.long_side) +
                                                    " leaves its " + std::to_string(first.width) + "x" +
                                                    std::to_string(first.height) + " images no whole " +
                                                    std::to_string(options_.patch_size) +
                                                    "-pixel patch; use at least " + std::to_string(enough));
      }
      // A stride past a quarter of the short side measures a handful of pixels, and every draw
      // failed "on overlap" (found by an outside probe: 64 on 64 x 48 measured one).
      const int most = std::max(1, std::min(size->width, size->height) / 4);
      if (options_.overlap_stride > most)
        throwInputError(scene.root.string(), 0, "field 'overlap_stride': " + std::to_string(options_.overlap_stride) +
                                                    " measures too few pixels of its " + std::to_string(size->width) +
                                                    "x" + std::to_string(size->height) +
                                                    " preprocessed images; use at most " + std::to_string(most));
    }
    total += with_depth.size();
    frames_with_depth_.push_back(std::move(with_depth));
  }
  if (total == 0) throwInputError(source(), 0, "no scene to train on");
}

std::string TrainingSampler::source() const {
  std::string folders;
  for (const Scene& scene : scenes_) folders += (folders.empty() ? "" : ", ") + scene.root.string();
  return folders.empty() ? name_ : name_ + " (" + folders + ")";
}

const TrainingSampler::PreparedFrame& TrainingSampler::prepared(size_t scene, size_t frame) {
  {
    const std::lock_guard<std::mutex> lock(cache_mutex_);
    const auto found = prepared_.find({scene, frame});
    if (found != prepared_.end()) return *found->second;
  }
  // Prepared outside the lock so that loader threads work in parallel; a frame two threads
  // prepare at once comes out the same, and the first one stored is kept.
  std::unique_ptr<PreparedFrame> entry;
  {
    const Frame& source = scenes_[scene].frames[frame];
    PreprocessOptions preprocess;
    preprocess.long_side = options_.long_side;
    preprocess.patch_size = options_.patch_size;
    PreprocessedImage image = preprocessImage(readImageRgb(source.image_path), source.intrinsics, preprocess);
    const cv::Mat1f depth = readDepthMetres(source);
    if (depth.cols != image.geometry.original_width || depth.rows != image.geometry.original_height) {
      throwInputError(source.depth->path.string(), 0, "depth size differs from the image of '" + source.name + "'");
    }
    entry = std::make_unique<PreparedFrame>();
    entry->rgb = image.rgb;
    entry->frame = source;
    entry->frame.intrinsics = image.intrinsics;
    entry->depth = preprocessDepthNearest(depth, image.geometry);
  }
  const std::lock_guard<std::mutex> lock(cache_mutex_);
  auto& slot = prepared_[{scene, frame}];
  if (!slot) slot = std::move(entry);
  return *slot;
}

double TrainingSampler::overlap(size_t scene, size_t a, size_t b) {
  const auto key = std::make_tuple(scene, std::min(a, b), std::max(a, b));
  {
    const std::lock_guard<std::mutex> lock(cache_mutex_);
    const auto found = overlaps_.find(key);
    if (found != overlaps_.end()) return found->second;
  }
  const PreparedFrame& first = prepared(scene, std::get<1>(key));
  const PreparedFrame& second = prepared(scene, std::get<2>(key));
  OverlapOptions overlap_options;
  overlap_options.stride = options_.overlap_stride;
  const double value = pairOverlap(first.frame, first.depth, second.frame, second.depth, overlap_options);
  const std::lock_guard<std::mutex> lock(cache_mutex_);
  overlaps_[key] = value;
  return value;
}

int64_t TrainingSampler::mapTokenCount(uint64_t seed) const {
  Rng rng(seed);
  return rng.between(options_.min_map_tokens, options_.max_map_tokens);
}

std::optional<TrainingSampler::Draw> TrainingSampler::tryQuery(size_t scene, size_t query, Rng& rng) {
  std::vector<size_t> candidates;
  for (const size_t f : frames_with_depth_[scene]) {
    if (f != query) candidates.push_back(f);
  }
  for (size_t i = candidates.size(); i > 1; --i) std::swap(candidates[i - 1], candidates[rng.below(i)]);
  candidates.resize(std::min(candidates.size(), static_cast<size_t>(options_.overlap_candidates)));
  Draw draw{scene, query, {}, {}};
  for (const size_t f : candidates) {
    const double value = overlap(scene, query, f);
    if (value < options_.min_overlap || value > options_.max_overlap) continue;
    draw.mapping.push_back(f);
    draw.overlaps.push_back(value);
    if (draw.mapping.size() == static_cast<size_t>(options_.mapping_frames)) return draw;
  }
  return std::nullopt;
}

TrainingSample TrainingSampler::sample(uint64_t seed, int64_t map_tokens) {
  Rng rng(seed);
  std::vector<size_t> usable_scenes;
  for (size_t s = 0; s < scenes_.size(); ++s) {
    if (frames_with_depth_[s].size() > static_cast<size_t>(options_.mapping_frames)) usable_scenes.push_back(s);
  }
  if (usable_scenes.empty()) {
    throwInputError(source(), 0, "no scene has more than " + std::to_string(options_.mapping_frames) +
                                            " frames with depth (query + mapping frames)");
  }
  // Random queries first; when they all fail, every query of every scene in an order drawn from the
  // seed, so that a scene where few queries qualify stops no run mid-way (an outside probe's run
  // died at a later step on an unlucky draw) and one where none does fails at the first draw.
  std::optional<Draw> draw;
  for (int attempt = 0; attempt < options_.max_attempts && !draw; ++attempt) {
    const size_t scene = usable_scenes[rng.below(usable_scenes.size())];
    const std::vector<size_t>& frames = frames_with_depth_[scene];
    draw = tryQuery(scene, frames[rng.below(frames.size())], rng);
  }
  if (!draw) {
    std::vector<std::pair<size_t, size_t>> queries;
    for (const size_t scene : usable_scenes)
      for (const size_t frame : frames_with_depth_[scene]) queries.emplace_back(scene, frame);
    for (size_t i = queries.size(); i > 1; --i) std::swap(queries[i - 1], queries[rng.below(i)]);
    for (size_t i = 0; i < queries.size() && !draw; ++i) draw = tryQuery(queries[i].first, queries[i].second, rng);
  }
  if (!draw) {
    // The others a query is compared with: its scene's other frames with depth, at most
    // overlap_candidates (a scene of 15 frames was said to have 64).
    size_t others = 0;
    for (const size_t scene : usable_scenes) others = std::max(others, frames_with_depth_[scene].size() - 1);
    others = std::min(others, static_cast<size_t>(options_.overlap_candidates));
    throwInputError(source(), 0, "no frame has " + std::to_string(options_.mapping_frames) +
                                     " mapping frames of overlap in [" + formatNumber(options_.min_overlap) + ", " +
                                     formatNumber(options_.max_overlap) + "] among " +
                                     (usable_scenes.size() > 1 ? "up to " : "") + std::to_string(others) +
                                     " others (every frame with depth tried as the query); widen min_overlap and "
                                     "max_overlap or lower mapping_frames");
  }
  const size_t scene = draw->scene, query = draw->query;
  const std::vector<size_t>& mapping = draw->mapping;
  const std::vector<double>& overlaps = draw->overlaps;

  TrainingSample out;
  const Scene& source = scenes_[scene];
  out.scene = source.name;
  out.query = source.frames[query].name;
  out.overlaps = overlaps;
  std::vector<const PreparedFrame*> mapping_frames;
  std::vector<MapCamera> cameras;
  for (size_t f : mapping) {
    const PreparedFrame& m = prepared(scene, f);
    mapping_frames.push_back(&m);
    cameras.push_back({m.frame.name, m.frame.camera_to_world, m.frame.intrinsics});
    out.mapping.push_back(m.frame.name);
  }
  const int patch = options_.patch_size;
  out.layout = planMap(cameras, patch, map_tokens, rng.next());

  // Query image and per-pixel ground truth.
  const PreparedFrame& q = prepared(scene, query);
  out.query_camera = q.frame.intrinsics;
  out.query_pose = q.frame.camera_to_world;
  out.query_image = normalizedImageTensor(jitterColour(q.rgb, options_.colour_jitter, rng));
  const int height = q.depth.rows, width = q.depth.cols;
  out.query_points = at::zeros({1, height, width, 3}, at::kFloat);
  out.query_valid = at::zeros({1, height, width}, at::kBool);
  float* points = out.query_points.data_ptr<float>();
  bool* valid = out.query_valid.data_ptr<bool>();
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      const float d = q.depth(y, x);
      if (d <= 0) continue;
      const Eigen::Vector3d p = normalizedPoint(q.frame, out.layout.normalization, x, y, d);
      const size_t i = static_cast<size_t>(y) * width + x;
      for (int c = 0; c < 3; ++c) points[3 * i + c] = static_cast<float>(p[c]);
      valid[i] = true;
    }
  }

  // Mapping images and the ground truth of the sampled tokens.
  for (const PreparedFrame* m : mapping_frames) {
    out.mapping_images.push_back(normalizedImageTensor(jitterColour(m->rgb, options_.colour_jitter, rng)));
  }
  const int64_t n = out.layout.indices.size(0);
  out.map_points = at::zeros({1, n, 3}, at::kFloat);
  out.map_valid = at::zeros({1, n}, at::kBool);
  const int64_t* pairs = out.layout.indices.data_ptr<int64_t>();
  float* map_points = out.map_points.data_ptr<float>();
  bool* map_valid = out.map_valid.data_ptr<bool>();
  std::vector<std::vector<Eigen::Vector3d>> patch_points;
  for (const PreparedFrame* m : mapping_frames) {
    patch_points.push_back(patchCentrePoints(m->depth, m->frame.intrinsics, m->frame.camera_to_world, patch));
  }
  for (int64_t i = 0; i < n; ++i) {
    const Eigen::Vector3d& world = patch_points[pairs[2 * i]][pairs[2 * i + 1]];
    if (!world.allFinite()) continue;
    const Eigen::Vector3d p = out.layout.normalization.normalize(world);
    for (int c = 0; c < 3; ++c) map_points[3 * i + c] = static_cast<float>(p[c]);
    map_valid[i] = true;
  }
  return out;
}

}  // namespace ffloc
