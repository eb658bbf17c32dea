#pragma once

#include <chrono>
#include <filesystem>
#include <functional>
#include <memory>
#include <mutex>
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

// Opens a map file for serving (the CLI passes openMapLocalizer's work; tests pass their own).
using MapOpener = std::function<ServedMap(const std::filesystem::path&)>;

// The maps of one server, by name. A map file replaced on disk (ffloc map writes by atomic
// rename) or written over in place is reopened on the first request that looks after the change
// (at most once per reload_check): requests already holding the old version finish on it, later
// ones get the new one, and a changed file that fails to open leaves the old version serving.
// The opener must return a map that holds its own copy of whatever it reads from the file
// (readMapFile's snapshot), or a file written over in place would change the served version.
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
  std::shared_ptr<const ServedMap> get(const std::string& name) const;
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
  std::vector<std::unique_ptr<Slot>> slots_;
  std::vector<std::string> names_;
  MapOpener open_;
  std::chrono::milliseconds reload_check_{0};
  std::function<void(const std::string&)> log_;
};

}  // namespace ffloc
