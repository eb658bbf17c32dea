#pragma once

namespace ffloc {

// Number of worker threads to use when the user asked for `requested` (0 = all hardware threads).
int resolveThreadCount(int requested);

}  // namespace ffloc
