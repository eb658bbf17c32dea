#include "ffloc/pipeline/mapper.h"

#include <ATen/core/Tensor.h>

#include <chrono>
#include <cstring>
#include <set>

#include "ffloc/core/error.h"
#include "ffloc/core/progress.h"
#include "ffloc/pipeline/prepared_image.h"
#include "ffloc/pipeline/query_descriptor.h"

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
  image.tokens.resize(static_cast<size_t>(half.numel()));
  std::memcpy(image.tokens.data(), half.data_ptr(), image.tokens.size() * sizeof(uint16_t));
  image.descriptor = encodingDescriptor(encoding, options.descriptor);
  return image;
}

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

  std::set<std::string> names;
  for (const MapImage& image : map.images) names.insert(image.name);
  MappingReport report;
  const auto start = std::chrono::steady_clock::now();
  ProgressBar progress("mapping " + scene.name, frames.size(), options.quiet);
  for (size_t i = 0; i < frames.size(); ++i) {
    if (frames[i] >= scene.frames.size())
      throw InputError("mapping: frame index " + std::to_string(frames[i]) + " out of range");
    const Frame& frame = scene.frames[frames[i]];
    if (!names.insert(frame.name).second) {
      ++report.skipped_duplicates;
    } else {
      map.images.push_back(encodeMappingImage(*model.model, frame, options));
      ++report.added;
    }
    progress.update(i + 1);
  }
  progress.finish();
  report.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return report;
}

}  // namespace ffloc
