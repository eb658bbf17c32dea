#pragma once

#include <filesystem>
#include <functional>
#include <string>

namespace ffloc {

// An exclusive advisory lock (flock) on a folder, held while the object lives: writers that
// read a file, add to it and rename a new one into place take it, so that two of them at once
// do not both start from the same old file and the later rename drop the earlier one's work.
// Blocks while another process holds it, after calling `on_wait` once. InputError naming the
// folder when it cannot be opened.
class FolderLock {
 public:
  FolderLock(const std::filesystem::path& folder, const std::function<void()>& on_wait);
  ~FolderLock();
  FolderLock(const FolderLock&) = delete;
  FolderLock& operator=(const FolderLock&) = delete;

 private:
  int descriptor_ = -1;
};

}  // namespace ffloc
