#include "cli/progress_reporter.h"

#include <unistd.h>

#include "util/stop_request.h"

namespace shadowcull::cli {

std::string formatDuration(double s) {
    char buf[32];
    const long t = long(s + 0.5);
    if (t < 60) std::snprintf(buf, sizeof buf, "%ld s", t);
    else if (t < 3600) std::snprintf(buf, sizeof buf, "%ld min %02ld s", t / 60, t % 60);
    else std::snprintf(buf, sizeof buf, "%ld h %02ld min", t / 3600, t / 60 % 60);
    return buf;
}

ProgressReporter::ProgressReporter(std::FILE* out, bool tty, Clock::duration interval)
    : out_(out), tty_(tty), interval_(interval) {
    ticker_ = std::thread([this] { tick(); });
}

ProgressReporter ProgressReporter::forStderr(bool enabled) {
    if (!enabled) return ProgressReporter();
    const bool tty = isatty(STDERR_FILENO);
    return ProgressReporter(stderr, tty, tty ? std::chrono::seconds(1) : std::chrono::seconds(10));
}

void ProgressReporter::scanned(size_t files, size_t total) {
    if (!out_) return;
    std::lock_guard<std::mutex> lock(mutex_);
    phase_ = Phase::Scanning;
    files_ = files, totalFiles_ = total;
    // The first line at once: the bake has begun.
    const auto minGap = tty_ ? Clock::duration(std::chrono::milliseconds(100)) : interval_;
    if (!printed_ || Clock::now() - last_ >= minGap) print(false);
}

void ProgressReporter::baked(const BakeProgress& p) {
    if (!out_) return;
    std::lock_guard<std::mutex> lock(mutex_);
    phase_ = Phase::Baking;
    chunks_ = p;
    const bool end = p.done == p.total;
    const auto minGap = tty_ ? Clock::duration(std::chrono::milliseconds(100)) : interval_;
    if (end || !printed_ || Clock::now() - last_ >= minGap) print(end);
}

void ProgressReporter::finish() {
    {
        std::lock_guard<std::mutex> lock(mutex_);
        if (stop_) return;
        stop_ = true;
    }
    wake_.notify_all();
    if (ticker_.joinable()) ticker_.join();
    if (out_ && lineOpen_) {
        std::fputc('\n', out_);
        std::fflush(out_);
        lineOpen_ = false;
    }
}

void ProgressReporter::tick() {
    std::unique_lock<std::mutex> lock(mutex_);
    while (!stop_) {
        // Woken a little after the interval since the last line (a callback may have printed).
        wake_.wait_until(lock, last_ + interval_);
        if (stop_) break;
        if (phase_ != Phase::Starting && Clock::now() - last_ >= interval_) print(false);
    }
}

void ProgressReporter::print(bool end) {
    // After a signal the handler's message stands last until the bake's own error.
    if (stopRequested()) return;
    const auto now = Clock::now();
    last_ = now;
    printed_ = true;
    const std::string line = text(std::chrono::duration<double>(now - start_).count(), end);
    if (tty_) {
        std::fprintf(out_, "\r%s   %s", line.c_str(), end ? "\n" : "");
        lineOpen_ = !end;
    } else {
        std::fprintf(out_, "shadowcull: %s\n", line.c_str());
    }
    std::fflush(out_);
}

std::string ProgressReporter::text(double elapsed, bool end) const {
    const std::string time = formatDuration(elapsed) + " elapsed";
    auto bar = [&](size_t done, size_t total) {
        const int width = 30;
        const int filled = total ? int(width * done / total) : width;
        return "[" + std::string(size_t(filled), '#') + std::string(size_t(width - filled), ' ') + "] ";
    };
    if (phase_ == Phase::Scanning) {
        // Scanned, and the first chunk (of a dense world: minutes) under way.
        const std::string counts = files_ == totalFiles_
                                       ? "scanned " + std::to_string(totalFiles_) + " chunk files; baking the first chunk"
                                       : "scanning the space: " + std::to_string(files_) + "/" + std::to_string(totalFiles_) +
                                             " chunk files";
        return tty_ ? bar(files_, totalFiles_) + counts + "  " + time : counts + ", " + time;
    }
    const BakeProgress& p = chunks_;
    const double eta = p.etaSeconds(elapsed);
    const std::string etaText = end ? "" : eta < 0 ? ", ETA unknown" : ", ETA " + formatDuration(eta);
    const std::string resumed = p.resumed ? " (" + std::to_string(p.resumed) + " unchanged)" : "";
    const std::string counts = std::to_string(p.done) + "/" + std::to_string(p.total) + " chunks" + resumed;
    return tty_ ? bar(p.done, p.total) + counts + "  " + time + etaText : counts + ", " + time + etaText;
}

}  // namespace shadowcull::cli
