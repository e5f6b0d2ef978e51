// shadowcull: bakes, per object, primitive group and light, whether the shadow can matter.
// Thin: options, the pipeline (cli/pipeline.cpp), reports (cli/report.cpp).

#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <fstream>
#include <iostream>

#include <CLI/CLI.hpp>

#include "cli/pipeline.h"
#include "cli/report.h"

using namespace shadowcull;
using namespace shadowcull::cli;

namespace {

// A one-line progress bar on a terminal (stderr), redrawn at most every 100 ms.
class ProgressBar {
public:
    explicit ProgressBar(bool enabled) : enabled_(enabled && isatty(STDERR_FILENO)) {}
    void operator()(size_t done, size_t total) {
        if (!enabled_) return;
        auto now = std::chrono::steady_clock::now();
        if (done < total && now - last_ < std::chrono::milliseconds(100)) return;
        last_ = now;
        const double elapsed = std::chrono::duration<double>(now - start_).count();
        const int width = 30;
        const int filled = total ? int(width * done / total) : width;
        const double eta = done ? elapsed * double(total - done) / double(done) : 0.0;
        std::fprintf(stderr, "\r[%.*s%*s] %zu/%zu chunks  %.0fs elapsed, ETA %.0fs ", filled,
                     "##############################", width - filled, "", done, total, elapsed, eta);
        if (done == total) std::fprintf(stderr, "\n");
        std::fflush(stderr);
    }

private:
    bool enabled_;
    std::chrono::steady_clock::time_point start_ = std::chrono::steady_clock::now(), last_{};
};

int runBakeCommand(const BakeOptions& opt, const std::string& resultsPath, bool quiet) {
    ProgressBar bar(!quiet);
    Expected<BakeResult> r = runBake(opt, [&](size_t d, size_t t) { bar(d, t); });
    if (!r) {
        std::fprintf(stderr, "shadowcull: error: %s\n", r.error().what().c_str());
        std::fprintf(stderr, "shadowcull: bake stopped; no chunk file was changed%s\n",
                     r.error().kind == ErrorKind::Io ? " but those the message names as updated" : "");
        return exitCodeFor(r.error().kind);
    }
    for (const Diagnostic& d : r->diagnostics) std::fprintf(stderr, "shadowcull: warning: %s\n", d.what().c_str());
    if (!resultsPath.empty()) {
        std::ofstream out(resultsPath, std::ios::binary);
        out << resultsJson(*r).dump(1) << "\n";
        if (!out) {
            std::fprintf(stderr, "shadowcull: error: %s: cannot write the results\n", resultsPath.c_str());
            return kExitIo;
        }
    }
    if (!quiet) std::fputs(formatSummary(*r, opt.write).c_str(), stdout);
    return r->diagnostics.empty() ? kExitOk : kExitSkippedInput;
}

}  // namespace

int main(int argc, char** argv) {
    CLI::App app{"shadowcull: bakes which shadow casters matter, per object, primitive group and light"};
    app.require_subcommand(1);

    BakeOptions opt;
    std::string resultsPath;
    bool quiet = false;
    CLI::App* bake = app.add_subcommand("bake", "Bake the <shadow> masks of a space's chunk files");
    bake->add_option("space", opt.spaceDir, "Space directory (holds space.xml and *.chunk)")->required()->check(CLI::ExistingDirectory);
    bake->add_option("--out", opt.outDir, "Write baked copies of the chunk files here instead of in place");
    bake->add_option("--res", opt.resourceRoot, "Resource root (default: <resourceRoot> of space.xml, else the space)");
    bake->add_option("--chunk", opt.chunkNames, "Bake only these chunks (XXXXZZZZo or XXXXZZZZo.chunk); repeatable");
    bake->add_option("--threads", opt.threads, "Worker threads (default: all cores)")->check(CLI::NonNegativeNumber);
    bake->add_option("--results", resultsPath, "Write per-bit verdicts and evidence as JSON");
    bake->add_option("--samples", opt.raycast.areaSamples, "Area samples per group and light for witness rays")
        ->check(CLI::Range(1, 1 << 20));
    std::vector<std::string> stageNames{"raycast", "geometry"};
    bake->add_option("--stages", stageNames, "Stages after the input/reach checks (default: raycast geometry)")
        ->delimiter(',')
        ->check(CLI::IsMember({"raycast", "geometry"}));
    bake->add_flag("--dry-run", [&](int64_t) { opt.write = false; }, "Compute and report, but write no chunk file");
    bake->add_flag("--quiet,-q", quiet, "No progress bar and no summary");
    bake->add_flag("--resume", opt.resume,
                   "Long bakes: commit each chunk when baked; skip chunks unchanged since the last --resume bake");

    try {
        app.parse(argc, argv);
    } catch (const CLI::CallForHelp& e) {
        return app.exit(e);
    } catch (const CLI::ParseError& e) {
        app.exit(e);
        return kExitUsage;
    }
    opt.raycast.threads = opt.threads;
    opt.useRaycast = std::find(stageNames.begin(), stageNames.end(), "raycast") != stageNames.end();
    opt.useGeometry = std::find(stageNames.begin(), stageNames.end(), "geometry") != stageNames.end();
    if (*bake) return runBakeCommand(opt, resultsPath, quiet);
    return kExitUsage;
}
