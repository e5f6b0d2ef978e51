// The heap of a long bake (util/heap_tuning.h).

#include "util/heap_tuning.h"

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <mutex>
#include <set>
#include <string>
#include <thread>
#include <utility>

#if defined(__GLIBC__)
#include <fcntl.h>
#include <malloc.h>
#include <sys/mman.h>
#include <unistd.h>
#endif

namespace shadowcull {

namespace {

// Set by tuneHeapForLongBakes: the executable wants its heaps advised.
std::atomic<bool> adviseHeaps{false};

#if defined(__GLIBC__)
// glibc's per-thread arena heaps: HEAP_MAX_SIZE, 2 x the largest mmap threshold (32 MiB)
// on 64-bit, each mapped at a multiple of its size.
constexpr uintptr_t kArenaHeap = uintptr_t(64) << 20;

// The ranges advised so far (a range seen again is not advised again), and the lock of a
// scan, of the process `pid`. Never destroyed: the watcher thread may scan while the
// process exits. A forked child makes its own (its parent's watcher may have held the
// lock at the fork, and is not in the child to release it).
struct AdviceState {
    pid_t pid = 0;
    std::mutex mutex;
    std::set<std::pair<uintptr_t, uintptr_t>> advised;
};
AdviceState& adviceState() {
    static std::atomic<AdviceState*> state{nullptr};
    AdviceState* s = state.load(std::memory_order_acquire);
    const pid_t pid = ::getpid();
    if (!s || s->pid != pid) {
        auto* fresh = new AdviceState;
        fresh->pid = pid;
        if (state.compare_exchange_strong(s, fresh, std::memory_order_acq_rel)) s = fresh;
        else delete fresh;  // another thread of this process made it first: `s` is now its state
    }
    return *s;
}

// Advises [lo, hi) unless it was; true when it was new.
bool advise(uintptr_t lo, uintptr_t hi) {
    if (!adviceState().advised.emplace(lo, hi).second) return false;
    madvise(reinterpret_cast<void*>(lo), hi - lo, MADV_HUGEPAGE);
    return true;
}

// Advises the main heap ([heap]: the program break's mapping, whole) and every run of
// anonymous mappings that starts at a multiple of 64 MiB and spans a whole number of
// 64 MiB: the arenas' heaps, their reserved (PROT_NONE) tails included, so that growing
// into them gets huge pages too. A few hundred lines, ~0.1 ms. Returns
// whether any range was new.
bool adviseHeapMappings() {
    const std::lock_guard<std::mutex> lock(adviceState().mutex);
    // Read whole with read(2), not stdio: exit flushes and locks every FILE.
    std::string text;
    const int fd = ::open("/proc/self/maps", O_RDONLY | O_CLOEXEC);
    if (fd < 0) return false;
    char chunk[16384];
    for (ssize_t got; (got = ::read(fd, chunk, sizeof chunk)) != 0;) {
        if (got < 0) {
            if (errno == EINTR) continue;
            break;
        }
        text.append(chunk, size_t(got));
    }
    ::close(fd);
    bool any = false;
    uintptr_t runStart = 0, runEnd = 0;
    auto flush = [&] {
        if (runEnd > runStart && runStart % kArenaHeap == 0 && (runEnd - runStart) % kArenaHeap == 0)
            any |= advise(runStart, runEnd);
        runStart = runEnd = 0;
    };
    for (size_t at = 0; at < text.size();) {
        const size_t eol = std::min(text.find('\n', at), text.size());
        const std::string line = text.substr(at, eol - at);
        at = eol + 1;
        unsigned long lo = 0, hi = 0, offset = 0, inode = 0;
        char perms[8] = {}, dev[16] = {};
        int pathAt = 0;
        if (std::sscanf(line.c_str(), "%lx-%lx %7s %lx %15s %lu %n", &lo, &hi, perms, &offset, dev, &inode, &pathAt) < 6) continue;
        const char* path = line.c_str() + pathAt;
        const bool anonymous = inode == 0 && *path == '\0';
        if (inode == 0 && std::strncmp(path, "[heap]", 6) == 0) any |= advise(lo, hi);
        if (!anonymous) {
            flush();
            continue;
        }
        if (runEnd == lo && runEnd > runStart) {
            runEnd = hi;  // the heap's next part (its reserved tail, or the next heap)
        } else {
            flush();
            runStart = lo;
            runEnd = hi;
        }
    }
    flush();
    return any;
}
#endif

}  // namespace

void tuneHeapForLongBakes() {
#if defined(__GLIBC__)
    // A heap appears, or grows, whenever a thread's allocations need it: a watcher advises
    // new ones within a few milliseconds (every 4 ms while they keep coming, backing off to
    // every 64 ms while none do; a scan costs ~0.1 ms). Until then their pages stay small.
    // One per process: a forked child (bake_bench's jobs) has none of its parent's threads,
    // so calling this again there starts its own.
    static std::atomic<pid_t> watcherOf{0};
    if (watcherOf.exchange(::getpid()) != ::getpid()) {
        std::thread([] {
            auto period = std::chrono::milliseconds(4);
            for (;;) {
                std::this_thread::sleep_for(period);
                period = adviseHeapMappings() ? std::chrono::milliseconds(4)
                                              : std::min(2 * period, std::chrono::milliseconds(64));
            }
        }).detach();
    }
    constexpr int kKeep = 256 << 20;
    mallopt(M_TRIM_THRESHOLD, kKeep);
    mallopt(M_TOP_PAD, kKeep);
    mallopt(M_MMAP_THRESHOLD, 32 << 20);
    adviseHeaps = true;
    // Grow the heap now (by the top pad), so that the advice covers its first 256 MiB. The
    // pointer is volatile: a block freed unused is otherwise left out by the compiler.
    void* volatile grow = std::malloc(1 << 20);
    std::free(grow);
    adviseHugePagesOnHeap();
#endif
}

void adviseHugePagesOnHeap() {
#if defined(__GLIBC__)
    if (adviseHeaps) adviseHeapMappings();
#endif
}

}  // namespace shadowcull
