// The heap of a long bake. A bake reads, builds and frees a chunk's worth of memory (its
// XML, its objects, its window) thousands of times; glibc's defaults give the top of the
// heap back to the kernel after each free above 128 KiB and fault it in again page by page
// on the next chunk: the scan of a 10,000-chunk world spent 3.5x its CPU time so (37 s of
// user and 17 s of system time against 14 s and 1 s). Keeping up to 64 MiB is cheap beside
// a window's memory. Executables call it first thing (a library does not change the
// process's allocator behind its back).
#pragma once

#if defined(__GLIBC__)
#include <malloc.h>
#endif

namespace shadowcull {

inline void tuneHeapForLongBakes() {
#if defined(__GLIBC__)
    mallopt(M_TRIM_THRESHOLD, 64 << 20);
    mallopt(M_TOP_PAD, 16 << 20);
#endif
}

}  // namespace shadowcull
