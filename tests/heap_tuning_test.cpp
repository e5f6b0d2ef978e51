// The heap settings every executable applies first (core/heap_tuning.h).

#include <cstdlib>

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

}  // namespace
}  // namespace shadowcull
