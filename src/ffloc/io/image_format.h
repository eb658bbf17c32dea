#pragma once

#include <filesystem>
#include <string>
#include <string_view>

namespace ffloc {

// The image formats ffloc lets OpenCV decode, told by their first bytes: PNG, JPEG, TIFF, BMP,
// WebP, Netpbm (PBM, PGM, PPM, PAM, PFM) and OpenEXR. OpenCV picks a decoder by signature among
// every one it was built with, and its DICOM decoder (GDCM) aborts the process on a damaged file
// (found by the localize_request fuzzer: a request body with "DICM" at byte 128 stopped the
// server), so bytes of any other format never reach a decoder.
bool hasDecodableImageSignature(std::string_view leading_bytes);

// The same for a file's first bytes; false when it cannot be read.
bool fileHasDecodableImageSignature(const std::filesystem::path& path);

// What the callers' refusals say: "not a PNG, JPEG, ... file".
std::string undecodableImageFormatMessage();

}  // namespace ffloc
