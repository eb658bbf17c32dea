#pragma once

#include <cstdint>
#include <vector>

#include "ffloc/geometry/pose.h"

namespace ffloc {

// How well global-descriptor retrieval finds, for each query, the mapping camera nearest to it by
// pose (nearestMappingCamera): the image the map representation most needs. Uniform and random
// selection (which ignore the query) are measured the same way, as the floor retrieval must beat.
struct RetrievalRecallOptions {
  std::vector<size_t> top_k = {1, 5, 10, 20};
  uint64_t seed = 0;            // of the random selection; one draw per K shared by all queries, as the localizer does
  double max_angle_deg = 45.0;  // nearestMappingCamera's viewing-direction gate
};

// Fractions of the queries whose K selected mapping images contain their nearest camera.
struct RecallAtK {
  size_t k = 0;
  double retrieval = 0;
  double uniform = 0;
  double random = 0;
};

struct RetrievalRecall {
  std::vector<RecallAtK> recall;  // one per options.top_k, in its order
  // Per query: the pose-nearest mapping camera and its 1-based rank in the query's similarity
  // ranking (topKBySimilarity's order, ties to the lower index).
  std::vector<size_t> nearest;
  std::vector<size_t> rank;
  double median_rank = 0;  // of `rank`; the mean of the two middle ranks for an even count
};

// InputError naming the field when the mapping set or the queries are empty, a count of poses and
// descriptors disagree, descriptors differ in length, or a K is zero.
RetrievalRecall measureRetrievalRecall(const std::vector<Pose>& mapping_poses, const std::vector<Pose>& query_poses,
                                       const std::vector<std::vector<float>>& mapping_descriptors,
                                       const std::vector<std::vector<float>>& query_descriptors,
                                       const RetrievalRecallOptions& options = {});

}  // namespace ffloc
