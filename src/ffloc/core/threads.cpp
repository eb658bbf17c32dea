#include "ffloc/core/threads.h"

#include <algorithm>
#include <thread>

namespace ffloc {

int resolveThreadCount(int requested) {
  if (requested > 0) return requested;
  return std::max(1u, std::thread::hardware_concurrency());
}

}  // namespace ffloc
