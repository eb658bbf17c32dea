#pragma once

#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "ffloc/eval/coordinate_source.h"
#include "ffloc/pipeline/localizer.h"
#include "ffloc/pipeline/mapper.h"
#include "ffloc/pipeline/model_loader.h"

namespace ffloc {

struct FastForwardSourceOptions {
  LocalizeOptions localize;
  // A map made by 'ffloc map' for the scene; empty: prepare() encodes the scene's mapping split
  // in memory.
  std::filesystem::path map_path;
  MappingOptions mapping;
};

// FastForward as an evaluation method ("fastforward" in ffloc eval).
class FastForwardSource : public CoordinateSource {
 public:
  FastForwardSource(std::shared_ptr<const LoadedModel> model, FastForwardSourceOptions options);

  std::string name() const override { return "fastforward"; }
  void prepare(const Scene& scene) override;
  Correspondences correspondences(const Scene& scene, size_t query_index) override;

  const Localizer& localizer() const;
  // The prediction behind the last correspondences() call (timings, selected images).
  const QueryPrediction& lastPrediction() const { return last_; }

 private:
  std::shared_ptr<const LoadedModel> model_;
  FastForwardSourceOptions options_;
  std::unique_ptr<Localizer> localizer_;
  QueryPrediction last_;
};

}  // namespace ffloc
