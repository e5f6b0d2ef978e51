// The heap of a long bake. A bake reads, builds and frees a chunk's worth of memory (its
// XML, its objects, its window) thousands of times; glibc's defaults give the top of the
// heap back to the kernel after each free above 128 KiB and fault it in again page by page
// on the next chunk: the scan of a 10,000-chunk world spent 3.5x its CPU time so (37 s of
// user and 17 s of system time against 14 s and 1 s). Keeping up to 64 MiB is cheap beside
// a window's memory, and so is growing the heap 64 MiB at a time (address space; pages are
// touched only when used). Setting any of these turns off glibc's sliding mmap threshold, so it
// is set too: left at 128 KiB, every large per-window buffer (the GPU stage's pieces, the
// geometry stage's tables, a dense mesh's trees) was a fresh mmap faulted in page by page,
// 19 % of a dense-mesh bake's time (world D: 4.3 s -> 3.7 s; docs/performance.md). 32 MiB is
// the largest glibc accepts on 64-bit; buffers above it are rare and large enough to pay
// for their own mapping. Executables call it first thing (a library does not change the
// process's allocator behind its back).
#pragma once

#if defined(__GLIBC__)
#include <malloc.h>
#endif

namespace shadowcull {

inline void tuneHeapForLongBakes() {
#if defined(__GLIBC__)
    mallopt(M_TRIM_THRESHOLD, 64 << 20);
    mallopt(M_TOP_PAD, 64 << 20);
    mallopt(M_MMAP_THRESHOLD, 32 << 20);
#endif
}

}  // namespace shadowcull
