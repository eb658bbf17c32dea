#pragma once

#include <cstdint>

#include "ffloc/synthetic/vec3.h"

// Defined here, inline: every textured pixel evaluates several noise layers, and inlined into
// the material code the octave loops unroll and the calls disappear.
namespace ffloc::synthetic {

// floor(x) as an integer, exact for |x| < 2^62: truncation and a correction, which is several
// times cheaper than std::floor on baseline x86-64 (no SSE4.1 rounding instruction).
inline int64_t floorToInt(double x) {
  const auto i = static_cast<int64_t>(x);
  return x < static_cast<double>(i) ? i - 1 : i;
}

inline double floorExact(double x) { return static_cast<double>(floorToInt(x)); }

namespace noise_detail {

// A 32-bit integer hash (xor of per-axis products, then a multiply-xorshift finaliser): far
// cheaper than a 64-bit mix, and plenty for texture noise.
inline uint32_t finalise(uint32_t h) {
  h ^= h >> 15;
  h *= 0x2c1b3c6dU;
  h ^= h >> 12;
  h *= 0x297a2d39U;
  h ^= h >> 15;
  return h;
}

constexpr uint32_t kPrimeX = 0x8da6b343U, kPrimeY = 0xd8163841U, kPrimeZ = 0xcb1ab31fU;
constexpr double kToUnit = 1.0 / 4294967296.0;

}  // namespace noise_detail

// A hash of an integer lattice point to [0, 1).
inline double latticeValue(int64_t x, int64_t y, int64_t z, uint32_t seed) {
  using namespace noise_detail;
  const uint32_t h = static_cast<uint32_t>(x) * kPrimeX ^ static_cast<uint32_t>(y) * kPrimeY ^
                     static_cast<uint32_t>(z) * kPrimeZ ^ seed * 0x165667b1U;
  return finalise(h) * kToUnit;
}

// Trilinear value noise with smoothstep weights, in [0, 1]; one feature per unit of p.
inline double valueNoise(const Vec3& p, uint32_t seed) {
  using namespace noise_detail;
  const int64_t fx = floorToInt(p.x), fy = floorToInt(p.y), fz = floorToInt(p.z);
  const auto ix = static_cast<uint32_t>(fx);
  const auto iy = static_cast<uint32_t>(fy);
  const auto iz = static_cast<uint32_t>(fz);
  double tx = p.x - static_cast<double>(fx), ty = p.y - static_cast<double>(fy),
         tz = p.z - static_cast<double>(fz);
  tx = tx * tx * (3.0 - 2.0 * tx);
  ty = ty * ty * (3.0 - 2.0 * ty);
  tz = tz * tz * (3.0 - 2.0 * tz);
  const uint32_t s = seed * 0x165667b1U;
  const uint32_t x0 = ix * kPrimeX, x1 = (ix + 1) * kPrimeX;
  const uint32_t y0 = iy * kPrimeY, y1 = (iy + 1) * kPrimeY;
  const uint32_t z0 = iz * kPrimeZ ^ s, z1 = (iz + 1) * kPrimeZ ^ s;
  auto edge = [&](uint32_t y, uint32_t z) {
    const double a = finalise(x0 ^ y ^ z) * kToUnit, b = finalise(x1 ^ y ^ z) * kToUnit;
    return a + (b - a) * tx;
  };
  auto face = [&](uint32_t z) {
    const double a = edge(y0, z), b = edge(y1, z);
    return a + (b - a) * ty;
  };
  const double a = face(z0), b = face(z1);
  return a + (b - a) * tz;
}

// How much of a pattern with period `period` a pixel of size `footprint` can still resolve:
// 1 when the period spans many pixels, falling to 0 when it spans about two.
inline double resolvable(double period, double footprint) {
  const double cycles_per_pixel = footprint / period;
  if (cycles_per_pixel <= 0.25) return 1.0;
  if (cycles_per_pixel >= 0.5) return 0.0;
  return (0.5 - cycles_per_pixel) * 4.0;
}

// Fractal sum of `octaves` value-noise layers, each at twice the frequency and half the weight
// of the last, in [0, 1]. `footprint` is the pixel's size in the same units as p: layers finer
// than the pixel fade to their mean, the cheap texture filtering that keeps distant surfaces
// from aliasing into salt-and-pepper.
inline double fractalNoise(const Vec3& p, int octaves, double footprint, uint32_t seed) {
  double sum = 0.0, weight = 0.5, total = 0.0, frequency = 1.0;
  for (int i = 0; i < octaves; ++i) {
    const double keep = resolvable(1.0 / frequency, footprint);
    const double layer =
        keep > 0.0 ? 0.5 + (valueNoise(p * frequency, seed + 1013u * i) - 0.5) * keep : 0.5;
    sum += layer * weight;
    total += weight;
    weight *= 0.5;
    frequency *= 2.0;
  }
  return sum / total;
}

}  // namespace ffloc::synthetic
