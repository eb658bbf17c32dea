#pragma once

#include <string>

#include "ffloc/pipeline/model_loader.h"

namespace ffloc::cli {

// What the commands that run the network do first: set the libtorch thread count (0 = all
// cores), load `model` (any --model form) in `dtype` (--dtype), and say on stderr which model
// with how many threads.
LoadedModel loadCommandModel(const std::string& model, const std::string& dtype, int threads);

}  // namespace ffloc::cli
