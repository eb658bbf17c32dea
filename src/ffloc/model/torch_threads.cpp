#include "ffloc/model/torch_threads.h"

#include <ATen/Parallel.h>

#include "ffloc/core/threads.h"

namespace ffloc {

int setTorchThreadCount(int requested) {
  const int threads = resolveThreadCount(requested);
  at::set_num_threads(threads);
  return threads;
}

}  // namespace ffloc
