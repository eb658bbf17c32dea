#include "ffloc/data/splits.h"

#include <unordered_map>

#include "ffloc/core/error.h"
#include "ffloc/data/text_file.h"

namespace ffloc {

bool applySplitFiles(Scene& scene) {
  const auto mapping_file = scene.root / kMappingSplitFile;
  const auto query_file = scene.root / kQuerySplitFile;
  if (!std::filesystem::exists(mapping_file) && !std::filesystem::exists(query_file)) return false;

  std::unordered_map<std::string, size_t> index_of;
  for (size_t i = 0; i < scene.frames.size(); ++i) index_of[scene.frames[i].name] = i;
  // Names are compared normalised, so "./images/a.jpg" matches "images/a.jpg".
  auto normalised = [](const std::string& name) {
    return std::filesystem::path(name).lexically_normal().generic_string();
  };
  for (auto& [name, index] : std::unordered_map<std::string, size_t>(index_of)) index_of[normalised(name)] = index;

  std::vector<Split> splits(scene.frames.size(), Split::kUnassigned);
  std::vector<std::string> listed_in(scene.frames.size());
  for (const auto& [file, split] : {std::pair{mapping_file, Split::kMapping}, {query_file, Split::kQuery}}) {
    if (!std::filesystem::exists(file)) continue;
    for (const auto& line : contentLines(readTextLines(file), true)) {
      // A whole line is one path (names may contain spaces); only the ends are trimmed.
      const std::string name(trimmed(line.text));
      const auto found = index_of.find(normalised(name));
      if (found == index_of.end())
        throwInputError(file.string(), line.number, "'" + name + "' is not a frame of this dataset");
      if (!listed_in[found->second].empty())
        throwInputError(file.string(), line.number,
                        "'" + name + "' is already listed in " + listed_in[found->second]);
      listed_in[found->second] = file.filename().string() + ":" + std::to_string(line.number);
      splits[found->second] = split;
    }
  }
  for (size_t i = 0; i < scene.frames.size(); ++i) scene.frames[i].split = splits[i];
  return true;
}

void requireSplit(const Scene& scene, Split split) {
  if (!scene.indices(split).empty()) return;
  // An empty split_query.txt was reported as an empty mapping split, naming no split file (an
  // outside probe): what the files say is named beside it.
  std::string files;
  for (const auto& [file, listed] : {std::pair{kMappingSplitFile, Split::kMapping}, {kQuerySplitFile, Split::kQuery}}) {
    if (!std::filesystem::exists(scene.root / file)) continue;
    files += (files.empty() ? "" : ", ") + std::string(file) + " lists " + std::to_string(scene.indices(listed).size()) +
             " frame(s)";
  }
  if (!files.empty()) files = " (" + files + "; split files replace the dataset's own split, and a frame neither lists is in none)";
  throwInputError(scene.root.string(), 0, std::string("split '") + toString(split) + "' is empty" + files);
}

bool hasNoSplit(const Scene& scene) {
  if (scene.frames.empty() || !scene.mappingIndices().empty() || !scene.queryIndices().empty()) return false;
  for (const char* file : {kMappingSplitFile, kQuerySplitFile})
    if (std::filesystem::exists(scene.root / file)) return false;
  return true;
}

void requireSplits(const Scene& scene) {
  for (Split split : {Split::kMapping, Split::kQuery}) requireSplit(scene, split);
}

}  // namespace ffloc
