#pragma once

#include <filesystem>
#include <functional>
#include <memory>
#include <string>

#include "ffloc/classical/classical_mapper.h"
#include "ffloc/data/scene.h"
#include "ffloc/localization/localizer.h"
#include "ffloc/model/model_loader.h"
#include "ffloc/pipeline/mapper.h"

namespace ffloc {

// What `ffloc map` and the Python build_map do: a map file of a scene's mapping split, with one
// method.
struct MapBuildOptions {
  LocalizationMethod method = LocalizationMethod::kClassical;
  ClassicalMappingOptions classical;
  MappingOptions fastforward;
  // Add to the map already at the output (same method, and model), which must exist: its images
  // stay as they are, frames whose name it holds are skipped.
  bool append = false;
};

// Which of the options that apply to one method only, or not to an append, a caller set (a
// flag given, a keyword passed), by their library names: model, dtype, vlad, use_depth,
// max_image_size, max_features.
using SetMapBuildOptions = std::vector<std::string>;

// The first of `set` that a build with `options` would ignore, as "<name>: why", or "": the user
// expects an option to act (a classical map takes no model, keeps its VLAD, and an append keeps
// the SIFT settings the map was built with).
std::string ignoredOptionProblem(const MapBuildOptions& options, const SetMapBuildOptions& set);

struct MapBuildReport {
  size_t previous_images = 0;  // in the map appended to
  size_t images = 0;           // in the written map
  size_t added = 0;
  size_t skipped_duplicates = 0;
  std::vector<std::string> featureless;  // classical: images left out with fewer than two keypoints
  size_t points = 0;               // classical
  size_t points_from_depth = 0;    // classical: of `points`, lifted with depth; the others triangulated
  size_t links = 0;                // classical
  size_t added_without_points = 0;  // fastforward: MappingReport's
  double seconds = 0;
  bool every_frame = false;  // the scene has no split (hasNoSplit), so every frame was mapped
};

// Maps scene.mappingIndices(), or every frame of a scene without a split, and writes the map to `output` atomically. `load_model` runs only
// for FastForward. InputError naming the dataset when it has no mapping frame, naming the
// output when appending to a map that is missing or of another method, or when it exists and is
// not a map (only maps are replaced). An output that is a symbolic link writes (and appends to) the map it points to.
MapBuildReport buildMap(const Scene& scene, const std::filesystem::path& output, const MapBuildOptions& options,
                        const std::function<LoadedModel()>& load_model);

// A FastForward localizer over a map of the scene's mapping split held in memory (ffloc eval,
// the Python evaluate). `model` must outlive it.
std::unique_ptr<Localizer> inMemoryFastForwardLocalizer(const LoadedModel& model, const Scene& scene,
                                                        const MappingOptions& options);

}  // namespace ffloc
