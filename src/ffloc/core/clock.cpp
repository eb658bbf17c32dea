#include "ffloc/core/clock.h"

#include <cstdio>
#include <ctime>

namespace ffloc {

std::string utcTimestamp(std::chrono::system_clock::time_point time) {
  const auto since_epoch = std::chrono::duration_cast<std::chrono::milliseconds>(time.time_since_epoch());
  // Floored, so that a time before 1970 still gets milliseconds in [0, 1000).
  auto seconds = std::chrono::floor<std::chrono::seconds>(since_epoch);
  const long long milliseconds = (since_epoch - seconds).count();
  const std::time_t whole = static_cast<std::time_t>(seconds.count());
  std::tm utc{};
  gmtime_r(&whole, &utc);
  char text[40];
  std::snprintf(text, sizeof(text), "%04d-%02d-%02dT%02d:%02d:%02d.%03lldZ", utc.tm_year + 1900, utc.tm_mon + 1,
                utc.tm_mday, utc.tm_hour, utc.tm_min, utc.tm_sec, milliseconds);
  return text;
}

}  // namespace ffloc
