#pragma once

namespace ffloc {

// Number of worker threads to use when the user asked for `requested` (0 = all hardware threads).
int resolveThreadCount(int requested);

// Sets the thread pools of OpenBLAS (behind libblas: matrix products) and OpenCV (SIFT, image
// resampling) to resolveThreadCount(requested) and returns it. Left alone each starts one
// thread per core, and their pools and libtorch's then fight over the same cores.
int setLibraryThreadCount(int requested);

}  // namespace ffloc
