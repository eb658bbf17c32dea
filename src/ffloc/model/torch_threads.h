#pragma once

namespace ffloc {

// Sets libtorch's intra-op thread count to resolveThreadCount(requested) (0 = all hardware
// threads) and returns it. libtorch has been seen to start with a single thread, so callers set
// this explicitly before running the network.
int setTorchThreadCount(int requested);

}  // namespace ffloc
