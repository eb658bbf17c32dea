#include "ffloc/synthetic/material.h"

#include <cmath>

#include "ffloc/synthetic/noise.h"

namespace ffloc::synthetic {
namespace {

double fract(double x) { return x - floorExact(x); }

double clamp01(double x) { return x < 0.0 ? 0.0 : (x > 1.0 ? 1.0 : x); }

// A smooth edge of width w, evaluated with polynomials only.
double smoothEdge(double edge0, double edge1, double x) {
  const double t = clamp01((x - edge0) / (edge1 - edge0));
  return t * t * (3.0 - 2.0 * t);
}

// Surface coordinates: the two local axes across the face the normal points out of; the
// second is vertical on walls so rows of bricks and windows come out level.
void faceCoordinates(const Vec3& p, const Vec3& n, double& s, double& t) {
  const double ax = std::fabs(n.x), ay = std::fabs(n.y), az = std::fabs(n.z);
  if (az >= ax && az >= ay) {
    s = p.x;
    t = p.y;
  } else if (ax >= ay) {
    s = p.y;
    t = p.z;
  } else {
    s = p.x;
    t = p.z;
  }
}

// Hash of a 2D cell to [0, 1).
double cellValue(double cs, double ct, uint32_t seed) {
  return latticeValue(static_cast<int64_t>(cs), static_cast<int64_t>(ct), 17, seed);
}

// Distance to the nearest grid line of a unit grid, in cells.
double lineDistance(double x) {
  const double f = fract(x);
  return f < 0.5 ? f : 1.0 - f;
}

}  // namespace

Vec3 albedo(const Material& m, const Vec3& p, const Vec3& n, double footprint) {
  double s, t;
  faceCoordinates(p, n, s, t);
  const double P = m.period;
  // A low-frequency stain shared by every pattern, so no surface is a flat colour.
  const double stain = fractalNoise(p * (1.0 / (3.0 * P)), 2, footprint / (3.0 * P), m.seed);
  const double grain = fractalNoise(p * (8.0 / P), 2, footprint * 8.0 / P, m.seed + 7);
  const double shade = 1.0 + m.roughness * ((stain - 0.5) * 1.2 + (grain - 0.5) * 0.5);
  Vec3 colour;
  switch (m.pattern) {
    case Pattern::kGrain: colour = m.base; break;
    case Pattern::kStone: {
      const double v = fractalNoise(p * (1.0 / P), 4, footprint / P, m.seed + 3);
      colour = lerp(m.base, m.accent, smoothEdge(0.35, 0.65, v));
      break;
    }
    case Pattern::kTiles: {
      const double u = s / P, w = t / P;
      const double cs = floorExact(u), ct = floorExact(w);
      const double jitter = cellValue(cs, ct, m.seed);
      const bool odd = (static_cast<int64_t>(cs + ct) & 1) != 0;
      const Vec3 tile = lerp(m.base, m.accent, odd ? 0.85 : 0.15 * jitter) * (0.9 + 0.2 * jitter);
      const double gap = std::fmin(lineDistance(u), lineDistance(w)) * P;
      // Tiles stay visible until they shrink to a pixel; the grout lines go much sooner and
      // then only darken the average.
      const double grout_keep = resolvable(P * 0.05, footprint);
      const double grout = (1.0 - smoothEdge(0.004, 0.008, gap)) * grout_keep + 0.03 * (1.0 - grout_keep);
      const Vec3 mean = lerp(m.base, m.accent, 0.5);
      colour = lerp(lerp(mean, tile, resolvable(P, footprint)), m.detail, grout);
      break;
    }
    case Pattern::kBricks: {
      const double row_f = t / P;
      const double row = floorExact(row_f);
      const double u = s / (2.0 * P) + ((static_cast<int64_t>(row) & 1) ? 0.5 : 0.0);
      const double jitter = cellValue(floorExact(u), row, m.seed);
      const Vec3 brick = lerp(m.base, m.accent, jitter);
      const double gap = std::fmin(lineDistance(u) * 2.0 * P, lineDistance(row_f) * P);
      const double mortar_keep = resolvable(P * 0.15, footprint);
      const double mortar =
          (1.0 - smoothEdge(P * 0.04, P * 0.08, gap)) * mortar_keep + 0.15 * (1.0 - mortar_keep);
      const Vec3 mean = lerp(m.base, m.accent, 0.5);
      colour = lerp(lerp(mean, brick, resolvable(P, footprint)), m.detail, mortar);
      break;
    }
    case Pattern::kWood: {
      const double plank = floorExact(s / (P * 1.5));
      const double warp = fractalNoise(Vec3{s * 0.3 / P, t * 4.0 / P, plank}, 3,
                                       footprint * 4.0 / P, m.seed + 11);
      const double rings = fract(t * 6.0 / P + warp * 3.0 + plank * 0.37);
      const double ring_keep = resolvable(P / 6.0, footprint);
      const Vec3 wood = lerp(m.base, m.accent, 0.5 + (rings * rings - 0.33) * ring_keep);
      const double seam = 1.0 - smoothEdge(0.002, 0.004, lineDistance(s / (P * 1.5)) * P * 1.5);
      colour = lerp(wood * (0.85 + 0.3 * cellValue(plank, 0, m.seed)), m.detail,
                    seam * resolvable(P * 0.05, footprint));
      break;
    }
    case Pattern::kStripes: {
      const double u = s / P;
      const double band = smoothEdge(0.45, 0.55, lineDistance(u) * 2.0);
      const double keep = resolvable(P * 0.5, footprint);
      colour = lerp(lerp(m.base, m.accent, 0.5), lerp(m.base, m.accent, band), keep);
      break;
    }
    case Pattern::kWindows: {
      const double cell_w = P, cell_h = P * 1.25;
      const double u = s / cell_w, w = t / cell_h;
      const double cs = floorExact(u), ct = floorExact(w);
      const double fu = u - cs, fw = w - ct;
      const bool glass_here = fu > 0.22 && fu < 0.78 && fw > 0.25 && fw < 0.82;
      const bool frame_here = fu > 0.19 && fu < 0.81 && fw > 0.21 && fw < 0.86;
      const double lit = cellValue(cs, ct, m.seed);
      Vec3 glass = m.detail * (0.6 + 0.8 * fw);
      if (lit > 0.85) glass = Vec3{0.9, 0.75, 0.45};
      else if (lit < 0.2) glass = lerp(glass, m.accent, 0.5 * (1.0 - fw));  // drawn blinds
      const Vec3 frame{0.85, 0.85, 0.82};
      // Window openings last until they shrink to a pixel or two; frames and ledges go first,
      // blending into the colour around them.
      const double fine = resolvable(P * 0.04, footprint);
      Vec3 c = fw < 0.06 ? lerp(m.base, lerp(m.base, m.accent, 0.6), fine) : m.base;
      if (frame_here) c = lerp(lerp(m.base, glass, 0.7), frame, fine);
      if (glass_here) c = glass;
      const Vec3 mean = lerp(m.base, m.detail, 0.3);
      colour = lerp(mean, c, resolvable(P * 0.4, footprint));
      break;
    }
    case Pattern::kMarble: {
      const double v = fractalNoise(p * (1.0 / P), 4, footprint / P, m.seed + 5);
      const double vein = lineDistance((s + t) / P + 4.0 * v) * 2.0;
      colour = lerp(m.base, m.detail, (1.0 - smoothEdge(0.0, 0.12, vein)) * 0.8);
      colour = lerp(colour, m.accent, smoothEdge(0.5, 0.8, v) * 0.4);
      break;
    }
    case Pattern::kDots: {
      const double u = s / P, w = t / P;
      const double du = fract(u) - 0.5, dw = fract(w) - 0.5;
      const double disc = 1.0 - smoothEdge(0.09, 0.11, du * du + dw * dw);
      const double keep = resolvable(P * 0.4, footprint);
      colour = lerp(lerp(m.base, m.accent, 0.3), lerp(m.base, m.accent, disc), keep);
      break;
    }
  }
  return colour * shade;
}

}  // namespace ffloc::synthetic
