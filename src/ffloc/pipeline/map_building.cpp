#include "ffloc/pipeline/map_building.h"

#include <iostream>

#include "ffloc/core/error.h"
#include "ffloc/core/writer_lock.h"
#include "ffloc/core/utf8.h"
#include "ffloc/core/file_paths.h"
#include "ffloc/data/splits.h"
#include "ffloc/io/map_file.h"
#include "ffloc/pipeline/fastforward_localizer.h"

namespace ffloc {

namespace {

bool appendsTo(const std::filesystem::path& output, const MapBuildOptions& options) {
  if (!options.append) return false;
  // A mistyped path made a new map of the dataset alone, and said it had appended.
  if (!std::filesystem::exists(output))
    throwInputError(output.string(), 0, "append: no map to append to (build it without append first)");
  MapHeader header;
  try {
    header = readMapHeader(output);
  } catch (const InputError& error) {
    // Said before: "exists and is not an ffloc map, so it is not replaced", to a user who asked
    // for no replacement.
    throwInputError(output.string(), 0,
                    "append: the map cannot be read, so nothing is appended and the file is left as it is (" +
                        withoutFileName(error.what(), output.string()) + ")");
  }
  if (header.method != toString(options.method))
    throwInputError(output.string(), 0, "append: the map was built with the " + header.method + " method, not " +
                                            toString(options.method) + " (method)");
  return true;
}

// Said by the mappers without the map file or the word append (found by an outside probe).
void requireUnitsOfTheMap(const std::filesystem::path& output, bool map_metric, const Scene& scene) {
  if (map_metric == scene.metric) return;
  const auto units = [](bool metric) { return metric ? "metric" : "not metric"; };
  throwInputError(output.string(), 0,
                  std::string("append: the map is ") + units(map_metric) + " and the dataset '" + scene.root.string() +
                      "' is " + units(scene.metric) + ": an append adds images in the map's units; map it on its own");
}

// Only a map is replaced: an output path typed by mistake must not overwrite a dataset's
// manifest or one of its images.
void requireReplaceable(const std::filesystem::path& output) {
  if (!std::filesystem::exists(output)) return;
  try {
    readMapHeader(output);
  } catch (const InputError& error) {
    throwInputError(output.string(), 0, std::string("exists and is not an ffloc map, so it is not replaced: write the "
                                                    "map to another path, or remove the file first (") +
                                            error.what() + ")");
  }
}

}  // namespace

std::string ignoredOptionProblem(const MapBuildOptions& options, const SetMapBuildOptions& set) {
  const bool classical = options.method == LocalizationMethod::kClassical;
  for (const std::string& name : set) {
    if (classical && (name == "model" || name == "dtype"))
      return name + ": the classical method uses no network; build with the fastforward method";
    if (classical && name == "vlad")
      return "vlad: a classical map always holds its VLAD descriptors; vlad is for the fastforward method";
    const bool sift = name == "max_image_size" || name == "max_features";
    if (!classical && (sift || name == "use_depth"))
      return name + ": applies to the classical method only, not " + toString(options.method);
    if (options.append && sift) return name + ": a map appended to keeps the SIFT settings it was built with";
  }
  return "";
}

MapBuildReport buildMap(const Scene& scene, const std::filesystem::path& named_output, const MapBuildOptions& options,
                        const std::function<LoadedModel()>& load_model) {
  // An append through a link replaced the link with a new map and left the map it named as it was.
  const std::filesystem::path output = followSymlinks(named_output);
  // A COLMAP model or a SLAM export has no split, and its user's first command maps all of it
  // (an outside review found no way to, short of converting and editing the copy).
  const bool every_frame = hasNoSplit(scene);
  if (!every_frame) requireSplit(scene, Split::kMapping);  // as evaluation says it, with what the split files list
  std::vector<size_t> frames = scene.mappingIndices();
  if (every_frame)
    for (size_t i = 0; i < scene.frames.size(); ++i) frames.push_back(i);
  // Map files store image names as JSON text, which must be UTF-8: refused here, not when the
  // map is written after all the work.
  for (const size_t index : frames) {
    const Frame& frame = scene.frames[index];
    if (!isUtf8(frame.name))
      throwInputError(frame.image_path.string(), 0,
                      "image name '" + frame.name + "' is not UTF-8, which a map file (JSON) cannot hold; rename the file");
  }
  // Held from reading the map appended to until the new one is renamed into place: two runs
  // appending at once each started from the same old map, and the later rename dropped the
  // earlier run's images while both reported them added.
  const bool quiet = options.method == LocalizationMethod::kClassical ? options.classical.quiet : options.fastforward.quiet;
  if (options.method == LocalizationMethod::kClassical) options.classical.check();
  const auto checkOutput = [&] {
    const bool append = appendsTo(output, options);
    if (!append) requireReplaceable(output);
    return append;
  };
  // Before the lock too: each refused run left the lock file it made beside its target, inside
  // the dataset's own folder for a mistyped -o (found by an outside probe). Again under the
  // lock, as the file may change while this run waits for it.
  checkOutput();
  // The model too, for the same reason: a missing --model left the lock file of a map never written.
  const std::optional<LoadedModel> model =
      options.method == LocalizationMethod::kClassical ? std::nullopt : std::optional<LoadedModel>(load_model());
  const WriterLock lock(output, [&] {
    if (!quiet) std::cerr << "waiting: another ffloc is writing " << output.string() << "\n";
  });
  const bool append = checkOutput();
  MapBuildReport report;
  report.every_frame = every_frame;
  if (options.method == LocalizationMethod::kClassical) {
    ClassicalMap map = emptyClassicalMap(scene.metric, options.classical);
    if (append) {
      map = readClassicalMap(output);
      requireUnitsOfTheMap(output, map.metric, scene);
    }
    report.previous_images = map.images.size();
    const ClassicalMappingReport added = addToClassicalMap(map, scene, frames, options.classical);
    writeClassicalMap(map, output);
    report.images = map.images.size();
    report.added = added.added;
    report.skipped_duplicates = added.skipped_duplicates;
    report.featureless = added.featureless;
    report.points = added.points;
    report.points_from_depth = added.points_from_depth;
    report.links = added.links;
    report.seconds = added.seconds;
    return report;
  }
  MapFile map = emptyMap(*model, scene.metric);
  if (append) {
    map = readMapFile(output, model->id);
    requireUnitsOfTheMap(output, map.metric, scene);
  }
  report.previous_images = map.images.size();
  const MappingReport added = [&] {
    try {
      return addToMap(map, *model, scene, frames, options.fastforward);
    } catch (const InputError& error) {
      throw namingMapFile(error, output);
    }
  }();
  writeMapFile(map, output);
  report.images = map.images.size();
  report.added = added.added;
  report.skipped_duplicates = added.skipped_duplicates;
  report.added_without_points = added.added_without_points;
  report.seconds = added.seconds;
  return report;
}

std::unique_ptr<Localizer> inMemoryFastForwardLocalizer(const LoadedModel& model, const Scene& scene,
                                                        const MappingOptions& options) {
  MapFile map = emptyMap(model, scene.metric);
  addToMap(map, model, scene, scene.mappingIndices(), options);
  return std::make_unique<FastForwardLocalizer>(*model.model, std::move(map));
}

}  // namespace ffloc
