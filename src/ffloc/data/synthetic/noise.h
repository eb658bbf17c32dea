#pragma once

#include <cstdint>

#include "ffloc/data/synthetic/vec3.h"

namespace ffloc::synthetic {

// A hash of an integer lattice point to [0, 1).
double latticeValue(int64_t x, int64_t y, int64_t z, uint32_t seed);

// Trilinear value noise with smoothstep weights, in [0, 1]; one feature per unit of p.
double valueNoise(const Vec3& p, uint32_t seed);

// Fractal sum of `octaves` value-noise layers, each at twice the frequency and half the weight
// of the last, in [0, 1]. `footprint` is the pixel's size in the same units as p: layers finer
// than the pixel fade to their mean, the cheap texture filtering that keeps distant surfaces
// from aliasing into salt-and-pepper.
double fractalNoise(const Vec3& p, int octaves, double footprint, uint32_t seed);

// How much of a pattern with period `period` a pixel of size `footprint` can still resolve:
// 1 when the period spans many pixels, falling to 0 when it spans about two.
double resolvable(double period, double footprint);

}  // namespace ffloc::synthetic
