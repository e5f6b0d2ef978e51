// The heap settings every executable applies first (util/heap_tuning.h).

#include <chrono>
#include <cstdint>
#include <cstdlib>
#include <fstream>
#include <sstream>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#if defined(__GLIBC__)
#include <malloc.h>
#include <sys/wait.h>
#include <unistd.h>
#endif

#include <gtest/gtest.h>

#include "util/heap_tuning.h"
#include "util/thread_arena.h"

#include <tbb/parallel_for.h>

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
    if (!std::ifstream("/sys/kernel/mm/transparent_hugepage/enabled")) GTEST_SKIP() << "a kernel without transparent huge pages";
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

// A forked child (bake_bench runs each bake in one) watches its own heaps once it calls
// tuneHeapForLongBakes again: a fork copies no thread, so the parent's watcher is not there
// to advise a heap the child's threads make (and may have held its lock at the fork). The
// child's second thread allocates until it holds a block in a mapping the child did not
// have at the start (a heap of its own), then waits for the watcher alone to advise it.
TEST(HeapTuning, AForkedChildWatchesItsOwnHeaps) {
#if defined(__GLIBC__)
    if (!std::ifstream("/sys/kernel/mm/transparent_hugepage/enabled")) GTEST_SKIP() << "a kernel without transparent huge pages";
    tuneHeapForLongBakes();
    std::fflush(stdout);
    std::fflush(stderr);
    const pid_t pid = fork();
    ASSERT_GE(pid, 0);
    if (pid == 0) {
        alarm(20);  // a child stuck on its parent's lock fails instead of hanging the suite
        tuneHeapForLongBakes();
        std::ifstream maps("/proc/self/maps");
        std::vector<std::pair<uintptr_t, uintptr_t>> before;
        for (std::string line; std::getline(maps, line);) {
            uintptr_t lo = 0, hi = 0;
            char dash = 0;
            std::istringstream(line) >> std::hex >> lo >> dash >> hi;
            before.emplace_back(lo, hi);
        }
        auto isNew = [&](const void* p) {
            const uintptr_t at = reinterpret_cast<uintptr_t>(p);
            for (const auto& [lo, hi] : before)
                if (lo <= at && at < hi) return false;
            return true;
        };
        void* fresh = nullptr;
        std::thread t([&] {
            for (int k = 0; k < 512 && !fresh; ++k) {  // up to 512 MiB of address space, untouched
                void* p = std::malloc(1 << 20);
                if (p && isNew(p)) fresh = p;
            }
        });
        t.join();
        if (!fresh) _exit(3);
        std::this_thread::sleep_for(std::chrono::milliseconds(300));  // the watcher's period is at most 64 ms
        _exit(vmFlagsAt(fresh).find(" hg") != std::string::npos ? 0 : 4);
    }
    int status = 0;
    ASSERT_EQ(waitpid(pid, &status, 0), pid);
    ASSERT_TRUE(WIFEXITED(status)) << "the child did not exit (status " << status << ")";
    EXPECT_NE(WEXITSTATUS(status), 3) << "the child's thread got no block in a new mapping";
    EXPECT_EQ(WEXITSTATUS(status), 0) << "the child's new heap was not advised";
#else
    GTEST_SKIP() << "glibc only";
#endif
}

// The watcher thread scans while the process exits: exiting at any moment after the tuning
// is a clean exit (its state was a static, destroyed under a scan: the CLI died of SIGSEGV
// in one exit out of a few). Each child is this test binary, started afresh (forking this
// multi-threaded process would copy locks other threads hold), exiting a little later
// than the one before, across the watcher's first scans.
TEST(HeapTuning, ExitingWhileTheWatcherScansIsClean) {
#if defined(__GLIBC__)
    if (const char* delay = std::getenv("SHADOWCULL_HEAP_EXIT_CHILD")) {
        // A teardown that takes a while after the statics are gone (the CLI's libraries
        // unload for milliseconds): registered first, so it runs after their destructors.
        std::atexit([] { std::this_thread::sleep_for(std::chrono::milliseconds(20)); });
        tuneHeapForLongBakes();
        std::this_thread::sleep_for(std::chrono::microseconds(std::atoi(delay)));
        std::exit(0);  // the watcher keeps scanning while the process exits
    }
    for (int k = 0; k < 24; ++k) {
        const std::string cmd = "SHADOWCULL_HEAP_EXIT_CHILD=" + std::to_string(250 * k) +
                                " /proc/" + std::to_string(getpid()) +
                                "/exe --gtest_filter=HeapTuning.ExitingWhileTheWatcherScansIsClean > /dev/null 2>&1";
        const int status = std::system(cmd.c_str());
        ASSERT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << "child " << k << ": status " << status;
    }
#else
    GTEST_SKIP() << "glibc only";
#endif
}

}  // namespace
// ThreadArena: objects made by several threads at once are value-initialised, aligned,
// and never share a byte (each thread's chunk is its own; a request larger than a chunk
// gets a chunk of its own size). Fails when the bump pointer skips the padding or two
// threads share a chunk.
TEST(ThreadArena, ObjectsFromManyThreadsAreDistinctAlignedAndInitialised) {
    struct alignas(16) Item {
        uint64_t id = 0;
        uint32_t filler[3] = {7, 7, 7};
    };
    ThreadArena arena(4096);  // small chunks: many chunk changes
    constexpr size_t kCount = 20000;
    std::vector<Item*> items(kCount, nullptr);
    std::vector<std::byte*> odd(kCount, nullptr);
    tbb::parallel_for(size_t(0), kCount, [&](size_t i) {
        odd[i] = static_cast<std::byte*>(arena.allocate(1 + i % 5, 1));  // unaligned sizes between the items
        Item* it = i % 97 == 0 ? arena.make<Item>(600) : arena.make<Item>();  // some larger than a chunk
        EXPECT_EQ(reinterpret_cast<uintptr_t>(it) % alignof(Item), 0u);
        EXPECT_EQ(it->id, 0u);
        EXPECT_EQ(it->filler[2], 7u);
        it->id = i + 1;
        for (size_t b = 0; b < 1 + i % 5; ++b) odd[i][b] = std::byte(0xAB);
        items[i] = it;
    });
    for (size_t i = 0; i < kCount; ++i) {
        ASSERT_EQ(items[i]->id, i + 1) << "item " << i << " was overwritten";
        ASSERT_EQ(items[i]->filler[0], 7u);
        for (size_t b = 0; b < 1 + i % 5; ++b) ASSERT_EQ(odd[i][b], std::byte(0xAB));
    }
}

}  // namespace shadowcull
