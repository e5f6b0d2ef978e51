#include "util/stop_request.h"

#include <unistd.h>

#include <csignal>
#include <cstring>

namespace shadowcull {

namespace {

// A lock-free atomic, not a volatile sig_atomic_t: the handler writes it on one thread and
// the workers (TBB, the import) read it on others.
std::atomic<int> requested{0};
static_assert(std::atomic<int>::is_always_lock_free, "the signal handler stores into it");

// The held temporary's path, NUL-terminated; valid while `held` is true (set after the
// path is written, cleared before it may change).
char heldPath[4096];
std::atomic<bool> held{false};
std::atomic<bool> claimed{false};
static_assert(std::atomic<bool>::is_always_lock_free, "the signal handler reads it");

}  // namespace

bool holdTemporary(const char* path) {
    if (std::strlen(path) >= sizeof heldPath || claimed.exchange(true)) return false;
    std::strcpy(heldPath, path);
    held.store(true, std::memory_order_release);
    return true;
}

void releaseTemporary() {
    held.store(false, std::memory_order_release);
    claimed.store(false);
}

void removeHeldTemporary() {
    if (held.load(std::memory_order_acquire)) ::unlink(heldPath);
}

int stopSignal() { return requested.load(std::memory_order_relaxed); }

void requestStop(int signal) { requested.store(signal, std::memory_order_relaxed); }

Status stopStatus() {
    const int signal = stopSignal();
    if (!signal) return Status::ok();
    return makeError(ErrorKind::Interrupted, "", 0,
                     std::string("interrupted by ") +
                         (signal == SIGTERM ? "SIGTERM" : signal == SIGINT ? "Ctrl-C (SIGINT)" : "a signal"));
}

}  // namespace shadowcull
