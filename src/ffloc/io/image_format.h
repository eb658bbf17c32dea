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

// Whether the bytes begin with the PNG signature, or with a JPEG's start-of-image marker and the
// first marker after it.
bool startsLikePng(std::string_view bytes);
bool startsLikeJpeg(std::string_view bytes);

// Whether the bytes are a JPEG whose compressed data runs on to its end-of-image marker (bytes
// after it, which some cameras append, do not matter). libjpeg decodes a file cut short without
// an error: it prints "Premature end of JPEG file", naming no file, and paints the rows it lacks
// grey, so a download cut short became a query or mapping image half grey without a word.
bool jpegReachesItsEnd(std::string_view bytes);
inline constexpr const char* kJpegCutShort =
    "a JPEG cut short: its compressed data ends before the end-of-image marker (a damaged or partial file)";

// What is wrong with a JPEG's compressed data, or "" for one libjpeg reads cleanly and for bytes
// that are not a JPEG: "damaged JPEG data ... (libjpeg: <its warning>)" for a bad Huffman code,
// data that ends inside a segment or runs on past the last block, a lost restart marker; libjpeg
// decodes such data without an error, prints "Corrupt JPEG data" naming no file and fills the
// blocks after the damage with garbage, which became a mapping image half noise without a word.
// A few stray bytes between segments, which some encoders write, are not damage, and a flipped
// bit can decode to other, valid codes, which nothing tells. "a JPEG of more than 256 scans ..."
// for one that would hold the decoder for minutes. A JPEG past OpenCV's pixel limit is left to
// its decoder's refusal.
std::string jpegDataProblem(std::string_view bytes);

// Throws InputError naming `path`, "<refusal>: not a PNG, JPEG, ... file", unless its first
// bytes are those of a format above, and "<refusal>: a JPEG whose header does not give its size"
// for a PNG or JPEG whose header walk finds no frame: libjpeg skips damaged segments that the
// walk stops at, and found a 65272 x 13041 frame behind one (2.5 GB; the localize_request
// fuzzer), where the size a caller checks must come from the header; "<refusal>: a JPEG cut
// short..." for a JPEG that does not reach its end (jpegReachesItsEnd), and "<refusal>: <problem>"
// for one whose data jpegDataProblem finds wrong.
void requireDecodableImageFile(const std::filesystem::path& path, const std::string& refusal);

}  // namespace ffloc
