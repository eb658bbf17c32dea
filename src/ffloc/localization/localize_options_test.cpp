#include <gtest/gtest.h>

#include <string>

#include "ffloc/core/error.h"
#include "ffloc/localization/localizer.h"

namespace ffloc {
namespace {

std::string errorOf(const QuerySettings& settings) {
  try {
    localizeOptions(settings);
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

TEST(QuerySettings, ThePresetHoldsUnlessAnOverrideIsGiven) {
  QuerySettings settings;
  settings.preset = "outdoor";
  const LocalizeOptions outdoor = localizeOptions(settings);
  EXPECT_EQ(outdoor.top_k, 20u);
  EXPECT_EQ(outdoor.num_features, 3000);
  EXPECT_TRUE(outdoor.verify_with_second_reference);
  EXPECT_TRUE(outdoor.pose_guided_retrieval);

  settings.top_k = 3;
  settings.features = 200;
  settings.seed = 9;
  settings.selection = "uniform";
  settings.retrieval = "vlad";
  settings.solver = "opencv-usac";
  settings.verify = false;
  settings.pose_guided = false;
  const LocalizeOptions options = localizeOptions(settings);
  EXPECT_EQ(options.top_k, 3u);
  EXPECT_EQ(options.num_features, 200);
  EXPECT_EQ(options.seed, 9u);
  EXPECT_EQ(options.pnp.seed, 9u);  // one seed for the sampling and RANSAC, as the CLI's --seed
  EXPECT_EQ(options.selection, ImageSelection::kUniform);
  EXPECT_EQ(options.retrieval, FastForwardRetrieval::kVlad);
  EXPECT_EQ(options.pnp.solver, PnpSolver::kOpenCvUsac);
  EXPECT_FALSE(options.verify_with_second_reference);
  EXPECT_FALSE(options.pose_guided_retrieval);
}

TEST(QuerySettings, ErrorsNameTheField) {
  QuerySettings settings;
  settings.top_k = 0;
  EXPECT_EQ(errorOf(settings), "top_k: must be positive, got 0");
  settings = {};
  settings.features = -1;
  EXPECT_EQ(errorOf(settings).rfind("num_features:", 0), 0u);
  settings = {};
  settings.preset = "attic";
  EXPECT_EQ(errorOf(settings).rfind("preset:", 0), 0u);
  settings = {};
  settings.selection = "best";
  EXPECT_EQ(errorOf(settings).rfind("selection:", 0), 0u);
  settings = {};
  settings.retrieval = "magic";
  EXPECT_EQ(errorOf(settings).rfind("retrieval:", 0), 0u);
}

}  // namespace
}  // namespace ffloc
