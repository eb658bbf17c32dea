#pragma once

#include <cstddef>
#include <cstdint>

namespace ffloc {

// SplitMix64 (Steele, Lea, Flood 2014), written out here rather than taken from <random>:
// the standard distributions are implementation-defined, and scenes must be identical on
// every machine and standard library.
inline uint64_t mix64(uint64_t z) {
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
  return z ^ (z >> 31);
}

class Rng {
 public:
  explicit Rng(uint64_t seed) : state_(seed) {}

  uint64_t next() {
    state_ += 0x9e3779b97f4a7c15ULL;
    return mix64(state_);
  }
  // In [0, 1), 53 random bits.
  double uniform() { return static_cast<double>(next() >> 11) * (1.0 / 9007199254740992.0); }
  double uniform(double lo, double hi) { return lo + (hi - lo) * uniform(); }
  // In [0, n); the modulo bias is below 2^-40 for the small n used here.
  int index(int n) { return static_cast<int>(next() % static_cast<uint64_t>(n)); }
  size_t below(size_t n) { return static_cast<size_t>(next() % static_cast<uint64_t>(n)); }
  // In [lo, hi], both included.
  int64_t between(int64_t lo, int64_t hi) { return lo + static_cast<int64_t>(below(static_cast<size_t>(hi - lo + 1))); }
  bool chance(double p) { return uniform() < p; }
  // Zero mean, unit variance, bell-shaped (Irwin-Hall of four uniforms): needs only sqrt,
  // which IEEE 754 rounds exactly, unlike the log and cos of Box-Muller.
  double normal() {
    const double sum = uniform() + uniform() + uniform() + uniform();
    return (sum - 2.0) * 1.7320508075688772;
  }
  // An independent stream for a named part of the scene, so adding draws to one part does not
  // shift every other part.
  Rng fork(uint64_t tag) const { return Rng(mix64(state_ ^ mix64(tag + 0x632be59bd9b4e019ULL))); }

 private:
  uint64_t state_;
};

}  // namespace ffloc
