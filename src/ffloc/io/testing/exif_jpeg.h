#pragma once

#include <string>
#include <vector>

#include <opencv2/imgcodecs.hpp>

namespace ffloc::testing {

// An APP1 segment of EXIF data holding one tag, Orientation (0x0112) = `orientation`, in a
// big-endian TIFF block: what a phone writes beside a portrait photo it stores sideways.
inline std::string exifOrientationSegment(int orientation) {
  std::string segment("\xff\xe1\x00\x22" "Exif\0\0" "MM\0\x2a\0\0\0\x08" "\0\x01"
                      "\x01\x12\0\x03\0\0\0\x01\0\x06\0\0" "\0\0\0\0", 36);
  segment[10 + 8 + 2 + 9] = static_cast<char>(orientation);
  return segment;
}

// `image` encoded as a JPEG whose EXIF data, right after the start of image, gives `orientation`.
inline std::string jpegWithExifOrientation(const cv::Mat& image, int orientation) {
  std::vector<uchar> jpeg;
  cv::imencode(".jpg", image, jpeg);
  return std::string(jpeg.begin(), jpeg.begin() + 2) + exifOrientationSegment(orientation) +
         std::string(jpeg.begin() + 2, jpeg.end());
}

}  // namespace ffloc::testing
