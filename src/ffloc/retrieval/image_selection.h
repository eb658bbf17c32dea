#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "ffloc/geometry/pose.h"

namespace ffloc {

// How the K mapping images behind a query's map representation are chosen (the paper's map
// representation table): by global-descriptor retrieval, evenly along the mapping sequence, or at
// random. Uniform and random ignore the query, so one map representation serves every query.
enum class ImageSelection { kRetrieval, kUniform, kRandom };
const char* toString(ImageSelection selection);
ImageSelection parseImageSelection(const std::string& name);  // InputError for unknown names

// Indices of the k database descriptors most similar (cosine) to the query, best first; ties
// keep the lower index. k larger than the database returns all of it.
std::vector<size_t> topKBySimilarity(const std::vector<std::vector<float>>& database,
                                     const std::vector<float>& query, size_t k);

// k indices evenly spaced over [0, count), including the first; all when k >= count.
std::vector<size_t> uniformSelection(size_t count, size_t k);

// k distinct indices of [0, count) drawn with a seeded generator, in increasing order.
std::vector<size_t> randomSelection(size_t count, size_t k, uint64_t seed);

// The mapping camera nearest to `query` by pose: the smallest centre distance among cameras
// whose viewing directions are within `max_angle_deg` of the query's, falling back to the
// smallest angle when none is. Used to measure retrieval: does the top-K contain it?
size_t nearestMappingCamera(const std::vector<Pose>& mapping, const Pose& query, double max_angle_deg = 45.0);

}  // namespace ffloc
