#pragma once

#include <string>

#include <nlohmann/json.hpp>

#include "ffloc/geometry/pose.h"
#include "ffloc/io/map_file.h"
#include "ffloc/pipeline/localizer.h"

namespace ffloc {

// {"camera_to_world": 4x4 rows, "world_to_camera": {"qwxyz": [...], "t": [...]}}: the pose in
// the project's convention and in the one COLMAP and hloc write.
nlohmann::json poseJson(const Pose& camera_to_world);

// What `ffloc localize --json` prints and the server answers for one query: name, status,
// pose (on success), inliers, the pairs PnP used, confidence, the selected map images by name
// and the time of each stage in milliseconds.
nlohmann::json localizationJson(const std::string& name, const LocalizationResult& result, const MapFile& map);

}  // namespace ffloc
