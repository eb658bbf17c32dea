#pragma once

#include <filesystem>
#include <functional>

namespace ffloc {

// The lock file of `target`'s writers.
std::filesystem::path writerLockFile(const std::filesystem::path& target);

// An exclusive advisory lock (flock) for the writers of one file, held while the object lives:
// writers that read the file, add to it and rename a new one into place take it, so that two of
// them at once do not both start from the same old file and the later rename drop the earlier
// one's work. The lock is on a hidden file beside the target, `.<name>.lock`, which stays (a
// lock file removed while another process waits on it would let a third one in beside it).
// Waits while another process holds it, after calling `on_wait` (when given) once; an
// exception from `on_wait` refuses to wait, and a StopCheck on this thread (Ctrl-C in Python)
// ends the wait with Stopped. InputError naming `target` when the lock file cannot be made (a
// folder for a target, its folder missing or closed to new files), and the lock file when it
// cannot be locked.
class WriterLock {
 public:
  WriterLock(const std::filesystem::path& target, const std::function<void()>& on_wait);
  ~WriterLock();
  WriterLock(const WriterLock&) = delete;
  WriterLock& operator=(const WriterLock&) = delete;

 private:
  int descriptor_ = -1;
};

}  // namespace ffloc
