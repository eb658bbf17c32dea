#include "ffloc/synthetic/palette.h"

#include <cmath>

namespace ffloc::synthetic {

// Every random draw below is its own statement (or inside a braced list, which C++ sequences
// left to right): the order of evaluation of function arguments is unspecified, and two
// compilers that order them differently would otherwise build different scenes.

Vec3 colourFromHsv(double hue, double saturation, double value) {
  const double h = (hue - std::floor(hue)) * 6.0;
  const double sector = std::floor(h);
  const double f = h - sector;
  const double p = value * (1.0 - saturation), q = value * (1.0 - saturation * f),
               t = value * (1.0 - saturation * (1.0 - f));
  Vec3 c;
  switch (static_cast<int>(sector)) {
    case 0: c = {value, t, p}; break;
    case 1: c = {q, value, p}; break;
    case 2: c = {p, value, t}; break;
    case 3: c = {p, q, value}; break;
    case 4: c = {t, p, value}; break;
    default: c = {value, p, q}; break;
  }
  return mul(c, c);
}

namespace {

struct Range {
  double lo, hi;
};

Vec3 randomColour(Rng& rng, Range hue, Range saturation, Range value) {
  const double h = rng.uniform(hue.lo, hue.hi);
  const double s = rng.uniform(saturation.lo, saturation.hi);
  const double v = rng.uniform(value.lo, value.hi);
  return colourFromHsv(h, s, v);
}

Vec3 jitter(Rng& rng, const Vec3& c, double amount) {
  return {c.x * (1.0 + rng.uniform(-amount, amount)), c.y * (1.0 + rng.uniform(-amount, amount)),
          c.z * (1.0 + rng.uniform(-amount, amount))};
}

Material make(Rng& rng, Pattern pattern, const Vec3& base, const Vec3& accent,
              const Vec3& detail, double period, double roughness) {
  Material m;
  m.pattern = pattern;
  m.base = base;
  m.accent = accent;
  m.detail = detail;
  m.period = period;
  m.roughness = roughness;
  m.seed = static_cast<uint32_t>(rng.next());
  return m;
}

}  // namespace

Material paintMaterial(Rng& rng) {
  const Vec3 base = randomColour(rng, {0, 1}, {0.05, 0.35}, {0.7, 0.95});
  const double period = rng.uniform(0.8, 2.0);
  const double roughness = rng.uniform(0.15, 0.35);
  return make(rng, Pattern::kGrain, base, base * 0.9, base * 0.7, period, roughness);
}

Material wallpaperMaterial(Rng& rng) {
  const double hue = rng.uniform();
  const Vec3 base = randomColour(rng, {hue, hue}, {0.1, 0.4}, {0.7, 0.95});
  const Vec3 accent = randomColour(rng, {hue - 0.1, hue + 0.1}, {0.2, 0.6}, {0.5, 0.85});
  const Pattern pattern = rng.chance(0.6) ? Pattern::kStripes : Pattern::kDots;
  const double period = rng.uniform(0.08, 0.3);
  return make(rng, pattern, base, accent, accent * 0.6, period, 0.2);
}

Material woodMaterial(Rng& rng, double scale) {
  const Vec3 base = randomColour(rng, {0.05, 0.1}, {0.45, 0.7}, {0.45, 0.85});
  const double darker = rng.uniform(0.55, 0.75);
  const double period = rng.uniform(0.12, 0.25) * scale;
  Material m = make(rng, Pattern::kWood, base, base * darker, base * 0.35, period, 0.3);
  m.specular = rng.uniform(0.0, 0.15);
  return m;
}

Material fabricMaterial(Rng& rng, double scale) {
  const double hue = rng.uniform();
  const Vec3 base = randomColour(rng, {hue, hue}, {0.2, 0.8}, {0.3, 0.85});
  const Vec3 accent = randomColour(rng, {hue + 0.1, hue + 0.5}, {0.2, 0.8}, {0.3, 0.9});
  const int which = rng.index(3);
  const Pattern pattern =
      which == 0 ? Pattern::kStripes : (which == 1 ? Pattern::kDots : Pattern::kGrain);
  const double period = rng.uniform(0.04, 0.15) * scale;
  return make(rng, pattern, base, accent, base * 0.5, period, 0.45);
}

Material metalMaterial(Rng& rng) {
  const Vec3 base = jitter(rng, Vec3{0.55, 0.56, 0.58}, 0.15);
  Material m = make(rng, Pattern::kGrain, base, base * 0.8, base * 0.5, 0.3, 0.15);
  m.specular = rng.uniform(0.3, 0.7);
  m.shininess = 64;
  return m;
}

Material plasticMaterial(Rng& rng, double scale) {
  const Vec3 base = randomColour(rng, {0, 1}, {0.4, 0.95}, {0.5, 0.95});
  const Vec3 accent = randomColour(rng, {0, 1}, {0.3, 0.9}, {0.5, 0.95});
  const int which = rng.index(4);
  const Pattern pattern = which == 0   ? Pattern::kDots
                          : which == 1 ? Pattern::kStripes
                                       : Pattern::kGrain;
  const double period = rng.uniform(0.02, 0.06) * scale;
  Material m = make(rng, pattern, base, accent, base * 0.4, period, 0.15);
  m.specular = rng.uniform(0.2, 0.5);
  m.shininess = 32;
  return m;
}

Material stoneMaterial(Rng& rng, double scale) {
  const double v = rng.uniform(0.35, 0.75);
  const Vec3 base = jitter(rng, Vec3{v, v * 0.97, v * 0.92}, 0.08);
  const double darker = rng.uniform(0.55, 0.8);
  const double period = rng.uniform(0.3, 0.8) * scale;
  return make(rng, Pattern::kStone, base, base * darker, base * 0.4, period, 0.35);
}

Material brickMaterial(Rng& rng, double scale) {
  const Vec3 base = randomColour(rng, {0.0, 0.06}, {0.45, 0.7}, {0.5, 0.75});
  const double darker = rng.uniform(0.6, 0.85);
  const Vec3 mortar = jitter(rng, Vec3{0.65, 0.63, 0.6}, 0.1);
  const double period = rng.uniform(0.07, 0.09) * scale;
  return make(rng, Pattern::kBricks, base, base * darker, mortar, period, 0.3);
}

Material tileMaterial(Rng& rng, double scale) {
  const double hue = rng.uniform();
  const Vec3 base = randomColour(rng, {hue, hue}, {0.0, 0.3}, {0.6, 0.95});
  Vec3 accent = base * 0.85;
  if (rng.chance(0.4)) accent = randomColour(rng, {hue + 0.5, hue + 0.5}, {0.0, 0.4}, {0.2, 0.6});
  const double period = rng.uniform(0.2, 0.6) * scale;
  Material m = make(rng, Pattern::kTiles, base, accent, Vec3{0.3, 0.3, 0.3}, period, 0.15);
  m.specular = rng.uniform(0.1, 0.4);
  m.shininess = 32;
  return m;
}

Material marbleMaterial(Rng& rng, double scale) {
  const double v = rng.uniform(0.7, 0.95);
  const Vec3 base = jitter(rng, Vec3{v, v, v * 0.97}, 0.05);
  const Vec3 veins = randomColour(rng, {0, 1}, {0.0, 0.3}, {0.2, 0.5});
  const double period = rng.uniform(0.2, 0.5) * scale;
  Material m = make(rng, Pattern::kMarble, base, base * 0.85, veins, period, 0.1);
  m.specular = 0.3;
  m.shininess = 32;
  return m;
}

Material posterMaterial(Rng& rng, double scale) {
  const Vec3 base = randomColour(rng, {0, 1}, {0.3, 0.9}, {0.4, 0.95});
  const Vec3 accent = randomColour(rng, {0, 1}, {0.3, 0.9}, {0.2, 0.9});
  const Vec3 detail = randomColour(rng, {0, 1}, {0.3, 1.0}, {0.1, 0.6});
  const Pattern patterns[] = {Pattern::kStone, Pattern::kMarble, Pattern::kDots,
                              Pattern::kStripes, Pattern::kTiles};
  const Pattern pattern = patterns[rng.index(5)];
  const double period = rng.uniform(0.05, 0.25) * scale;
  return make(rng, pattern, base, accent, detail, period, 0.4);
}

Material facadeMaterial(Rng& rng) {
  const int family = rng.index(4);
  Vec3 base;
  if (family == 0) base = randomColour(rng, {0.08, 0.14}, {0.15, 0.4}, {0.7, 0.9});
  else if (family == 1) base = randomColour(rng, {0.0, 0.05}, {0.4, 0.6}, {0.5, 0.7});
  else if (family == 2) base = jitter(rng, Vec3{0.55, 0.55, 0.55}, 0.1);
  else base = randomColour(rng, {0, 1}, {0.1, 0.35}, {0.65, 0.9});
  const Vec3 glass = randomColour(rng, {0.5, 0.65}, {0.2, 0.5}, {0.15, 0.35});
  const double period = rng.uniform(2.4, 4.0);
  Material m = make(rng, Pattern::kWindows, base, base * 0.75, glass, period, 0.3);
  m.specular = 0.05;
  return m;
}

Material foliageMaterial(Rng& rng) {
  const Vec3 base = randomColour(rng, {0.2, 0.35}, {0.45, 0.8}, {0.3, 0.6});
  const Vec3 accent = randomColour(rng, {0.15, 0.3}, {0.5, 0.9}, {0.15, 0.35});
  const double period = rng.uniform(0.15, 0.35);
  return make(rng, Pattern::kStone, base, accent, accent * 0.5, period, 0.6);
}

Material groundMaterial(Rng& rng) {
  if (rng.chance(0.5)) {
    const Vec3 base = randomColour(rng, {0.18, 0.3}, {0.35, 0.6}, {0.35, 0.55});
    const Vec3 accent = randomColour(rng, {0.08, 0.12}, {0.3, 0.5}, {0.3, 0.5});
    const double period = rng.uniform(3.0, 8.0);
    return make(rng, Pattern::kStone, base, accent, accent * 0.5, period, 0.5);
  }
  const double v = rng.uniform(0.25, 0.4);
  const double period = rng.uniform(2.0, 5.0);
  return make(rng, Pattern::kStone, Vec3{v, v, v * 1.02}, Vec3{v * 0.7, v * 0.7, v * 0.72},
              Vec3{0.1, 0.1, 0.1}, period, 0.4);
}

}  // namespace ffloc::synthetic
