#include "command_model.h"

#include <iostream>

#include "ffloc/model/torch_threads.h"
#include "ffloc/pipeline/model_options.h"

namespace ffloc::cli {

LoadedModel loadCommandModel(const std::string& model, const std::string& dtype, int threads) {
  const int used_threads = setTorchThreadCount(threads);
  ModelLoadOptions options;
  options.dtype = parseNetworkDtype(dtype);
  LoadedModel loaded = loadModel(model, options);
  std::cerr << "model: " << loaded.description << " (" << used_threads << " threads, " << dtype << ")\n";
  return loaded;
}

}  // namespace ffloc::cli
