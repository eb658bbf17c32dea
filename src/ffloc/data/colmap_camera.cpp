#include "ffloc/data/colmap_camera.h"

#include <algorithm>

namespace ffloc {
namespace {

struct ModelSpec {
  const char* name;
  size_t parameters;
};

const ModelSpec kModels[] = {{"SIMPLE_PINHOLE", 3}, {"PINHOLE", 4}, {"SIMPLE_RADIAL", 4},
                             {"RADIAL", 5},         {"OPENCV", 8},  {"FULL_OPENCV", 12}};

}  // namespace

const char* const kSupportedColmapModels = "SIMPLE_PINHOLE, PINHOLE, SIMPLE_RADIAL, RADIAL, OPENCV, FULL_OPENCV";

std::optional<size_t> colmapModelParameterCount(const std::string& model) {
  const auto spec =
      std::find_if(std::begin(kModels), std::end(kModels), [&](const ModelSpec& m) { return model == m.name; });
  if (spec == std::end(kModels)) return std::nullopt;
  return spec->parameters;
}

Intrinsics colmapIntrinsics(const std::string& model, const std::vector<double>& p) {
  Intrinsics K;
  if (model == "SIMPLE_PINHOLE" || model == "SIMPLE_RADIAL" || model == "RADIAL") {
    K.fx = K.fy = p[0];
    K.cx = p[1];
    K.cy = p[2];
    if (model == "SIMPLE_RADIAL") K.distortion = {p[3], 0, 0, 0};
    if (model == "RADIAL") K.distortion = {p[3], p[4], 0, 0};
  } else {
    K.fx = p[0];
    K.fy = p[1];
    K.cx = p[2];
    K.cy = p[3];
    // COLMAP's OPENCV and FULL_OPENCV parameter order is OpenCV's: k1 k2 p1 p2 [k3 k4 k5 k6].
    if (model == "OPENCV" || model == "FULL_OPENCV") K.distortion.assign(p.begin() + 4, p.end());
  }
  K.cx -= 0.5;
  K.cy -= 0.5;
  if (std::all_of(K.distortion.begin(), K.distortion.end(), [](double d) { return d == 0.0; })) K.distortion.clear();
  return K;
}

ColmapCamera colmapCamera(const Intrinsics& K) {
  ColmapCamera camera;
  camera.parameters = {K.fx, K.fy, K.cx + 0.5, K.cy + 0.5};
  if (K.distortion.empty()) {
    camera.model = "PINHOLE";
  } else if (K.distortion.size() == 4) {
    camera.model = "OPENCV";
    camera.parameters.insert(camera.parameters.end(), K.distortion.begin(), K.distortion.end());
  } else {
    camera.model = "FULL_OPENCV";
    std::vector<double> coefficients = K.distortion;
    coefficients.resize(8, 0.0);
    camera.parameters.insert(camera.parameters.end(), coefficients.begin(), coefficients.end());
  }
  return camera;
}

}  // namespace ffloc
