#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <string>
#include <string_view>
#include <vector>

// What the fuzz targets share. Each target is one LLVMFuzzerTestOneInput in targets/.
namespace ffloc::fuzz {

// The pieces of an input that stands for several files, split at NUL bytes: piece i is the
// content of the i-th file the target names. The text formats hold no NUL, so a seed is its
// files joined by NULs, and an input with fewer pieces leaves the last files out.
std::vector<std::string_view> splitFiles(const uint8_t* data, size_t size);

// A folder of this process's own for the files a target writes, emptied before each input.
// It lies on tmpfs (/dev/shm) where there is one: the dataset targets write a file tree for
// every input, and a disk would make that the bottleneck.
class ScratchFolder {
 public:
  ScratchFolder();
  ~ScratchFolder();
  ScratchFolder(const ScratchFolder&) = delete;
  ScratchFolder& operator=(const ScratchFolder&) = delete;

  const std::filesystem::path& path() const { return path_; }
  // Removes everything in it.
  void clear() const;
  // Writes `bytes` to path()/relative, creating the folders on the way.
  void write(const std::string& relative, std::string_view bytes) const;

 private:
  std::filesystem::path path_;
};

// The process's scratch folder, created on first use and removed at exit.
const ScratchFolder& scratchFolder();

// A dataset target's file tree: the scratch folder emptied, then `text_files[i]` written with
// piece i of the input (splitFiles) and every one of `image_files` written as smallPng().
// Returns the folder.
const std::filesystem::path& writeDatasetTree(const uint8_t* data, size_t size,
                                              const std::vector<std::string>& text_files,
                                              const std::vector<std::string>& image_files);

// The frames every dataset seed names: PNGs of this size, encoded once.
inline constexpr int kImageWidth = 8;
inline constexpr int kImageHeight = 6;
const std::string& smallPng();

// Runs `parse`. An ffloc::InputError is the answer bad input should get; any other exception
// is a finding (the CLI would report it as an internal error), so its message is printed and
// the process aborts, which makes libFuzzer save the input as a crash. With the environment
// variable FFLOC_FUZZ_SHOW_ERRORS set, every answer is printed (accepted, or the InputError).
void expectOnlyInputErrors(const std::function<void()>& parse);

// Reads every byte of a buffer a parser handed out, so that AddressSanitizer sees a view that
// reaches outside its file.
void touch(const uint8_t* bytes, size_t size);

}  // namespace ffloc::fuzz
