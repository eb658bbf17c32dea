#include "ffloc/eval/scene_ply.h"

#include <algorithm>
#include <map>

namespace ffloc {

double cameraGlyphSize(const std::vector<Pose>& cameras) {
  if (cameras.empty()) return 1;
  Eigen::Vector3d low = cameras.front().t, high = cameras.front().t;
  for (const Pose& camera : cameras) {
    low = low.cwiseMin(camera.t);
    high = high.cwiseMax(camera.t);
  }
  const double extent = (high - low).maxCoeff();
  return extent > 0 ? 0.05 * extent : 1.0;
}

void addPredictedPoints(PlyWriter& ply, const Correspondences& pairs, float min_confidence, size_t max_points,
                        PlyWriter::Colour colour) {
  std::vector<size_t> kept;
  for (size_t i = 0; i < pairs.size(); ++i)
    if (pairs.confidences[i] >= min_confidence && pairs.points[i].allFinite()) kept.push_back(i);
  const size_t stride = max_points == 0 ? 1 : std::max<size_t>(1, (kept.size() + max_points - 1) / max_points);
  for (size_t k = 0; k < kept.size(); k += stride) ply.addPoint(pairs.points[kept[k]], colour);
}

PlyWriter evaluationPly(const Scene& scene, const std::vector<FrameResult>& frames, const Correspondences* points,
                        float min_confidence) {
  std::vector<Pose> mapping;
  for (size_t index : scene.mappingIndices()) mapping.push_back(scene.frames[index].camera_to_world);
  const double size = cameraGlyphSize(mapping);
  std::map<std::string, const Frame*> by_name;
  for (const Frame& frame : scene.frames) by_name[frame.name] = &frame;

  PlyWriter ply;
  for (size_t index : scene.mappingIndices())
    ply.addCamera(scene.frames[index].camera_to_world, scene.frames[index].intrinsics, size, PlyWriter::kGrey);
  for (const FrameResult& result : frames) {
    const auto frame = by_name.find(result.frame);
    if (frame == by_name.end()) continue;
    ply.addCamera(result.truth, frame->second->intrinsics, size, PlyWriter::kGreen);
    if (result.succeeded()) ply.addCamera(result.estimate, frame->second->intrinsics, size, PlyWriter::kBlue);
  }
  if (points) addPredictedPoints(ply, *points, min_confidence, 50000, PlyWriter::kRed);
  return ply;
}

}  // namespace ffloc
