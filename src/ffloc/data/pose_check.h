#pragma once

#include <Eigen/Core>
#include <filesystem>
#include <string>
#include <vector>

#include "ffloc/geometry/camera.h"
#include "ffloc/geometry/pose.h"

// The checks every reader applies to a pose it parses.
namespace ffloc {

// Scene units from the origin beyond which a camera centre is refused: geocentric coordinates in
// metres stay below 1e7, while centres near 1e300 overflow the maps' points to infinity.
inline constexpr double kMaxCameraDistance = 1e9;

// What is wrong with a 4x4 camera-to-world matrix (non-finite, last row not 0 0 0 1, camera centre
// beyond kMaxCameraDistance, rotation not orthonormal within 1e-2), or an empty string when
// nothing is.
std::string poseMatrixProblem(const Eigen::Matrix4d& T);
// What is wrong with a camera centre (beyond kMaxCameraDistance or not finite), or "".
std::string cameraCentreProblem(const Eigen::Vector3d& centre);
std::string rotationProblem(const Eigen::Matrix3d& R);

// The checked matrix as a Pose, its rotation re-orthonormalised (parsed text loses digits).
// `row_lines`: the line each row of T was read from (3 for a file of the top three rows). Throws
// InputError "<file>:<line of the row at fault>: <problem>".
Pose validatedPose(const Eigen::Matrix4d& T, const std::filesystem::path& file, const std::vector<int>& row_lines);
Eigen::Matrix3d validatedRotation(const Eigen::Matrix3d& R, const std::filesystem::path& file, int line);

// Whether `frame` is the pose a map stores for the same image: equal up to the digits a pose
// exported again loses. Another image under the same name is centimetres or degrees away.
bool isSamePoseAsMapped(const Pose& mapped, const Pose& frame);

// An append skips the frames whose name the map already holds, as the same images again. Under
// such a name with another pose is another image (a second dataset named alike, whose frames the
// skip left out without a word): InputError naming the dataset, the frame and how far apart the
// two poses are.
void requireSamePoseAsMapped(const std::filesystem::path& dataset, const std::string& name, const Pose& mapped,
                             const Pose& frame);

// The same for the camera: the same viewpoints taken again with another camera or at another
// size, under the same names, were skipped as mapped (found by an outside probe). `mapped` and
// `frame` as the map stores the image's camera; sizes are compared where both are known, focal
// lengths and principal points up to the digits an export loses.
void requireSameCameraAsMapped(const std::filesystem::path& dataset, const std::string& name, const Intrinsics& mapped,
                               const Intrinsics& frame);

}  // namespace ffloc
