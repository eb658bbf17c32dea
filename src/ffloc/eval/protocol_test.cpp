#include "ffloc/eval/protocol.h"

#include <gtest/gtest.h>

#include <cstdio>

#include "ffloc/core/error.h"
#include "ffloc/eval/metrics.h"

namespace ffloc {
namespace {

TEST(Protocol, PaperSettingsPerBenchmark) {
  for (const BenchmarkProtocol& p : benchmarkProtocols()) {
    SCOPED_TRACE(p.name);
    EXPECT_EQ(p.top_k, p.outdoor ? 20u : 10u);
    EXPECT_EQ(p.features, p.outdoor ? 3000 : 1500);
    EXPECT_TRUE(p.medians);
    EXPECT_FALSE(p.mapping_time.empty());
    // Every reported accuracy is one the evaluator computes.
    for (const std::string& key : p.accuracy_keys) {
      bool known = false;
      for (const AccuracyThreshold& threshold : accuracyThresholds()) known = known || key == threshold.key;
      EXPECT_TRUE(known) << key;
    }
  }
  EXPECT_EQ(benchmarkProtocol("wayspots").accuracy_keys, std::vector<std::string>{"10cm_10deg"});
  EXPECT_EQ(benchmarkProtocol("indoor6").accuracy_keys.front(), "10cm_10deg");
  EXPECT_EQ(benchmarkProtocol("7scenes").accuracy_keys, (std::vector<std::string>{"5cm_5deg", "10cm_10deg"}));
  EXPECT_TRUE(benchmarkProtocol("cambridge").accuracy_keys.empty());
  EXPECT_EQ(benchmarkProtocol("7scenes").mapping_stride, 15);
  EXPECT_EQ(benchmarkProtocol("rio10").mapping_time, "10s");
  EXPECT_THROW(benchmarkProtocol("aachen"), InputError);
  const std::string text = describeProtocol(benchmarkProtocol("wayspots"), 20, 3000);
  EXPECT_NE(describeProtocol(benchmarkProtocol("wayspots"), 5, 3000).find("top-K 5 (the paper's 20), N 3000;"),
            std::string::npos);
  EXPECT_NE(text.find("top-K 20, N 3000"), std::string::npos);
  EXPECT_NE(text.find("10cm_10deg"), std::string::npos);
}

TEST(Protocol, ThinningKeepsEveryNthMappingFrameAndAllQueries) {
  Scene scene;
  for (int i = 0; i < 40; ++i) {
    Frame frame;
    frame.name = std::to_string(i);
    frame.split = i < 31 ? Split::kMapping : Split::kQuery;
    scene.frames.push_back(frame);
  }
  thinMappingFrames(scene, 15);
  EXPECT_EQ(scene.mappingIndices(), (std::vector<size_t>{0, 15, 30}));
  EXPECT_EQ(scene.queryIndices().size(), 9u);
  EXPECT_EQ(scene.indices(Split::kUnassigned).size(), 28u);
  EXPECT_THROW(thinMappingFrames(scene, 0), InputError);
}

// The shared redkitchen sample keeps every 4th capture of its scan: the paper's one frame in 15
// captures is then one file in 4, not one in 15; each sequence folder counts on its own.
TEST(Protocol, ThinningFollowsTheCaptureNumberOfSevenScenesNames) {
  Scene scene;
  for (const char* sequence : {"seq-01", "seq-02"}) {
    for (int capture = 0; capture < 64; capture += 4) {
      Frame frame;
      char name[64];
      std::snprintf(name, sizeof(name), "%s/frame-%06d.color.png", sequence, capture);
      frame.name = name;
      frame.split = Split::kMapping;
      scene.frames.push_back(frame);
    }
  }
  thinMappingFrames(scene, 15);
  std::vector<std::string> kept;
  for (size_t i : scene.mappingIndices()) kept.push_back(scene.frames[i].name);
  const std::vector<std::string> expected = {
      "seq-01/frame-000000.color.png", "seq-01/frame-000016.color.png", "seq-01/frame-000032.color.png",
      "seq-01/frame-000048.color.png", "seq-02/frame-000000.color.png", "seq-02/frame-000016.color.png",
      "seq-02/frame-000032.color.png", "seq-02/frame-000048.color.png"};
  EXPECT_EQ(kept, expected);
}

}  // namespace
}  // namespace ffloc
