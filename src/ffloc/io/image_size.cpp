#include "ffloc/io/image_size.h"

#include <array>
#include <cstdint>
#include <fstream>
#include <optional>
#include <sstream>
#include <string>
#include <opencv2/imgcodecs.hpp>

#include "ffloc/core/error.h"
#include "ffloc/io/image_format.h"
#include "ffloc/io/input_file.h"

namespace ffloc {
namespace {

uint32_t bigEndian(const unsigned char* bytes, int count) {
  uint32_t value = 0;
  for (int i = 0; i < count; ++i) value = (value << 8) | bytes[i];
  return value;
}

// A PNG's IHDR, and an eXIf chunk anywhere before IEND (OpenCV reads one before the image data
// with the header and one after it at the end, and applies either's orientation).
std::optional<ImageHeader> pngFrame(std::istream& in) {
  std::array<unsigned char, 24> header{};
  in.seekg(0);
  if (!in.read(reinterpret_cast<char*>(header.data()), header.size())) return std::nullopt;
  if (!startsLikePng(std::string_view(reinterpret_cast<const char*>(header.data()), header.size()))) return std::nullopt;
  if (std::string(header.begin() + 12, header.begin() + 16) != "IHDR") return std::nullopt;
  ImageHeader frame;
  frame.size = cv::Size(static_cast<int>(bigEndian(&header[16], 4)), static_cast<int>(bigEndian(&header[20], 4)));
  // Chunks: length, type, data, CRC. IHDR's data is 13 bytes.
  in.seekg(8 + 8 + 13 + 4);
  std::array<unsigned char, 8> chunk{};
  while (in.read(reinterpret_cast<char*>(chunk.data()), chunk.size())) {
    const std::string type(chunk.begin() + 4, chunk.end());
    if (type == "IEND") break;
    if (type == "eXIf") {
      frame.with_exif = true;
      break;
    }
    in.seekg(static_cast<std::streamoff>(bigEndian(chunk.data(), 4)) + 4, std::ios::cur);
  }
  return frame;
}

// Walks the JPEG marker segments up to the first start of scan the way libjpeg reads them, for
// the first start-of-frame and an EXIF segment anywhere before the scan (libjpeg's header
// reading saves those, and OpenCV applies their orientation):
// where a marker should start and does not, the bytes up to the next one are skipped (libjpeg
// warns of "extraneous bytes before marker" and decodes on). A stricter walk gave up there, and
// the decoder then found and allocated a frame this walk had not seen (found by the
// localize_request fuzzer: 12040x14895 pixels behind a damaged quantisation table).
std::optional<ImageHeader> jpegFrame(std::istream& in) {
  in.seekg(0);
  if (in.get() != 0xFF || in.get() != 0xD8) return std::nullopt;
  ImageHeader frame;
  bool framed = false;
  // Past the frame, a walk that ends early (a file cut short) still knows the frame's size.
  const auto walkEnded = [&]() -> std::optional<ImageHeader> {
    if (framed) return frame;
    return std::nullopt;
  };
  while (true) {
    // A marker is 0xFF, any number of fill bytes 0xFF, then its type; 0xFF 0x00 is not one.
    int type = 0;
    while (type == 0) {
      int byte = in.get();
      while (byte != std::char_traits<char>::eof() && byte != 0xFF) byte = in.get();
      while (byte == 0xFF) byte = in.get();
      if (byte == std::char_traits<char>::eof()) return walkEnded();
      type = byte;
    }
    if (type == 0xDA || type == 0xD9) return walkEnded();  // start of scan, end of image
    if (type == 0x01 || (type >= 0xD0 && type <= 0xD7)) continue;  // markers without a length
    unsigned char bytes[5];
    if (!in.read(reinterpret_cast<char*>(bytes), 2)) return walkEnded();
    const uint32_t length = bigEndian(bytes, 2);
    if (length < 2) return walkEnded();
    const bool start_of_frame = type >= 0xC0 && type <= 0xCF && type != 0xC4 && type != 0xC8 && type != 0xCC;
    uint32_t read = 2;
    if (start_of_frame && !framed && length >= 7) {
      if (!in.read(reinterpret_cast<char*>(bytes), 5)) return std::nullopt;
      frame.size = cv::Size(static_cast<int>(bigEndian(bytes + 3, 2)), static_cast<int>(bigEndian(bytes + 1, 2)));
      framed = true;
      read += 5;
    }
    // An APP1 segment too short for a tag is skipped like any other (seeking back by a tag that
    // was never read returned to this marker, forever: found by the image_size fuzzer).
    if (type == 0xE1 && length >= 6) {
      char tag[10];
      const uint32_t tag_length = length >= 12 ? 10 : 4;
      if (!in.read(tag, tag_length)) return walkEnded();
      // OpenCV takes an APP1 holding a TIFF header after its six-byte tag as EXIF, whatever the tag.
      const std::string tiff = tag_length == 10 ? std::string(tag + 6, 4) : "";
      frame.with_exif = frame.with_exif || std::string(tag, 4) == "Exif" || tiff == std::string("II*\0", 4) ||
                        tiff == std::string("MM\0*", 4);
      read += tag_length;
    }
    in.seekg(static_cast<std::streamoff>(length - read), std::ios::cur);
  }
}

// What a PNG or JPEG header declares, nullopt for a size it does not give.
std::optional<ImageHeader> imageHeader(std::istream& in) {
  std::optional<ImageHeader> frame = pngFrame(in);
  if (!frame) {
    in.clear();
    frame = jpegFrame(in);
  }
  if (frame && frame->size.width > 0 && frame->size.height > 0) return frame;
  return std::nullopt;
}

// The size a PNG or JPEG header declares. With `as_decoded`, an image with EXIF data gives
// nullopt, since its orientation may swap the sides of the decoded image.
std::optional<cv::Size> headerSize(std::istream& in, bool as_decoded) {
  const std::optional<ImageHeader> frame = imageHeader(in);
  if (!frame || (as_decoded && frame->with_exif)) return std::nullopt;
  return frame->size;
}

}  // namespace

std::optional<cv::Size> encodedImageSize(const std::string& bytes) {
  std::istringstream in(bytes);
  return headerSize(in, true);
}

std::optional<cv::Size> encodedFrameSize(const std::string& bytes) {
  std::istringstream in(bytes);
  return headerSize(in, false);
}

std::optional<ImageHeader> fileImageHeader(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return std::nullopt;
  return imageHeader(in);
}

bool decodingTurnsImage(const std::filesystem::path& path) {
  const std::optional<ImageHeader> header = fileImageHeader(path);
  if (!header || !header->with_exif) return false;
  const int flags = cv::IMREAD_ANYDEPTH | cv::IMREAD_ANYCOLOR;
  cv::Mat as_decoded, as_stored;
  try {
    as_decoded = cv::imread(path.string(), flags);
    as_stored = cv::imread(path.string(), flags | cv::IMREAD_IGNORE_ORIENTATION);
  } catch (const cv::Exception&) {
    return false;  // left to the reader that decodes it, which names the file
  }
  if (as_decoded.empty() || as_stored.empty()) return false;
  return as_decoded.size() != as_stored.size() || cv::norm(as_decoded, as_stored, cv::NORM_INF) != 0;
}

std::optional<cv::Size> fileFrameSize(const std::filesystem::path& path) {
  const std::optional<ImageHeader> header = fileImageHeader(path);
  if (!header) return std::nullopt;
  return header->size;
}

cv::Size readImageSize(const std::filesystem::path& path) {
  requireRegularFile(path, "image file");
  std::ifstream in(path, std::ios::binary);
  if (!in) throwInputError(path.string(), 0, "cannot open image file");
  if (const std::optional<cv::Size> size = headerSize(in, true)) return *size;
  requireDecodableImageFile(path, "cannot decode image");
  cv::Mat image;
  try {
    // Not IMREAD_UNCHANGED: it ignores the EXIF orientation that readImageRgb applies.
    image = cv::imread(path.string(), cv::IMREAD_ANYDEPTH | cv::IMREAD_ANYCOLOR);
  } catch (const cv::Exception& error) {
    // OpenCV refuses some headers (a size beyond its limits) by throwing rather than failing.
    throwInputError(path.string(), 0, std::string("cannot decode image: ") + error.err);
  }
  if (image.empty()) throwInputError(path.string(), 0, "cannot decode image (not a readable image file)");
  return image.size();
}

}  // namespace ffloc
