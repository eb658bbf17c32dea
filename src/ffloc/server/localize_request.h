#pragma once

#include <cstddef>
#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "ffloc/geometry/camera.h"
#include "ffloc/localization/localizer.h"

namespace ffloc {

// One POST /localize, decoded and checked before any network work starts.
struct LocalizeRequest {
  std::string name = "query";  // for logs and the answer
  cv::Mat rgb;                 // 8-bit RGB
  Intrinsics intrinsics;       // of `rgb`
  LocalizeOptions options;     // the server's defaults with the request's overrides
};

// What one request may ask for: a server answers queries one at a time, so one request should
// not hold it for minutes, nor decode into gigabytes.
struct RequestLimits {
  size_t max_image_pixels = 40'000'000;
  size_t max_top_k = 100;
  int64_t max_features = 20000;
};

// `fields` are the URL query parameters and form fields, `image_bytes` an encoded image (any
// format OpenCV reads: JPEG, PNG, TIFF, ...). Fields:
//   fx, fy, cx, cy   required, pixels of the sent image
//   distortion       optional, OpenCV order k1,k2,p1,p2[,k3[,k4,k5,k6]]
//   name             optional label
//   top_k, features, seed, selection   optional overrides of `defaults`
// InputError naming the field for a missing, malformed, unknown or out-of-limits field, and
// naming "image" for bytes that do not decode or an image over the pixel limit (refused from
// the PNG or JPEG header, before decoding, where the header tells). The image is decoded as
// `ffloc localize` reads files: OpenCV applies a JPEG's EXIF orientation.
LocalizeRequest parseLocalizeRequest(const std::map<std::string, std::string>& fields, const std::string& image_bytes,
                                     const LocalizeOptions& defaults, const RequestLimits& limits = {});

// The distortion field's text, "k1,k2,p1,p2[,k3[,k4,k5,k6]]", also `ffloc localize --distortion`'s:
// InputError naming "distortion" for a count other than 4, 5 or 8, or a coefficient that is not a
// finite decimal number.
std::vector<double> parseDistortion(const std::string& text);

// The fields alone, checked as parseLocalizeRequest checks them, with no image (`rgb` empty, the
// intrinsics not yet checked against an image size): for a request whose fields are all known
// before its body arrives, so that a 30 MB upload is not read only to be refused for its fields.
LocalizeRequest parseLocalizeFields(const std::map<std::string, std::string>& fields, const LocalizeOptions& defaults,
                                    const RequestLimits& limits = {});

}  // namespace ffloc
