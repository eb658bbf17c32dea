#pragma once

#include <c10/core/DeviceType.h>
#include <c10/core/ScalarType.h>

namespace ffloc {

// Mixed precision for the scope of the guard: libtorch's autocast on `device` with `dtype`
// (matrix products and convolutions in `dtype`, weights kept in float32), restored on exit; the
// cache of cast weights is dropped when the outermost guard ends, so an optimiser step is never
// followed by stale copies. Does nothing when `enabled` is false. The autocast calls differ between
// libtorch 1.13 and 2.x; this is the one place that spells them.
class AutocastGuard {
 public:
  AutocastGuard(c10::DeviceType device, c10::ScalarType dtype, bool enabled);
  ~AutocastGuard();
  AutocastGuard(const AutocastGuard&) = delete;
  AutocastGuard& operator=(const AutocastGuard&) = delete;

 private:
  bool enabled_ = false;
  c10::DeviceType device_;
  bool previous_enabled_ = false;
  c10::ScalarType previous_dtype_ = c10::ScalarType::Float;
};

}  // namespace ffloc
