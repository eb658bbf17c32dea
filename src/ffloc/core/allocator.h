#pragma once

#include <cstddef>

namespace ffloc {

// glibc's malloc settings for ffloc's processes. glibc hands a freed block of 128 KB or more
// straight back to the kernel (it was mmap'd, or it tops the heap beyond the trim threshold),
// and raises those bounds only as far as the largest block freed so far. Work that allocates
// and frees image-sized buffers for every frame (decoded images, depth maps, SIFT's scale
// pyramid, tensors) then pays the kernel for zeroed pages again for each frame: mapping
// redkitchen spent 1.7 s of its 7 s in the kernel for it (docs/pipeline.md, "Mapping time").
struct AllocatorOptions {
  // Blocks below this come from the heap and are reused; glibc accepts at most 32 MiB here.
  size_t mmap_threshold_bytes = size_t{32} << 20;
  // Free memory at the heap's top is returned to the kernel only beyond this.
  size_t trim_threshold_bytes = size_t{128} << 20;
  // Arenas for threads that allocate at once; 0 keeps glibc's default (8 per core). A server's
  // many connection threads otherwise each come to hold an arena of their own.
  int max_arenas = 0;
};

// Applies `options` to glibc's malloc. A setting whose MALLOC_*_ environment variable is set
// (MALLOC_MMAP_THRESHOLD_, MALLOC_TRIM_THRESHOLD_, MALLOC_ARENA_MAX) is left to it. Under
// another C library does nothing.
void configureAllocator(const AllocatorOptions& options = {});

// Hands the heap's free memory back to the kernel now, whatever the trim threshold: for a
// measurement that should start from what is live (a benchmark's peak-memory window). Under
// another C library does nothing.
void returnFreeMemory();

}  // namespace ffloc
