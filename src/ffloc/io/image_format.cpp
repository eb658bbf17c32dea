#include "ffloc/io/image_format.h"

#include <array>
#include <fstream>
#include <iterator>

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

bool jpegReachesItsEnd(std::string_view bytes) {
  const auto byteAt = [&](size_t at) { return static_cast<unsigned char>(bytes[at]); };
  if (!startsLikeJpeg(bytes)) return false;
  size_t at = 2;
  while (true) {
    // A marker: 0xFF, fill bytes 0xFF, its type. Bytes where a marker should start are skipped,
    // as libjpeg skips them.
    while (at < bytes.size() && byteAt(at) != 0xFF) ++at;
    while (at < bytes.size() && byteAt(at) == 0xFF) ++at;
    if (at >= bytes.size()) return false;
    const unsigned type = byteAt(at++);
    if (type == 0xD9) return true;                                  // end of image
    if (type == 0x00 || type == 0x01 || (type >= 0xD0 && type <= 0xD7)) continue;  // no length
    if (at + 2 > bytes.size()) return false;
    const size_t length = (size_t{byteAt(at)} << 8) | byteAt(at + 1);
    if (length < 2 || at + length > bytes.size()) return false;
    at += length;
    if (type != 0xDA) continue;
    // After a start of scan, the compressed data: 0xFF is followed by 0x00 (a stuffed byte), a
    // restart marker, or the marker that ends the scan.
    while (true) {
      while (at < bytes.size() && byteAt(at) != 0xFF) ++at;
      if (at + 1 >= bytes.size()) return false;
      const unsigned next = byteAt(at + 1);
      if (next == 0x00 || (next >= 0xD0 && next <= 0xD7)) {
        at += 2;
      } else if (next == 0xFF) {
        ++at;
      } else {
        break;
      }
    }
  }
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
  if (startsLikeJpeg(bytes)) {
    in.clear();
    in.seekg(0);
    const std::string whole((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    if (!jpegReachesItsEnd(whole)) throwInputError(path.string(), 0, refusal + ": " + kJpegCutShort);
  }
}

}  // namespace ffloc
