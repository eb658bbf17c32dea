#include <chrono>
#include <filesystem>
#include <iomanip>
#include <iostream>
#include <memory>

#include "commands.h"
#include "ffloc/core/error.h"
#include "ffloc/data/dataset.h"
#include "ffloc/model/torch_threads.h"
#include "ffloc/pipeline/mapper.h"
#include "ffloc/pipeline/model_loader.h"
#include "ffloc/pipeline/model_options.h"

namespace ffloc::cli {
namespace {

struct MapArguments {
  std::string dataset;
  std::string format = "auto";
  std::string model = "default";
  std::string output;
  std::string dtype = "f32";
  bool append = false;
  int threads = 0;
  bool quiet = false;
};

void runMap(const MapArguments& args) {
  const int threads = setTorchThreadCount(args.threads);
  ModelLoadOptions load_options;
  load_options.dtype = parseNetworkDtype(args.dtype);
  auto start = std::chrono::steady_clock::now();
  const LoadedModel model = loadModel(args.model, load_options);
  const double load_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  std::cerr << "model: " << model.description << "\n  id " << model.id << ", loaded in " << std::fixed
            << std::setprecision(2) << load_seconds << " s, " << threads << " threads, " << args.dtype << "\n";

  const Scene scene = loadDataset(args.dataset, args.format);
  const std::vector<size_t> frames = scene.mappingIndices();
  if (frames.empty()) throwInputError(args.dataset, 0, "dataset has no mapping frames (split_mapping.txt or its native split)");

  MapFile map;
  const bool exists = std::filesystem::exists(args.output);
  if (args.append && exists) {
    map = readMapFile(args.output, model.id);
    std::cerr << "appending to " << args.output << " (" << map.images.size() << " images)\n";
  } else {
    map = emptyMap(model, scene.metric);
  }
  MappingOptions options;
  options.quiet = args.quiet;
  const MappingReport report = addToMap(map, model, scene, frames, options);
  writeMapFile(map, args.output);

  std::cout << "mapped " << report.added << " images";
  if (report.skipped_duplicates > 0) std::cout << " (" << report.skipped_duplicates << " already in the map, skipped)";
  std::cout << " in " << std::fixed << std::setprecision(2) << report.seconds << " s";
  if (report.added > 0) std::cout << " (" << std::setprecision(3) << report.seconds / report.added << " s/image)";
  std::cout << "; " << args.output << " holds " << map.images.size() << " images, "
            << std::setprecision(1) << std::filesystem::file_size(args.output) / (1024.0 * 1024.0) << " MiB\n";
}

}  // namespace

void registerMapCommand(CLI::App& app) {
  auto args = std::make_shared<MapArguments>();
  CLI::App* cmd = app.add_subcommand(
      "map",
      "Build a FastForward map: encode every mapping image of a dataset once and store its tokens (fp16), pose, "
      "intrinsics, preprocessing and global descriptor in one versioned file.");
  cmd->add_option("--dataset", args->dataset, "Dataset folder (its mapping split is mapped)")->required();
  cmd->add_option("--format", args->format, "Dataset format (auto detects)")->capture_default_str();
  cmd->add_option("--model", args->model,
                  "'default' (the shipped model, models/MODEL_CARD.md; FFLOC_MODEL overrides), a FastForward "
                  "checkpoint, a DUSt3R checkpoint (.pth or safetensors; initialises FastForward, whose ray MLP and "
                  "map head are then untrained) or random:<tiny|small|large>[:seed] for tests")
      ->capture_default_str();
  cmd->add_option("-o,--output", args->output, "Map file to write (atomically)")->required();
  cmd->add_flag("--append", args->append,
                "Add the dataset's images to an existing map (same model required); images already in it (by name) "
                "are skipped and the earlier ones kept as they are");
  cmd->add_option("--dtype", args->dtype, "Network precision: f32, or bf16 (encoder, decoder and DPT head; tokens are stored fp16 either way)")
      ->capture_default_str();
  cmd->add_option("--threads", args->threads, "libtorch threads (0 = all cores)")->capture_default_str();
  cmd->add_flag("--quiet", args->quiet, "No progress bar");
  cmd->callback([args] { runMap(*args); });
}

}  // namespace ffloc::cli
