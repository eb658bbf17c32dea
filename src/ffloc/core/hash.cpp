#include "ffloc/core/hash.h"

#include <algorithm>
#include <cstdio>

namespace ffloc {
namespace {

constexpr uint64_t kOffsetBasis = 0xcbf29ce484222325ULL;

inline uint64_t fnvStep(uint64_t hash, uint8_t byte) { return (hash ^ byte) * 0x100000001b3ULL; }

}  // namespace

uint64_t fnv1a64(const uint8_t* data, size_t size, uint64_t hash) {
  for (size_t i = 0; i < size; ++i) hash = fnvStep(hash, data[i]);
  return hash;
}

uint64_t fnv1a64(const std::string& text) { return fnv1a64(reinterpret_cast<const uint8_t*>(text.data()), text.size()); }

std::vector<uint64_t> fnv1a64Each(const std::vector<ByteRange>& ranges) {
  constexpr size_t kLanes = 4;
  constexpr size_t kNone = SIZE_MAX;
  // Each turn hashes the same number of bytes in every lane; a lane with no range left hashes
  // these zeros, and its hash is dropped, so that the inner loop keeps one shape.
  constexpr size_t kTurn = size_t{1} << 16;
  static const uint8_t kIdle[kTurn] = {};
  struct Lane {
    size_t range = kNone;
    size_t done = 0;
    uint64_t hash = kOffsetBasis;
  };
  std::vector<uint64_t> hashes(ranges.size());
  Lane lanes[kLanes];
  size_t next = 0;
  // Records a finished range's hash and gives the lane the next range (empty ones finish at once).
  const auto refill = [&](Lane& lane) {
    while (lane.range == kNone || lane.done == ranges[lane.range].size) {
      if (lane.range != kNone) hashes[lane.range] = lane.hash;
      if (next == ranges.size()) {
        lane = Lane();
        return;
      }
      lane = Lane{next++, 0, kOffsetBasis};
    }
  };
  while (true) {
    size_t turn = kTurn;
    for (Lane& lane : lanes) {
      refill(lane);
      if (lane.range != kNone) turn = std::min(turn, ranges[lane.range].size - lane.done);
    }
    if (std::all_of(lanes, lanes + kLanes, [](const Lane& lane) { return lane.range == kNone; })) break;
    const uint8_t* data[kLanes];
    uint64_t hash[kLanes];
    for (size_t k = 0; k < kLanes; ++k) {
      data[k] = lanes[k].range == kNone ? kIdle : ranges[lanes[k].range].data + lanes[k].done;
      hash[k] = lanes[k].hash;
    }
    for (size_t i = 0; i < turn; ++i) {
      for (size_t k = 0; k < kLanes; ++k) hash[k] = fnvStep(hash[k], data[k][i]);
    }
    for (size_t k = 0; k < kLanes; ++k) {
      lanes[k].hash = hash[k];
      lanes[k].done += turn;
    }
  }
  return hashes;
}

std::string hex64(uint64_t value) {
  char buffer[17];
  std::snprintf(buffer, sizeof(buffer), "%016llx", static_cast<unsigned long long>(value));
  return buffer;
}

}  // namespace ffloc
