#include "ffloc/pipeline/localization_json.h"

namespace ffloc {

nlohmann::json poseJson(const Pose& camera_to_world) {
  nlohmann::json rows = nlohmann::json::array();
  const Eigen::Matrix4d T = camera_to_world.matrix();
  for (int r = 0; r < 4; ++r) rows.push_back({T(r, 0), T(r, 1), T(r, 2), T(r, 3)});
  const Pose world_to_camera = camera_to_world.inverse();
  const Eigen::Quaterniond q = world_to_camera.quaternion();
  return {{"camera_to_world", rows},
          {"world_to_camera", {{"qwxyz", {q.w(), q.x(), q.y(), q.z()}},
                               {"t", {world_to_camera.t.x(), world_to_camera.t.y(), world_to_camera.t.z()}}}}};
}

nlohmann::json localizationJson(const std::string& name, const LocalizationResult& result, const MapFile& map) {
  nlohmann::json out = {{"name", name}, {"status", result.pnp.ok() ? "success" : toString(result.pnp.status)}};
  if (result.pnp.ok()) out.update(poseJson(result.pnp.camera_to_world));
  out["inliers"] = result.pnp.inliers;
  out["pnp_correspondences"] = result.pnp.used_correspondences;
  out["confidence"] = result.confidence();
  nlohmann::json selected = nlohmann::json::array();
  for (size_t index : result.prediction.selected) selected.push_back(map.images[index].name);
  out["selected"] = selected;
  const QueryTimings& t = result.prediction.timings;
  out["timings_ms"] = {{"preprocessing", 1e3 * t.preprocessing}, {"retrieval", 1e3 * t.retrieval},
                       {"encoding", 1e3 * t.encoding},           {"decoding", 1e3 * t.decoding},
                       {"pnp", 1e3 * t.pnp},                     {"total", 1e3 * t.total()}};
  return out;
}

}  // namespace ffloc
