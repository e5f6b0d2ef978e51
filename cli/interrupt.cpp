#include "cli/interrupt.h"

#include <signal.h>
#include <unistd.h>

#include <csignal>
#include <initializer_list>

namespace shadowcull::cli {

namespace {

volatile std::sig_atomic_t received = 0;

void onSignal(int signal) {
    const bool first = received == 0;
    received = signal;
    if (!first) return;
    // write(2) is async-signal-safe; a partial write is harmless here.
    static const char message[] =
        "\nshadowcull: interrupted: stopping after the step in hand and removing the bake's temporary files "
        "(interrupt again to stop at once)\n";
    const ssize_t n = ::write(STDERR_FILENO, message, sizeof message - 1);
    (void)n;
}

}  // namespace

void installInterruptHandlers() {
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

int pendingInterrupt() { return int(received); }

void clearInterrupt() { received = 0; }

void simulateInterrupt(int signal) { received = signal; }

}  // namespace shadowcull::cli
