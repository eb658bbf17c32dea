#include "ffloc/synthetic/capture.h"

#include <algorithm>
#include <cmath>

#include "ffloc/synthetic/det_math.h"

namespace ffloc::synthetic {

Pose toPose(const CameraState& camera) {
  const Vec3 f = normalized(camera.forward);
  Vec3 right = normalized(cross(f, Vec3{0, 0, 1}));
  Vec3 down = cross(f, right);
  if (camera.roll != 0.0) {
    const double c = detCos(camera.roll), s = detSin(camera.roll);
    const Vec3 r = right * c + down * s;
    down = down * c - right * s;
    right = r;
  }
  Pose pose;
  for (int i = 0; i < 3; ++i) {
    pose.R(i, 0) = right[i];
    pose.R(i, 1) = down[i];
    pose.R(i, 2) = f[i];
  }
  pose.t = {camera.position.x, camera.position.y, camera.position.z};
  return pose;
}

Vec3 direction(double yaw, double pitch) {
  const double cp = detCos(pitch);
  return {cp * detCos(yaw), cp * detSin(yaw), detSin(pitch)};
}

Vec3 turn(const Vec3& forward, double yaw, double pitch) {
  const double c = detCos(yaw), s = detSin(yaw);
  Vec3 f{forward.x * c - forward.y * s, forward.x * s + forward.y * c, forward.z};
  if (pitch != 0.0) {
    const Vec3 horizontal = normalized(Vec3{f.x, f.y, 0.0});
    const double h = std::sqrt(f.x * f.x + f.y * f.y);
    // Elevation change without atan2: rotate (h, z) by pitch in the vertical plane.
    const double cp = detCos(pitch), sp = detSin(pitch);
    const double nh = h * cp - f.z * sp, nz = h * sp + f.z * cp;
    f = horizontal * nh + Vec3{0, 0, nz};
  }
  return normalized(f);
}

const char* toString(QueryKind kind) {
  switch (kind) {
    case QueryKind::kNear: return "near";
    case QueryKind::kFar: return "far";
    case QueryKind::kOpposite: return "opposite";
  }
  return "near";
}

bool viewIsUsable(const World& world, const Intrinsics& camera, const CameraState& state,
                  const ViewRequirements& req) {
  // Inside (or within the clearance of) any shape's own box, whatever its orientation.
  for (const auto& s : world.shapes) {
    const Vec3 local = s.rotation.transposeTimes(state.position - s.centre);
    if (std::fabs(local.x) < s.half.x + req.clearance &&
        std::fabs(local.y) < s.half.y + req.clearance &&
        std::fabs(local.z) < s.half.z + req.clearance)
      return false;
  }
  const Pose pose = toPose(state);
  const Vec3 centre{pose.t.x(), pose.t.y(), pose.t.z()};
  Mat3 rotation;
  rotation.c0 = {pose.R(0, 0), pose.R(1, 0), pose.R(2, 0)};
  rotation.c1 = {pose.R(0, 1), pose.R(1, 1), pose.R(2, 1)};
  rotation.c2 = {pose.R(0, 2), pose.R(1, 2), pose.R(2, 2)};
  constexpr int kCols = 12, kRows = 9;
  int blocked = 0, hits = 0;
  for (int j = 0; j < kRows; ++j) {
    for (int i = 0; i < kCols; ++i) {
      const double u = (i + 0.5) * camera.width / kCols, v = (j + 0.5) * camera.height / kRows;
      const Ray ray{centre, rotation * Vec3{(u - camera.cx) / camera.fx,
                                            (v - camera.cy) / camera.fy, 1.0}};
      Hit hit;
      if (!world.closestHit(ray, 0.0, 5000.0, hit)) continue;
      ++hits;
      if (hit.t < req.min_depth) ++blocked;
    }
  }
  const double total = kCols * kRows;
  return blocked <= req.max_blocked_fraction * total && hits >= req.min_hit_fraction * total;
}

namespace {

double distanceToScan(const Vec3& p, const std::vector<CameraState>& mapping) {
  double best = 1e300;
  for (const auto& m : mapping) best = std::min(best, norm(p - m.position));
  return best;
}

CameraState nearView(Rng& rng, const std::vector<CameraState>& mapping,
                     const QuerySampling& sampling) {
  CameraState c = mapping[rng.index(static_cast<int>(mapping.size()))];
  c.position = c.position + Vec3{rng.normal() * sampling.near_translation,
                                 rng.normal() * sampling.near_translation,
                                 rng.normal() * sampling.near_translation * 0.3};
  const double yaw = rng.normal() * sampling.near_rotation;
  const double pitch = rng.normal() * sampling.near_rotation * 0.4;
  c.forward = turn(c.forward, yaw, pitch);
  c.roll += rng.normal() * 0.03;
  return c;
}

CameraState oppositeView(Rng& rng, const std::vector<CameraState>& mapping,
                         const QuerySampling& sampling) {
  CameraState c = mapping[rng.index(static_cast<int>(mapping.size()))];
  c.position = c.position + Vec3{rng.normal() * sampling.near_translation * 0.5,
                                 rng.normal() * sampling.near_translation * 0.5, 0.0};
  c.forward = turn(c.forward, kPi + rng.uniform(-0.35, 0.35), 0.0);
  return c;
}

}  // namespace

QueryPlan sampleQueries(Rng& rng, const World& world, const Intrinsics& camera,
                        const std::vector<CameraState>& mapping, int count,
                        const QuerySampling& sampling) {
  QueryPlan plan;
  constexpr int kTries = 60, kFarCandidates = 12;
  for (int q = 0; q < count; ++q) {
    const auto kind = static_cast<QueryKind>(q % 3);
    CameraState chosen = mapping[rng.index(static_cast<int>(mapping.size()))];
    bool found = false;
    if (kind == QueryKind::kFar) {
      double best = -1.0;
      for (int attempt = 0; attempt < kTries * 2 && !(found && attempt >= kFarCandidates);
           ++attempt) {
        const CameraState candidate = sampling.far_candidate(rng);
        if (!viewIsUsable(world, camera, candidate, sampling.requirements)) continue;
        const double d = distanceToScan(candidate.position, mapping);
        if (d > best) {
          best = d;
          chosen = candidate;
          found = true;
        }
      }
    } else {
      for (int attempt = 0; attempt < kTries && !found; ++attempt) {
        const CameraState candidate = kind == QueryKind::kNear
                                          ? nearView(rng, mapping, sampling)
                                          : oppositeView(rng, mapping, sampling);
        if (viewIsUsable(world, camera, candidate, sampling.requirements)) {
          chosen = candidate;
          found = true;
        }
      }
    }
    plan.cameras.push_back(chosen);
    plan.kinds.push_back(found ? kind : QueryKind::kNear);
  }
  return plan;
}

}  // namespace ffloc::synthetic
