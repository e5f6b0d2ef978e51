// Ctrl-C (SIGINT) and SIGTERM. The handlers are installed first thing in main, for every
// command, so that a signal is never met by the default action while the process starts.
// How a signal is then taken depends on what the process is doing (InterruptMode): before
// a command is under way, or in a command with nothing to clean up, it ends the process at
// once with 128 + signal; in a command that stages its outputs, the handler only records
// the signal (util/stop_request.h) and says on stderr that it is stopping, and the command
// notices it between steps, on its own thread, removes its temporaries there and returns
// an Interrupted error (exit code 128 + signal, 130 for Ctrl-C). Nothing that is not
// async-signal-safe runs in the handler.
#pragma once

namespace shadowcull::cli {

enum class InterruptMode {
    // Nothing is written yet, or the command only reads (or writes one file atomically at
    // its very end): the handler says so and ends the process at once, 128 + signal.
    ExitAtOnce,
    // The command stages what it writes and checks the request between its steps.
    StopBetweenSteps,
};

// Installs the handlers for SIGINT and SIGTERM, unless the signal was ignored when the
// process started (then it stays ignored). Each handler is reset to the default by its
// first delivery (SA_RESETHAND), so a second Ctrl-C ends the process at once.
void installInterruptHandlers(InterruptMode mode = InterruptMode::StopBetweenSteps);

// Changes how the installed handlers take a signal (main, once the command is known).
void setInterruptMode(InterruptMode mode);

// The signal received since the handlers were installed, or 0.
int pendingInterrupt();

// The conventional exit code for a process stopped by `signal`: 128 + signal.
inline int exitCodeForSignal(int signal) { return 128 + signal; }

// Forgets a recorded signal (tests that interrupt a bake in-process).
void clearInterrupt();

// Records `signal` as if it had been delivered (tests).
void simulateInterrupt(int signal);

}  // namespace shadowcull::cli
