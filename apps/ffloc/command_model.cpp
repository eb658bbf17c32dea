#include "command_model.h"

#include <iostream>

#include "command_options.h"
#include "ffloc/core/error.h"
#include "ffloc/model/model_options.h"
#include "ffloc/model/torch_threads.h"

namespace ffloc::cli {

void addModelOptions(CLI::App& command, ModelArguments& args, const std::string& model_help) {
  command.add_option("--model", args.model, model_help)->capture_default_str();
  command.add_option("--dtype", args.dtype, "Network precision: f32, or bf16 (encoder, decoder and DPT head)")
      ->capture_default_str();
  command.add_option("--threads", args.threads, "libtorch, BLAS and OpenCV threads (0 = all cores)")
      ->check(threadCountRange())
      ->capture_default_str();
}

LoadedModel loadCommandModel(const ModelArguments& args) {
  const int used_threads = setTorchThreadCount(args.threads);
  ModelLoadOptions options;
  options.dtype = parseNetworkDtype(args.dtype);
  LoadedModel loaded = loadModel(args.model, options);
  std::cerr << "model: " << loaded.description << " (" << used_threads << " threads, " << args.dtype << ")\n";
  return loaded;
}

}  // namespace ffloc::cli
