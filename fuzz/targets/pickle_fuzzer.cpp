// The pickle machine alone, on the input as a pickle stream.
#include "../support/fuzz_support.h"
#include "ffloc/io/pickle.h"

using namespace ffloc;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  fuzz::expectOnlyInputErrors([&] {
    const pickle::Unpickled result = pickle::unpickle(data, size, "fuzz.pkl");
    if (result.root == nullptr) std::abort();
    // What the checkpoint reader asks of the top-level object first.
    pickle::dictGet(result.root, "model");
    pickle::dictGet(result.root, "state_dict");
  });
  return 0;
}
