#pragma once

#include <filesystem>
#include <functional>
#include <memory>
#include <string>

#include "ffloc/localization/localizer.h"
#include "ffloc/model/model_loader.h"

namespace ffloc {

// A map file opened for queries with the method it was built with, and the model it needs.
struct MapLocalizer {
  std::unique_ptr<LoadedModel> model;  // FastForward maps only
  std::unique_ptr<Localizer> localizer;
  std::string description;  // "classical map, 150 images" and the like
};

// Reads the map's header and opens it with its method. `load_model` runs only for a map that
// needs a network; the map must have been built by that model. InputError naming the file for a
// map of another version, a method this build does not have, or another model.
MapLocalizer openMapLocalizer(const std::filesystem::path& map_path, const std::function<LoadedModel()>& load_model);

}  // namespace ffloc
