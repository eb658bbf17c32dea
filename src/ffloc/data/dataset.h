#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "ffloc/data/scene.h"
#include "ffloc/data/splits.h"

namespace ffloc {

// The formats loadDataset reads, in detection order: {"manifest", "7scenes", "nerf", "colmap",
// "strecha", "cambridge", "kapture", "mapfree", "ace", "rio10", "indoor6"}. docs/datasets.md describes each.
std::vector<std::string> datasetFormats();

// The first format in datasetFormats() whose files are in `dir`. Throws InputError listing what
// it looked for when none matches (or when `dir` is not a folder).
std::string detectDatasetFormat(const std::filesystem::path& dir);

// Reads a dataset folder (`format` "auto" detects it). Afterwards split_mapping.txt /
// split_query.txt in the folder, when present, override the native split (splits.h). Frame
// names are unique; Scene::root and all paths are absolute and lexically normalised. An empty
// split is not an error here; call requireSplits for that.
Scene loadDataset(const std::filesystem::path& dir, const std::string& format = "auto");

}  // namespace ffloc
