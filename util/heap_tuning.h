// The heap of a long bake. A bake reads, builds and frees a chunk's worth of memory (its
// XML, its objects, its window) thousands of times; glibc's defaults give the top of the
// heap back to the kernel after each free above 128 KiB and fault it in again page by page
// on the next chunk: the scan of a 10,000-chunk world spent 3.5x its CPU time so (37 s of
// user and 17 s of system time against 14 s and 1 s). So the heap keeps up to 256 MiB at
// its top and grows 256 MiB at a time (address space; pages are touched only when used).
// Setting any of these turns off glibc's sliding mmap threshold, so it is set too: left at
// 128 KiB, every large per-window buffer (the GPU stage's pieces, the geometry stage's
// tables, a dense mesh's trees) was a fresh mmap faulted in page by page, about a fifth of
// a dense-mesh bake's time. 32 MiB is the
// largest glibc accepts on 64-bit; buffers above it are rare and large enough to pay for
// their own mapping.
//
// Transparent huge pages. In a virtual machine a page fault can cost microseconds (10.7 us
// per 4 KiB page on the benchmark VM): world D's bake faulted in 130 MiB of meshes, trees
// and buffers, 34,000 faults, a quarter of its CPU time. glibc's heaps are advised
// MADV_HUGEPAGE (2 MiB pages where the kernel has them to give, 512 times fewer faults; a
// hint, ignored where THP is off): the main heap, and the heaps of the per-thread arenas
// (mappings of 64 MiB aligned to 64 MiB, found in /proc/self/maps). One shared arena
// instead (M_ARENA_MAX 1) made the geometry stage's CGAL allocations contend: +25 % on
// world D2k. Heaps appear and grow as threads need them, so a watcher thread advises new
// ones within milliseconds; pages touched before that stay small.
//
// Executables call tuneHeapForLongBakes first thing (a library does not change the
// process's allocator behind its back); until they do, adviseHugePagesOnHeap does nothing.
#pragma once

namespace shadowcull {

// Sets the heap up for a long bake (above), advises its heaps for huge pages and starts
// the watcher that advises those to come. Once per process matters; later calls repeat it
// (a forked child calls it again: the watcher is a thread, and a fork copies none).
void tuneHeapForLongBakes();

// Advises glibc's heaps as they are now for transparent huge pages (a part already advised
// is left as it is). Does nothing until tuneHeapForLongBakes was called.
void adviseHugePagesOnHeap();

}  // namespace shadowcull
