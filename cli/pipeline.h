// The bake pipeline behind `shadowcull bake`: load the space, run the stages per chunk
// window, write the masks atomically, and gather what the summary and results JSON show.
#pragma once

#include <future>

#include <functional>
#include <map>
#include <string>
#include <vector>

#include "cli/bake_totals.h"
#include "core/scene.h"
#include "core/stage.h"
#include "core/verdict.h"
#include "core/window_plan.h"
#include "geometry/geometry_stage.h"
#include "gpu/baseline.h"
#include "gpu/confirm_stage.h"
#include "io/results_file.h"
#include "io/space_source.h"
#include "raycast/raycast_stage.h"

namespace shadowcull::cli {

// Exit codes, one per kind of outcome (documented in docs/cli.md).
enum ExitCode : int {
    kExitOk = 0,
    kExitSkippedInput = 1,  // baked, but some input was skipped (see the warnings)
    kExitUsage = 2,
    kExitBadInput = 3,      // stopped before writing anything
    kExitIo = 4,            // writing failed; files are either original or complete
    kExitInternal = 5,      // a library failed; nothing written
    kExitBusy = 6,          // another bake holds the output directory's lock; nothing done
    kExitStalePlan = 9,     // --plan: the space changed since `shadowcull plan` (7 and 8 are merge's)
    kExitInterrupted = 130,  // Ctrl-C (128 + SIGINT; SIGTERM gives 143): temporary files removed
};

int exitCodeFor(ErrorKind kind);

struct BakeOptions {
    std::string spaceDir;
    std::string outDir;       // empty: in place
    std::string resourceRoot; // --res
    std::vector<std::string> chunkNames;  // empty: every chunk
    int threads = 0;          // 0: all cores
    raycast::RaycastOptions raycast;
    bool useRaycast = true;   // witness rays (proves 1s)
    bool useGeometry = true;  // exact shadow volumes (proves 0s)
    bool useGpu = true;       // conservative GPU confirmation (proves 0s; skipped without GL)
    geometry::GeometryOptions geometry;
    // The original tool's method instead of the analytic pipeline (a baseline to compare
    // with: NOT conservative, see gpu/baseline.h).
    bool gpuBaseline = false;
    // With gpuBaseline: also cast witness rays at the bits the baseline culled, to say how
    // many of them a shadow is seen for (bake's note; `check` lists them). Not written.
    bool witnessBaselineCulls = false;
    int gpuResolution = 1024;  // pixels per side of each light view
    // After the GPU confirmation and its witness search, the confirmation again for the
    // directional bits still undecided, each view framed on the casters it examines, at
    // this many pixels per side (GpuConfirmStage::runCloseUp: more 0s, more fragments; at
    // most gpuResolution). 0: no close-up. `bake --gpu-close-up N`.
    int gpuCloseUpResolution = 512;
    bool gpuTerrain = false;   // also send terrain groups to the GPU confirmation
    bool write = true;        // false: compute only (tests, reports)
    // Per-bit verdicts as JSON (bake --results), written with the chunk files: staged
    // before any of them is renamed, renamed after them.
    std::string resultsPath;
    // Replace chunk files that are read-only or whose owner cannot be kept (otherwise such
    // a chunk is not baked, with a warning).
    bool forceWrite = false;
    // Long bakes: commit each chunk as soon as it is baked, record what was written, and
    // skip chunks whose inputs and file are unchanged since (cli/resume.h).
    bool resume = false;
    // bake --shard K/N (cli/shard.h): bake only the K-th of N parts of the space (K from
    // 1), with its own lock, resume state and results. 0: the whole space.
    int shardIndex = 0, shardCount = 0;
    // bake --shard K/N --plan DIR (cli/plan.h): the shard's chunks and the summaries of its
    // windows come from the plan, and only the chunks its windows hold are read.
    std::string planDir;
    // Keep every baked chunk's verdicts in BakeResult::chunks (tests, sweep, check). The CLI's
    // bake keeps none: it counts them (BakeResult::totals) and streams the chunk files and
    // the results, so that its memory follows the window and not the world.
    bool keepVerdicts = true;
    // Benchmarks: bake only these chunks (in grid order) of a space read whole, as a bake
    // of every chunk reads it (--chunk reads only the named chunks and their neighbours).
    std::vector<ChunkCoord> bakeOnly;
    // Benchmarks only (bake_bench --window-only): the analytic bake's windows are the
    // `neighbours` rectangle, as before receivers became the whole space. NOT
    // conservative against the engine: a shadow landing beyond the rectangle is not seen,
    // and its caster may be written 0. It exists to measure what whole-space receivers cost.
    bool neighbourWindows = false;
    // Called with each baked chunk's window and verdicts while the window is still loaded,
    // before the bake lets them go (benchmarks count them, `check` compares and draws them,
    // without keeping them). An error stops the bake with it.
    std::function<Status(const BakeWindow&, const ChunkVerdicts&)> onChunkBaked;
    // Called as the scan reads the chunk files, before any chunk is baked (the CLI's
    // progress: a world's scan takes minutes).
    ScanProgress onScanned;
};

struct StageTiming {
    std::string name;
    StageStats stats;
};

struct BakeResult {
    SpaceSettings settings;
    std::vector<Diagnostic> diagnostics;
    std::vector<ChunkVerdicts> chunks;  // in grid order; only with BakeOptions::keepVerdicts
    BakeTotals totals;                  // every chunk baked (not those --resume skipped)
    std::vector<StageTiming> stages;    // in pipeline order
    double loadSeconds = 0, writeSeconds = 0, totalSeconds = 0;
    double loadCpuSeconds = 0;  // CPU time of the process (every thread) until the space was read
    int chunksWritten = 0;
    int chunksResumed = 0;  // skipped by --resume: unchanged since the last bake
    std::vector<std::string> notes;  // what the bake did differently from what was asked
    std::string gl;                  // the OpenGL context the GPU stages ran on, "" if none ran
    // Every file the bake read (space.xml, the chunk files, each resource named), sorted:
    // outputs written beside the bake check theirs against it (cli/output_guard.h).
    std::vector<std::string> inputFiles;
    // With --resume, --results and keepVerdicts: the chunks skipped as unchanged, as recorded
    // when they were baked (their part of the results file).
    std::vector<results::ChunkRecord> resumedRecords;
    // The most chunks held in memory at once (memory follows the window: a bake of a grid
    // W chunks deep whose windows reach R chunks along x holds at most (2R + 1) W of them,
    // whatever its size; R is 1 where every shadow stays within neighbours 1).
    size_t peakLoadedChunks = 0;
    // How far the windows reached past the `neighbours` rectangle for the shadows (the
    // analytic bake: core/window_plan.h), per light.
    ReachTotals reach;
    // With keepVerdicts and whole-space windows: each baked chunk's window (explain).
    std::map<ChunkCoord, WindowPlan> plans;
    std::optional<results::ShardRecord> shard;  // bake --shard: this shard's part
};

// The stages a bake runs, in order, made once per bake from its options (the GPU stages
// need an OpenGL context: without one the confirmation is skipped with a note, and the
// baseline method fails).
class StageRunner {
public:
    // `glProbe`, when given and valid: the result of probeGl(options) started earlier (on
    // another thread, beside the scan); otherwise the probe runs here.
    explicit StageRunner(const BakeOptions& options, std::future<Status>* glProbe = nullptr);
    // Whether the GPU stages these options ask for can get an OpenGL context (a context
    // made and released: loading the driver takes tens of milliseconds on one thread, so
    // runBake starts it beside the scan). OK when no GPU stage is asked for.
    static Status probeGl(const BakeOptions& options);
    const Status& status() const { return status_; }
    const std::vector<std::string>& notes() const { return notes_; }
    // One StageTiming per stage, in order (for `bake`'s accumulation).
    std::vector<StageTiming> timings() const;
    // Runs every stage on one window; adds each stage's stats to `timings`.
    Status bake(const BakeWindow& window, ChunkVerdicts& verdicts, std::vector<StageTiming>& timings);
    // Every stage forgets these meshes (about to be freed: Stage::forgetMeshes).
    void forgetMeshes(const std::unordered_set<const Mesh*>& meshes);
    // With witnessBaselineCulls: bits the baseline culled for which a witness ray was
    // found so far (false culls; the verdicts written are the baseline's all the same).
    uint64_t baselineCullsWitnessed() const { return baselineCullsWitnessed_; }
    // The backend, GL_VENDOR, GL_RENDERER and GL_VERSION the GPU stages ran on ("" if none ran).
    std::string glDescription() const;

private:
    ReachStage reach_;
    ReachStage inputOnly_{false};
    raycast::RaycastStage rays_;
    geometry::GeometryStage volumes_;
    gpu::GpuConfirmStage confirm_;
    gpu::GpuBaselineMethod baseline_;
    std::vector<Stage*> stages_;
    bool candidatePass_ = false;  // witness rays at the geometry stage's candidates
    const Stage* deferredAfter_ = nullptr;  // the stage after which the deferred searches go on
    bool densePass_ = false;
    // The GPU confirmation again for the directional bits still undecided, each view framed
    // on the casters (GpuConfirmStage::runCloseUp), then witness rays at its pixels.
    bool closeUpPass_ = false;
    bool witnessBaselineCulls_ = false;
    uint64_t baselineCullsWitnessed_ = 0;
    Status status_;
    std::vector<std::string> notes_;
};

// One chunk baked in memory (no file written), with its window for reports that look at
// it again (render, check). The window points into `space`.
struct ChunkBake {
    std::unique_ptr<Space> space;
    WindowPlan plan;  // the chunks the window holds, and what the shadows took past the rectangle
    TerrainMeshes terrainMeshes;
    BakeWindow window;
    ChunkVerdicts verdicts;
    std::vector<StageTiming> stages;
    std::vector<std::string> notes;
    std::string gl;  // the OpenGL context the GPU stages ran on, "" if none ran
};
Expected<ChunkBake> bakeChunk(const BakeOptions& options, ChunkCoord chunk);

// Where a bake is, after each chunk.
struct BakeProgress {
    size_t done = 0;     // chunks finished (baked, or skipped by --resume)
    size_t total = 0;
    size_t resumed = 0;  // of those done, skipped as unchanged (cost almost nothing)
    // Seconds still to go, from the time per baked chunk so far; negative while no chunk
    // has been baked (unknown).
    double etaSeconds(double elapsedSeconds) const {
        const size_t baked = done - resumed;
        return baked ? elapsedSeconds / double(baked) * double(total - done) : -1.0;
    }
};
using Progress = std::function<void(const BakeProgress&)>;

// Runs the whole bake. Every chunk file is either as it was or complete. On error the
// message ends by naming the chunk files updated before it ("no chunk file was changed",
// or each one: possible only with --resume or during the final renames). A chunk whose file
// is read-only or changed during the bake is not written and gets a warning.
Expected<BakeResult> runBake(const BakeOptions& options, const Progress& progress = {});

// Ok, or an Interrupted error once SIGINT or SIGTERM arrived (cli/interrupt.h): the bake
// checks it between stages and chunks (the scan, the window's loads and the stages' loops
// check it too: util/stop_request.h) and cleans up on its own thread.
Status interrupted();

// Effects the window calls for, as the bake simulated them (for the summary and JSON).
std::vector<std::string> simulatedEffects(const BakeWindow& window, const ChunkVerdicts& verdicts);

}  // namespace shadowcull::cli
