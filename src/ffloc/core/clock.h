#pragma once

#include <chrono>

namespace ffloc {

// Wall-clock seconds since `start` on the monotonic clock: how every stage time is measured.
inline double secondsSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

}  // namespace ffloc
