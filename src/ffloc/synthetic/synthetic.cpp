#include "ffloc/synthetic/synthetic.h"

#include <atomic>
#include <cstdio>
#include <fstream>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <thread>

#include "ffloc/core/error.h"
#include "ffloc/core/progress.h"
#include "ffloc/core/text_file_writer.h"
#include "ffloc/core/threads.h"
#include "ffloc/data/dataset_writers.h"
#include "ffloc/data/depth.h"
#include "ffloc/data/manifest.h"
#include "ffloc/synthetic/det_math.h"
#include "ffloc/core/random.h"

namespace ffloc {


const char* toString(SceneKind kind) {
  switch (kind) {
    case SceneKind::kIndoor: return "indoor";
    case SceneKind::kOutdoor: return "outdoor";
    case SceneKind::kObject: return "object";
  }
  return "indoor";
}

SceneKind parseSceneKind(const std::string& text, const std::string& field) {
  for (SceneKind kind : allSceneKinds())
    if (text == toString(kind)) return kind;
  throwInputError(field, 0, "unknown scene kind '" + text + "' (expected indoor, outdoor or object)");
}

std::vector<SceneKind> allSceneKinds() {
  return {SceneKind::kIndoor, SceneKind::kOutdoor, SceneKind::kObject};
}

void validate(const SyntheticOptions& o) {
  if (o.width < 16 || o.height < 16 || o.width > 8192 || o.height > 8192)
    throwInputError("width, height", 0, "image size " + std::to_string(o.width) + "x" +
                                     std::to_string(o.height) + " is outside 16..8192");
  // 100000000 frames took 3.9 GB in 8 s before the first was rendered; frame names have four digits.
  if (o.mapping_frames < 2 || o.mapping_frames > kMaxSyntheticFrames)
    throwInputError("mapping_frames", 0, "must be in [2, " + std::to_string(kMaxSyntheticFrames) + "], got " +
                                             std::to_string(o.mapping_frames));
  if (o.query_frames < 0 || o.query_frames > kMaxSyntheticFrames)
    throwInputError("query_frames", 0, "must be in [0, " + std::to_string(kMaxSyntheticFrames) + "], got " +
                                           std::to_string(o.query_frames));
  if (!(o.min_fov_deg >= 20.0 && o.max_fov_deg <= 120.0 && o.min_fov_deg <= o.max_fov_deg))
    throwInputError("min_fov_deg, max_fov_deg", 0, "field of view must satisfy 20 <= min <= max <= 120 degrees");
  if (!(o.image_noise >= 0.0 && o.image_noise <= 64.0))
    throwInputError("image_noise", 0, "must be in [0, 64] levels");
  if (!(o.depth_noise >= 0.0 && o.depth_noise <= 0.5))
    throwInputError("depth_noise", 0, "must be in [0, 0.5]");
}

uint64_t sceneDepthBytes(const SyntheticOptions& options) {
  const uint64_t frames = static_cast<uint64_t>(options.mapping_frames) + static_cast<uint64_t>(options.query_frames);
  return frames * static_cast<uint64_t>(options.width) * static_cast<uint64_t>(options.height) * sizeof(float);
}

uint64_t sceneSeed(uint64_t seed, int index) {
  return mix64(seed * 0x9e3779b97f4a7c15ULL + static_cast<uint64_t>(index) + 1);
}

int SyntheticScene::frameCount() const {
  return static_cast<int>(layout.mapping.size() + layout.queries.cameras.size());
}

bool SyntheticScene::isQuery(int frame) const {
  return frame >= static_cast<int>(layout.mapping.size());
}

Pose SyntheticScene::pose(int frame) const {
  const int m = static_cast<int>(layout.mapping.size());
  return synthetic::toPose(frame < m ? layout.mapping[frame] : layout.queries.cameras[frame - m]);
}

const synthetic::Lighting& SyntheticScene::lighting(int frame) const {
  const int m = static_cast<int>(layout.mapping.size());
  return frame < m ? layout.mapping_lighting : layout.query_lighting[frame - m];
}

namespace {

std::string frameStem(const SyntheticScene& scene, int frame) {
  char buffer[64];
  const int m = static_cast<int>(scene.layout.mapping.size());
  if (frame < m) {
    std::snprintf(buffer, sizeof(buffer), "mapping_%04d", frame);
  } else {
    std::snprintf(buffer, sizeof(buffer), "query_%04d_%s", frame - m,
                  synthetic::toString(scene.layout.queries.kinds[frame - m]));
  }
  return buffer;
}

}  // namespace

std::string SyntheticScene::imageName(int frame) const {
  return "images/" + frameStem(*this, frame) + ".png";
}

std::string SyntheticScene::depthName(int frame) const {
  return "depth/" + frameStem(*this, frame) + ".tiff";
}

SyntheticScene planSyntheticScene(const SyntheticOptions& options) {
  validate(options);
  SyntheticScene scene;
  scene.options = options;
  Rng rng(options.seed);
  Rng camera_rng = rng.fork(1);
  const double fov = synthetic::degrees(camera_rng.uniform(options.min_fov_deg, options.max_fov_deg));
  // fx from the half-angle's tangent, as sine over cosine of the deterministic kernels.
  const double tan_half = synthetic::detSin(fov / 2) / synthetic::detCos(fov / 2);
  Intrinsics& camera = scene.camera;
  camera.width = options.width;
  camera.height = options.height;
  camera.fx = camera.fy = options.width / 2.0 / tan_half;
  camera.cx = (options.width - 1) / 2.0;
  camera.cy = (options.height - 1) / 2.0;
  Rng layout_rng = rng.fork(2 + static_cast<uint64_t>(options.kind));
  switch (options.kind) {
    case SceneKind::kIndoor:
      scene.layout = synthetic::buildIndoorLayout(layout_rng, camera, options.mapping_frames,
                                                  options.query_frames);
      break;
    case SceneKind::kOutdoor:
      scene.layout = synthetic::buildOutdoorLayout(layout_rng, camera, options.mapping_frames,
                                                   options.query_frames);
      break;
    case SceneKind::kObject:
      scene.layout = synthetic::buildObjectLayout(layout_rng, camera, options.mapping_frames,
                                                  options.query_frames);
      break;
  }
  return scene;
}

synthetic::RenderedView renderSyntheticFrame(const SyntheticScene& scene, int frame) {
  synthetic::RenderOptions render;
  render.image_noise = scene.options.image_noise;
  render.noise_seed = mix64(scene.options.seed ^ (0x5eed0000ULL + frame));
  synthetic::RenderedView view =
      synthetic::renderView(scene.layout.world, scene.lighting(frame), scene.camera,
                            scene.pose(frame), render);
  if (scene.options.depth_noise > 0.0) {
    Rng rng(mix64(scene.options.seed ^ (0xde97000000ULL + frame)));
    for (int v = 0; v < view.depth.rows; ++v) {
      float* row = view.depth.ptr<float>(v);
      for (int u = 0; u < view.depth.cols; ++u)
        if (row[u] > 0.0f)
          row[u] = static_cast<float>(row[u] * (1.0 + scene.options.depth_noise * rng.normal()));
    }
  }
  return view;
}

namespace {

void writeMetadata(const SyntheticScene& scene, const std::filesystem::path& path) {
  nlohmann::ordered_json meta;
  meta["generator"] = "ffloc synth";
  meta["kind"] = toString(scene.options.kind);
  meta["seed"] = scene.options.seed;
  meta["width"] = scene.options.width;
  meta["height"] = scene.options.height;
  meta["image_noise"] = scene.options.image_noise;
  meta["depth_noise"] = scene.options.depth_noise;
  meta["world_up"] = {0, 0, 1};
  meta["shapes"] = scene.layout.world.shapes.size();
  nlohmann::ordered_json queries = nlohmann::ordered_json::array();
  const int m = static_cast<int>(scene.layout.mapping.size());
  for (int q = 0; q < static_cast<int>(scene.layout.queries.kinds.size()); ++q) {
    queries.push_back({{"image", scene.imageName(m + q)},
                       {"kind", synthetic::toString(scene.layout.queries.kinds[q])}});
  }
  meta["queries"] = queries;
  writeTextFile(path, meta.dump(2) + "\n");
}

}  // namespace

namespace {

Scene writeSyntheticScene(const SyntheticScene& scene, const std::filesystem::path& out_dir) {
  const SyntheticOptions& options = scene.options;
  std::filesystem::create_directories(out_dir / "images");
  std::filesystem::create_directories(out_dir / "depth");

  const int frames = scene.frameCount();
  ProgressBar progress("synth " + out_dir.filename().string(), frames, options.quiet);
  std::atomic<int> next{0}, done{0};
  std::vector<std::string> failures(frames);
  auto worker = [&]() {
    for (int f = next++; f < frames; f = next++) {
      try {
        const auto view = renderSyntheticFrame(scene, f);
        cv::Mat bgr;
        cv::cvtColor(view.rgb, bgr, cv::COLOR_RGB2BGR);
        const auto image_path = out_dir / scene.imageName(f);
        if (!cv::imwrite(image_path.string(), bgr))
          throwInputError(image_path.string(), 0, "cannot write the image");
        writeDepth(view.depth, out_dir / scene.depthName(f));
      } catch (const std::exception& e) {
        failures[f] = e.what();
      }
      ++done;
    }
  };
  const int threads = std::max(1, std::min(resolveThreadCount(options.threads), frames));
  std::vector<std::thread> pool;
  for (int t = 1; t < threads; ++t) pool.emplace_back(worker);
  // The calling thread renders too and keeps the progress bar current between frames.
  worker();
  for (auto& t : pool) t.join();
  progress.update(done);
  progress.finish();
  for (const auto& failure : failures)
    if (!failure.empty()) throw InputError(failure);

  Scene out;
  out.name = out_dir.filename().string();
  out.root = out_dir;
  out.format = "manifest";
  out.metric = true;
  for (int f = 0; f < frames; ++f) {
    Frame frame;
    frame.name = scene.imageName(f);
    frame.image_path = out_dir / scene.imageName(f);
    frame.intrinsics = scene.camera;
    frame.camera_to_world = scene.pose(f);
    DepthSource depth;
    depth.path = out_dir / scene.depthName(f);
    depth.scale = 1.0;
    depth.invalid_values = {0.0};
    frame.depth = depth;
    frame.split = scene.isQuery(f) ? Split::kQuery : Split::kMapping;
    out.frames.push_back(frame);
  }
  writeManifest(out, out_dir / kManifestFileName);
  writeMetadata(scene, out_dir / "synthetic.json");
  return readManifest(out_dir / kManifestFileName);
}

}  // namespace

Scene generateSyntheticScene(const SyntheticOptions& options, const std::filesystem::path& out_dir) {
  const SyntheticScene scene = planSyntheticScene(options);
  Scene written;
  writeIntoNewFolder(out_dir, [&](const std::filesystem::path& out) { written = writeSyntheticScene(scene, out); });
  return written;
}

}  // namespace ffloc
