#include "ffloc/eval/exports.h"

#include <gtest/gtest.h>

#include <sstream>

#include "ffloc/core/error.h"

namespace ffloc {
namespace {

FrameResult succeeded(const std::string& name, const Pose& pose) {
  FrameResult f;
  f.frame = name;
  f.status = PnpStatus::kSuccess;
  f.estimate = pose;
  f.inliers = 321;
  return f;
}

TEST(Exports, HlocPoseListIsWorldToCamera) {
  Pose pose;
  pose.R = Eigen::AngleAxisd(0.4, Eigen::Vector3d(0, 0, 1)).toRotationMatrix();
  pose.t = Eigen::Vector3d(1, 2, 3);
  FrameResult failed;
  failed.frame = "lost.png";
  const std::string text = hlocPoseList({succeeded("seq1/a.png", pose), failed});
  std::istringstream in(text);
  std::string name;
  double qw, qx, qy, qz, tx, ty, tz;
  in >> name >> qw >> qx >> qy >> qz >> tx >> ty >> tz;
  EXPECT_EQ(name, "seq1/a.png");
  const Pose world_to_camera = Pose::fromQuaternion(qw, qx, qy, qz, {tx, ty, tz});
  EXPECT_LT((world_to_camera.inverse().matrix() - pose.matrix()).norm(), 1e-9);
  EXPECT_EQ(text.find("lost.png"), std::string::npos);
  EXPECT_NE(mapFreeSubmission({succeeded("q.jpg", pose)}).find(" 321\n"), std::string::npos);
}

// A name with a space or a newline was written as it was, and read back as another name and
// numbers, or as two lines.
TEST(Exports, PoseListsRefuseNamesTheirReadersWouldSplit) {
  for (const std::string name : {"with space.png", "two\nlines.png", "tab\t.png", "bell\a.png", "", "latin1 \xE9.png"}) {
    EXPECT_FALSE(poseListNameProblem(name).empty()) << name;
    try {
      hlocPoseList({succeeded(name, Pose())});
      ADD_FAILURE() << "wrote '" << name << "'";
    } catch (const InputError& e) {
      EXPECT_EQ(std::string(e.what()).rfind("poses: frame '" + name + "': ", 0), 0u) << e.what();
    }
    EXPECT_THROW(mapFreeSubmission({succeeded(name, Pose())}), InputError) << name;
  }
  EXPECT_EQ(poseListNameProblem("seq-01/caf\xC3\xA9-\xE2\x82\xAC.png"), "");
  EXPECT_EQ(hlocPoseList({succeeded("seq-01/caf\xC3\xA9.png", Pose())}).rfind("seq-01/caf\xC3\xA9.png 1 0 0 0 ", 0), 0u);
}

TEST(Exports, PlyHeaderCountsMatchTheBody) {
  PlyWriter ply;
  ply.addPoint({0, 0, 1}, PlyWriter::kRed);
  ply.addCamera(Pose(), Intrinsics{500, 500, 320, 240, 640, 480, {}}, 0.1, PlyWriter::kGreen);
  const std::string text = ply.str();
  EXPECT_NE(text.find("element vertex 6\n"), std::string::npos);
  EXPECT_NE(text.find("element face 4\n"), std::string::npos);
  const auto body = text.substr(text.find("end_header\n") + 11);
  EXPECT_EQ(std::count(body.begin(), body.end(), '\n'), 10);
  // The frustum base lies `size` along the optical axis.
  EXPECT_NE(body.find(" 0.1 40 200 40"), std::string::npos);
}

}  // namespace
}  // namespace ffloc
