#pragma once

#include <filesystem>

namespace ffloc {

// A file written beside its target and renamed over it once complete. It is removed when the
// write fails, and also when SIGINT, SIGTERM or SIGHUP ends the process first: a Ctrl-C while a
// 2.2 GB checkpoint was converted left its 566 MB temporary behind, hidden, each time. The
// signal handler is installed only where the signal's disposition is still the default: a
// command that handles Ctrl-C itself stops by an exception, which removes the file here.
// Removal by the signal covers a few files written at once and paths under 4096 bytes; any
// other is still removed when the write fails and by the next write of its target.
// Removes the temporaries being written, then ends the process by `signal_number` as its default
// action would. Async-signal-safe: for a command's own handler of these signals.
[[noreturn]] void removeTemporaryFilesAndRaise(int signal_number);

class TemporaryFile {
 public:
  explicit TemporaryFile(std::filesystem::path path);
  ~TemporaryFile();  // removes the file unless kept
  TemporaryFile(const TemporaryFile&) = delete;
  TemporaryFile& operator=(const TemporaryFile&) = delete;

  const std::filesystem::path& path() const { return path_; }
  // The file was renamed into place: nothing is left to remove.
  void keep();

 private:
  std::filesystem::path path_;
  int slot_ = -1;  // in the signal handler's list; -1: not in it
  bool kept_ = false;
};

}  // namespace ffloc
