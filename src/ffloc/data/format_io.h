#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "ffloc/core/number_text.h"
#include "ffloc/data/scene.h"

// What the benchmark-format readers and writers (mapfree, ace, rio10, indoor6, kapture) share:
// number formatting that round-trips (core/number_text.h), pose conversions with their checks, and copying a frame's
// image and depth into another layout.
namespace ffloc {

// A world-to-camera pose given as a Hamilton quaternion (scalar first) and a translation, as
// COLMAP, kapture and map-free write it, turned into the camera-to-world pose a Frame holds.
// Throws InputError "<file>:<line>: ..." when a value is not finite or |q| is not 1 within 1e-2.
Pose cameraToWorldFromQuaternion(const double q_wxyz[4], const Eigen::Vector3d& t_world_to_camera,
                                 const std::filesystem::path& file, int line);

// "qw qx qy qz tx ty tz" of the world-to-camera transform of a camera-to-world pose, separated by
// `separator` (" " or ", ").
std::string worldToCameraQuaternionText(const Pose& camera_to_world, const std::string& separator);

// writeTextFile (atomic) after creating the file's folder.
void writeTextCreatingFolders(const std::filesystem::path& path, const std::string& text);

// Rows of a matrix, one per line, numbers separated by spaces.
std::string matrixText(const Eigen::MatrixXd& matrix);

// Checks that the image file exists and has the size its format's text claims; the error names
// the claim's file and line and the image.
void requireImageSize(const std::filesystem::path& image, int width, int height, const std::string& claim_file,
                      int claim_line);

// The folder must not exist or be empty: a conversion or a synthetic scene never mixes its files
// with others. InputError naming the folder otherwise, or when it cannot be examined (a loop of
// links).
void requireEmptyOutputFolder(const std::filesystem::path& dir);

// Copies the frame's image to `destination` (creating folders). With `as_jpeg`, a source that is
// not a JPEG is re-encoded (quality 95) for formats whose tools only look for .jpg files.
void copyFrameImage(const Frame& frame, const std::filesystem::path& destination, bool as_jpeg = false);

// The frame's depth in scene units as a uint16 PNG of millimetres (0 = no depth), the encoding
// of 7-Scenes, ACE, RIO10 and map-free. Depths beyond 65.534 m become 0.
void writeDepthMillimetrePng(const Frame& frame, const std::filesystem::path& destination);

// The frame's depth in scene units as raw little-endian float32, row-major (kapture's .depth).
void writeDepthRawFloat(const Frame& frame, const std::filesystem::path& destination);

// The depth a frame gets from a uint16 millimetre PNG (0 invalid; 65535 too, as 7-Scenes uses it).
DepthSource millimetreDepth(const std::filesystem::path& path);

// For formats that only know mapping and query: unassigned frames travel with the mapping ones.
bool isQuerySide(const Frame& frame);

// Frame names as relative paths a writer can put under its output folder: leading ".." parts
// (images outside the dataset folder) dropped. Throws InputError naming both frames when two
// names then coincide.
std::vector<std::string> portableFrameNames(const Scene& scene);

// A file stem per frame, unique within the scene, for formats that pair files by the stem before
// the first '.': the portable name's folders joined by '_' (their dots made '_' too) and its file
// name cut at the first '.'
// ("seq-01/frame-000000.color.png" -> "seq-01_frame-000000"). Throws InputError naming both
// frames when two stems coincide.
std::vector<std::string> uniqueFrameStems(const Scene& scene);

// Bit-for-bit equal intrinsics (size, K and distortion).
bool sameIntrinsics(const Intrinsics& a, const Intrinsics& b);

bool endsWith(const std::string& text, const std::string& suffix);

// Throws InputError naming the first distorted frame: `format` has no field for distortion.
void requireNoDistortion(const Scene& scene, const std::string& format);

// The extension of the frame's image file (".png", ".jpg").
std::string imageExtension(const Frame& frame);

}  // namespace ffloc
