#pragma once

#include <chrono>
#include <filesystem>
#include <functional>
#include <memory>
#include <mutex>
#include <stdexcept>
#include <string>
#include <vector>

#include "ffloc/localization/localizer.h"

namespace ffloc {

// A map as a server answers with it: its localizer (which keeps alive whatever it needs, such as
// its model) and what /health and /maps say of its model.
struct ServedMap {
  std::shared_ptr<const Localizer> localizer;
  std::string model_description;
};

// A served map whose file changed in place and no longer opens (MapCatalog::get).
class MapWithdrawn : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// Opens a map file for serving (the CLI passes openMapLocalizer's work; tests pass their own).
using MapOpener = std::function<ServedMap(const std::filesystem::path&)>;

// The maps of one server, by name. A map file replaced on disk (ffloc map writes by atomic
// rename) is reopened on the first request that looks after the change: requests already holding
// the old version finish on it, later ones get the new one, and a replacement that fails to open
// leaves the old version serving. A file changed in place (written over, cut short) that fails to
// open takes the old version with it: the map is withdrawn until the file opens again.
class MapCatalog {
 public:
  struct Source {
    std::string name;
    std::filesystem::path path;
  };

  // Opens every map now. InputError naming the file of a map that does not open, or a name that
  // is empty, given twice, or holds '/'.
  MapCatalog(std::vector<Source> sources, MapOpener open, std::chrono::milliseconds reload_check = std::chrono::seconds(1));
  // One map that never changes, from no file.
  MapCatalog(std::string name, ServedMap map);
  ~MapCatalog();

  // The current version of the named map (null for a name the catalog does not hold).
  // MapWithdrawn, saying why, for a withdrawn map.
  std::shared_ptr<const ServedMap> get(const std::string& name) const;
  // How many maps are withdrawn now.
  size_t withdrawnCount() const;
  // Names in the order given.
  const std::vector<std::string>& names() const { return names_; }
  // Called with a line for each reload and each failed one (from a request's thread).
  void setLog(std::function<void(const std::string&)> log) { log_ = std::move(log); }

  // "NAME=PATH" or "PATH" (named by the file's stem).
  static Source parseSource(const std::string& text);
  // Every *.ffmap file of a folder, named by stem, sorted by name. InputError when there is none.
  static std::vector<Source> sourcesInFolder(const std::filesystem::path& folder);

 private:
  struct Slot;
  static std::shared_ptr<const ServedMap> served(const Slot& slot);
  std::vector<std::unique_ptr<Slot>> slots_;
  std::vector<std::string> names_;
  MapOpener open_;
  std::chrono::milliseconds reload_check_{0};
  std::function<void(const std::string&)> log_;
};

}  // namespace ffloc
