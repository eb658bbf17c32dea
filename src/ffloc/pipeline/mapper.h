#pragma once

#include <string>
#include <vector>

#include "ffloc/data/scene.h"
#include "ffloc/io/map_file.h"
#include "ffloc/model/model_loader.h"
#include "ffloc/retrieval/global_descriptor.h"

namespace ffloc {

// Mapping (ffloc map): every mapping image is encoded once and its tokens stored (fp16) with its
// pose, the intrinsics of the preprocessed image, the preprocessing geometry and a global
// descriptor pooled from the same tokens. Queries never run the encoder on mapping images again.
struct MappingOptions {
  // Long side of the preprocessed image; 0: the model's input_long_side (512 for the paper's
  // model). Tests use less for speed.
  int long_side = 0;
  GlobalDescriptorOptions descriptor;
  // Also store the classical VLAD descriptor of every image (SIFT with the default SiftOptions),
  // so that queries may select their K images by classical retrieval.
  bool vlad = false;
  bool quiet = false;  // no progress bar
  // Frames read and encoded at once, each on a thread of its own with single-threaded kernels.
  // 0: as many as libtorch has threads when the encoder is dense SIFT (one image is too little
  // work to split over threads), 1 for a ViT encoder (its products use every thread).
  int frame_workers = 0;
};

struct MappingReport {
  size_t added = 0;
  size_t skipped_duplicates = 0;  // names already in the map
  // Added without depth for a model that matches on its tokens' 3D points: nothing in them can
  // be matched, so a query these images alone see is not placed.
  size_t added_without_points = 0;
  double seconds = 0;             // reading, preprocessing and encoding the added images, and any vocabulary learnt
};

// Reads and encodes one posed image (with its depth's points, for a model whose tokens carry them).
MapImage encodeMappingImage(const FastForwardModel& model, const Frame& frame, const MappingOptions& options = {});

// An empty map for `model`.
MapFile emptyMap(const LoadedModel& model, bool metric);

// Adds `frames` (indices into scene.frames) to `map`, keeping the images already there untouched
// and skipping frames whose name the map already holds. InputError when the map was built by
// another model, with another token width, or in other units (metric vs not), and for an option
// out of range. The map's images come out in the order of `frames` however many workers ran.
MappingReport addToMap(MapFile& map, const LoadedModel& model, const Scene& scene, const std::vector<size_t>& frames,
                       const MappingOptions& options = {});

// Gives every image of `map` that has none a VLAD descriptor (from the scene frame of the same
// name), training the vocabulary when the map has none yet. InputError when an image is not in
// the scene, or when the map was built without VLAD and already holds images.
void addVladRetrieval(MapFile& map, const Scene& scene, bool quiet);

}  // namespace ffloc
