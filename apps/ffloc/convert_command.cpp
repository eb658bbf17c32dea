#include <iostream>
#include <memory>
#include <string>

#include "command_options.h"
#include "commands.h"
#include "ffloc/core/error.h"
#include "ffloc/io/convert_weights.h"
#include "ffloc/model/model_loader.h"

namespace ffloc::cli {
namespace {

struct ConvertArguments {
  std::string input;
  std::string output;
  std::string dtype;
  bool quiet = false;
};

void runConvert(const ConvertArguments& args) {
  // A fresh model of a preset, written as a checkpoint: the matching family's untrained state is
  // a working model (nearest-neighbour matching, docs/model.md), worth shipping as a file.
  if (args.input.rfind("random:", 0) == 0) {
    if (!args.dtype.empty() && args.dtype != "f32") throw InputError("--dtype: a fresh model is written as f32");
    const LoadedModel model = [&] {
      try {
        return loadModel(args.input);
      } catch (const InputError& e) {
        // The library names its field 'model', which other commands' --model sets; here --input.
        const std::string what = e.what();
        if (what.rfind("model: ", 0) == 0) throw InputError("--input: " + what.substr(7));
        throw;
      }
    }();
    saveModel(*model.model, args.output, {{"source", args.input}});
    std::cout << "wrote " << args.output << ": " << model.description << "\n";
    return;
  }
  ConvertWeightsOptions options;
  if (!args.dtype.empty()) options.float_dtype = parseFloatDType(args.dtype, "--dtype");
  options.quiet = args.quiet;
  const ConvertWeightsSummary summary = convertWeights(args.input, args.output, options);
  std::cout << "wrote " << args.output << ": " << summary.tensors_written << " tensors ("
            << summary.bytes_written / (1024.0 * 1024.0) << " MiB of data) from "
            << summary.tensors_read << " names; " << summary.aliases_dropped
            << " aliases stored once under their first name\n";
}

}  // namespace

void registerConvertCommand(CLI::App& app, CommandRun& run) {
  auto args = std::make_shared<ConvertArguments>();
  CLI::App* cmd = app.add_subcommand(
      "convert",
      "Convert network weights (a zip-format torch.save() checkpoint such as DUSt3R's .pth, or a "
      "safetensors file) to safetensors in the Hugging Face hub layout: names in order, aliases "
      "stored once, the input's metadata kept (format=pt added where it has none) and source=<the input's file "
      "name>.");
  cmd->add_option("--input", args->input,
                  "Checkpoint (.pth) or safetensors file to read, or random:<preset>[:<seed>] to write a fresh model")
      ->required()
      ->check(nonEmptyPath());
  // An empty --output said "error: : cannot rename the temporary file into place".
  cmd->add_option("--output", args->output, "safetensors file to write (atomically)")->required()->check(nonEmptyPath());
  cmd->add_option("--dtype", args->dtype,
                  "Store floating-point tensors as f32, f16, bf16 or f64 (default: keep each tensor's "
                  "dtype); integer tensors are never cast");
  cmd->add_flag("--quiet", args->quiet, "No progress bar");
  cmd->callback([args, &run] {
    run = [args] {
      runConvert(*args);
      return 0;
    };
  });
}

}  // namespace ffloc::cli
