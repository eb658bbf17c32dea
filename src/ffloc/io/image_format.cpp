#include "ffloc/io/image_format.h"

#include <array>
#include <fstream>

#include "ffloc/core/error.h"
#include "ffloc/io/image_size.h"

namespace ffloc {

bool startsLikePng(std::string_view bytes) { return bytes.substr(0, 8) == "\x89PNG\r\n\x1a\n"; }

bool startsLikeJpeg(std::string_view bytes) { return bytes.substr(0, 3) == "\xFF\xD8\xFF"; }

bool hasDecodableImageSignature(std::string_view bytes) {
  const auto startsWith = [&](std::string_view prefix, size_t at = 0) {
    return bytes.size() >= at + prefix.size() && bytes.substr(at, prefix.size()) == prefix;
  };
  if (startsLikePng(bytes) || startsLikeJpeg(bytes)) return true;
  if (startsWith(std::string_view("II*\0", 4)) || startsWith(std::string_view("MM\0*", 4))) return true;
  if (startsWith(std::string_view("II+\0", 4)) || startsWith(std::string_view("MM\0+", 4))) return true;  // BigTIFF
  if (startsWith("BM")) return true;
  if (startsWith("RIFF") && startsWith("WEBP", 8)) return true;
  if (bytes.size() >= 2 && bytes[0] == 'P' && ((bytes[1] >= '1' && bytes[1] <= '7') || bytes[1] == 'F' || bytes[1] == 'f')) {
    return true;
  }
  return startsWith("\x76\x2F\x31\x01");  // OpenEXR
}

void requireDecodableImageFile(const std::filesystem::path& path, const std::string& refusal) {
  std::ifstream in(path, std::ios::binary);
  std::array<char, 12> leading{};
  in.read(leading.data(), leading.size());
  const std::string_view bytes(leading.data(), static_cast<size_t>(in.gcount()));
  if (!hasDecodableImageSignature(bytes)) {
    throwInputError(path.string(), 0,
                    refusal + ": not a PNG, JPEG, TIFF, BMP, WebP, Netpbm or OpenEXR file (the image formats ffloc decodes)");
  }
  const bool png = startsLikePng(bytes);
  if ((png || startsLikeJpeg(bytes)) && !fileFrameSize(path)) {
    throwInputError(path.string(), 0, refusal + ": a " + (png ? "PNG" : "JPEG") + " whose header does not give its size");
  }
}

}  // namespace ffloc
