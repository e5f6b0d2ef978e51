#include "cli/interrupt.h"

#include <signal.h>
#include <unistd.h>

#include <atomic>
#include <initializer_list>

#include "util/stop_request.h"

namespace shadowcull::cli {

namespace {

std::atomic<InterruptMode> mode{InterruptMode::StopBetweenSteps};
static_assert(std::atomic<InterruptMode>::is_always_lock_free, "the signal handler reads it");

// write(2) is async-signal-safe; a partial write is harmless here.
void say(const char* text, size_t length) {
    const ssize_t n = ::write(STDERR_FILENO, text, length);
    (void)n;
}

void exitAtOnce(int signal) {
    static const char sigint[] = "\nshadowcull: error: interrupted by Ctrl-C (SIGINT)\n";
    static const char sigterm[] = "\nshadowcull: error: interrupted by SIGTERM\n";
    if (signal == SIGTERM) say(sigterm, sizeof sigterm - 1);
    else say(sigint, sizeof sigint - 1);
    removeHeldTemporary();  // a one-file atomic write in hand (writeFileAtomic)
    ::_exit(exitCodeForSignal(signal));
}

void onSignal(int signal) {
    if (mode.load(std::memory_order_relaxed) == InterruptMode::ExitAtOnce) exitAtOnce(signal);
    const bool first = stopSignal() == 0;
    requestStop(signal);
    if (!first) return;
    static const char message[] =
        "\nshadowcull: interrupted: stopping after the step in hand and removing the temporary files "
        "(interrupt again to stop at once)\n";
    say(message, sizeof message - 1);
}

}  // namespace

void installInterruptHandlers(InterruptMode m) {
    mode.store(m);
    struct sigaction sa {};
    sa.sa_handler = onSignal;
    sigemptyset(&sa.sa_mask);
    // SA_RESTART: reads and writes in progress go on instead of failing with EINTR.
    sa.sa_flags = SA_RESTART | SA_RESETHAND;
    for (int signal : {SIGINT, SIGTERM}) {
        // A signal ignored when the process started (nohup, a script's background job)
        // stays ignored, as the shell that started it asked.
        struct sigaction old {};
        if (::sigaction(signal, nullptr, &old) == 0 && old.sa_handler == SIG_IGN) continue;
        ::sigaction(signal, &sa, nullptr);
    }
}

void setInterruptMode(InterruptMode m) { mode.store(m); }

int pendingInterrupt() { return stopSignal(); }

void clearInterrupt() { requestStop(0); }

void simulateInterrupt(int signal) { requestStop(signal); }

}  // namespace shadowcull::cli
