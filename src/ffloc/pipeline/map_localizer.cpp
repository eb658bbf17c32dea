#include "ffloc/pipeline/map_localizer.h"

#include "ffloc/classical/classical_localizer.h"
#include "ffloc/core/error.h"
#include "ffloc/io/map_file.h"
#include "ffloc/pipeline/fastforward_localizer.h"

namespace ffloc {

MapLocalizer openMapLocalizer(const std::filesystem::path& map_path, const std::function<LoadedModel()>& load_model) {
  const MapHeader header = readMapHeader(map_path);
  MapLocalizer out;
  // A map in memory knows no file: its errors ("map: holds no images") are given the file's name.
  try {
    if (header.method == toString(LocalizationMethod::kClassical)) {
      out.localizer = std::make_unique<ClassicalLocalizer>(readClassicalMap(map_path));
    } else if (header.method == toString(LocalizationMethod::kFastForward)) {
      out.model = std::make_unique<LoadedModel>(load_model());
      out.localizer = std::make_unique<FastForwardLocalizer>(*out.model->model, readMapFile(map_path, out.model->id));
    } else {
      throwInputError(map_path.string(), 0,
                      "map method '" + header.method + "' is not one this build knows (classical, fastforward)");
    }
  } catch (const InputError& error) {
    throw namingMapFile(error, map_path);
  }
  out.description = std::string(toString(out.localizer->method())) + " map, " +
                    std::to_string(out.localizer->cameras().size()) + " images";
  return out;
}

}  // namespace ffloc
