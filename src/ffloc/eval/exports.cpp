#include "ffloc/eval/exports.h"

#include <sstream>

#include "ffloc/core/error.h"
#include "ffloc/core/utf8.h"
#include "ffloc/eval/report.h"

namespace ffloc {
namespace {

// One line per succeeded frame: `name qw qx qy qz tx ty tz` (world-to-camera), then the inlier
// count when asked for.
std::string worldToCameraLines(const std::vector<FrameResult>& frames, bool with_inliers) {
  std::ostringstream out;
  out.precision(12);
  for (const FrameResult& f : frames) {
    if (!f.succeeded()) continue;
    const std::string problem = poseListNameProblem(f.frame);
    if (!problem.empty()) throw InputError("poses: frame '" + f.frame + "': " + problem);
    const Pose world_to_camera = f.estimate.inverse();
    const Eigen::Quaterniond q = world_to_camera.quaternion();
    out << f.frame << " " << q.w() << " " << q.x() << " " << q.y() << " " << q.z() << " " << world_to_camera.t.x()
        << " " << world_to_camera.t.y() << " " << world_to_camera.t.z();
    if (with_inliers) out << " " << f.inliers;
    out << "\n";
  }
  return out.str();
}

}  // namespace

std::string poseListNameProblem(const std::string& name) {
  if (name.empty()) return "the name is empty";
  for (const char c : name) {
    if (c == ' ' || c == '\t' || c == '\n' || c == '\r' || c == '\v' || c == '\f')
      return "the name holds whitespace, which separates the fields of a pose list";
    if (static_cast<unsigned char>(c) < 0x20 || c == 0x7F) return "the name holds a control character";
  }
  if (!isUtf8(name)) return "the name is not UTF-8";
  return "";
}

std::string hlocPoseList(const std::vector<FrameResult>& frames) { return worldToCameraLines(frames, false); }

std::string mapFreeSubmission(const std::vector<FrameResult>& frames) { return worldToCameraLines(frames, true); }

void PlyWriter::addPoint(const Eigen::Vector3d& point, Colour colour) { vertices_.push_back({point, colour}); }

void PlyWriter::addCamera(const Pose& camera_to_world, const Intrinsics& intrinsics, double size, Colour colour) {
  const int apex = static_cast<int>(vertices_.size());
  vertices_.push_back({camera_to_world.t, colour});
  const double half_w = 0.5 * intrinsics.width / intrinsics.fx * size;
  const double half_h = 0.5 * intrinsics.height / intrinsics.fy * size;
  const Eigen::Vector3d corners[4] = {
      {-half_w, -half_h, size}, {half_w, -half_h, size}, {half_w, half_h, size}, {-half_w, half_h, size}};
  for (const auto& corner : corners) vertices_.push_back({camera_to_world * corner, colour});
  for (int i = 0; i < 4; ++i) faces_.push_back({apex, apex + 1 + i, apex + 1 + (i + 1) % 4});
}

std::string PlyWriter::str() const {
  std::ostringstream out;
  out << "ply\nformat ascii 1.0\ncomment written by ffloc\n"
      << "element vertex " << vertices_.size() << "\n"
      << "property float x\nproperty float y\nproperty float z\n"
      << "property uchar red\nproperty uchar green\nproperty uchar blue\n"
      << "element face " << faces_.size() << "\nproperty list uchar int vertex_indices\nend_header\n";
  out.precision(9);
  for (const Vertex& v : vertices_)
    out << v.position.x() << " " << v.position.y() << " " << v.position.z() << " " << int(v.colour[0]) << " "
        << int(v.colour[1]) << " " << int(v.colour[2]) << "\n";
  for (const auto& f : faces_) out << "3 " << f[0] << " " << f[1] << " " << f[2] << "\n";
  return out.str();
}

void PlyWriter::write(const std::filesystem::path& path) const { writeTextFile(path, str()); }

}  // namespace ffloc
