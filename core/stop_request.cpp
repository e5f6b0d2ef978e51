#include "core/stop_request.h"

#include <csignal>

namespace shadowcull {

namespace {

// A lock-free atomic, not a volatile sig_atomic_t: the handler writes it on one thread and
// the workers (TBB, the import) read it on others.
std::atomic<int> requested{0};
static_assert(std::atomic<int>::is_always_lock_free, "the signal handler stores into it");

}  // namespace

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
