#pragma once

#include <vector>

#include "ffloc/data/scene.h"
#include "ffloc/eval/exports.h"
#include "ffloc/eval/metrics.h"
#include "ffloc/pose/correspondences.h"

namespace ffloc {

// Helpers for the PLY views of ffloc localize / ffloc eval: mapping cameras, query cameras and a
// query's predicted points in one world frame.

// A camera glyph size that reads well at the scene's scale: 5% of the largest extent of the
// camera centres (1 when they coincide).
double cameraGlyphSize(const std::vector<Pose>& cameras);

// At most `max_points` of the predicted points whose confidence is at least `min_confidence`,
// evenly strided over the image so the cloud covers all of it.
void addPredictedPoints(PlyWriter& ply, const Correspondences& pairs, float min_confidence, size_t max_points,
                        PlyWriter::Colour colour);

// The PLY of an evaluation run on one scene: mapping cameras grey, ground-truth query cameras
// green, estimated ones blue (succeeded frames), and `points` (e.g. one query's predictions,
// confidence >= min_confidence, at most 50000) red when given.
PlyWriter evaluationPly(const Scene& scene, const std::vector<FrameResult>& frames, const Correspondences* points,
                        float min_confidence);

}  // namespace ffloc
