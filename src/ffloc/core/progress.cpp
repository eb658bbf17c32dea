#include "ffloc/core/progress.h"

#include <unistd.h>

#include <cstdio>
#include <utility>

#include "ffloc/core/clock.h"

namespace ffloc {

ProgressBar::ProgressBar(std::string label, std::size_t total, bool quiet,
                         std::chrono::steady_clock::duration log_interval)
    : label_(std::move(label)), total_(total), quiet_(quiet), terminal_(isatty(fileno(stderr)) != 0),
      log_interval_(log_interval),
      start_(std::chrono::steady_clock::now()), last_draw_(start_) {}

double ProgressBar::elapsedSeconds() const {
  return secondsSince(start_);
}

namespace {
thread_local std::function<bool()> stop_requested_here;

bool stopRequestedHere() { return stop_requested_here && stop_requested_here(); }
}  // namespace

StopCheck::StopCheck(std::function<bool()> stop_requested) : previous_(std::move(stop_requested_here)) {
  stop_requested_here = std::move(stop_requested);
}

StopCheck::~StopCheck() { stop_requested_here = std::move(previous_); }

void stopIfRequested(const std::string& what) {
  if (stopRequestedHere()) throw Stopped(what + ": stopped");
}

void ProgressBar::update(std::size_t done) {
  if (stopRequestedHere())
    throw Stopped(label_ + ": stopped at " + std::to_string(done) + " of " + std::to_string(total_));
  if (quiet_) return;
  const auto now = std::chrono::steady_clock::now();
  if (terminal_) {
    if (done < total_ && now - last_draw_ < std::chrono::milliseconds(100)) return;
  } else if (done >= total_ || now - last_draw_ < log_interval_) {  // finish() prints the last line
    return;
  }
  last_draw_ = now;
  draw(done, false);
}

void ProgressBar::finish(std::size_t done) {
  if (quiet_ || finished_) return;
  finished_ = true;
  draw(done, true);
}

void ProgressBar::draw(std::size_t done, bool final_line) {
  const int width = 30;
  const double fraction = total_ ? static_cast<double>(done) / static_cast<double>(total_) : 1.0;
  const int filled = static_cast<int>(fraction * width);
  const double elapsed = elapsedSeconds();
  const double eta = done ? elapsed / static_cast<double>(done) * static_cast<double>(total_ - done) : 0.0;
  // A terminal gets an in-place bar, a log file one line each time.
  std::fprintf(stderr, "%s%s [%.*s%*s] %zu/%zu  %.1fs", terminal_ ? "\r" : "", label_.c_str(), filled,
               "==============================", width - filled, "", done, total_, elapsed);
  if (!final_line) std::fprintf(stderr, "  eta %.1fs", eta);
  std::fprintf(stderr, final_line || !terminal_ ? "\n" : "   ");
  std::fflush(stderr);
}

}  // namespace ffloc
