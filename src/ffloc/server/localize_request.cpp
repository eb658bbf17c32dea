#include "ffloc/server/localize_request.h"

#include <cerrno>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <limits>
#include <optional>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <set>
#include <sstream>

#include "ffloc/core/error.h"
#include "ffloc/core/utf8.h"
#include "ffloc/io/image.h"
#include "ffloc/io/image_format.h"
#include "ffloc/io/image_size.h"

namespace ffloc {
namespace {

const std::set<std::string>& knownFields() {
  static const std::set<std::string> fields = {"fx",   "fy",    "cx",       "cy",   "distortion",
                                               "name", "top_k", "features", "seed", "selection"};
  return fields;
}

std::string knownFieldList() {
  std::string list;
  for (const std::string& field : knownFields()) list += (list.empty() ? "" : ", ") + field;
  return list;
}

// A client's text as an answer shows it: on one line, and cut after 64 bytes (a 1 MB value was
// quoted whole).
std::string shownText(const std::string& text) { return escapeControlCharacters(cutText(text, 64)); }

std::string quotedValue(const std::string& text) { return "'" + shownText(text) + "'"; }

// Plain decimal only: strtod alone would also take leading blanks, hexadecimal and "inf".
bool isDecimalText(const std::string& text) {
  return !text.empty() && text.find_first_not_of("0123456789+-.eE") == std::string::npos;
}

double parseFiniteNumber(const std::string& field, const std::string& text) {
  if (!isDecimalText(text)) throw InputError(field + ": expected a finite number, got " + quotedValue(text));
  const char* begin = text.c_str();
  char* end = nullptr;
  errno = 0;
  const double value = std::strtod(begin, &end);
  if (text.empty() || end != begin + text.size() || errno == ERANGE || !std::isfinite(value))
    throw InputError(field + ": expected a finite number, got " + quotedValue(text));
  return value;
}

long long parseInteger(const std::string& field, const std::string& text, long long min, long long max) {
  const char* begin = text.c_str();
  char* end = nullptr;
  errno = 0;
  const long long value = std::strtoll(begin, &end, 10);
  if (!isDecimalText(text) || end != begin + text.size() || errno == ERANGE || value < min || value > max) {
    throw InputError(field + ": expected an integer in [" + std::to_string(min) + ", " + std::to_string(max) +
                     "], got " + quotedValue(text));
  }
  return value;
}

double requiredNumber(const std::map<std::string, std::string>& fields, const std::string& field) {
  const auto it = fields.find(field);
  if (it == fields.end()) throw InputError(field + ": missing (the query's intrinsics fx, fy, cx, cy are required)");
  return parseFiniteNumber(field, it->second);
}

std::string pixelLimitError(const cv::Size& size, size_t max_image_pixels) {
  return "image: " + std::to_string(size.width) + "x" + std::to_string(size.height) + " is more than the " +
         std::to_string(max_image_pixels) + " pixels this server accepts";
}

cv::Mat decodeRgb(const std::string& bytes, size_t max_image_pixels) {
  if (bytes.empty()) throw InputError("image: the request carries no image");
  if (bytes.size() > static_cast<size_t>(std::numeric_limits<int>::max()))
    throw InputError("image: " + std::to_string(bytes.size()) + " bytes is more than an image may have");
  // Only images whose pixel grid the header declares reach a decoder, so that the pixel limit
  // holds before any allocation: OpenCV reads its own limit (OPENCV_IO_MAX_IMAGE_PIXELS) once, as
  // the library loads, so a server cannot set it, and its default lets a decoder allocate 3 GB.
  const std::optional<cv::Size> declared = encodedFrameSize(bytes);
  if (!declared) {
    const bool png = startsLikePng(bytes);
    if (!png && !startsLikeJpeg(bytes)) {
      throw InputError("image: not a PNG or JPEG file (the server decodes those two, whose size it reads before decoding)");
    }
    throw InputError("image: a " + std::string(png ? "PNG" : "JPEG") +
                     " whose header does not give its size; it is not decoded");
  }
  if (static_cast<size_t>(declared->width) * static_cast<size_t>(declared->height) > max_image_pixels) {
    throw InputError(pixelLimitError(*declared, max_image_pixels));
  }
  // A 16-bit PNG decodes to twice the bytes of an 8-bit one at its size, so it is held to half
  // the pixels: a 6000x6000 16-bit PNG of 280 KB took 580 MB while it decoded (an outside probe:
  // five at once, 2.3 GB). IHDR's bit depth is the 25th byte.
  const bool sixteen_bit = startsLikePng(bytes) && bytes.size() > 24 && static_cast<unsigned char>(bytes[24]) == 16;
  if (sixteen_bit && 2 * static_cast<size_t>(declared->width) * static_cast<size_t>(declared->height) > max_image_pixels) {
    throw InputError("image: a 16-bit PNG of " + std::to_string(declared->width) + "x" + std::to_string(declared->height) +
                     " is more than the " + std::to_string(max_image_pixels / 2) +
                     " pixels this server accepts at 16 bits (half its limit at 8)");
  }
  if (startsLikeJpeg(bytes) && !jpegReachesItsEnd(bytes)) throw InputError(std::string("image: ") + kJpegCutShort);
  if (const std::string problem = jpegDataProblem(bytes); !problem.empty()) throw InputError("image: " + problem);
  const cv::Mat encoded(1, static_cast<int>(bytes.size()), CV_8UC1, const_cast<char*>(bytes.data()));
  cv::Mat bgr;
  try {
    bgr = cv::imdecode(encoded, cv::IMREAD_COLOR | cv::IMREAD_ANYDEPTH);
  } catch (const cv::Exception&) {
    bgr.release();
  }
  if (bgr.empty()) throw InputError("image: " + std::to_string(bytes.size()) + " bytes that OpenCV cannot decode as an image");
  if (static_cast<size_t>(bgr.total()) > max_image_pixels) throw InputError(pixelLimitError(bgr.size(), max_image_pixels));
  return rgbFromDecoded(bgr);
}

}  // namespace

std::vector<double> parseDistortion(const std::string& text) {
  std::vector<double> coefficients;
  if (!text.empty() && text.back() == ',') throw InputError("distortion: trailing comma in " + quotedValue(text));
  std::stringstream stream(text);
  std::string item;
  while (std::getline(stream, item, ',')) coefficients.push_back(parseFiniteNumber("distortion", item));
  const size_t n = coefficients.size();
  if (n != 4 && n != 5 && n != 8)
    throw InputError("distortion: expected 4, 5 or 8 comma-separated coefficients (k1,k2,p1,p2[,k3[,k4,k5,k6]]), got " +
                     std::to_string(n));
  return coefficients;
}

LocalizeRequest parseLocalizeFields(const std::map<std::string, std::string>& fields, const LocalizeOptions& defaults,
                                    const RequestLimits& limits) {
  for (const auto& [field, value] : fields) {
    if (!knownFields().count(field)) {
      throw InputError(shownText(field) + ": unknown field (known: " + knownFieldList() + ")");
    }
  }
  LocalizeRequest request;
  request.options = defaults;
  request.intrinsics.fx = requiredNumber(fields, "fx");
  request.intrinsics.fy = requiredNumber(fields, "fy");
  request.intrinsics.cx = requiredNumber(fields, "cx");
  request.intrinsics.cy = requiredNumber(fields, "cy");
  if (const auto it = fields.find("distortion"); it != fields.end()) request.intrinsics.distortion = parseDistortion(it->second);
  if (const auto it = fields.find("name"); it != fields.end() && !it->second.empty()) request.name = it->second;
  if (const auto it = fields.find("top_k"); it != fields.end())
    request.options.top_k = static_cast<size_t>(parseInteger("top_k", it->second, 1, static_cast<long long>(limits.max_top_k)));
  if (const auto it = fields.find("features"); it != fields.end())
    request.options.num_features = parseInteger("features", it->second, 1, limits.max_features);
  if (const auto it = fields.find("seed"); it != fields.end()) {
    request.options.seed = static_cast<uint64_t>(parseInteger("seed", it->second, 0, INT64_MAX));
    request.options.pnp.seed = request.options.seed;
  }
  if (const auto it = fields.find("selection"); it != fields.end()) request.options.selection = parseImageSelection(it->second);
  request.options.check();
  return request;
}

LocalizeRequest parseLocalizeRequest(const std::map<std::string, std::string>& fields, const std::string& image_bytes,
                                     const LocalizeOptions& defaults, const RequestLimits& limits) {
  LocalizeRequest request = parseLocalizeFields(fields, defaults, limits);
  request.rgb = decodeRgb(image_bytes, limits.max_image_pixels);
  request.intrinsics.width = request.rgb.cols;
  request.intrinsics.height = request.rgb.rows;
  checkIntrinsicsFitImage(request.intrinsics, request.rgb.cols, request.rgb.rows);
  return request;
}

}  // namespace ffloc
