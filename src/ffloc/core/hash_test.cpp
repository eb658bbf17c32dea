#include "ffloc/core/hash.h"

#include <gtest/gtest.h>

#include <vector>

#include "ffloc/core/random.h"

namespace ffloc {
namespace {

TEST(Fnv1a64, MatchesThePublishedValues) {
  EXPECT_EQ(hex64(fnv1a64("")), "cbf29ce484222325");
  EXPECT_EQ(hex64(fnv1a64("a")), "af63dc4c8601ec8c");
  EXPECT_EQ(hex64(fnv1a64("foobar")), "85944171f73967e8");
}

// The ranges' lengths put every lane through empty ranges, ranges shorter and longer than one
// turn, and turns where some lanes have nothing left.
TEST(Fnv1a64, EachRangeHashedTogetherAsAlone) {
  Rng rng(3);
  std::vector<std::vector<uint8_t>> buffers;
  for (size_t size : {0, 1, 7, 65535, 65536, 65537, 0, 200003, 3, 0, 131072, 9, 1000000, 5, 0}) {
    std::vector<uint8_t> bytes(size);
    for (uint8_t& byte : bytes) byte = static_cast<uint8_t>(rng.uniform(0.0, 256.0));
    buffers.push_back(std::move(bytes));
  }
  for (size_t count = 0; count <= buffers.size(); ++count) {
    std::vector<ByteRange> ranges;
    for (size_t i = 0; i < count; ++i) ranges.push_back({buffers[i].data(), buffers[i].size()});
    const std::vector<uint64_t> hashes = fnv1a64Each(ranges);
    ASSERT_EQ(hashes.size(), count);
    for (size_t i = 0; i < count; ++i) EXPECT_EQ(hashes[i], fnv1a64(buffers[i].data(), buffers[i].size())) << i;
  }
}

}  // namespace
}  // namespace ffloc
