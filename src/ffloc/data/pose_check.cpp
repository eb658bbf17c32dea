#include "ffloc/data/pose_check.h"

#include <algorithm>
#include <cmath>
#include <sstream>

#include "ffloc/core/error.h"

namespace ffloc {

std::string rotationProblem(const Eigen::Matrix3d& R) {
  if (!R.allFinite()) return "rotation has a non-finite value (NaN or inf)";
  Eigen::Matrix3d projected = R;
  if (projectToRotation(projected)) return "";
  std::ostringstream what;
  // An orthonormal matrix of determinant -1 mirrors the scene (a flipped axis convention): said
  // so, it was reported as "not orthonormal".
  if (orthogonalityError(R) <= 1e-2 && R.determinant() < 0)
    what << "rotation is a reflection (det " << R.determinant() << "): an axis is flipped";
  else
    what << "rotation is not orthonormal (det " << R.determinant() << ", max |R^T R - I| " << orthogonalityError(R)
         << ")";
  return what.str();
}

namespace {

// poseMatrixProblem, and in `row` the row (0-3) at fault: the first holding a non-finite value,
// the last, the one of the largest translation for a centre too far away, else the first (the
// rotation spans three rows).
std::string poseMatrixProblemAt(const Eigen::Matrix4d& T, Eigen::Index* row) {
  for (*row = 0; *row < 4; ++*row)
    if (!T.row(*row).allFinite()) return "pose has a non-finite value (NaN or inf)";
  *row = 3;
  const Eigen::RowVector4d last = T.row(3);
  if ((last - Eigen::RowVector4d(0, 0, 0, 1)).cwiseAbs().maxCoeff() > 1e-6) {
    std::ostringstream what;
    what << "pose's last row is (" << last << "), expected (0 0 0 1)";
    return what.str();
  }
  T.topRightCorner<3, 1>().cwiseAbs().maxCoeff(row);
  const std::string centre = cameraCentreProblem(T.topRightCorner<3, 1>());
  if (!centre.empty()) return centre;
  *row = 0;
  return rotationProblem(T.topLeftCorner<3, 3>());
}

}  // namespace

std::string poseMatrixProblem(const Eigen::Matrix4d& T) {
  Eigen::Index row = 0;
  return poseMatrixProblemAt(T, &row);
}

std::string cameraCentreProblem(const Eigen::Vector3d& centre) {
  const double distance = centre.stableNorm();
  if (distance <= kMaxCameraDistance) return "";
  std::ostringstream what;
  what << "camera centre is " << distance << " from the origin, beyond the " << kMaxCameraDistance
       << " that any scene fits in";
  return what.str();
}

Pose validatedPose(const Eigen::Matrix4d& T, const std::filesystem::path& file, const std::vector<int>& row_lines) {
  // A translation of 1e308 on line 1 was blamed on the file's last line.
  Eigen::Index row = 0;
  const std::string problem = poseMatrixProblemAt(T, &row);
  if (!problem.empty())
    throwInputError(file.string(), row_lines[std::min(static_cast<size_t>(row), row_lines.size() - 1)], problem);
  Pose pose = Pose::fromMatrix(T);
  projectToRotation(pose.R);
  return pose;
}

Eigen::Matrix3d validatedRotation(const Eigen::Matrix3d& R, const std::filesystem::path& file, int line) {
  const std::string problem = rotationProblem(R);
  if (!problem.empty()) throwInputError(file.string(), line, problem);
  Eigen::Matrix3d projected = R;
  projectToRotation(projected);
  return projected;
}

bool isSamePoseAsMapped(const Pose& mapped, const Pose& frame) {
  // A map stores the reader's pose exactly (JSON keeps every digit). The slack lets the same
  // images through with poses exported again at fewer digits (6 give 1e-6).
  return translationError(mapped, frame) <= 1e-5 * std::max(1.0, mapped.t.norm()) &&
         rotationErrorDeg(mapped, frame) <= 1e-3;
}

void requireSamePoseAsMapped(const std::filesystem::path& dataset, const std::string& name, const Pose& mapped,
                             const Pose& frame) {
  if (isSamePoseAsMapped(mapped, frame)) return;
  std::ostringstream what;
  what << "frame '" << name << "' is already in the map with another pose (" << translationError(mapped, frame)
       << " apart, " << rotationErrorDeg(mapped, frame)
       << " deg): an append adds images by name, so this is another image under a mapped name; rename it, or "
          "map without appending";
  throwInputError(dataset.string(), 0, what.str());
}

void requireSameCameraAsMapped(const std::filesystem::path& dataset, const std::string& name, const Intrinsics& mapped,
                               const Intrinsics& frame) {
  const bool sizes_known = mapped.width > 0 && frame.width > 0;
  const bool same_size = !sizes_known || (mapped.width == frame.width && mapped.height == frame.height);
  const double slack = 1e-5 * std::max(1.0, std::abs(mapped.fx));
  const bool same_camera = std::abs(mapped.fx - frame.fx) <= slack && std::abs(mapped.fy - frame.fy) <= slack &&
                           std::abs(mapped.cx - frame.cx) <= slack && std::abs(mapped.cy - frame.cy) <= slack;
  if (same_size && same_camera) return;
  std::ostringstream what;
  what << "frame '" << name << "' is already in the map with another camera (";
  if (!same_size)
    what << mapped.width << "x" << mapped.height << " mapped, " << frame.width << "x" << frame.height << " now";
  else
    what << "fx, fy, cx, cy " << mapped.fx << ", " << mapped.fy << ", " << mapped.cx << ", " << mapped.cy << " mapped, "
         << frame.fx << ", " << frame.fy << ", " << frame.cx << ", " << frame.cy << " now";
  what << "): an append adds images by name, so this is another image under a mapped name; rename it, or map "
          "without appending";
  throwInputError(dataset.string(), 0, what.str());
}

}  // namespace ffloc
