// Single-threaded rendering rate of the synthetic scenes, per kind and image size. The
// "frames_per_second" counter is the figure docs/synthetic.md reports; geometry planning is
// done once outside the timed loop (it is per scene, not per frame).
#include <benchmark/benchmark.h>

#include "ffloc/synthetic/synthetic.h"

namespace {

void renderFrames(benchmark::State& state, ffloc::SceneKind kind, int width, int height) {
  ffloc::SyntheticOptions options;
  options.kind = kind;
  options.seed = 7;
  options.width = width;
  options.height = height;
  options.mapping_frames = 24;
  options.query_frames = 6;
  const ffloc::SyntheticScene scene = ffloc::planSyntheticScene(options);
  int frame = 0;
  for (auto _ : state) {
    const auto view = ffloc::renderSyntheticFrame(scene, frame);
    benchmark::DoNotOptimize(view.rgb.data);
    frame = (frame + 1) % scene.frameCount();
  }
  state.counters["frames_per_second"] =
      benchmark::Counter(static_cast<double>(state.iterations()), benchmark::Counter::kIsRate);
}

void planScene(benchmark::State& state, ffloc::SceneKind kind) {
  ffloc::SyntheticOptions options;
  options.kind = kind;
  options.mapping_frames = 60;
  options.query_frames = 15;
  uint64_t seed = 0;
  for (auto _ : state) {
    options.seed = seed++;
    const auto scene = ffloc::planSyntheticScene(options);
    benchmark::DoNotOptimize(scene.layout.world.shapes.data());
  }
}

}  // namespace

BENCHMARK_CAPTURE(renderFrames, indoor_256x192, ffloc::SceneKind::kIndoor, 256, 192)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(renderFrames, outdoor_256x192, ffloc::SceneKind::kOutdoor, 256, 192)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(renderFrames, object_256x192, ffloc::SceneKind::kObject, 256, 192)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(renderFrames, indoor_512x384, ffloc::SceneKind::kIndoor, 512, 384)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(renderFrames, outdoor_512x384, ffloc::SceneKind::kOutdoor, 512, 384)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(renderFrames, object_512x384, ffloc::SceneKind::kObject, 512, 384)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(planScene, indoor, ffloc::SceneKind::kIndoor)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(planScene, outdoor, ffloc::SceneKind::kOutdoor)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(planScene, object, ffloc::SceneKind::kObject)->Unit(benchmark::kMillisecond);

BENCHMARK_MAIN();
