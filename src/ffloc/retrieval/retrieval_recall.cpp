#include "ffloc/retrieval/retrieval_recall.h"

#include <algorithm>
#include <string>

#include "ffloc/core/error.h"
#include "ffloc/core/statistics.h"
#include "ffloc/retrieval/image_selection.h"

namespace ffloc {
namespace {

void checkInputs(const std::vector<Pose>& mapping_poses, const std::vector<Pose>& query_poses,
                 const std::vector<std::vector<float>>& mapping_descriptors,
                 const std::vector<std::vector<float>>& query_descriptors, const RetrievalRecallOptions& options) {
  if (mapping_poses.empty()) throw InputError("retrieval recall: no mapping images");
  if (query_poses.empty()) throw InputError("retrieval recall: no queries");
  if (mapping_descriptors.size() != mapping_poses.size())
    throw InputError("retrieval recall: " + std::to_string(mapping_descriptors.size()) + " mapping descriptors for " +
                     std::to_string(mapping_poses.size()) + " mapping poses");
  if (query_descriptors.size() != query_poses.size())
    throw InputError("retrieval recall: " + std::to_string(query_descriptors.size()) + " query descriptors for " +
                     std::to_string(query_poses.size()) + " query poses");
  const size_t length = mapping_descriptors[0].size();
  if (length == 0) throw InputError("retrieval recall: mapping descriptor 0 is empty");
  auto checkLength = [&](const std::vector<std::vector<float>>& descriptors, const char* what) {
    for (size_t i = 0; i < descriptors.size(); ++i)
      if (descriptors[i].size() != length)
        throw InputError("retrieval recall: " + std::string(what) + " descriptor " + std::to_string(i) + " has " +
                         std::to_string(descriptors[i].size()) + " values, mapping descriptor 0 has " +
                         std::to_string(length));
  };
  checkLength(mapping_descriptors, "mapping");
  checkLength(query_descriptors, "query");
  if (options.top_k.empty()) throw InputError("retrieval recall: top_k: no K given");
  for (size_t k : options.top_k)
    if (k == 0) throw InputError("retrieval recall: top_k: K must be positive");
}

bool contains(const std::vector<size_t>& indices, size_t index) {
  return std::find(indices.begin(), indices.end(), index) != indices.end();
}

}  // namespace

RetrievalRecall measureRetrievalRecall(const std::vector<Pose>& mapping_poses, const std::vector<Pose>& query_poses,
                                       const std::vector<std::vector<float>>& mapping_descriptors,
                                       const std::vector<std::vector<float>>& query_descriptors,
                                       const RetrievalRecallOptions& options) {
  checkInputs(mapping_poses, query_poses, mapping_descriptors, query_descriptors, options);
  const size_t count = mapping_poses.size();
  const size_t queries = query_poses.size();

  RetrievalRecall out;
  for (size_t q = 0; q < queries; ++q) {
    const size_t nearest = nearestMappingCamera(mapping_poses, query_poses[q], options.max_angle_deg);
    // The full ranking from the localizer's own selection function, so rank and recall agree with
    // what it would pick at any K.
    const std::vector<size_t> order = topKBySimilarity(mapping_descriptors, query_descriptors[q], count);
    const size_t position = static_cast<size_t>(std::find(order.begin(), order.end(), nearest) - order.begin());
    out.nearest.push_back(nearest);
    out.rank.push_back(position + 1);
  }
  for (size_t k : options.top_k) {
    const std::vector<size_t> uniform = uniformSelection(count, k);
    const std::vector<size_t> random = randomSelection(count, k, options.seed);
    RecallAtK recall;
    recall.k = k;
    for (size_t q = 0; q < queries; ++q) {
      recall.retrieval += out.rank[q] <= k;
      recall.uniform += contains(uniform, out.nearest[q]);
      recall.random += contains(random, out.nearest[q]);
    }
    recall.retrieval /= static_cast<double>(queries);
    recall.uniform /= static_cast<double>(queries);
    recall.random /= static_cast<double>(queries);
    out.recall.push_back(recall);
  }
  out.median_rank = median(std::vector<double>(out.rank.begin(), out.rank.end()));
  return out;
}

}  // namespace ffloc
