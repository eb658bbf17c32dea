#include "ffloc/io/image_size.h"

#include <array>
#include <cstdint>
#include <fstream>
#include <optional>
#include <sstream>
#include <string>
#include <opencv2/imgcodecs.hpp>

#include "ffloc/core/error.h"
#include "ffloc/io/input_file.h"

namespace ffloc {
namespace {

uint32_t bigEndian(const unsigned char* bytes, int count) {
  uint32_t value = 0;
  for (int i = 0; i < count; ++i) value = (value << 8) | bytes[i];
  return value;
}

std::optional<cv::Size> pngSize(std::istream& in) {
  std::array<unsigned char, 24> header{};
  in.seekg(0);
  if (!in.read(reinterpret_cast<char*>(header.data()), header.size())) return std::nullopt;
  static const unsigned char kSignature[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
  if (!std::equal(kSignature, kSignature + 8, header.begin())) return std::nullopt;
  if (std::string(header.begin() + 12, header.begin() + 16) != "IHDR") return std::nullopt;
  return cv::Size(static_cast<int>(bigEndian(&header[16], 4)), static_cast<int>(bigEndian(&header[20], 4)));
}

// Walks the JPEG marker segments up to the first start-of-frame. Gives up (nullopt) on EXIF,
// since cv::imread applies the EXIF orientation and may swap width and height.
std::optional<cv::Size> jpegSize(std::istream& in) {
  unsigned char marker[4];
  in.seekg(0);
  if (!in.read(reinterpret_cast<char*>(marker), 2) || marker[0] != 0xFF || marker[1] != 0xD8) return std::nullopt;
  while (in.read(reinterpret_cast<char*>(marker), 2)) {
    if (marker[0] != 0xFF) return std::nullopt;
    const unsigned char type = marker[1];
    if (type == 0xFF) {  // fill byte before a marker
      in.seekg(-1, std::ios::cur);
      continue;
    }
    if (type == 0x01 || (type >= 0xD0 && type <= 0xD7)) continue;  // markers without a length
    if (!in.read(reinterpret_cast<char*>(marker + 2), 2)) return std::nullopt;
    const uint32_t length = bigEndian(marker + 2, 2);
    if (length < 2) return std::nullopt;
    const bool start_of_frame = type >= 0xC0 && type <= 0xCF && type != 0xC4 && type != 0xC8 && type != 0xCC;
    if (start_of_frame) {
      unsigned char frame[5];
      if (!in.read(reinterpret_cast<char*>(frame), 5)) return std::nullopt;
      return cv::Size(static_cast<int>(bigEndian(frame + 3, 2)), static_cast<int>(bigEndian(frame + 1, 2)));
    }
    // An APP1 segment too short for a tag is skipped like any other: seeking back by the tag's
    // four bytes that were never read would return to this marker, forever.
    if (type == 0xE1 && length >= 6) {
      char tag[4];
      if (!in.read(tag, 4)) return std::nullopt;
      if (std::string(tag, 4) == "Exif") return std::nullopt;
      in.seekg(static_cast<std::streamoff>(length) - 2 - 4, std::ios::cur);
      continue;
    }
    in.seekg(static_cast<std::streamoff>(length) - 2, std::ios::cur);
  }
  return std::nullopt;
}

std::optional<cv::Size> headerSize(std::istream& in) {
  std::optional<cv::Size> size = pngSize(in);
  if (!size) {
    in.clear();
    size = jpegSize(in);
  }
  if (size && size->width > 0 && size->height > 0) return size;
  return std::nullopt;
}

}  // namespace

std::optional<cv::Size> encodedImageSize(const std::string& bytes) {
  std::istringstream in(bytes);
  return headerSize(in);
}

cv::Size readImageSize(const std::filesystem::path& path) {
  requireRegularFile(path, "image file");
  std::ifstream in(path, std::ios::binary);
  if (!in) throwInputError(path.string(), 0, "cannot open image file");
  if (const std::optional<cv::Size> size = headerSize(in)) return *size;
  cv::Mat image;
  try {
    image = cv::imread(path.string(), cv::IMREAD_UNCHANGED);
  } catch (const cv::Exception& error) {
    // OpenCV refuses some headers (a size beyond its limits) by throwing rather than failing.
    throwInputError(path.string(), 0, std::string("cannot decode image: ") + error.err);
  }
  if (image.empty()) throwInputError(path.string(), 0, "cannot decode image (not a readable image file)");
  return image.size();
}

}  // namespace ffloc
