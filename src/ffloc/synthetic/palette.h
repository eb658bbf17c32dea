#pragma once

#include "ffloc/synthetic/material.h"
#include "ffloc/core/random.h"

namespace ffloc::synthetic {

// Linear RGB from hue (turns), saturation and value, with a square for the display gamma.
Vec3 colourFromHsv(double hue, double saturation, double value);

// Randomised materials by what they imitate. `scale` multiplies the pattern period, so the
// same family serves a desk (centimetre detail) and a street (metre detail).
Material paintMaterial(Rng& rng);
Material wallpaperMaterial(Rng& rng);
Material woodMaterial(Rng& rng, double scale = 1.0);
Material fabricMaterial(Rng& rng, double scale = 1.0);
Material metalMaterial(Rng& rng);
Material plasticMaterial(Rng& rng, double scale = 1.0);
Material stoneMaterial(Rng& rng, double scale = 1.0);
Material brickMaterial(Rng& rng, double scale = 1.0);
Material tileMaterial(Rng& rng, double scale = 1.0);
Material marbleMaterial(Rng& rng, double scale = 1.0);
Material posterMaterial(Rng& rng, double scale = 1.0);
Material facadeMaterial(Rng& rng);
Material foliageMaterial(Rng& rng);
Material groundMaterial(Rng& rng);

}  // namespace ffloc::synthetic
