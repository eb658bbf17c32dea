#pragma once

#include <string>

#include <CLI/CLI.hpp>

#include "ffloc/model/model_loader.h"

namespace ffloc::cli {

// The options of every command that runs the network, declared once.
struct ModelArguments {
  std::string model = "default";
  std::string dtype = "f32";
  int threads = 0;
};
void addModelOptions(CLI::App& command, ModelArguments& args, const std::string& model_help);

// What the commands that run the network do first: set the libtorch thread count (0 = all
// cores), load the model in the dtype, and say on stderr which model with how many threads.
LoadedModel loadCommandModel(const ModelArguments& args);

}  // namespace ffloc::cli
