#pragma once

#include <chrono>
#include <cstddef>
#include <string>

namespace ffloc {

// A one-line progress bar on stderr for long loops; redraws at most ~10 times a second and
// prints nothing when quiet. finish() prints the total time. Where stderr is not a terminal (a
// log file, CI, a service) a line every `log_interval` instead: a redrawn bar there is noise, and
// none at all left a long mapping run silent for minutes.
class ProgressBar {
 public:
  static constexpr std::chrono::seconds kLogInterval{10};

  ProgressBar(std::string label, std::size_t total, bool quiet = false,
              std::chrono::steady_clock::duration log_interval = kLogInterval);
  void update(std::size_t done);
  void finish();
  double elapsedSeconds() const;

 private:
  void draw(std::size_t done, bool final_line);

  std::string label_;
  std::size_t total_;
  bool quiet_;
  bool finished_ = false;
  bool terminal_;
  std::chrono::steady_clock::duration log_interval_;
  std::chrono::steady_clock::time_point start_;
  std::chrono::steady_clock::time_point last_draw_;
};

}  // namespace ffloc
