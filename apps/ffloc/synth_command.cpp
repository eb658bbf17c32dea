#include <cstdio>
#include <filesystem>
#include <iostream>
#include <string>

#include "command_options.h"
#include "commands.h"
#include "ffloc/core/error.h"
#include "ffloc/data/dataset_writers.h"
#include "ffloc/synthetic/synthetic.h"

namespace ffloc::cli {
namespace {

struct SynthArguments {
  std::string out;
  uint64_t seed = 0;
  int scenes = 1;
  std::string kind = "mixed";
  std::string size = "256x192";
  SyntheticOptions options;
};

void parseSize(const std::string& text, int& width, int& height) {
  const auto x = text.find('x');
  try {
    size_t used_w = 0, used_h = 0;
    if (x == std::string::npos) throw std::invalid_argument("no x");
    width = std::stoi(text.substr(0, x), &used_w);
    height = std::stoi(text.substr(x + 1), &used_h);
    if (used_w != x || used_h != text.size() - x - 1) throw std::invalid_argument("trailing");
  } catch (const std::logic_error&) {
    throw InputError("--size: expected WIDTHxHEIGHT (e.g. 256x192), got '" + text + "'");
  }
}

// Refused up front rather than failing when the disk fills, hours in, and removing every scene
// written (a failed batch leaves nothing behind).
void requireFreeSpace(const std::filesystem::path& out, uint64_t needed) {
  std::filesystem::path existing = std::filesystem::absolute(out);
  while (!std::filesystem::exists(existing) && existing.has_parent_path() && existing != existing.parent_path())
    existing = existing.parent_path();
  std::error_code error;
  const std::filesystem::space_info space = std::filesystem::space(existing, error);
  if (error || space.available >= needed) return;
  const auto gigabytes = [](uint64_t bytes) {
    char text[32];
    std::snprintf(text, sizeof(text), "%.1f GB", static_cast<double>(bytes) / 1e9);
    return std::string(text);
  };
  throw InputError("--out: the scenes need at least " + gigabytes(needed) + " (their depth maps alone) and " +
                   existing.string() + " has " + gigabytes(space.available) + " free");
}

void runSynth(const SynthArguments& args) {
  if (args.scenes < 1 || args.scenes > kMaxSyntheticScenes)
    throw InputError("--scenes: must be in [1, " + std::to_string(kMaxSyntheticScenes) + "], got " +
                     std::to_string(args.scenes));
  SyntheticOptions options = args.options;
  parseSize(args.size, options.width, options.height);
  const bool mixed = args.kind == "mixed";
  if (!mixed) {
    try {
      options.kind = parseSceneKind(args.kind);
    } catch (const InputError&) {
      throw InputError("--kind: unknown scene kind '" + args.kind +
                       "' (expected indoor, outdoor, object or mixed)");
    }
  }
  validate(options);
  // A folder of earlier scenes was written over, mixing their stale frames with the new ones.
  checkOutputFolder("--out", args.out);
  requireFreeSpace(args.out, args.scenes * sceneDepthBytes(options));
  const auto kinds = allSceneKinds();
  writeIntoNewFolder(args.out, [&](const std::filesystem::path& out) {
    for (int i = 0; i < args.scenes; ++i) {
      SyntheticOptions scene_options = options;
      if (mixed) scene_options.kind = kinds[i % kinds.size()];
      scene_options.seed = sceneSeed(args.seed, i);
      char name[64];
      std::snprintf(name, sizeof(name), "scene_%03d_%s", i, toString(scene_options.kind));
      const Scene scene = generateSyntheticScene(scene_options, out / name);
      if (!options.quiet || args.scenes == 1)
        std::cout << (std::filesystem::path(args.out) / name).string() << ": " << scene.mappingIndices().size()
                  << " mapping + " << scene.queryIndices().size() << " query frames\n";
    }
  });
}

}  // namespace

void registerSynthCommand(CLI::App& app, CommandRun& run) {
  auto args = std::make_shared<SynthArguments>();
  args->options.quiet = false;
  args->options.threads = 0;
  CLI::App* cmd = app.add_subcommand(
      "synth", "Write procedural RGB-D scenes with exact depth and poses (native manifest format)");
  cmd->add_option("--out", args->out, "New (or empty) output folder; scene i goes to OUT/scene_<i>_<kind>")
      ->required()
      ->check(nonEmptyPath());
  cmd->add_option("--seed", args->seed, "Seed; the same seed gives the same bytes")
      ->check(wholeNumber())
      ->capture_default_str();
  cmd->add_option("--scenes", args->scenes, "Number of scenes")->capture_default_str();
  cmd->add_option("--kind", args->kind, "indoor, outdoor, object, or mixed (cycles the three)")
      ->capture_default_str();
  cmd->add_option("--size", args->size, "Image size WIDTHxHEIGHT")->capture_default_str();
  cmd->add_option("--mapping-frames", args->options.mapping_frames, "Frames in the mapping scan")
      ->capture_default_str();
  cmd->add_option("--query-frames", args->options.query_frames,
                  "Query frames (cycling near / far / opposite)")
      ->capture_default_str();
  cmd->add_option("--min-fov", args->options.min_fov_deg, "Smallest horizontal field of view (deg)")
      ->capture_default_str();
  cmd->add_option("--max-fov", args->options.max_fov_deg, "Largest horizontal field of view (deg)")
      ->capture_default_str();
  cmd->add_option("--image-noise", args->options.image_noise,
                  "Pixel noise std-dev in 8-bit levels (0: none)")
      ->capture_default_str();
  cmd->add_option("--depth-noise", args->options.depth_noise,
                  "Relative depth noise std-dev (0: exact depth)")
      ->capture_default_str();
  cmd->add_option("--threads", args->options.threads,
                  "Render threads (0: all cores); output does not depend on it")
      ->check(threadCountRange())
      ->capture_default_str();
  cmd->add_flag("--quiet", args->options.quiet, "No progress output");
  cmd->callback([args, &run] {
    run = [args] {
      runSynth(*args);
      return 0;
    };
  });
}

}  // namespace ffloc::cli
