#include "fuzz_support.h"

#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <exception>
#include <fstream>
#include <opencv2/imgcodecs.hpp>

#include "ffloc/core/error.h"

namespace ffloc::fuzz {

namespace fs = std::filesystem;

std::vector<std::string_view> splitFiles(const uint8_t* data, size_t size) {
  const std::string_view input(reinterpret_cast<const char*>(data), size);
  std::vector<std::string_view> pieces;
  size_t begin = 0;
  while (true) {
    const size_t end = input.find('\0', begin);
    pieces.push_back(input.substr(begin, end == std::string_view::npos ? std::string_view::npos : end - begin));
    if (end == std::string_view::npos) return pieces;
    begin = end + 1;
  }
}

ScratchFolder::ScratchFolder() {
  const fs::path base = fs::is_directory("/dev/shm") && ::access("/dev/shm", W_OK) == 0
                            ? fs::path("/dev/shm")
                            : fs::temp_directory_path();
  std::string pattern = (base / "ffloc-fuzz-XXXXXX").string();
  if (::mkdtemp(pattern.data()) == nullptr) {
    std::perror("ffloc fuzz: cannot create a scratch folder");
    std::abort();
  }
  path_ = pattern;
}

ScratchFolder::~ScratchFolder() {
  std::error_code ignored;
  fs::remove_all(path_, ignored);
}

void ScratchFolder::clear() const {
  for (const auto& entry : fs::directory_iterator(path_)) fs::remove_all(entry.path());
}

void ScratchFolder::write(const std::string& relative, std::string_view bytes) const {
  const fs::path file = path_ / relative;
  fs::create_directories(file.parent_path());
  std::ofstream(file, std::ios::binary).write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
}

const ScratchFolder& scratchFolder() {
  static const ScratchFolder folder;
  return folder;
}

const fs::path& writeDatasetTree(const uint8_t* data, size_t size, const std::vector<std::string>& text_files,
                                 const std::vector<std::string>& image_files) {
  const ScratchFolder& folder = scratchFolder();
  folder.clear();
  const std::vector<std::string_view> pieces = splitFiles(data, size);
  for (size_t i = 0; i < pieces.size() && i < text_files.size(); ++i) folder.write(text_files[i], pieces[i]);
  for (const std::string& image : image_files) folder.write(image, smallPng());
  return folder.path();
}

const std::string& smallPng() {
  static const std::string png = [] {
    std::vector<uint8_t> bytes;
    cv::imencode(".png", cv::Mat(kImageHeight, kImageWidth, CV_8UC3, cv::Scalar(40, 80, 120)), bytes);
    return std::string(bytes.begin(), bytes.end());
  }();
  return png;
}

void expectOnlyInputErrors(const std::function<void()>& parse) {
  // Set when running a target on single inputs, to see what each parser answered.
  static const bool show_errors = std::getenv("FFLOC_FUZZ_SHOW_ERRORS") != nullptr;
  try {
    parse();
    if (show_errors) std::fprintf(stderr, "ffloc fuzz: accepted\n");
  } catch (const InputError& error) {
    if (show_errors) std::fprintf(stderr, "ffloc fuzz: InputError: %s\n", error.what());
  } catch (const std::exception& error) {
    std::fprintf(stderr, "ffloc fuzz: an exception other than InputError escaped: %s\n", error.what());
    std::abort();
  } catch (...) {
    std::fprintf(stderr, "ffloc fuzz: a non-standard exception escaped\n");
    std::abort();
  }
}

void touch(const uint8_t* bytes, size_t size) {
  // Stored where the optimiser must assume someone looks, so the reads are not dropped.
  static volatile uint64_t sink = 0;
  uint64_t sum = 0;
  for (size_t i = 0; i < size; ++i) sum = sum * 31 + bytes[i];
  sink = sum;
}

}  // namespace ffloc::fuzz
