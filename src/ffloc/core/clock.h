#pragma once

#include <chrono>
#include <string>

namespace ffloc {

// Wall-clock seconds since `start` on the monotonic clock: how every stage time is measured.
inline double secondsSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

// `time` in UTC as ISO 8601 to the millisecond, "2026-12-05T09:20:01.123Z": a log line's stamp.
std::string utcTimestamp(std::chrono::system_clock::time_point time);

}  // namespace ffloc
