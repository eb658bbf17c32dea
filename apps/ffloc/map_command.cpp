#include <filesystem>
#include <iomanip>
#include <iostream>
#include <memory>

#include "command_model.h"
#include "command_options.h"
#include "commands.h"
#include "ffloc/classical/classical_mapper.h"
#include "ffloc/core/error.h"
#include "ffloc/core/threads.h"
#include "ffloc/data/dataset.h"
#include "ffloc/io/map_file.h"
#include "ffloc/localization/localizer.h"
#include "ffloc/pipeline/mapper.h"

namespace ffloc::cli {
namespace {

struct MapArguments {
  std::string dataset;
  std::string format = "auto";
  std::string method = "classical";
  ModelArguments model;
  std::string output;
  bool append = false;
  bool no_depth = false;
  int max_image_size = SiftOptions().max_image_size;
  int max_features = SiftOptions().max_features;
  bool vlad = false;
  bool quiet = false;
};

void printSummary(size_t added, size_t duplicates, double seconds, size_t images, const std::string& output) {
  std::cout << "mapped " << added << " images";
  if (duplicates > 0) std::cout << " (" << duplicates << " already in the map, skipped)";
  std::cout << " in " << std::fixed << std::setprecision(2) << seconds << " s";
  if (added > 0) std::cout << " (" << std::setprecision(3) << seconds / added << " s/image)";
  std::cout << "; " << output << " holds " << images << " images, " << std::setprecision(1)
            << std::filesystem::file_size(output) / (1024.0 * 1024.0) << " MiB\n";
}

void requireAppendTarget(const MapArguments& args, LocalizationMethod method) {
  const MapHeader header = readMapHeader(args.output);
  if (header.method != toString(method))
    throwInputError(args.output, 0, "--append: the map was built with the " + header.method + " method, not " +
                                        toString(method) + " (--method)");
}

int mapClassical(const MapArguments& args, const Scene& scene, const std::vector<size_t>& frames) {
  ClassicalMappingOptions options;
  options.use_depth = !args.no_depth;
  options.sift.max_image_size = args.max_image_size;
  options.sift.max_features = args.max_features;
  options.quiet = args.quiet;
  options.check();
  ClassicalMap map = emptyClassicalMap(scene.metric, options);
  if (args.append && std::filesystem::exists(args.output)) {
    requireAppendTarget(args, LocalizationMethod::kClassical);
    map = readClassicalMap(args.output);
    std::cerr << "appending to " << args.output << " (" << map.images.size() << " images)\n";
  }
  const ClassicalMappingReport report = addToClassicalMap(map, scene, frames, options);
  writeClassicalMap(map, args.output);
  if (report.skipped_featureless > 0)
    std::cerr << report.skipped_featureless << " images with fewer than two SIFT keypoints left out\n";
  std::cerr << report.points << " points (" << (options.use_depth ? "depth where the frames have it, " : "")
            << "triangulated elsewhere), " << report.links << " links\n";
  printSummary(report.added, report.skipped_duplicates, report.seconds, map.images.size(), args.output);
  return 0;
}

int mapFastForward(const MapArguments& args, const Scene& scene, const std::vector<size_t>& frames) {
  const LoadedModel model = loadCommandModel(args.model);
  MapFile map = emptyMap(model, scene.metric);
  if (args.append && std::filesystem::exists(args.output)) {
    requireAppendTarget(args, LocalizationMethod::kFastForward);
    map = readMapFile(args.output, model.id);
    std::cerr << "appending to " << args.output << " (" << map.images.size() << " images)\n";
  }
  MappingOptions options;
  options.quiet = args.quiet;
  options.vlad = args.vlad;
  const MappingReport report = addToMap(map, model, scene, frames, options);
  writeMapFile(map, args.output);
  printSummary(report.added, report.skipped_duplicates, report.seconds, map.images.size(), args.output);
  return 0;
}

int runMap(const MapArguments& args) {
  setLibraryThreadCount(args.model.threads);
  const LocalizationMethod method = parseLocalizationMethod(args.method);
  const Scene scene = loadDataset(args.dataset, args.format);
  const std::vector<size_t> frames = scene.mappingIndices();
  if (frames.empty()) throwInputError(args.dataset, 0, "dataset has no mapping frames (split_mapping.txt or its native split)");
  return method == LocalizationMethod::kClassical ? mapClassical(args, scene, frames) : mapFastForward(args, scene, frames);
}

}  // namespace

void registerMapCommand(CLI::App& app, CommandRun& run) {
  auto args = std::make_shared<MapArguments>();
  CLI::App* cmd = app.add_subcommand(
      "map",
      "Build a map of a dataset's mapping split, in one versioned, checksummed file. classical (the default): SIFT "
      "keypoints and descriptors, links between the images, a 3D point per keypoint (lifted with the frame's depth "
      "where it has depth, triangulated elsewhere), a VLAD vocabulary. fastforward (experimental): encoder tokens "
      "(fp16) and global descriptors of every image for the network.");
  cmd->add_option("--dataset", args->dataset, "Dataset folder (its mapping split is mapped)")->required();
  cmd->add_option("--format", args->format, "Dataset format (auto detects)")->capture_default_str();
  cmd->add_option("--method", args->method, "classical or fastforward")->capture_default_str();
  addModelOptions(*cmd, args->model,
                  "fastforward: 'default' (the shipped model, models/MODEL_CARD.md; FFLOC_MODEL overrides), a "
                  "FastForward checkpoint, a DUSt3R checkpoint (.pth or safetensors; initialises FastForward, whose "
                  "ray MLP and map head are then untrained) or random:<tiny|small|large>[:seed] for tests");
  cmd->add_option("-o,--output", args->output, "Map file to write (atomically)")->required();
  cmd->add_flag("--append", args->append,
                "Add the dataset's images to an existing map of the same method (and model); images already in it "
                "(by name) are skipped and the earlier ones kept as they are");
  cmd->add_flag("--no-depth", args->no_depth, "classical: triangulate every point, even where frames have depth");
  cmd->add_option("--max-image-size", args->max_image_size,
                  "classical: SIFT runs on images shrunk to this long side (queries too: the map records it)")
      ->capture_default_str();
  cmd->add_option("--max-features", args->max_features, "classical: SIFT keypoints per image, strongest first (queries too)")
      ->capture_default_str();
  cmd->add_flag("--vlad", args->vlad,
                "fastforward: also store the classical VLAD descriptor of every image, for 'localize --retrieval vlad'");
  cmd->add_flag("--quiet", args->quiet, "No progress bar");
  cmd->callback([args, &run] { run = [args] { return runMap(*args); }; });
}

}  // namespace ffloc::cli
