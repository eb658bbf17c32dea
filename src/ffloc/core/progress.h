#pragma once

#include <chrono>
#include <cstddef>
#include <functional>
#include <stdexcept>
#include <string>

namespace ffloc {

// Long work asked to stop (StopCheck) at one of its progress steps, before it wrote anything.
class Stopped : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// While one lives, every ProgressBar::update on its thread asks `stop_requested` and throws
// Stopped when it says so: the Python bindings ask Python whether Ctrl-C was pressed, which a
// build_map with the interpreter's lock released heard only when it returned, its map written.
class StopCheck {
 public:
  explicit StopCheck(std::function<bool()> stop_requested);
  ~StopCheck();
  StopCheck(const StopCheck&) = delete;
  StopCheck& operator=(const StopCheck&) = delete;

 private:
  std::function<bool()> previous_;
};

// Throws Stopped, saying `what` stopped, when a StopCheck on this thread asks: for waits that are
// no loop of steps (a lock held by another process).
void stopIfRequested(const std::string& what);

// A one-line progress bar on stderr for long loops; redraws at most ~10 times a second and
// prints nothing when quiet. finish() prints the total time. Where stderr is not a terminal (a
// log file, CI, a service) a line every `log_interval` instead: a redrawn bar there is noise, and
// none at all left a long mapping run silent for minutes.
class ProgressBar {
 public:
  static constexpr std::chrono::seconds kLogInterval{10};

  ProgressBar(std::string label, std::size_t total, bool quiet = false,
              std::chrono::steady_clock::duration log_interval = kLogInterval);
  // Throws Stopped when a StopCheck on this thread asks (quiet or not).
  void update(std::size_t done);
  void finish() { finish(total_); }
  // The last line, at `done`: work stopped early ends its bar where it stopped (a validation cut
  // short by a time budget showed a full bar).
  void finish(std::size_t done);
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
