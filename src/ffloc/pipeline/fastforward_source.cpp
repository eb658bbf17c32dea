#include "ffloc/pipeline/fastforward_source.h"

#include <stdexcept>

#include "ffloc/core/error.h"
#include "ffloc/io/image.h"

namespace ffloc {

FastForwardSource::FastForwardSource(std::shared_ptr<const LoadedModel> model, FastForwardSourceOptions options)
    : model_(std::move(model)), options_(std::move(options)) {
  if (!model_ || !model_->model) throw std::invalid_argument("FastForwardSource: no model");
}

void FastForwardSource::prepare(const Scene& scene) {
  MapFile map;
  if (!options_.map_path.empty()) {
    map = readMapFile(options_.map_path, model_->id);
  } else {
    map = emptyMap(*model_, scene.metric);
    addToMap(map, *model_, scene, scene.mappingIndices(), options_.mapping);
  }
  localizer_ = std::make_unique<Localizer>(*model_->model, std::move(map));
}

const Localizer& FastForwardSource::localizer() const {
  if (!localizer_) throw std::logic_error("FastForwardSource: prepare() was not called");
  return *localizer_;
}

Correspondences FastForwardSource::correspondences(const Scene& scene, size_t query_index) {
  if (query_index >= scene.frames.size())
    throw InputError(scene.name + ": query index " + std::to_string(query_index) + " out of range");
  const Frame& frame = scene.frames[query_index];
  last_ = localizer().predict(readImageRgb(frame.image_path), frame.intrinsics, frame.name, options_.localize);
  return last_.correspondences;
}

}  // namespace ffloc
