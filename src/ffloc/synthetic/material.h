#pragma once

#include <cstdint>

#include "ffloc/synthetic/vec3.h"

namespace ffloc::synthetic {

// Procedural surface patterns, evaluated in the shape's local frame so each object carries its
// own texture with it. Several are periodic (tiles, bricks, windows, stripes, dots): the
// repetitive structure that makes matching ambiguous in real scenes.
enum class Pattern : uint8_t {
  kGrain,    // base colour with multi-scale noise (plaster, paint, plastic)
  kStone,    // two colours mixed by fractal noise (concrete, rock, asphalt, grass)
  kTiles,    // square tiles with grout and per-tile shade
  kBricks,   // running-bond bricks with mortar
  kWood,     // planks with distorted grain
  kStripes,  // wallpaper / fabric stripes
  kWindows,  // a facade grid of windows, some lit
  kMarble,   // veined stone
  kDots,     // a regular grid of discs (fabric, packaging)
};

struct Material {
  Pattern pattern = Pattern::kGrain;
  Vec3 base{0.6, 0.6, 0.6};    // linear albedo
  Vec3 accent{0.4, 0.4, 0.4};  // second colour of the pattern
  Vec3 detail{0.2, 0.2, 0.2};  // grout, mortar, frames, veins
  double period = 0.5;         // the pattern's main period, scene units
  double roughness = 0.3;      // amplitude of the noise that modulates the pattern
  double specular = 0.0;       // strength of the highlight
  int shininess = 16;          // Blinn-Phong exponent, a power of two
  uint32_t seed = 0;
};

// Albedo at a point of a surface with the given local normal. `footprint` is the pixel's size
// on the surface: detail finer than about two pixels fades to its mean colour.
Vec3 albedo(const Material& material, const Vec3& local_point, const Vec3& local_normal,
            double footprint);

}  // namespace ffloc::synthetic
