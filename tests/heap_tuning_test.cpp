// The heap settings every executable applies first (core/heap_tuning.h).

#include <cstdint>
#include <cstdlib>
#include <fstream>
#include <sstream>
#include <string>
#include <thread>

#if defined(__GLIBC__)
#include <malloc.h>
#endif

#include <gtest/gtest.h>

#include "core/heap_tuning.h"

namespace shadowcull {
namespace {

// A window's large buffers (the GPU stage's pieces, a dense mesh's trees: a few MiB each)
// must come from the kept heap, not from a fresh mapping faulted in page by page: with only
// the trim threshold set, glibc pinned the mmap threshold at 128 KiB and a dense-mesh bake
// spent a fifth of its time in page faults.
TEST(HeapTuning, LargeBuffersComeFromTheHeapNotFreshMappings) {
#if defined(__GLIBC__)
    tuneHeapForLongBakes();
    for (std::size_t mib : {1, 4, 16}) {
        // mallinfo2().hblkhd: the bytes glibc holds in blocks it mapped one by one.
        const std::size_t mappedBefore = mallinfo2().hblkhd;
        void* block = std::malloc(mib << 20);
        ASSERT_NE(block, nullptr);
        EXPECT_EQ(mallinfo2().hblkhd, mappedBefore) << mib << " MiB was mapped on its own";
        std::free(block);
    }
#else
    GTEST_SKIP() << "glibc only";
#endif
}

// The VmFlags of the mapping holding `p` (/proc/self/smaps), or "" when none does.
std::string vmFlagsAt(const void* p) {
    std::ifstream smaps("/proc/self/smaps");
    const uintptr_t at = reinterpret_cast<uintptr_t>(p);
    std::string line;
    bool inside = false;
    while (std::getline(smaps, line)) {
        uintptr_t lo = 0, hi = 0;
        char dash = 0;
        std::istringstream head(line);
        if (head >> std::hex >> lo >> dash >> hi && dash == '-' && line.find(' ') != std::string::npos &&
            line.find(':') > line.find(' ')) {
            inside = lo <= at && at < hi;
            continue;
        }
        if (inside && line.rfind("VmFlags:", 0) == 0) return line;
    }
    return "";
}

// Both kinds of glibc heap are advised for transparent huge pages ("hg" in VmFlags): the
// main heap, and the heap of the arena a second thread allocates from (a page fault costs
// microseconds in a VM: world D's bake spent a quarter of its CPU time in them).
TEST(HeapTuning, TheHeapsAreAdvisedForHugePages) {
#if defined(__GLIBC__)
    tuneHeapForLongBakes();
    void* main = std::malloc(1 << 20);
    void* other = nullptr;
    std::thread t([&] { other = std::malloc(1 << 20); });
    t.join();
    ASSERT_NE(main, nullptr);
    ASSERT_NE(other, nullptr);
    adviseHugePagesOnHeap();
    const std::string mainFlags = vmFlagsAt(main), otherFlags = vmFlagsAt(other);
    EXPECT_NE(mainFlags.find(" hg"), std::string::npos) << mainFlags;
    EXPECT_NE(otherFlags.find(" hg"), std::string::npos) << otherFlags;
    std::free(main);
    std::free(other);
#else
    GTEST_SKIP() << "glibc only";
#endif
}

}  // namespace
}  // namespace shadowcull
