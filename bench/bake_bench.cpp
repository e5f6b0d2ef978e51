// bake_bench: bakes the benchmark worlds (bench/world_gen.h) and reports, per world and per
// stage, time, rays, rays/s, exact (CGAL) tests, GPU passes, bits proved 0 / proved 1 /
// left undecided and peak memory, then the issue-6 ratios (L vs M per chunk, pipeline rays/s
// vs a bare Embree occlusion loop over the same scene, analytic vs GPU). See bench/README.md.
//
//   bake_bench [--sizes S,M,L,XL,D,D2k,R] [--work DIR] [--threads N] [--max-chunks N]
//              [--baseline-rays N] [--no-baseline] [--no-fork] [--no-raycast] [--no-geometry]
//              [--cross-check] [--no-gpu] [--gpu-baseline S,M,L|none] [--gpu-res N]
//              [--gen-only] [--json FILE] [--gl auto,egl,osmesa] [--rounds N] [--window-only] [--write]
//
// Each world is generated once into the work directory, keyed by a hash of its spec and
// the generator version, and reused by later runs. Generation, each bake and each Embree
// baseline run in their own child process (fork), so that each peak RSS (wait4 ru_maxrss)
// belongs to one job only; the parent never starts TBB or Embree.

#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cerrno>
#include <cinttypes>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iterator>
#include <map>
#include <optional>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <nlohmann/json.hpp>

#include "bench/bake_bench_report.h"
#include "bench/machine.h"
#include "bench/world_gen.h"
#include "cli/pipeline.h"
#include "cli/report.h"
#include "gpu/gl_context.h"
#include "tests/support/space_builder.h"
#include "util/heap_tuning.h"

namespace shadowcull::bench {
// bench/embree_baseline.cpp (no header of its own: only this program calls it).
nlohmann::json runEmbreeBaseline(const std::string& spaceDir, int centreX, int centreZ, uint64_t rays, int threads,
                                 const std::vector<double>& lightWeights);
}  // namespace shadowcull::bench

using namespace shadowcull;
using namespace shadowcull::bench;
using nlohmann::json;
namespace fs = std::filesystem;

namespace {

constexpr uint64_t kDefaultBaselineCap = 4000000;  // rays per baseline loop unless --baseline-rays

struct Options {
    std::vector<std::string> sizes{"S", "M"};
    fs::path work = fs::temp_directory_path() / "shadowcull-bench";
    int threads = 0;
    int maxChunks = 0;           // 0: every chunk; else bake at most N chunks (spread) and project
    // With maxChunks: N consecutive chunks in grid order from the middle of the world instead
    // of N spread ones. A run of two columns or more holds in memory what a bake of every
    // chunk holds (the columns the sliding window still needs), spread chunks do not.
    bool contiguous = false;
    uint64_t baselineRays = 0;   // 0: as many as the pipeline cast, capped at kDefaultBaselineCap
    bool baseline = true;
    bool fork = true;
    bool genOnly = false;
    bool raycast = true, geometry = true;  // stages to run (--no-raycast / --no-geometry: profiling)
    bool crossCheck = false;               // geometry also examines witnessed bits; fails on a contradiction
    bool gpu = true;                       // the pipeline's GPU confirmation stage (BakeOptions::useGpu)
    std::vector<std::string> gpuBaselineSizes{"M"};  // worlds the original GPU method is run on
    int gpuBaselineResolution = 2048;
    std::string jsonOut;         // all figures as JSON
    // --gl: only the GPU stages, once per OpenGL backend, side by side (printBackends).
    std::vector<std::string> glBackends;
    std::string glBackend;       // the backend a child bakes on ("": the default, auto)
    // --rounds N: the analytic bakes N times, the worlds' order reversed every other round;
    // each world reports its median round. (On a VM whose host backs guest memory lazily, a
    // bake that runs right after another reuses the pages that one freed, and the first
    // bake of a run pays for fresh ones: in one round, order alone moved D / D2k by 0.1-0.2.)
    int rounds = 1;
    // --window-only: each world baked again with the `neighbours` rectangle as its windows
    // (BakeOptions::neighbourWindows), side by side: what whole-space receivers cost.
    bool windowOnly = false;
    // --write: the analytic bakes write their chunk files, as a user's bake does, into
    // WORK/out-NAME (emptied before, removed after): the write is timed beside the stages.
    bool write = false;
};

[[noreturn]] void usage(const char* why) {
    std::fprintf(stderr,
                 "bake_bench: %s\n"
                 "usage: bake_bench [--sizes S,M,L,XL,D,D2k,R] [--work DIR] [--threads N] [--max-chunks N [--contiguous]]\n"
                 "                  [--baseline-rays N] [--no-baseline] [--no-fork] [--no-raycast] [--no-geometry]\n"
                 "                  [--cross-check] [--no-gpu] [--gpu-baseline S,M,L|none] [--gpu-res N]\n"
                 "                  [--gen-only] [--json FILE] [--gl auto,egl,osmesa] [--rounds N] [--window-only]\n"
                 "                  [--write]\n",
                 why);
    std::exit(2);
}

Options parseArgs(int argc, char** argv) {
    Options o;
    for (int i = 1; i < argc; ++i) {
        const std::string a = argv[i];
        auto value = [&]() -> std::string {
            if (i + 1 >= argc) usage(("missing value after " + a).c_str());
            return argv[++i];
        };
        auto number = [&](const std::string& v) -> long long {
            char* end = nullptr;
            const long long n = std::strtoll(v.c_str(), &end, 10);
            if (v.empty() || *end || n < 0) usage(("not a count: " + v).c_str());
            return n;
        };
        if (a == "--sizes") {
            o.sizes.clear();
            std::stringstream ss(value());
            for (std::string s; std::getline(ss, s, ',');) {
                WorldSpec spec;
                if (!worldByName(s, spec)) usage(("unknown size " + s + " (S, M, L, XL, D, D2k or R)").c_str());
                o.sizes.push_back(spec.name);
            }
        } else if (a == "--work") {
            o.work = value();
        } else if (a == "--threads") {
            o.threads = int(number(value()));
        } else if (a == "--max-chunks") {
            o.maxChunks = int(number(value()));
        } else if (a == "--contiguous") {
            o.contiguous = true;
        } else if (a == "--baseline-rays") {
            o.baselineRays = uint64_t(number(value()));
        } else if (a == "--no-baseline") {
            o.baseline = false;
        } else if (a == "--no-fork") {
            o.fork = false;
        } else if (a == "--no-raycast") {
            o.raycast = false;
        } else if (a == "--no-geometry") {
            o.geometry = false;
        } else if (a == "--cross-check") {
            o.crossCheck = true;
        } else if (a == "--no-gpu") {
            o.gpu = false;
        } else if (a == "--gpu-baseline") {
            o.gpuBaselineSizes.clear();
            std::stringstream ss(value());
            for (std::string sz; std::getline(ss, sz, ',');) {
                if (sz == "none") continue;
                WorldSpec spec;
                if (!worldByName(sz, spec)) usage(("unknown size " + sz + " (S, M, L, D, D2k, R or none)").c_str());
                o.gpuBaselineSizes.push_back(spec.name);
            }
        } else if (a == "--gpu-res") {
            o.gpuBaselineResolution = int(number(value()));
            if (o.gpuBaselineResolution < 1) usage("--gpu-res must be positive");
        } else if (a == "--gen-only" || a == "--generate-only") {
            o.genOnly = true;
        } else if (a == "--gl") {
            std::stringstream ss(value());
            for (std::string b; std::getline(ss, b, ',');) {
                if (!gpu::parseGlBackend(b)) usage(("unknown OpenGL backend " + b + " (auto, egl, osmesa)").c_str());
                o.glBackends.push_back(b);
            }
        } else if (a == "--window-only") {
            o.windowOnly = true;
        } else if (a == "--write") {
            o.write = true;
        } else if (a == "--json") {
            o.jsonOut = value();
        } else if (a == "--rounds") {
            o.rounds = int(number(value()));
            if (o.rounds < 1) usage("--rounds must be at least 1");
        } else if (a == "-h" || a == "--help") {
            usage("help");
        } else {
            usage(("unknown option " + a).c_str());
        }
    }
    return o;
}

double since(std::chrono::steady_clock::time_point t) {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - t).count();
}

// ---------------------------------------------------------------------------------------
// Child processes

struct Job {
    bool ok = false;
    long maxRssKiB = 0;   // peak resident set of the job (its own process with fork)
    double wallSeconds = 0;
    double cpuSeconds = 0;  // user + system time of the job's process (all its threads)
    std::string failure;    // how the job failed ("exit code 1", "killed by signal 6 (Aborted)")
};

// One bake of one world in one round (--rounds).
struct BakeRound {
    int round = 0, position = 0;  // from 1; position in the round's order
    Job job;
    bool ok = false;
    nlohmann::json bake;
    std::string loadBefore, loadAfter;
};

double cpuOf(const rusage& ru) {
    return double(ru.ru_utime.tv_sec + ru.ru_stime.tv_sec) + 1e-6 * double(ru.ru_utime.tv_usec + ru.ru_stime.tv_usec);
}

// Runs `body` (returns an exit code) in a child process, or in this one with --no-fork
// (then the peak RSS is the whole program's so far).
Job runJob(bool useFork, const std::function<int()>& body) {
    Job job;
    const auto t0 = std::chrono::steady_clock::now();
    if (!useFork) {
        rusage before{};
        getrusage(RUSAGE_SELF, &before);
        job.ok = body() == 0;
        if (!job.ok) job.failure = "failed";
        rusage ru{};
        getrusage(RUSAGE_SELF, &ru);
        job.maxRssKiB = ru.ru_maxrss;
        job.cpuSeconds = cpuOf(ru) - cpuOf(before);
        job.wallSeconds = since(t0);
        return job;
    }
    std::fflush(stdout);
    std::fflush(stderr);
    const pid_t pid = fork();
    if (pid < 0) {
        std::perror("bake_bench: fork");
        return job;
    }
    if (pid == 0) {
        // The heap watcher is a thread, and a fork copies none: the job starts its own, as
        // the shadowcull executable has one (without it, every heap a job's worker threads
        // made was faulted in 4 KiB at a time, and world D's bake measured 0.1 s slower).
        tuneHeapForLongBakes();
        int code = 1;
        try {
            code = body();
        } catch (const std::exception& e) {
            std::fprintf(stderr, "bake_bench: %s\n", e.what());
        }
        std::fflush(stdout);
        std::fflush(stderr);
        _exit(code);  // skip tearing down the job's data: its time is not the job's
    }
    int status = 0;
    rusage ru{};
    while (wait4(pid, &status, 0, &ru) < 0 && errno == EINTR) {
    }
    job.ok = WIFEXITED(status) && WEXITSTATUS(status) == 0;
    if (WIFEXITED(status) && !job.ok) job.failure = "exit code " + std::to_string(WEXITSTATUS(status));
    if (WIFSIGNALED(status)) {
        job.failure = "killed by signal " + std::to_string(WTERMSIG(status)) + " (" + strsignal(WTERMSIG(status)) + ")";
        std::fprintf(stderr, "bake_bench: job %s\n", job.failure.c_str());
    }
    job.maxRssKiB = ru.ru_maxrss;
    job.cpuSeconds = cpuOf(ru);
    job.wallSeconds = since(t0);
    return job;
}

// "1.23 0.80 0.51" (1, 5, 15 minutes): other load on the machine skews every time here.
std::string loadAverage() {
    double l[3] = {0, 0, 0};
    if (getloadavg(l, 3) != 3) return "?";
    char buf[64];
    std::snprintf(buf, sizeof buf, "%.2f %.2f %.2f", l[0], l[1], l[2]);
    return buf;
}

bool writeJson(const fs::path& p, const json& j) {
    std::ofstream out(p);
    out << j.dump(1) << "\n";
    return bool(out);
}

bool readJson(const fs::path& p, json& j) {
    std::ifstream in(p);
    if (!in) return false;
    try {
        in >> j;
    } catch (const std::exception&) {
        return false;
    }
    return true;
}

// ---------------------------------------------------------------------------------------
// Generation (cached)

json statsJson(const WorldStats& s) {
    return {{"chunks", s.chunks},
            {"models", s.models},
            {"byKind", s.byKind},
            {"uniqueMeshes", s.uniqueMeshes},
            {"uniqueMeshTriangles", s.uniqueMeshTriangles},
            {"placedTriangles", s.placedTriangles},
            {"terrainTriangles", s.terrainTriangles},
            {"lights", s.lights},
            {"directionalLights", s.directionalLights},
            {"pointLights", s.pointLights},
            {"spotLights", s.spotLights},
            {"bytesOnDisk", s.bytesOnDisk},
            {"files", s.files},
            {"buildSeconds", s.buildSeconds},
            {"writeSeconds", s.writeSeconds}};
}

// The world's directory, generated unless a complete copy is there; its stats in `stats`.
bool ensureWorld(const WorldSpec& spec, const Options& o, fs::path& dir, json& stats) {
    dir = o.work / ("world-" + spec.name + "-" + specHashHex(spec));
    const fs::path marker = dir / "bench-world.json";
    if (readJson(marker, stats)) {
        stats["cached"] = true;
        return true;
    }
    const fs::path tmp = dir.string() + ".tmp";
    std::error_code ec;
    fs::remove_all(tmp, ec);
    fs::remove_all(dir, ec);
    fs::create_directories(o.work, ec);
    std::fprintf(stderr, "[%s] generating %dx%d chunks into %s ...\n", spec.name.c_str(), spec.chunksX, spec.chunksZ,
                 dir.string().c_str());
    const Job job = runJob(o.fork, [&] {
        const WorldStats s = writeWorld(spec, tmp.string());
        json j = statsJson(s);
        j["spec"] = {{"name", spec.name},      {"chunksX", spec.chunksX},       {"chunksZ", spec.chunksZ},
                     {"seed", spec.seed},      {"objectsPerChunk", spec.objectsPerChunk},
                     {"chunkSize", spec.chunkSize}, {"terrainSamples", spec.terrainSamples},
                     {"localLights", spec.localLights}, {"neighbours", spec.neighbours}, {"hash", specHashHex(spec)}};
        return writeJson(tmp / "bench-world.json", j) ? 0 : 1;
    });
    if (!job.ok) return false;
    fs::rename(tmp, dir, ec);
    if (ec || !readJson(marker, stats)) return false;
    stats["generationPeakRssKiB"] = job.maxRssKiB;
    stats["generationWallSeconds"] = job.wallSeconds;
    writeJson(marker, stats);
    stats["cached"] = false;
    return true;
}

// ---------------------------------------------------------------------------------------
// The bake (in a child)

// Chunks of the grid, row-major as the generator makes them.
std::vector<std::pair<int, int>> gridChunks(const WorldSpec& spec) {
    std::vector<std::pair<int, int>> out;
    const int gx0 = -(spec.chunksX / 2), gz0 = -(spec.chunksZ / 2);
    for (int i = 0; i < spec.chunksX; ++i)
        for (int j = 0; j < spec.chunksZ; ++j) out.emplace_back(gx0 + i, gz0 + j);
    return out;
}

// One byte per bit, chunks in order, objects in document order, groups x lights: 'k' kept
// with a witness, 'c' culled (proved 0), 'u' undecided (written 1). Two bakes of the same
// chunks compare bit by bit.
void appendVerdictCodes(const ChunkVerdicts& cv, std::string& codes) {
    for (const ObjectVerdicts& ov : cv.objects)
        for (const Decision& d : ov.decisions) codes += d.verdict == Verdict::Kept ? 'k' : d.verdict == Verdict::Culled ? 'c' : 'u';
}

// Bakes the world (write = false) with the pipeline's options, or with the original GPU
// method (`gpuBaseline`), and writes the figures to `out` and the verdict codes beside it.
// `neighbourWindows`: the analytic bake with the `neighbours` rectangle as its windows
// (--window-only).
int bakeChild(const WorldSpec& spec, const fs::path& dir, const Options& o, const fs::path& out, bool gpuBaseline,
              bool neighbourWindows = false) {
    cli::BakeOptions opt;
    opt.spaceDir = dir.string();
    opt.write = false;
    opt.threads = o.threads;
    opt.raycast.threads = o.threads;
    opt.useRaycast = o.raycast;
    opt.useGeometry = o.geometry;
    opt.geometry.crossCheckWitnesses = o.crossCheck;
    opt.useGpu = o.gpu;
    opt.neighbourWindows = neighbourWindows;
    if (gpuBaseline) {
        opt.gpuBaseline = true;
        opt.gpuResolution = o.gpuBaselineResolution;
    }
    // --write: the chunk files written beside the world, never over it.
    const fs::path outDir = o.work / ("out-" + spec.name);
    if (o.write && !gpuBaseline && !neighbourWindows) {
        std::error_code ec;
        fs::remove_all(outDir, ec);
        opt.write = true;
        opt.outDir = outDir.string();
    }
    // The device, if any, from SHADOWCULL_GL_DEVICE (as for the CLI's --gl-device).
    if (!o.glBackend.empty()) gpu::setGlChoice({*gpu::parseGlBackend(o.glBackend), gpu::glChoice().device});
    const std::vector<std::pair<int, int>> all = gridChunks(spec);
    if (o.maxChunks > 0 && size_t(o.maxChunks) < all.size()) {
        // Evenly spread over the grid (every k-th chunk in row-major order), of the world
        // read whole as a bake of all of it reads it (the scan of every chunk file).
        const size_t first = (all.size() - size_t(o.maxChunks)) / 2;
        for (int n = 0; n < o.maxChunks; ++n) {
            const auto& c = o.contiguous ? all[first + size_t(n)] : all[size_t(uint64_t(n) * all.size() / uint64_t(o.maxChunks))];
            opt.bakeOnly.push_back(*parseChunkArgument(testing::chunkName(c.first, c.second)));
        }
    }
    // As the CLI bakes: verdicts counted chunk by chunk, not kept (memory follows the window).
    opt.keepVerdicts = false;
    std::string codes;
    std::vector<std::map<std::string, uint64_t>> perLight;
    opt.onChunkBaked = [&](const BakeWindow&, const ChunkVerdicts& cv) -> Status {
        appendVerdictCodes(cv, codes);
        const size_t nl = size_t(cv.lightCount);
        perLight.resize(nl);
        for (const ObjectVerdicts& ov : cv.objects)
            for (size_t k = 0; k < ov.decisions.size(); ++k) {
                const Decision& d = ov.decisions[k];
                auto& m = perLight[k % nl];
                const char* v = d.verdict == Verdict::Undecided ? "undecided" : d.verdict == Verdict::Kept ? "kept" : "culled";
                if (d.verdict == Verdict::Culled) ++m["culled:" + std::string(d.stage)];
                else ++m[v];
                // Issue 19: the terrain's bits, and the shadow-pass triangles left undecided.
                if (ov.terrain) ++m[std::string("terrain:") + v];
                const size_t g = k / nl;
                const uint64_t tris = g < ov.groupTriangles.size() ? ov.groupTriangles[g] : 0;
                m["triangles"] += tris;
                if (d.verdict == Verdict::Undecided) m["undecidedTriangles"] += tris;
            }
        return Status::ok();
    };
    long rssFirstChunk = 0, rssMidChunk = 0, rssLastChunk = 0;
    auto last = std::chrono::steady_clock::now();
    const auto t0 = last;
    const long rssStart = procStatusKiB("VmRSS:");
    auto progress = [&](const cli::BakeProgress& p) {
        const size_t done = p.done, total = p.total;
        if (done == 1) rssFirstChunk = procStatusKiB("VmRSS:");
        if (done == (total + 1) / 2) rssMidChunk = procStatusKiB("VmRSS:");
        if (done == total) rssLastChunk = procStatusKiB("VmRSS:");
        if (since(last) < 15.0 && done != total) return;
        last = std::chrono::steady_clock::now();
        const double el = since(t0);
        std::fprintf(stderr, "[%s%s] %zu/%zu chunks, %.0f s, ETA %.0f s, RSS %.0f MiB\n", spec.name.c_str(),
                     gpuBaseline ? " gpu method" : "", done, total, el,
                     p.etaSeconds(el), procStatusKiB("VmRSS:") / 1024.0);
    };
    rusage ru0{};
    getrusage(RUSAGE_SELF, &ru0);
    Expected<cli::BakeResult> r = cli::runBake(opt, progress);
    rusage ru1{};
    getrusage(RUSAGE_SELF, &ru1);
    if (!r) {
        std::fprintf(stderr, "bake_bench: bake of %s failed: %s\n", spec.name.c_str(), r.error().what().c_str());
        return 1;
    }
    const double wall = since(t0);
    json j;
    j["chunksBaked"] = r->totals.chunks;
    j["peakLoadedChunks"] = r->peakLoadedChunks;
    // How far the windows reached past the rectangle for the shadows (issue 33).
    j["reach"] = {{"windows", r->reach.windows}, {"chunks", r->reach.chunks}, {"chunksBeyond", r->reach.chunksBeyond}};
    j["chunksTotal"] = all.size();
    j["loadSeconds"] = r->loadSeconds;
    j["loadCpuSeconds"] = r->loadCpuSeconds;
    j["totalSeconds"] = r->totalSeconds;
    if (opt.write) {
        j["writeSeconds"] = r->writeSeconds;  // staging every chunk file and committing them
        std::error_code ec;
        fs::remove_all(outDir, ec);
    }
    j["wallSeconds"] = wall;
    j["cpuSeconds"] = cpuOf(ru1) - cpuOf(ru0);  // every thread of the bake: robust to other load
    j["threads"] = o.threads > 0 ? o.threads : int(std::thread::hardware_concurrency());
    j["rssStartKiB"] = rssStart;
    j["rssAfterFirstChunkKiB"] = rssFirstChunk;
    j["rssAfterMidChunkKiB"] = rssMidChunk;
    j["rssAfterLastChunkKiB"] = rssLastChunk;
    j["vmHwmKiB"] = procStatusKiB("VmHWM:");
    json stages = json::array();
    for (const cli::StageTiming& st : r->stages) {
        const StageStats& s = st.stats;
        stages.push_back({{"name", st.name},
                          {"seconds", s.seconds},
                          {"bitsExamined", s.bitsExamined},
                          {"raysCast", s.raysCast},
                          {"exactTests", s.exactTests},
                          {"gpuPasses", s.gpuPasses},
                          {"gpuSeconds", s.gpuSeconds},
                          {"gpuTimed", s.gpuTimed},
                          {"provedKept", s.provedKept},
                          {"provedCulled", s.provedCulled}});
    }
    j["stages"] = stages;
    const cli::BitCounts c = cli::countBits(*r);
    j["bits"] = {{"groups", c.groups},         {"bits", c.bits},           {"kept", c.kept},
                 {"culled", c.culled},         {"provedKept", c.provedKept}, {"undecided", c.undecided},
                 {"culledBy", c.culledBy}};
    // Per light: witnesses, proofs by stage, undecided.
    json lights = json::array();
    const size_t nl = r->settings.lights.size();
    perLight.resize(nl);
    for (size_t l = 0; l < nl; ++l)
        lights.push_back({{"name", r->settings.lights[l].name},
                          {"type", lightTypeName(r->settings.lights[l].type)},
                          {"counts", perLight[l]}});
    j["lights"] = lights;
    j["notes"] = r->notes;
    j["gl"] = r->gl;
    j["gpuResolution"] = opt.gpuResolution;
    j["warnings"] = r->diagnostics.size();
    json first = json::array();
    for (size_t k = 0; k < std::min<size_t>(5, r->diagnostics.size()); ++k) first.push_back(r->diagnostics[k].what());
    j["firstWarnings"] = first;
    std::ofstream codesFile(out.string() + ".bits", std::ios::binary);
    codesFile << codes;
    return writeJson(out, j) && codesFile ? 0 : 1;
}

// --gl: the GPU stages of each world on each OpenGL backend, one child process per bake
// (a backend per process: see docs/design.md, "OpenGL backends"): the pipeline with its
// GPU confirmation, and the original GPU method where --gpu-baseline names the world.
// Wall and GPU (GL_TIME_ELAPSED) seconds side by side; verdicts compared with the first
// backend's, bit by bit.
int runBackends(const std::vector<WorldRun>& runs, const Options& o) {
    std::printf("\n## GPU stages per OpenGL backend\n\n");
    std::printf("One child process per bake; GPU time: GL_TIMESTAMP queries around each chunk's GPU work, summed. Verdicts: "
                "bits that differ from the first backend's bake of the same kind.\n\n");
    std::printf("| world | chunks | backend | OpenGL (backend: vendor, renderer, version) | bake | gpu stage wall s | GPU time s | "
                "GPU passes | bake total s | verdicts vs first |\n|---|---:|---|---|---|---:|---:|---:|---:|---|\n");
    bool allSame = true;
    for (const WorldRun& w : runs) {
        for (const bool method : {false, true}) {
            if (method && std::find(o.gpuBaselineSizes.begin(), o.gpuBaselineSizes.end(), w.spec.name) == o.gpuBaselineSizes.end())
                continue;
            std::string firstBits;
            for (const std::string& backend : o.glBackends) {
                Options child = o;
                child.glBackend = backend;
                const fs::path out = o.work / ("gl-" + w.spec.name + (method ? "-gpu-method-" : "-bake-") + backend + ".json");
                std::error_code ec;
                fs::remove(out, ec);
                std::fprintf(stderr, "[%s] %s on --gl %s ...\n", w.spec.name.c_str(), method ? "GPU method" : "bake", backend.c_str());
                const Job job = runJob(o.fork, [&] { return bakeChild(w.spec, w.dir, child, out, method); });
                json b;
                const char* kind = method ? "GPU method" : "pipeline";
                if (!job.ok || !readJson(out, b)) {
                    std::printf("| %s | | %s | failed (%s) | %s | | | | | |\n", w.spec.name.c_str(), backend.c_str(),
                                job.failure.empty() ? "no results" : job.failure.c_str(), kind);
                    continue;
                }
                double wall = 0, gpuTime = 0;
                bool timed = false;
                uint64_t passes = 0;
                for (const json& st : b["stages"]) {
                    if (st.value("gpuPasses", uint64_t(0)) == 0 && !st.value("gpuTimed", false)) continue;
                    wall += st["seconds"].get<double>();
                    gpuTime += st.value("gpuSeconds", 0.0);
                    timed = timed || st.value("gpuTimed", false);
                    passes += st.value("gpuPasses", uint64_t(0));
                }
                std::ifstream in(out.string() + ".bits", std::ios::binary);
                const std::string bits((std::istreambuf_iterator<char>(in)), {});
                std::string verdicts = "(first)";
                if (firstBits.empty()) {
                    firstBits = bits;
                } else if (bits.size() != firstBits.size()) {
                    verdicts = "**table size differs**", allSame = false;
                } else {
                    uint64_t differ = 0;
                    for (size_t k = 0; k < bits.size(); ++k) differ += bits[k] != firstBits[k];
                    verdicts = differ ? "**" + count(differ) + " differ**" : "identical";
                    allSame = allSame && differ == 0;
                }
                const std::string gl = b.value("gl", std::string());
                std::printf("| %s | %s of %s | %s | %s | %s | %s | %s | %s | %s | %s |\n", w.spec.name.c_str(),
                            count(b["chunksBaked"].get<uint64_t>()).c_str(), count(b["chunksTotal"].get<uint64_t>()).c_str(), backend.c_str(),
                            gl.empty() ? "none (GPU stages skipped)" : gl.c_str(), kind, seconds(wall).c_str(),
                            timed ? seconds(gpuTime).c_str() : "n/a", count(passes).c_str(),
                            seconds(b["totalSeconds"].get<double>()).c_str(), verdicts.c_str());
            }
        }
    }
    return allSame ? 0 : 1;
}
}  // namespace

// Every world's analytic bakes, --rounds times, one world after the other (in alternating
// order from round to round), so that the figures compared across worlds are measured
// close together in time.
std::vector<std::vector<BakeRound>> bakeRounds(std::vector<WorldRun>& runs, const Options& o) {
    std::error_code ec;
    std::vector<std::vector<BakeRound>> rounds(runs.size());
    for (int r = 0; r < o.rounds; ++r) {
        for (size_t i = 0; i < runs.size(); ++i) {
            const size_t at = r % 2 == 0 ? i : runs.size() - 1 - i;
            WorldRun& w = runs[at];
            const fs::path out = o.work / ("bake-" + w.spec.name + ".json");
            fs::remove(out, ec);
            if (o.rounds > 1) std::fprintf(stderr, "[%s] baking (round %d of %d) ...\n", w.spec.name.c_str(), r + 1, o.rounds);
            else std::fprintf(stderr, "[%s] baking ...\n", w.spec.name.c_str());
            BakeRound round;
            round.round = r + 1;
            round.position = int(i) + 1;
            round.loadBefore = loadAverage();
            const Job job = runJob(o.fork, [&] { return bakeChild(w.spec, w.dir, o, out, false); });
            round.loadAfter = loadAverage();
            round.job = job;
            round.ok = job.ok && readJson(out, round.bake);
            if (!round.ok) std::fprintf(stderr, "bake_bench: bake of %s failed\n", w.spec.name.c_str());
            rounds[at].push_back(std::move(round));
        }
    }
    return rounds;
}

// A world's figures are those of its median round (by total seconds), its peak RSS the
// largest of any round; a failed round fails the world. Returns M and L when baked.
std::pair<WorldRun*, WorldRun*> takeMedianRounds(std::vector<WorldRun>& runs, std::vector<std::vector<BakeRound>>& rounds,
                                                 const Options& o) {
    WorldRun* bakedM = nullptr;
    WorldRun* bakedL = nullptr;
    for (size_t i = 0; i < runs.size(); ++i) {
        WorldRun& w = runs[i];
        w.contiguous = o.contiguous;
        std::vector<BakeRound>& rs = rounds[i];
        const bool allOk = std::all_of(rs.begin(), rs.end(), [](const BakeRound& x) { return x.ok; });
        if (!allOk) continue;  // not baked: a failed round fails the world
        std::vector<size_t> byTime(rs.size());
        for (size_t k = 0; k < rs.size(); ++k) byTime[k] = k;
        std::sort(byTime.begin(), byTime.end(), [&](size_t a, size_t b) {
            return rs[a].bake["totalSeconds"].get<double>() < rs[b].bake["totalSeconds"].get<double>();
        });
        const BakeRound& median = rs[byTime[(rs.size() - 1) / 2]];  // the lower median of an even count
        w.baked = true;
        w.bake = median.bake;
        w.loadBefore = median.loadBefore;
        w.loadAfter = median.loadAfter;
        w.bakeJobCpu = median.job.cpuSeconds;
        w.bakeJobWall = median.job.wallSeconds;
        for (const BakeRound& x : rs) {
            w.bakePeakKiB = std::max(w.bakePeakKiB, x.job.maxRssKiB);
            w.rounds.push_back({{"round", x.round}, {"position", x.position}, {"totalSeconds", x.bake["totalSeconds"]},
                                {"cpuSeconds", x.bake["cpuSeconds"]}, {"peakRssKiB", x.job.maxRssKiB}});
        }
        if (w.spec.name == "M") bakedM = &w;
        if (w.spec.name == "L") bakedL = &w;
    }
    return {bakedM, bakedL};
}

// The bake with neighbours-rectangle windows, compared with the whole bake `out`.
void runWindowOnly(WorldRun& w, const Options& o, const fs::path& out) {
    std::error_code ec;
    const fs::path wout = o.work / ("window-" + w.spec.name + ".json");
    fs::remove(wout, ec);
    std::fprintf(stderr, "[%s] baking with neighbours-rectangle windows ...\n", w.spec.name.c_str());
    const Job wj = runJob(o.fork, [&] { return bakeChild(w.spec, w.dir, o, wout, false, true); });
    w.windowRun = true;
    w.windowPeakKiB = wj.maxRssKiB;
    w.windowBaked = wj.ok && readJson(wout, w.windowBake);
    if (w.windowBaked) compareWindowOnly(w, out.string() + ".bits", wout.string() + ".bits");
}

// The original GPU method, compared bit by bit with the analytic bake `out`.
void runGpuBaseline(WorldRun& w, const Options& o, const fs::path& out) {
    std::error_code ec;
    const fs::path gout = o.work / ("gpu-" + w.spec.name + ".json");
    fs::remove(gout, ec);
    std::fprintf(stderr, "[%s] original GPU method at %d px ...\n", w.spec.name.c_str(), o.gpuBaselineResolution);
    const Job gj = runJob(o.fork, [&] { return bakeChild(w.spec, w.dir, o, gout, true); });
    w.gpuRun = true;
    w.gpuPeakKiB = gj.maxRssKiB;
    w.gpuBaked = gj.ok && readJson(gout, w.gpuBake);
    if (!w.gpuBaked) {
        w.gpuFailure = gj.failure.empty() ? "no results" : gj.failure;
        w.gpuBake = {{"gpuResolution", o.gpuBaselineResolution}};
    } else {
        compareWithGpu(w, out.string() + ".bits", gout.string() + ".bits");
    }
}

// The bare Embree loops on the window of chunk (0, 0), as many rays as the raycast stage cast.
void runBaseline(WorldRun& w, const Options& o) {
    std::error_code ec;
    const json* rc = w.stage("raycast");
    uint64_t n = o.baselineRays;
    if (n == 0) n = std::min<uint64_t>(rc ? (*rc)["raysCast"].get<uint64_t>() : 0, kDefaultBaselineCap);
    if (n == 0) n = kDefaultBaselineCap;
    const fs::path bout = o.work / ("baseline-" + w.spec.name + ".json");
    fs::remove(bout, ec);
    std::fprintf(stderr, "[%s] Embree baseline, %s rays per loop ...\n", w.spec.name.c_str(), count(n).c_str());
    // Per light, the bits the raycast stage examined (kept + left undecided + culled after it).
    std::vector<double> weights;
    for (const json& l : w.bake["lights"]) {
        double x = 0;
        for (auto it = l["counts"].begin(); it != l["counts"].end(); ++it)
            if (it.key() == "kept" || it.key() == "undecided" || it.key() == "culled:geometry" || it.key() == "culled:gpu")
                x += it.value().get<double>();
        weights.push_back(x);
    }
    const Job bj = runJob(o.fork, [&] {
        const json j = runEmbreeBaseline(w.dir.string(), 0, 0, n, o.threads, weights);
        if (j.contains("error")) std::fprintf(stderr, "bake_bench: baseline: %s\n", j["error"].get<std::string>().c_str());
        return writeJson(bout, j) && !j.contains("error") ? 0 : 1;
    });
    w.baselined = bj.ok && readJson(bout, w.baseline);
    w.baselinePeakKiB = bj.maxRssKiB;
}

// Every figure of every world as JSON (--json).
void writeAllJson(const std::vector<WorldRun>& runs, const fs::path& file) {
    json all = json::array();
    for (const WorldRun& w : runs)
        all.push_back({{"world", w.spec.name}, {"dir", w.dir.string()}, {"stats", w.stats}, {"bake", w.bake},
                       {"bakePeakRssKiB", w.bakePeakKiB}, {"bakeRounds", w.rounds}, {"bakeAgain", w.again}, {"baseline", w.baseline}, {"baselinePeakRssKiB", w.baselinePeakKiB},
                       {"gpuBaseline", {{"run", w.gpuRun}, {"ok", w.gpuBaked}, {"failure", w.gpuFailure}, {"bake", w.gpuBake},
                                        {"peakRssKiB", w.gpuPeakKiB}, {"culls", w.gpuCulls}, {"falseCulls", w.gpuFalseCulls},
                                        {"analyticCullsGpuKeeps", w.analyticCullsGpuKeeps}, {"comparedBits", w.comparedBits}}},
                       {"windowOnly", {{"run", w.windowRun}, {"ok", w.windowBaked}, {"bake", w.windowBake},
                                       {"peakRssKiB", w.windowPeakKiB}, {"differences", w.windowDiff}}}});
    writeJson(file, all);
}

int main(int argc, char** argv) {
    tuneHeapForLongBakes();  // as the shadowcull executable does
    const Options o = parseArgs(argc, argv);
    std::error_code ec;
    fs::create_directories(o.work, ec);
    if (ec) usage(("cannot create work directory " + o.work.string()).c_str());

    std::vector<WorldRun> runs;
    for (const std::string& name : o.sizes) {
        WorldRun w;
        worldByName(name, w.spec);
        if (!ensureWorld(w.spec, o, w.dir, w.stats)) {
            std::fprintf(stderr, "bake_bench: generating world %s failed\n", name.c_str());
            return 1;
        }
        runs.push_back(std::move(w));
    }
    std::printf("# bake_bench\n\nMachine: %s, %u hardware threads, %.1f GiB RAM; bake threads: %s; load average %s. "
                "Work dir: %s\n",
                cpuModel().c_str(), std::thread::hardware_concurrency(),
                double(sysconf(_SC_PHYS_PAGES)) * double(sysconf(_SC_PAGE_SIZE)) / (1024.0 * 1024 * 1024),
                o.threads > 0 ? std::to_string(o.threads).c_str() : "all", loadAverage().c_str(), o.work.string().c_str());
    if (o.genOnly) {
        printWorlds(runs);
        return 0;
    }
    if (!o.glBackends.empty()) return runBackends(runs, o);

    // 1. The analytic bakes, one after the other (and M again right after L), so that the
    // figures compared across worlds are measured close together in time; 2. the baselines.
    // With --rounds, every round's bake of a world is kept; the world's figures are then
    // those of its median round (by total seconds), its peak RSS the largest of any round.
    std::vector<std::vector<BakeRound>> rounds = bakeRounds(runs, o);
    const std::pair<WorldRun*, WorldRun*> ml = takeMedianRounds(runs, rounds, o);
    WorldRun* bakedM = ml.first;
    WorldRun* bakedL = ml.second;
    if (bakedM && bakedL) {
        const fs::path again = o.work / "bake-M-again.json";
        fs::remove(again, ec);
        std::fprintf(stderr, "[M] baking again, after L ...\n");
        const Job job = runJob(o.fork, [&] { return bakeChild(bakedM->spec, bakedM->dir, o, again, false); });
        if (!job.ok || !readJson(again, bakedM->again)) std::fprintf(stderr, "bake_bench: second bake of M failed\n");
        bakedM->loadAfter = loadAverage();
    }
    for (WorldRun& w : runs) {
        if (!w.baked) continue;
        const fs::path out = o.work / ("bake-" + w.spec.name + ".json");
        if (o.windowOnly) runWindowOnly(w, o, out);
        if (std::find(o.gpuBaselineSizes.begin(), o.gpuBaselineSizes.end(), w.spec.name) != o.gpuBaselineSizes.end())
            runGpuBaseline(w, o, out);
        if (o.baseline) runBaseline(w, o);
    }

    printWorlds(runs);
    for (const WorldRun& w : runs)
        if (w.baked) printBake(w);
    printGpuBaseline(runs);
    printWindowOnly(runs);

    printComparisons(runs);

    if (!o.jsonOut.empty()) writeAllJson(runs, o.jsonOut);
    for (const WorldRun& w : runs)
        if (!w.baked) return 1;
    return 0;
}
