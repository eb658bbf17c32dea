#pragma once

#include <filesystem>

#include "ffloc/data/scene.h"

namespace ffloc {

inline constexpr const char* kMappingSplitFile = "split_mapping.txt";
inline constexpr const char* kQuerySplitFile = "split_query.txt";

// When split_mapping.txt and/or split_query.txt exist in scene.root (one image path relative to
// the root per line, as Frame::name), they replace every frame's native split: listed frames get
// that split, all others become unassigned. A line naming no frame, or a frame listed in both
// files, is an InputError naming the split file and line. Returns whether a file was found.
bool applySplitFiles(Scene& scene);

// Throws InputError "<root>: split 'mapping' is empty" (or 'query'), with what the split files
// list where there are some, unless the scene has a frame of `split`. Mapping requires it.
void requireSplit(const Scene& scene, Split split);

// Whether the scene has no split at all: frames, none of them in a split, and no split file. A
// COLMAP model or a SLAM export has none; a map of it holds every frame.
bool hasNoSplit(const Scene& scene);

// requireSplit for both splits. Reading never requires this; evaluation does.
void requireSplits(const Scene& scene);

}  // namespace ffloc
