#include "ffloc/server/map_catalog.h"

#include <algorithm>

#include "ffloc/core/error.h"
#include "ffloc/core/file_stamp.h"

namespace ffloc {

struct MapCatalog::Slot {
  Source source;
  mutable std::mutex mutex;  // guards current, stamp, last_check
  std::shared_ptr<const ServedMap> current;
  std::optional<FileStamp> stamp;  // of the file last looked at
  std::chrono::steady_clock::time_point last_check;
  mutable std::mutex reloading;  // one reload of a map at a time
};

MapCatalog::MapCatalog(std::vector<Source> sources, MapOpener open, std::chrono::milliseconds reload_check)
    : open_(std::move(open)), reload_check_(reload_check) {
  if (sources.empty()) throw InputError("maps: no map to serve");
  for (Source& source : sources) {
    // A name is a segment of the URL /maps/NAME: '%', '?' and '#' change what a client sends, and
    // clients rewrite '.' and '..' away, so such a map was listed but could not be reached.
    const bool unreachable = source.name == "." || source.name == ".." ||
                             std::any_of(source.name.begin(), source.name.end(), [](char c) {
                               return c == '/' || c == '%' || c == '?' || c == '#' || static_cast<unsigned char>(c) < 0x20;
                             });
    if (source.name.empty() || unreachable) {
      throwInputError(source.path.string(), 0,
                      "map name '" + source.name +
                          "' cannot be reached as /maps/NAME: give one that is not '.' or '..' and holds none of "
                          "'/', '%', '?', '#' or a control character");
    }
    if (std::find(names_.begin(), names_.end(), source.name) != names_.end()) {
      throwInputError(source.path.string(), 0, "map name '" + source.name + "' given twice");
    }
    auto slot = std::make_unique<Slot>();
    slot->stamp = fileStampOf(source.path);
    slot->current = std::make_shared<const ServedMap>(open_(source.path));
    slot->last_check = std::chrono::steady_clock::now();
    slot->source = std::move(source);
    names_.push_back(slot->source.name);
    slots_.push_back(std::move(slot));
  }
}

MapCatalog::MapCatalog(std::string name, ServedMap map) {
  auto slot = std::make_unique<Slot>();
  slot->source.name = name;
  slot->current = std::make_shared<const ServedMap>(std::move(map));
  names_.push_back(std::move(name));
  slots_.push_back(std::move(slot));
}

MapCatalog::~MapCatalog() = default;

std::shared_ptr<const ServedMap> MapCatalog::get(const std::string& name) const {
  const auto found = std::find(names_.begin(), names_.end(), name);
  if (found == names_.end()) return nullptr;
  Slot& slot = *slots_[static_cast<size_t>(found - names_.begin())];
  {
    const std::lock_guard<std::mutex> lock(slot.mutex);
    const auto now = std::chrono::steady_clock::now();
    if (!open_ || now - slot.last_check < reload_check_) return slot.current;
    slot.last_check = now;
  }
  std::optional<FileStamp> stamp;
  std::unique_lock<std::mutex> reload(slot.reloading, std::try_to_lock);
  {
    const std::lock_guard<std::mutex> lock(slot.mutex);
    // Another request is reopening it, or the file is missing (mid-replacement) or unchanged.
    if (!reload.owns_lock() || !(stamp = fileStampOf(slot.source.path)) || stamp == slot.stamp) return slot.current;
  }
  std::shared_ptr<const ServedMap> reopened;
  std::string failure;
  try {
    reopened = std::make_shared<const ServedMap>(open_(slot.source.path));
  } catch (const std::exception& e) {
    failure = e.what();
  }
  const std::lock_guard<std::mutex> lock(slot.mutex);
  // The stamp seen before the open: a file that does not open is tried again once it changes
  // again, and a write landing during the open is looked at on a later request.
  slot.stamp = stamp;
  if (reopened) {
    slot.current = std::move(reopened);
    if (log_) log_("map '" + slot.source.name + "': reloaded " + slot.source.path.string());
  } else if (log_) {
    log_("map '" + slot.source.name + "': the changed file does not open, still serving the previous one: " + failure);
  }
  return slot.current;
}

MapCatalog::Source MapCatalog::parseSource(const std::string& text) {
  const size_t equals = text.find('=');
  Source source;
  if (equals == std::string::npos) {
    source.path = text;
    source.name = source.path.stem().string();
  } else {
    source.name = text.substr(0, equals);
    source.path = text.substr(equals + 1);
  }
  return source;
}

std::vector<MapCatalog::Source> MapCatalog::sourcesInFolder(const std::filesystem::path& folder) {
  std::error_code error;
  if (!std::filesystem::is_directory(folder, error)) throwInputError(folder.string(), 0, "not a folder of maps");
  std::vector<Source> sources;
  for (const auto& entry : std::filesystem::directory_iterator(folder, error)) {
    if (entry.path().extension() == ".ffmap" && entry.is_regular_file(error)) {
      sources.push_back({entry.path().stem().string(), entry.path()});
    }
  }
  if (sources.empty()) throwInputError(folder.string(), 0, "holds no .ffmap file");
  std::sort(sources.begin(), sources.end(), [](const Source& a, const Source& b) { return a.name < b.name; });
  return sources;
}

}  // namespace ffloc
