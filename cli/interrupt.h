// Ctrl-C (SIGINT) and SIGTERM during a bake: the handler only records the signal (and
// says on stderr, with write(2), that the bake is stopping); the bake itself notices it
// between stages and chunks, on its own thread, removes its temporary files there and
// returns an Interrupted error (exit code 128 + signal, 130 for Ctrl-C). Nothing that is
// not async-signal-safe runs in the handler.
#pragma once

namespace shadowcull::cli {

// Installs the handlers for SIGINT and SIGTERM, unless the signal was ignored when the
// process started (then it stays ignored). Each handler is reset to the default by its
// first delivery (SA_RESETHAND), so a second Ctrl-C ends the process at once.
void installInterruptHandlers();

// The signal received since the handlers were installed, or 0.
int pendingInterrupt();

// The conventional exit code for a process stopped by `signal`: 128 + signal.
inline int exitCodeForSignal(int signal) { return 128 + signal; }

// Forgets a recorded signal (tests that interrupt a bake in-process).
void clearInterrupt();

// Records `signal` as if it had been delivered (tests).
void simulateInterrupt(int signal);

}  // namespace shadowcull::cli
