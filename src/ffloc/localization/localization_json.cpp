#include "ffloc/localization/localization_json.h"

#include <cmath>

#include "ffloc/io/json_fields.h"

namespace ffloc {
namespace {

// An evidence measure that was not taken (negative) or has no finite value (a failed second
// estimate, a pose its inliers do not determine) is null: JSON has no infinity.
nlohmann::json measuredOrNull(double value) {
  return value >= 0 && std::isfinite(value) ? nlohmann::json(value) : nlohmann::json();
}

}  // namespace

std::string jsonText(const nlohmann::json& value, int indent) {
  return value.dump(indent, ' ', false, nlohmann::json::error_handler_t::replace);
}

nlohmann::json poseJson(const Pose& camera_to_world) {
  const Pose world_to_camera = camera_to_world.inverse();
  const Eigen::Quaterniond q = world_to_camera.quaternion();
  return {{"camera_to_world", matrix4Json(camera_to_world.matrix())},
          {"world_to_camera", {{"qwxyz", {q.w(), q.x(), q.y(), q.z()}},
                               {"t", {world_to_camera.t.x(), world_to_camera.t.y(), world_to_camera.t.z()}}}}};
}

nlohmann::json localizationJson(const std::string& name, const LocalizationResult& result, const Localizer& localizer) {
  const PoseVerdict& verdict = result.verdict;
  nlohmann::json out = {{"name", name}, {"method", toString(localizer.method())}, {"status", toString(verdict.status)}};
  if (!verdict.reason.empty()) out["reason"] = verdict.reason;
  if (result.pnp.ok()) out.update(poseJson(result.pnp.camera_to_world));
  const PoseEvidence& e = verdict.evidence;
  out["inliers"] = e.inliers;
  out["pnp_correspondences"] = e.used_correspondences;
  out["evidence"] = {{"inlier_ratio", measuredOrNull(e.inlier_ratio)},
                     {"inlier_spread", measuredOrNull(e.inlier_spread)},
                     {"agreement_translation", measuredOrNull(e.agreement_translation)},
                     {"agreement_rotation_deg", measuredOrNull(e.agreement_rotation_deg)},
                     {"agreement_distance", measuredOrNull(e.agreement_distance)},
                     {"residual_sigma_px", measuredOrNull(e.residual_sigma_px)},
                     {"predicted_centre_sigma", measuredOrNull(e.predicted_centre_sigma)},
                     {"predicted_centre_sigma_relative", measuredOrNull(e.predicted_centre_sigma_relative)},
                     {"predicted_rotation_sigma_deg", measuredOrNull(e.predicted_rotation_sigma_deg)},
                     {"focal_scale", measuredOrNull(e.focal_scale)},
                     {"focal_scale_log_sigma", measuredOrNull(e.focal_scale_log_sigma)},
                     {"focal_aspect", measuredOrNull(e.focal_aspect)},
                     {"focal_aspect_log_sigma", measuredOrNull(e.focal_aspect_log_sigma)},
                     {"principal_point_shift", measuredOrNull(e.principal_point_shift)},
                     {"principal_point_shift_significance", measuredOrNull(e.principal_point_shift_significance)},
                     {"focal_scan_factor", measuredOrNull(e.focal_scan_factor)},
                     {"focal_scan_inlier_gain", measuredOrNull(e.focal_scan_inlier_gain)}};
  nlohmann::json selected = nlohmann::json::array();
  for (size_t index : result.selected) selected.push_back(localizer.cameras().at(index).name);
  out["selected"] = selected;
  const QueryTimings& t = result.timings;
  out["timings_ms"] = {{"preprocessing", 1e3 * t.preprocessing}, {"features", 1e3 * t.features},
                       {"retrieval", 1e3 * t.retrieval},         {"matching", 1e3 * t.matching},
                       {"pnp", 1e3 * t.pnp},                     {"verification", 1e3 * t.verification},
                       {"total", 1e3 * t.total()}};
  return out;
}

}  // namespace ffloc
