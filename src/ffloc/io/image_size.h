#pragma once

#include <filesystem>
#include <optional>
#include <string>
#include <opencv2/core.hpp>

namespace ffloc {

// Width and height of an image file as cv::imread would return it. PNG and JPEG sizes come from
// the file header alone (readers call this for every frame, and decoding hundreds of full images
// just for their size is slow); other formats, and PNGs and JPEGs carrying EXIF data (whose
// orientation tag may swap the sides), are decoded as readImageRgb decodes them. Throws InputError naming the file when it is missing or
// not a readable image.
cv::Size readImageSize(const std::filesystem::path& path);

// The size an encoded PNG or JPEG (without EXIF data) in memory declares in its header, before any
// decoding; nullopt for other formats and for bytes whose header does not tell.
std::optional<cv::Size> encodedImageSize(const std::string& bytes);

// The size of the pixel grid an encoded PNG or JPEG in memory declares, EXIF or not: what a
// decoder allocates, whatever the orientation it applies afterwards. For refusing oversized
// images before decoding; nullopt for other formats and for bytes whose header does not tell.
std::optional<cv::Size> encodedFrameSize(const std::string& bytes);

// What a file's PNG or JPEG header declares: the pixel grid it stores, and whether it carries
// EXIF data, whose orientation the decoder applies (so that the decoded image may be turned).
// nullopt for other formats and for headers that do not give the size.
struct ImageHeader {
  cv::Size size;
  bool with_exif = false;
};
std::optional<ImageHeader> fileImageHeader(const std::filesystem::path& path);

// Whether decoding the file (as readImageRgb and readDepthMetres decode it) turns or mirrors its
// pixels by an EXIF orientation. A turn of 180 degrees keeps the size, so only the pixels tell:
// false without EXIF data, two decodings otherwise.
bool decodingTurnsImage(const std::filesystem::path& path);

// fileImageHeader's stored size alone: for explaining why a decoder refused a file.
std::optional<cv::Size> fileFrameSize(const std::filesystem::path& path);

}  // namespace ffloc
