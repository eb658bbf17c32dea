// kapture (NAVER LABS, format 1.1): sensors/sensors.txt (camera models named as COLMAP names
// them), records_camera.txt, trajectories.txt (world-to-device), optional rigs.txt and
// records_depth.txt, files under sensors/records_data/. A dataset is one such folder, or
// mapping/ and query/ folders each holding one.
#include <algorithm>
#include <cctype>
#include <map>
#include <regex>
#include <set>

#include "ffloc/core/error.h"
#include "ffloc/data/colmap_camera.h"
#include "ffloc/data/dataset_writers.h"
#include "ffloc/data/format_io.h"
#include "ffloc/data/pose_check.h"
#include "ffloc/data/readers.h"
#include "ffloc/data/text_file.h"

namespace ffloc {
namespace {

namespace fs = std::filesystem;

constexpr const char* kHeader = "# kapture format: 1.1\n";
const std::pair<const char*, Split> kKaptureFolders[] = {
    {"", Split::kUnassigned}, {"mapping", Split::kMapping}, {"query", Split::kQuery}};

// kapture text: comma-separated values, spaces around commas ignored, '#' lines are comments.
struct CsvLine {
  int number = 0;
  std::vector<std::string> fields;
};

// The versions whose sensors/ files read alike: kapture's 1.0 -> 1.1 upgrade rewrites only their
// header line. A later version may lay its columns out otherwise, and was read as 1.1. The version
// is found as kapture's readers find it, a search of the first line for digits.digits after
// 'kapture format:' (so '# kapture format: 1.1 (note)' was refused), spaces around '#' and ':'
// allowed as kapture's C++ reader allows them (so '#kapture format: 2.0' was read as 1.1).
void requireReadableVersion(const std::vector<TextLine>& lines, const fs::path& file) {
  static const std::regex kVersionLine(R"(#\s*kapture format\s*:\s*(\d+\.\d+))");
  std::smatch match;
  if (lines.empty() || !std::regex_search(lines[0].text, match, kVersionLine)) return;
  const std::string version = match[1];
  if (version != "1.0" && version != "1.1")
    throwInputError(file.string(), lines[0].number,
                    "kapture format '" + version + "' is not one ffloc reads (1.0, 1.1)");
}

std::vector<CsvLine> readCsv(const fs::path& file) {
  std::vector<TextLine> lines = readTextLines(file);
  requireReadableVersion(lines, file);
  std::vector<CsvLine> rows;
  for (const auto& line : contentLines(std::move(lines), true)) {
    CsvLine row{line.number, {}};
    size_t start = 0;
    while (true) {
      const size_t comma = line.text.find(',', start);
      row.fields.emplace_back(
          trimmed(std::string_view(line.text).substr(start, comma == std::string::npos ? std::string::npos : comma - start)));
      if (comma == std::string::npos) break;
      start = comma + 1;
    }
    rows.push_back(std::move(row));
  }
  return rows;
}

// Timestamps are unsigned integers and compared as numbers, as kapture's own reader does ("0000" is
// "0"): compared as text, a depth record at "0000" missed the image at "0", which went on without
// depth.
long readTimestamp(const CsvLine& row, const fs::path& file) {
  const long timestamp = parseInteger(row.fields[0], file, row.number, "timestamp");
  if (timestamp < 0)
    throwInputError(file.string(), row.number,
                    "timestamp " + row.fields[0] + " is negative (kapture timestamps are unsigned integers)");
  return timestamp;
}

struct Sensor {
  std::string type;  // "camera", "depth", ...
  Intrinsics intrinsics;
  int line = 0;
};

std::map<std::string, Sensor> readSensors(const fs::path& file) {
  std::map<std::string, Sensor> sensors;
  for (const CsvLine& row : readCsv(file)) {
    if (row.fields.size() < 3) throwInputError(file.string(), row.number, "expected 'sensor_device_id, name, sensor_type, ...'");
    Sensor sensor{row.fields[2], {}, row.number};
    // Other sensor types (gnss, wifi, lidar, ...) are skipped; a camera model in the type's place
    // is a line missing its name column, whose camera was skipped and its images then blamed.
    if (colmapModelParameterCount(sensor.type))
      throwInputError(file.string(), row.number,
                      "sensor type '" + sensor.type + "' is a camera model: expected 'sensor_device_id, name, camera, " +
                          sensor.type + ", ...' (is the name column missing? it may be empty, not absent)");
    if (sensor.type == "camera" || sensor.type == "depth") {
      if (row.fields.size() < 6)
        throwInputError(file.string(), row.number, "expected '..., " + sensor.type + ", model, width, height, parameters'");
      const std::string& model = row.fields[3];
      const auto count = colmapModelParameterCount(model);
      if (!count)
        throwInputError(file.string(), row.number,
                        "unsupported camera model '" + model + "' (supported: " + kSupportedColmapModels + ")");
      if (row.fields.size() != 6 + *count)
        throwInputError(file.string(), row.number,
                        model + " takes width, height and " + std::to_string(*count) + " parameters, found " +
                            std::to_string(row.fields.size() - 4) + " values");
      std::vector<double> parameters;
      for (size_t i = 6; i < row.fields.size(); ++i)
        parameters.push_back(parseDouble(row.fields[i], file, row.number, "parameter " + std::to_string(i - 5)));
      sensor.intrinsics = colmapIntrinsics(model, parameters);
      sensor.intrinsics.width = static_cast<int>(parseInteger(row.fields[4], file, row.number, "width"));
      sensor.intrinsics.height = static_cast<int>(parseInteger(row.fields[5], file, row.number, "height"));
      requireLensDistortion(sensor.intrinsics, file, row.number);
      if (!sensor.intrinsics.isValid())
        throwInputError(file.string(), row.number, "invalid camera (size and focal length must be positive)");
    }
    if (!sensors.emplace(row.fields[0], sensor).second)
      throwInputError(file.string(), row.number, "duplicate sensor_device_id '" + row.fields[0] + "'");
  }
  return sensors;
}

// "qw, qx, qy, qz, tx, ty, tz" starting at field `first`, as a world-to-device (or rig-to-sensor)
// transform; returned as the inverse, device-to-world (sensor-to-rig).
Pose readDeviceToWorld(const CsvLine& row, size_t first, const fs::path& file) {
  const char* names[] = {"qw", "qx", "qy", "qz", "tx", "ty", "tz"};
  double v[7];
  for (int k = 0; k < 7; ++k) v[k] = parseDouble(row.fields[first + k], file, row.number, names[k]);
  return cameraToWorldFromQuaternion(v, Eigen::Vector3d(v[4], v[5], v[6]), file, row.number);
}

using TimedDevice = std::pair<long, std::string>;  // (timestamp, device_id)

struct KaptureFolder {
  fs::path root;  // the folder holding sensors/
  std::map<std::string, Sensor> sensors;
  std::map<std::string, std::pair<std::string, Pose>> rig_of_sensor;  // sensor -> (rig, sensor-to-rig)
  std::map<TimedDevice, Pose> device_to_world;
};

KaptureFolder readFolderGeometry(const fs::path& root) {
  KaptureFolder folder;
  folder.root = root;
  const fs::path sensors = root / "sensors";
  folder.sensors = readSensors(sensors / "sensors.txt");
  if (fs::exists(sensors / "rigs.txt")) {
    // A sensor placed in a rig twice took the last line's place silently (poses 6 units off).
    std::map<std::string, int> line_of_sensor;
    for (const CsvLine& row : readCsv(sensors / "rigs.txt")) {
      if (row.fields.size() != 9)
        throwInputError((sensors / "rigs.txt").string(), row.number,
                        "expected 'rig_device_id, sensor_device_id, qw, qx, qy, qz, tx, ty, tz'");
      if (const auto [first, added] = line_of_sensor.emplace(row.fields[1], row.number); !added)
        throwInputError((sensors / "rigs.txt").string(), row.number,
                        "sensor '" + row.fields[1] + "' is placed in a rig again (first on line " +
                            std::to_string(first->second) + ")");
      folder.rig_of_sensor[row.fields[1]] = {row.fields[0], readDeviceToWorld(row, 2, sensors / "rigs.txt")};
    }
  }
  const fs::path trajectories = sensors / "trajectories.txt";
  if (fs::exists(trajectories))
    for (const CsvLine& row : readCsv(trajectories)) {
      if (row.fields.size() != 9)
        throwInputError(trajectories.string(), row.number, "expected 'timestamp, device_id, qw, qx, qy, qz, tx, ty, tz'");
      // The last of two poses for one (timestamp, device) won: a frame got another frame's pose as
      // its ground truth, and was scored against it.
      const Pose device_to_world = readDeviceToWorld(row, 2, trajectories);
      // Named here: a centre 1e300 out was blamed on the image's line of records_camera.txt (an
      // outside probe), where NaN was already named here.
      if (const std::string centre = cameraCentreProblem(device_to_world.t); !centre.empty())
        throwInputError(trajectories.string(), row.number, "device '" + row.fields[1] + "': " + centre);
      const auto [entry, added] =
          folder.device_to_world.emplace(TimedDevice{readTimestamp(row, trajectories), row.fields[1]}, device_to_world);
      if (!added)
        throwInputError(trajectories.string(), row.number,
                        "a second pose for timestamp " + row.fields[0] + ", device '" + row.fields[1] + "'");
    }
  return folder;
}

// The sensor's pose at `timestamp`: its own trajectory entry, or its rig's composed with its
// place on the rig.
std::optional<Pose> sensorToWorld(const KaptureFolder& folder, long timestamp, const std::string& sensor) {
  if (const auto own = folder.device_to_world.find({timestamp, sensor}); own != folder.device_to_world.end())
    return own->second;
  const auto rig = folder.rig_of_sensor.find(sensor);
  if (rig == folder.rig_of_sensor.end()) return std::nullopt;
  const auto rig_pose = folder.device_to_world.find({timestamp, rig->second.first});
  if (rig_pose == folder.device_to_world.end()) return std::nullopt;
  return rig_pose->second * rig->second.second;
}

// A second record of one (timestamp, device) is refused: both images got the pose of that instant,
// so one of them was scored against the other's (records_camera.txt), or one depth map was paired
// and the other dropped (records_depth.txt).
void requireFirstRecord(std::map<TimedDevice, int>& line_of_record, const TimedDevice& record, const CsvLine& row,
                        const fs::path& file) {
  const auto [first, added] = line_of_record.emplace(record, row.number);
  if (!added)
    throwInputError(file.string(), row.number,
                    "a second record for timestamp " + row.fields[0] + ", device '" + record.second + "' (first on line " +
                        std::to_string(first->second) + ")");
}

struct DepthRecord {
  long timestamp = 0;
  std::string sensor;
  fs::path path;
  int line = 0;
};

// Poses as text agree only to their printed digits.
bool samePose(const Pose& a, const Pose& b) { return (a.matrix() - b.matrix()).cwiseAbs().maxCoeff() <= 1e-6; }

std::string listed(const std::vector<size_t>& frames, const Scene& scene) {
  std::string text;
  for (size_t i : frames) text += (text.empty() ? "" : " and ") + scene.frames[i].image_path.string();
  return text;
}

// ffloc reads only registered depth, a map in its colour image's pixel grid: what a depth sensor
// with its colour camera's intrinsics records. A record belongs to the image of its instant whose
// camera has its sensor's intrinsics and, where the data gives the sensor a pose (ffloc's writer
// gives it its camera's), that pose. A sensor whose intrinsics are no camera's (an Azure Kinect's
// 640x576 depth beside its 1280x720 colour) records in a grid of its own, which ffloc does not
// read: its records are not used, and its images go without depth. Paired by size instead, two
// cameras of one size both took the first depth map of their instant and the second was dropped.
void pairDepthRecords(const std::vector<DepthRecord>& records, const KaptureFolder& folder,
                      const std::multimap<long, size_t>& frames_at, const fs::path& depth_file, Scene& scene) {
  std::map<size_t, int> depth_line_of_frame;
  for (const DepthRecord& record : records) {
    const Intrinsics& depth_camera = folder.sensors.at(record.sensor).intrinsics;
    std::vector<size_t> same_grid;
    const auto [first, end] = frames_at.equal_range(record.timestamp);
    for (auto it = first; it != end; ++it)
      if (sameIntrinsics(scene.frames[it->second].intrinsics, depth_camera)) same_grid.push_back(it->second);
    if (same_grid.empty()) continue;
    std::vector<size_t> owners = same_grid;
    const std::optional<Pose> pose = sensorToWorld(folder, record.timestamp, record.sensor);
    if (pose)
      owners.erase(std::remove_if(owners.begin(), owners.end(),
                                  [&](size_t i) { return !samePose(scene.frames[i].camera_to_world, *pose); }),
                   owners.end());
    const std::string map_name = "depth map " + record.path.string() + " (sensor '" + record.sensor + "')";
    if (owners.empty())
      throwInputError(depth_file.string(), record.line,
                      map_name + " has the intrinsics of " + listed(same_grid, scene) +
                          " of its timestamp but another pose: it is not in their pixel grid");
    if (owners.size() > 1)
      throwInputError(depth_file.string(), record.line,
                      map_name + " could be the depth of " + listed(owners, scene) + " of its timestamp: " +
                          (pose ? "each has its intrinsics and pose"
                                : "each has its intrinsics, and the sensor has no pose (trajectories.txt or rigs.txt) "
                                  "to tell which is its own"));
    Frame& frame = scene.frames[owners.front()];
    const auto [earlier, added] = depth_line_of_frame.emplace(owners.front(), record.line);
    if (!added)
      throwInputError(depth_file.string(), record.line,
                      map_name + " belongs to " + frame.image_path.string() + ", which has the depth map of line " +
                          std::to_string(earlier->second));
    // A missing file is left to readDepthMetres, which refuses it by name when the map is read.
    std::error_code missing;
    const std::uintmax_t bytes = fs::file_size(record.path, missing);
    const std::uintmax_t expected = static_cast<std::uintmax_t>(depth_camera.width) * depth_camera.height * sizeof(float);
    if (!missing && bytes != expected)
      throwInputError(depth_file.string(), record.line,
                      map_name + " has " + std::to_string(bytes) + " bytes, but the sensor is " +
                          std::to_string(depth_camera.width) + "x" + std::to_string(depth_camera.height) + " (" +
                          std::to_string(expected) + " bytes of float32)");
    DepthSource depth;
    depth.path = record.path;
    depth.scale = 1.0;  // float32 metres
    depth.invalid_values.clear();
    frame.depth = depth;
  }
}

void readFolder(const fs::path& root, const fs::path& dataset_dir, Split split, Scene& scene) {
  const KaptureFolder folder = readFolderGeometry(root);
  const fs::path sensors_dir = root / "sensors";
  const fs::path data_dir = sensors_dir / "records_data";
  std::vector<DepthRecord> depth_records;
  const fs::path depth_file = sensors_dir / "records_depth.txt";
  if (fs::exists(depth_file)) {
    std::map<TimedDevice, int> line_of_record;
    for (const CsvLine& row : readCsv(depth_file)) {
      if (row.fields.size() != 3) throwInputError(depth_file.string(), row.number, "expected 'timestamp, device_id, depth_map_path'");
      const auto sensor = folder.sensors.find(row.fields[1]);
      if (sensor == folder.sensors.end() || sensor->second.type != "depth")
        throwInputError(depth_file.string(), row.number, "'" + row.fields[1] + "' is not a depth sensor in sensors.txt");
      const long timestamp = readTimestamp(row, depth_file);
      requireFirstRecord(line_of_record, {timestamp, row.fields[1]}, row, depth_file);
      depth_records.push_back({timestamp, row.fields[1], (data_dir / row.fields[2]).lexically_normal(), row.number});
    }
  }

  const fs::path records = sensors_dir / "records_camera.txt";
  std::multimap<long, size_t> frames_at;  // timestamp -> index into scene.frames
  std::map<TimedDevice, int> line_of_record;
  for (const CsvLine& row : readCsv(records)) {
    if (row.fields.size() != 3) throwInputError(records.string(), row.number, "expected 'timestamp, device_id, image_path'");
    const long timestamp = readTimestamp(row, records);
    const std::string& device = row.fields[1];
    const auto sensor = folder.sensors.find(device);
    if (sensor == folder.sensors.end() || sensor->second.type != "camera")
      throwInputError(records.string(), row.number, "'" + device + "' is not a camera in sensors.txt");
    requireFirstRecord(line_of_record, {timestamp, device}, row, records);
    Frame frame;
    frame.image_path = (data_dir / row.fields[2]).lexically_normal();
    frame.name = frameName(frame.image_path, dataset_dir);
    frame.intrinsics = sensor->second.intrinsics;
    if (!fs::is_regular_file(frame.image_path))
      throwInputError(records.string(), row.number, "image " + frame.image_path.string() + " not found");
    requireImageSize(frame.image_path, frame.intrinsics.width, frame.intrinsics.height,
                     (sensors_dir / "sensors.txt").string(), sensor->second.line);
    const auto pose = sensorToWorld(folder, timestamp, device);
    if (!pose)
      throwInputError(records.string(), row.number,
                      "no pose for image '" + row.fields[2] + "' (timestamp " + row.fields[0] + ", device " + device +
                          ") in trajectories.txt");
    // Here, before the depth records are paired by pose: a camera 1e300 from the origin was
    // reported as a depth map with "another pose".
    if (const std::string centre = cameraCentreProblem(pose->t); !centre.empty())
      throwInputError(records.string(), row.number, "image '" + row.fields[2] + "': " + centre);
    frame.camera_to_world = *pose;
    frame.split = split;
    frames_at.emplace(timestamp, scene.frames.size());
    scene.frames.push_back(std::move(frame));
  }

  if (frames_at.empty()) throwInputError(records.string(), 0, "lists no image");
  pairDepthRecords(depth_records, folder, frames_at, depth_file, scene);
}

}  // namespace

bool looksLikeKapture(const fs::path& dir) {
  for (const auto& [folder, split] : kKaptureFolders)
    if (fs::is_regular_file(dir / folder / "sensors" / "sensors.txt")) return true;
  return false;
}

Scene readKapture(const fs::path& dir) {
  // Named with --format kapture, any folder read as a dataset of no frames, exit 0.
  if (!looksLikeKapture(dir))
    throwInputError(dir.string(), 0, "not a kapture dataset: no sensors/sensors.txt in it, nor in mapping/ or query/");
  Scene scene = emptyScene(dir, "kapture", true);
  for (const auto& [folder, split] : kKaptureFolders) {
    const fs::path sensors = dir / folder / "sensors";
    if (fs::is_regular_file(sensors / "sensors.txt")) {
      readFolder((dir / folder).lexically_normal(), dir, split, scene);
    } else if (fs::exists(sensors)) {
      // Without it the half was skipped whole: a dataset whose mapping half lost its sensors.txt
      // read as its query half alone.
      throwInputError((sensors / "sensors.txt").string(), 0, "not found (kapture's list of the cameras of " +
                                                                   sensors.string() + ")");
    }
  }
  return scene;
}

std::vector<std::string> writeKapture(const Scene& scene, const fs::path& out) {
  const std::vector<std::string> paths = portableFrameNames(scene);
  std::vector<std::string> names(scene.frames.size());
  for (const auto& [folder_name, side_is_query] : {std::pair{"mapping", false}, {"query", true}}) {
    const fs::path sensors_dir = out / folder_name / "sensors";
    std::vector<const Intrinsics*> cameras;
    std::string records, trajectories, depth_records;
    std::set<std::string> depth_paths;
    bool any_depth = false;
    int timestamp = 0;
    for (size_t i = 0; i < scene.frames.size(); ++i) {
      const Frame& frame = scene.frames[i];
      if (isQuerySide(frame) != side_is_query) continue;
      const std::string& path = paths[i];
      if (path.find(',') != std::string::npos)
        throwInputError(frame.name, 0, "kapture paths cannot contain ','");
      // kapture's reader trims every field: such a name would not be found again.
      if (std::isspace(static_cast<unsigned char>(path.front())) || std::isspace(static_cast<unsigned char>(path.back())))
        throwInputError(frame.name, 0, "kapture paths cannot start or end with a space");
      size_t camera = 0;
      while (camera < cameras.size() && !sameIntrinsics(*cameras[camera], frame.intrinsics)) ++camera;
      if (camera == cameras.size()) cameras.push_back(&frame.intrinsics);
      const std::string ts = std::to_string(timestamp++);
      const std::string id = std::to_string(camera);
      const std::string pose = worldToCameraQuaternionText(frame.camera_to_world, ", ");
      copyFrameImage(frame, sensors_dir / "records_data" / path);
      records += ts + ", cam" + id + ", " + path + "\n";
      trajectories += ts + ", cam" + id + ", " + pose + "\n";
      if (frame.depth) {
        const std::string depth = fs::path(path).replace_extension(".depth").generic_string();
        // x.png and x.jpg both wrote x.depth: the second's depth replaced the first's, exit 0.
        if (!depth_paths.insert(depth).second)
          throwInputError(frame.name, 0, "its depth would be written to '" + depth +
                                             "', as another frame's is (names that differ only in their extension); "
                                             "rename one of them");
        writeDepthRawFloat(frame, sensors_dir / "records_data" / depth);
        depth_records += ts + ", depth" + id + ", " + depth + "\n";
        trajectories += ts + ", depth" + id + ", " + pose + "\n";
        any_depth = true;
      }
      names[i] = (fs::path(folder_name) / "sensors" / "records_data" / path).generic_string();
    }
    if (cameras.empty()) continue;
    std::string sensors;
    for (size_t c = 0; c < cameras.size(); ++c) {
      const ColmapCamera camera = colmapCamera(*cameras[c]);
      std::string parameters = camera.model + ", " + std::to_string(cameras[c]->width) + ", " +
                               std::to_string(cameras[c]->height);
      for (double p : camera.parameters) parameters += ", " + formatNumber(p);
      sensors += "cam" + std::to_string(c) + ", , camera, " + parameters + "\n";
      if (any_depth) sensors += "depth" + std::to_string(c) + ", , depth, " + parameters + "\n";
    }
    writeTextCreatingFolders(sensors_dir / "sensors.txt",
                             std::string(kHeader) + "# sensor_device_id, name, sensor_type, [sensor_params]+\n" + sensors);
    writeTextCreatingFolders(sensors_dir / "records_camera.txt",
                             std::string(kHeader) + "# timestamp, device_id, image_path\n" + records);
    writeTextCreatingFolders(sensors_dir / "trajectories.txt",
                             std::string(kHeader) + "# timestamp, device_id, qw, qx, qy, qz, tx, ty, tz\n" + trajectories);
    if (any_depth)
      writeTextCreatingFolders(sensors_dir / "records_depth.txt",
                               std::string(kHeader) + "# timestamp, device_id, depth_map_path\n" + depth_records);
  }
  return names;
}

}  // namespace ffloc
