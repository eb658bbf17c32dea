#pragma once

#include <string>

#include <nlohmann/json.hpp>

#include "ffloc/geometry/pose.h"
#include "ffloc/localization/localizer.h"

namespace ffloc {

// {"camera_to_world": 4x4 rows, "world_to_camera": {"qwxyz": [...], "t": [...]}}: the pose in
// the project's convention and in the one COLMAP and hloc write.
nlohmann::json poseJson(const Pose& camera_to_world);

// What `ffloc localize --json` prints and the server answers for one query, the same for every
// method: name, method, status (localized, uncertain or failed) and why, the pose (for
// localized and uncertain), the evidence, the selected map images by name and the time of each
// stage in milliseconds.
nlohmann::json localizationJson(const std::string& name, const LocalizationResult& result, const Localizer& localizer);

// value.dump() with text that is not UTF-8 (a file name, a request field) replaced rather than
// thrown on; indent as dump's.
std::string jsonText(const nlohmann::json& value, int indent = -1);

}  // namespace ffloc
