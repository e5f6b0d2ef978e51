// A bake's progress on stderr (docs/cli.md): on a terminal a one-line bar; in a log (not a
// terminal) a line as soon as the bake starts, then one every 10 s and one at the end. The
// lines come from a ticker thread as well as from the bake's callbacks, because one step
// of a large world (the scan of its chunk files, one dense chunk) can run for minutes
// without calling back. The ETA counts only chunks that were baked, not those --resume
// skipped. Quiet once a signal asked the bake to stop (its own message says so).
#pragma once

#include <chrono>
#include <condition_variable>
#include <cstdio>
#include <mutex>
#include <string>
#include <thread>

#include "cli/pipeline.h"

namespace shadowcull::cli {

class ProgressReporter {
public:
    using Clock = std::chrono::steady_clock;
    // `tty`: a bar redrawn in place, at most every 100 ms and at least every `interval`
    // (a second); otherwise a line per `interval` (10 s) and one at the end.
    ProgressReporter(std::FILE* out, bool tty, Clock::duration interval);
    // On stderr: a bar on a terminal, else a log; nothing when not `enabled` (--quiet).
    static ProgressReporter forStderr(bool enabled);
    ~ProgressReporter() { finish(); }
    ProgressReporter(const ProgressReporter&) = delete;
    ProgressReporter& operator=(const ProgressReporter&) = delete;

    // The scan's callback (BakeOptions::onScanned) and the bake's (runBake's Progress).
    void scanned(size_t files, size_t total);
    void baked(const BakeProgress& p);
    // Stops the ticker and ends the bar's line; what is printed next starts a line of its own.
    void finish();

private:
    ProgressReporter() = default;  // disabled
    enum class Phase { Starting, Scanning, Baking };
    void tick();
    // Prints the state now (the mutex held); `end`: the bake's last line.
    void print(bool end);
    std::string text(double elapsed, bool end) const;

    std::FILE* out_ = nullptr;
    bool tty_ = false;
    Clock::duration interval_{};
    Clock::time_point start_ = Clock::now(), last_ = start_;
    bool printed_ = false, lineOpen_ = false;
    Phase phase_ = Phase::Starting;
    size_t files_ = 0, totalFiles_ = 0;
    BakeProgress chunks_;
    std::mutex mutex_;
    std::condition_variable wake_;
    bool stop_ = false;
    std::thread ticker_;
};

// 42 s, 7 min 05 s, 2 h 03 min.
std::string formatDuration(double seconds);

}  // namespace shadowcull::cli
