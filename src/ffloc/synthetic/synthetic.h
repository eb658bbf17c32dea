#pragma once

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "ffloc/data/scene.h"
#include "ffloc/synthetic/layouts.h"
#include "ffloc/synthetic/render.h"

namespace ffloc {

// Procedural RGB-D scenes with exact ground truth (docs/synthetic.md): colour, z-depth,
// intrinsics and camera-to-world poses all come from one ray per pixel through one geometry,
// so depth and poses agree to float precision.
enum class SceneKind { kIndoor, kOutdoor, kObject };
const char* toString(SceneKind kind);
// "indoor", "outdoor" or "object"; throws InputError naming `field` otherwise.
SceneKind parseSceneKind(const std::string& text, const std::string& field = "kind");
std::vector<SceneKind> allSceneKinds();

struct SyntheticOptions {
  SceneKind kind = SceneKind::kIndoor;
  uint64_t seed = 0;
  int width = 256;
  int height = 192;
  int mapping_frames = 60;
  int query_frames = 15;
  // Horizontal field of view, drawn per scene in [min, max] degrees.
  double min_fov_deg = 55.0;
  double max_fov_deg = 75.0;
  // Standard deviation of additive pixel noise in 8-bit levels (0: clean images).
  double image_noise = 0.0;
  // Relative standard deviation of multiplicative noise on the stored depth (0: exact depth).
  double depth_noise = 0.0;
  int threads = 1;     // render threads (0: all cores); the output does not depend on it
  bool quiet = true;   // no progress bar
};

// The most mapping frames, and the most query frames, of a scene.
constexpr int kMaxSyntheticFrames = 10000;

// Throws InputError naming the option when a value is out of range.
void validate(const SyntheticOptions& options);

// A scene before rendering: its camera, geometry, capture and lighting. Frames are numbered
// mapping first (in scan order), then queries.
struct SyntheticScene {
  SyntheticOptions options;
  Intrinsics camera;
  synthetic::Layout layout;

  int frameCount() const;
  bool isQuery(int frame) const;
  Pose pose(int frame) const;
  const synthetic::Lighting& lighting(int frame) const;
  // "images/mapping_0000.png", "images/query_0003_far.png", ...
  std::string imageName(int frame) const;
  std::string depthName(int frame) const;
};

// Builds the scene for options.seed (pure; no files).
SyntheticScene planSyntheticScene(const SyntheticOptions& options);

// Renders one frame, with the options' noise applied.
synthetic::RenderedView renderSyntheticFrame(const SyntheticScene& scene, int frame);

// Plans, renders and writes one scene into `out_dir`: manifest.json (format "ffloc-manifest",
// metric, mapping/query split), images/*.png, depth/*.tiff (float32 metres, 0 = no surface)
// and synthetic.json (generator settings and each query's kind). Returns the written scene
// as readManifest would. Identical options give identical files. `out_dir` must not exist or be
// empty, and a failed run leaves nothing in it (writeIntoNewFolder).
Scene generateSyntheticScene(const SyntheticOptions& options, const std::filesystem::path& out_dir);

// The most scenes one batch writes: 10 000 at the default size take about 180 GB.
constexpr int kMaxSyntheticScenes = 10000;

// A lower bound on the bytes one scene takes on disk: its depth maps, float32 and uncompressed
// (at the default size 14.7 MB of a scene's 18 MB; the PNG images are the rest).
uint64_t sceneDepthBytes(const SyntheticOptions& options);

// The seed of the i-th scene of a batch started from `seed`.
uint64_t sceneSeed(uint64_t seed, int index);

}  // namespace ffloc
