#include "command_model.h"

#include <chrono>
#include <cstdio>

#include "command_options.h"
#include "ffloc/core/clock.h"
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
  const auto started = std::chrono::steady_clock::now();
  LoadedModel loaded = loadModel(args.model, options);
  // The id is what a map records and another model is refused by; it showed only in errors.
  std::fprintf(stderr, "model: %s (%d threads, %s), id %s, loaded in %.2f s\n", loaded.description.c_str(),
               used_threads, args.dtype.c_str(), loaded.id.c_str(), secondsSince(started));
  return loaded;
}

}  // namespace ffloc::cli
