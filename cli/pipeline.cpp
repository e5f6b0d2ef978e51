#include "cli/pipeline.h"

#include <sys/resource.h>

#include <chrono>
#include <csignal>
#include <cmath>

#include <glm/geometric.hpp>
#include <filesystem>
#include <memory>
#include <unordered_set>

#include <tbb/global_control.h>

#include "cli/bake_files.h"
#include "cli/interrupt.h"
#include "cli/report.h"
#include "cli/resume.h"
#include "cli/shard.h"
#include "io/shard_plan.h"
#include "core/window.h"
#include "gpu/baseline.h"
#include "gpu/confirm_stage.h"
#include "gpu/gl_context.h"
#include "io/chunk_writer.h"
#include "io/results_file.h"
#include "io/space_source.h"
#include "util/format.h"
#include "util/hash.h"
#include "util/stop_request.h"

namespace fs = std::filesystem;

namespace shadowcull::cli {

int exitCodeFor(ErrorKind kind) {
    switch (kind) {
        case ErrorKind::BadInput:
        case ErrorKind::MissingResource: return kExitBadInput;
        case ErrorKind::Io: return kExitIo;
        case ErrorKind::Internal: return kExitInternal;
        case ErrorKind::Busy: return kExitBusy;
        case ErrorKind::StalePlan: return kExitStalePlan;
        case ErrorKind::Interrupted: return exitCodeForSignal(pendingInterrupt() ? pendingInterrupt() : SIGINT);
    }
    return kExitInternal;
}

std::vector<std::string> simulatedEffects(const BakeWindow& w, const ChunkVerdicts& cv) {
    std::vector<std::string> out;
    if (w.hasAlphaTested) out.push_back("alpha-tested groups let light pass");
    if (w.hasTerrain) out.push_back("terrain rule (receivers deeper than " + formatNumber(w.terrainTolerance) + " m under terrain do not count)");
    const std::vector<bool> reaching = lightsWithUndecided(cv);
    for (size_t l = 0; l < w.lsLights.size(); ++l) {
        const Light& L = w.lsLights[l];
        std::string who = "light " + std::to_string(l + 1) + " '" + L.name + "': ";
        bool anyGroup = false;
        for (const ObjectVerdicts& ov : cv.objects) anyGroup |= ov.groupCount > 0;
        if (anyGroup && !reaching[l]) {
            // Not traced only when the input and reach checks decided every bit of it.
            bool reachCulledAll = true;
            for (const ObjectVerdicts& ov : cv.objects)
                for (int g = 0; g < ov.groupCount; ++g) {
                    const std::string_view stage = ov.decisions[size_t(g) * size_t(cv.lightCount) + l].stage;
                    reachCulledAll &= stage == "reach" || stage == "input";
                }
            if (reachCulledAll) {
                out.push_back(who + "cannot reach the chunk's casters (not traced)");
                continue;
            }
        }
        if (L.type != LightType::Directional) out.push_back(who + "range " + formatNumber(L.range) + " m");
        if (L.type == LightType::Spot) out.push_back(who + "cone " + formatNumber(L.coneHalfAngleDeg) + " deg");
        if (L.bias > 0) out.push_back(who + "bias " + formatNumber(L.bias) + " m");
        if (L.slopeBias > 0) out.push_back(who + "slope bias " + formatNumber(L.slopeBias) + " m");
        if (L.filterRadius > 0)
            out.push_back(who + "filter radius " + formatNumber(L.filterRadius) +
                          " m (shadow volumes dilated by it; witnesses need no dilation)");
        if (L.normalBias > 0)
            out.push_back(who + "normal bias " + formatNumber(L.normalBias) +
                          " m (receivers looked up off their surfaces: witnesses through the moved surfaces, shadow "
                          "volumes dilated by it, the GPU stage proves only \"never lit\")");
    }
    return out;
}

namespace {

// The own samples a terrain's witness search traces before the shadow volumes (the area
// samples: where nearly every terrain witness is found; the rest, up to 1,280 samples and
// 2,048 receiver-side points, finds nothing on most terrains and waits for the volumes).
constexpr size_t kTerrainShortSearch = 256;

// Whether a bake's windows hold every chunk its shadows reach (core/window_plan.h), or the
// `neighbours` rectangle: the original method's window, and the benchmarks' window-only bake.
bool wholeSpaceWindows(const BakeOptions& opt) { return !opt.gpuBaseline && !opt.neighbourWindows; }

// Appends `point` and four points `r` metres from it to its sides across `direction`
// (unit): a small cross of witness targets around a point the search is aimed at.
void appendCross(const glm::dvec3& point, const glm::dvec3& direction, double r, std::vector<glm::dvec3>& targets) {
    const glm::dvec3& d = direction;
    const glm::dvec3 u = glm::normalize(std::abs(d.y) < 0.9 ? glm::cross(d, glm::dvec3(0, 1, 0)) : glm::cross(d, glm::dvec3(1, 0, 0)));
    const glm::dvec3 v = glm::cross(d, u);
    for (const glm::dvec3& off : {glm::dvec3(0.0), r * u, -r * u, r * v, -r * v}) targets.push_back(point + off);
}

// Targets for a dense witness search around the pixels where the GPU confirmation saw
// samples pass: each pixel's ray and four rays a third of its footprint to the sides.
std::vector<raycast::WitnessSearch> denseSearches(const std::vector<gpu::GroupPixels>& passed, const ChunkVerdicts& cv) {
    std::vector<raycast::WitnessSearch> out;
    for (const gpu::GroupPixels& gp : passed) {
        if (gp.pixels.empty() || cv.at(gp.object, gp.group, gp.light).verdict != Verdict::Undecided) continue;
        raycast::WitnessSearch ws{gp.object, gp.group, gp.light, {}};
        for (const gpu::PassedPixel& px : gp.pixels) appendCross(px.lsPoint, px.lsDirection, px.footprint / 3.0, ws.targets);
        out.push_back(std::move(ws));
    }
    return out;
}

// Targets for a witness search where the geometry stage could not exclude a receiver: the
// point of it the shadow volume reaches, and four more 2 mm to its sides across the light
// (the point is rounded; a sliver of the terrain band is ~1 cm thick).
std::vector<raycast::WitnessSearch> candidateSearches(const std::vector<geometry::GeometryStage::Candidate>& candidates,
                                                      const BakeWindow& window, const ChunkVerdicts& cv) {
    std::vector<raycast::WitnessSearch> out;
    for (const geometry::GeometryStage::Candidate& c : candidates) {
        if (cv.at(c.object, c.group, c.light).verdict != Verdict::Undecided) continue;
        const Light& L = window.lsLights[size_t(c.light)];
        const glm::dvec3 d = L.type == LightType::Directional || glm::length(c.lsPoint - L.position) == 0.0
                                 ? L.direction
                                 : glm::normalize(c.lsPoint - L.position);
        raycast::WitnessSearch ws{c.object, c.group, c.light, {}};
        appendCross(c.lsPoint, d, 2e-3, ws.targets);
        if (L.normalBias > 0) {
            // The engine looks the receiver point's shadow up off its surface (semantics.md
            // condition 5): aim at the lookup points too, and test the receiver's moved copy.
            const WindowObject& ro = window.objects[c.receiverObject];
            const std::array<glm::dvec3, 3> t = ro.lsTriangle(c.receiverTriangle);
            const glm::dvec3 n = glm::cross(t[1] - t[0], t[2] - t[0]);
            if (glm::length(n) > 0) {
                const glm::dvec3 offset = (ro.flipsWinding ? -L.normalBias : L.normalBias) * glm::normalize(n);
                appendCross(c.lsPoint + offset, d, 2e-3, ws.targets);
                if (ro.mesh->groups[ro.mesh->triangleGroup[c.receiverTriangle]].twoSided())
                    appendCross(c.lsPoint - offset, d, 2e-3, ws.targets);
            }
            ws.receiver = std::array<uint32_t, 2>{c.receiverObject, c.receiverTriangle};
        }
        out.push_back(std::move(ws));
    }
    return out;
}

}  // namespace

Status interrupted() {
    const Status stop = stopStatus();
    if (stop) return stop;
    Error e = stop.error();
    e.message += "; the bake's temporary files were removed";
    return e;
}

Status StageRunner::probeGl(const BakeOptions& opt) {
    if (!(opt.useGpu || opt.gpuBaseline)) return Status::ok();
    Expected<std::unique_ptr<gpu::GlContext>> probe = gpu::createOffscreenContext(16, 16);
    if (!probe) return probe.error();
    return Status::ok();
}

StageRunner::StageRunner(const BakeOptions& opt, std::future<Status>* glProbe)
    : rays_(opt.raycast),
      volumes_(opt.geometry),
      confirm_([&] {
          gpu::GpuConfirmOptions o;
          o.resolution = opt.gpuResolution;
          o.includeTerrain = opt.gpuTerrain;
          o.closeUpResolution = opt.gpuCloseUpResolution;
          return o;
      }()),
      baseline_(gpu::GpuBaselineOptions{opt.gpuResolution}) {
    bool useGpu = opt.useGpu && !opt.gpuBaseline;
    if (useGpu || opt.gpuBaseline) {
        // The GPU passes need an OpenGL context; without one the confirmation is skipped
        // (its bits stay undecided, kept) and the baseline cannot run at all.
        const Status probe = glProbe && glProbe->valid() ? glProbe->get() : probeGl(opt);
        if (!probe) {
            if (opt.gpuBaseline) status_ = probe.error();
            notes_.push_back("gpu stage skipped: " + probe.error().message);
            useGpu = false;
        }
    }
    // Cheap to expensive; each stage skips what an earlier one decided. Witness rays come
    // before shadow volumes: most bits of a real world are 1s, found after a few rays.
    if (opt.gpuBaseline) {
        stages_ = {&inputOnly_, &baseline_};
    } else {
        stages_ = {&reach_};
        if (opt.useRaycast) stages_.push_back(&rays_);
        if (opt.useGeometry) stages_.push_back(&volumes_);
        if (useGpu) stages_.push_back(&confirm_);
    }
    candidatePass_ = opt.useGeometry && opt.useRaycast && !opt.gpuBaseline;
    // A terrain's bits: the shadow volumes before most of their witness rays, and a large
    // caster's receiver-side search after the GPU confirmation too (raycast_stage.h): they
    // find a witness for few bits that those stages do not prove 0.
    if (candidatePass_) rays_.deferLongSearches(kTerrainShortSearch);
    deferredAfter_ = useGpu ? static_cast<Stage*>(&confirm_) : static_cast<Stage*>(&volumes_);
    densePass_ = useGpu && opt.useRaycast;
    closeUpPass_ = useGpu && opt.gpuCloseUpResolution > 0;
    witnessBaselineCulls_ = opt.gpuBaseline && opt.witnessBaselineCulls;
}

void StageRunner::forgetMeshes(const std::unordered_set<const Mesh*>& meshes) {
    for (Stage* s : {static_cast<Stage*>(&reach_), static_cast<Stage*>(&inputOnly_), static_cast<Stage*>(&rays_),
                     static_cast<Stage*>(&volumes_), static_cast<Stage*>(&confirm_), static_cast<Stage*>(&baseline_)})
        s->forgetMeshes(meshes);
}

std::string StageRunner::glDescription() const {
    const std::string confirm = confirm_.glDescription();
    return confirm.empty() ? baseline_.glDescription() : confirm;
}

std::vector<StageTiming> StageRunner::timings() const {
    std::vector<StageTiming> t;
    for (Stage* s : stages_) t.push_back({s->name(), {}});
    if (candidatePass_) t.push_back({"raycast (geometry candidates)", {}});
    if (densePass_) t.push_back({"raycast (gpu pixels)", {}});
    if (closeUpPass_) t.push_back({"gpu (close-up)", {}});
    if (closeUpPass_ && densePass_) t.push_back({"raycast (close-up pixels)", {}});
    return t;
}

Status StageRunner::bake(const BakeWindow& window, ChunkVerdicts& cv, std::vector<StageTiming>& timings) {
    // The window's witness searches (the stage's and the later passes) share one Embree scene.
    rays_.keepScene(window);
    struct DropScene {
        raycast::RaycastStage& rays;
        ~DropScene() { rays.dropScene(); }
    } dropScene{rays_};
    for (size_t s = 0; s < stages_.size(); ++s) {
        if (Status i = interrupted(); !i) return i;
        StageStats st;
        if (Status status = stages_[s]->run(window, cv, st); !status) return status;
        timings[s].stats.add(st);
        if (candidatePass_ && stages_[s] == &volumes_) {
            // Witness rays at the receivers the shadow volumes reach (before the GPU stage:
            // a bit proved 1 here needs no confirmation).
            StageStats cs;
            if (Status status = rays_.searchAt(window, cv, candidateSearches(volumes_.candidates(), window, cv), cs,
                                               "witness ray at the receiver the shadow volume reaches");
                !status)
                return status;
            timings[stages_.size()].stats.add(cs);
        }
        if (candidatePass_ && stages_[s] == deferredAfter_) {
            // Then the witness searches cut short for the shadow volumes (and the GPU
            // confirmation) go on where none decided the bit (on the raycast stage's row).
            StageStats rs;
            if (Status status = rays_.finishDeferred(window, cv, rs); !status) return status;
            timings[size_t(std::find(stages_.begin(), stages_.end(), &rays_) - stages_.begin())].stats.add(rs);
        }
    }
    if (Status i = interrupted(); !i) return i;
    if (witnessBaselineCulls_) {
        // The baseline's 0s made undecided again in a copy, for the witness rays alone.
        ChunkVerdicts probe = cv;
        std::vector<Decision*> culled;
        for (size_t oi = 0; oi < probe.objects.size(); ++oi)
            for (int g = 0; g < probe.objects[oi].groupCount; ++g)
                for (int l = 0; l < probe.lightCount; ++l) {
                    Decision& d = probe.at(oi, g, l);
                    if (d.verdict == Verdict::Culled && d.stage == baseline_.name()) {
                        d = Decision{};
                        culled.push_back(&d);
                    }
                }
        // The reach stage first: what it proves 0 can have no witness, and it is cheap.
        StageStats st;
        if (!culled.empty())
            for (Stage* stage : {static_cast<Stage*>(&reach_), static_cast<Stage*>(&rays_)})
                if (Status status = stage->run(window, probe, st); !status) return status;
        for (const Decision* d : culled) baselineCullsWitnessed_ += d->verdict == Verdict::Kept;
    }
    size_t next = stages_.size() + (candidatePass_ ? 1 : 0);  // the timings after the stages'
    if (densePass_) {
        // The dense witness search where the GPU confirmation saw samples pass.
        StageStats st;
        if (Status status = rays_.searchAt(window, cv, denseSearches(confirm_.passedPixels(), cv), st); !status)
            return status;
        timings[next++].stats.add(st);
    }
    if (closeUpPass_) {
        if (Status i = interrupted(); !i) return i;
        StageStats st;
        if (Status status = confirm_.runCloseUp(window, cv, st); !status) return status;
        timings[next++].stats.add(st);
        if (densePass_) {
            StageStats rs;
            if (Status status = rays_.searchAt(window, cv, denseSearches(confirm_.passedPixels(), cv), rs,
                                               "witness ray where the GPU stage's close-up saw samples pass");
                !status)
                return status;
            timings[next++].stats.add(rs);
        }
    }
    return Status::ok();
}

Expected<ChunkBake> bakeChunk(const BakeOptions& opt, ChunkCoord chunk) {
    // The original method reads the chunk and its neighbours; the analytic bake the whole
    // space's summaries, since a shadow may land anywhere (core/window_plan.h).
    std::vector<ChunkCoord> only{chunk};
    Expected<SpaceSource> scanned = SpaceSource::scan(opt.spaceDir, opt.resourceRoot, wholeSpaceWindows(opt) ? nullptr : &only);
    if (!scanned) return scanned.error();
    if (Status i = interrupted(); !i) return i.error();
    ChunkBake out;
    out.space = std::make_unique<Space>();
    out.space->settings = scanned->settings();
    out.space->diagnostics = scanned->diagnostics();
    if (!scanned->chunks().count(chunk))
        return makeError(ErrorKind::BadInput, (fs::path(opt.spaceDir) / chunkFileName(chunk)).string(), 0,
                         "no such chunk file in the space");
    const WindowPlanner planner(scanned->settings(), scanned->chunks(), wholeSpaceWindows(opt));
    out.plan = planner.plan(chunk);
    for (ChunkCoord c : out.plan.chunks)
        if (Status s = scanned->load(c, *out.space, out.space->diagnostics); !s) return s.error();
    StageRunner runner(opt);
    if (!runner.status()) return runner.status().error();
    out.window = buildWindow(*out.space, chunk, out.plan.chunks, out.terrainMeshes);
    if (Status i = interrupted(); !i) return i.error();  // the window may be incomplete
    out.verdicts = makeChunkVerdicts(*out.space, out.window);
    out.stages = runner.timings();
    if (Status s = runner.bake(out.window, out.verdicts, out.stages); !s) return s.error();
    out.verdicts.simulated = simulatedEffects(out.window, out.verdicts);
    out.notes = runner.notes();
    out.gl = runner.glDescription();
    return out;
}

namespace {

// runBake without the note on what was written; `committed` lists the chunk files renamed
// so far, whatever happens after.
Expected<BakeResult> runBakeWriting(const BakeOptions& opt, const Progress& progress, std::vector<std::string>& committed);

}  // namespace

Expected<BakeResult> runBake(const BakeOptions& opt, const Progress& progress) {
    std::vector<std::string> committed;
    Expected<BakeResult> r = runBakeWriting(opt, progress, committed);
    if (!r) {
        Error e = r.error();
        // Stopped anywhere (the scan, a stage): the message says what was cleaned up.
        if (e.kind == ErrorKind::Interrupted)
            if (Status i = interrupted(); !i) e = i.error();
        e.message += writtenNote(committed);
        return e;
    }
    return r;
}

namespace {

// User and system time of the process so far, every thread (seconds).
double processCpuSeconds() {
    rusage ru{};
    getrusage(RUSAGE_SELF, &ru);
    return double(ru.ru_utime.tv_sec + ru.ru_stime.tv_sec) + 1e-6 * double(ru.ru_utime.tv_usec + ru.ru_stime.tv_usec);
}

double secondsSince(std::chrono::steady_clock::time_point t) {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - t).count();
}

// The chunks --chunk names.
Expected<std::vector<ChunkCoord>> namedChunks(const BakeOptions& opt) {
    std::vector<ChunkCoord> only;
    for (const std::string& name : opt.chunkNames) {
        std::optional<ChunkCoord> c = parseChunkArgument(name);
        if (!c) return makeError(ErrorKind::BadInput, name, 0, "not a chunk name (XXXXZZZZo.chunk, 16-bit hex)");
        only.push_back(*c);
    }
    return only;
}

// The space as the bake reads it: scanned (the whole space, or what `only`'s rectangles
// hold), or with --plan the shard's part of a plan (`plannedTargets` gets its chunks).
Expected<SpaceSource> openSpace(const BakeOptions& opt, const std::vector<ChunkCoord>* only,
                                std::vector<ChunkCoord>& plannedTargets) {
    if (opt.planDir.empty()) return SpaceSource::scan(opt.spaceDir, opt.resourceRoot, only, opt.onScanned);
    Expected<LoadedShardPlan> plan = readShardPlan(opt.planDir, opt.shardIndex, opt.shardCount);
    if (!plan) return plan.error();
    plannedTargets = plan->shard.assigned;
    return SpaceSource::planned(opt.spaceDir, opt.resourceRoot, plannedSpaceOf(opt.planDir, std::move(*plan)));
}

// The chunks to bake: every chunk, or those named (--chunk, or bakeOnly), in grid order,
// once each (the order of the results file). With --shard, this shard's part of every
// chunk (from its plan, or computed as every shard computes it), and its record in `result`.
Expected<std::vector<ChunkCoord>> chunksToBake(const BakeOptions& opt, const SpaceSource& source,
                                               const std::vector<ChunkCoord>& only,
                                               const std::vector<ChunkCoord>& plannedTargets, BakeResult& result) {
    std::vector<ChunkCoord> targets;
    if (opt.chunkNames.empty() && opt.bakeOnly.empty()) {
        for (const auto& [c, e] : source.chunks()) targets.push_back(c);
    } else {
        for (ChunkCoord c : opt.chunkNames.empty() ? opt.bakeOnly : only) {
            if (!source.chunks().count(c))
                return makeError(ErrorKind::BadInput, (fs::path(opt.spaceDir) / chunkFileName(c)).string(), 0,
                                 "no such chunk file in the space");
            targets.push_back(c);
        }
        std::sort(targets.begin(), targets.end());
        targets.erase(std::unique(targets.begin(), targets.end()), targets.end());
    }
    if (opt.shardCount > 0) {
        // Every shard scans the same space and computes the same partition.
        if (!opt.chunkNames.empty()) return makeError(ErrorKind::BadInput, "", 0, "--shard bakes a part of the whole space: not with --chunk");
        targets = source.isPlanned() ? plannedTargets : partitionChunks(source, opt.shardCount)[size_t(opt.shardIndex - 1)];
        results::ShardRecord sh;
        sh.index = opt.shardIndex, sh.count = opt.shardCount;
        sh.inputs = hexHash(spaceInputHash(source, opt));
        sh.spaceChunks = source.outline().chunks;
        for (ChunkCoord c : targets) sh.assigned.push_back(chunkFileName(c));
        sh.spaceWarnings = source.diagnostics().size();
        result.shard = std::move(sh);
    }
    return targets;
}

// A planned shard knows the rest of the space's inputs (every chunk file and resource)
// from its plan, read only when one of its outputs exists: an output that does not exist
// cannot be an input, and the list grows with the world.
Status completeInputs(const BakeOptions& opt, SpaceSource& source, const std::vector<ChunkCoord>& targets,
                      const BakeFiles& files) {
    if (!source.isPlanned()) return Status::ok();
    std::error_code ec;
    bool exists = !opt.resultsPath.empty() && fs::exists(opt.resultsPath, ec);
    // In place, the targets are the chunk files themselves (inputs by design, never refused).
    if (!opt.outDir.empty())
        for (size_t k = 0; k < targets.size() && !exists; ++k)
            exists = fs::exists(files.targetOf(source.chunks().at(targets[k]).path), ec);
    return exists ? source.readOtherInputs() : Status::ok();
}

// The chunk loop of one bake: each chunk's window entered (the chunks it needs loaded),
// baked, its new text staged (BakeFiles), and left (the chunks no later window needs
// dropped): memory follows the window.
struct ChunkLoop {
    const BakeOptions& opt;
    const Progress& progress;
    const SpaceSource& source;
    const std::vector<ChunkCoord>& targets;
    BakeResult& result;
    BakeFiles& files;
    StageRunner& runner;
    const WindowPlanner& planner;
    WindowSequence& windows;
    Space& space;
    TerrainMeshes& terrainMeshes;
    size_t done = 0;

    Status run() {
        for (size_t k = 0; k < targets.size(); ++k)
            if (Status s = bakeOne(k); !s) return s;
        return Status::ok();
    }

    // Leaves chunk k's window: every stage forgets the meshes freed, before their
    // addresses can be reused.
    void release(size_t k) {
        const std::vector<std::shared_ptr<const Mesh>> gone = windows.leave(k, space, terrainMeshes);
        if (gone.empty()) return;
        std::unordered_set<const Mesh*> meshes;
        for (const auto& m : gone) meshes.insert(m.get());
        runner.forgetMeshes(meshes);
    }

    void finished(size_t k) {
        release(k);
        if (progress) progress({++done, targets.size(), size_t(result.chunksResumed)});
    }

    Status bakeOne(size_t k) {
        if (Status i = interrupted(); !i) return i;
        const ChunkEntry& entry = source.chunks().at(targets[k]);
        const std::string target = files.targetOf(entry.path);
        const std::string chunkName = chunkFileName(targets[k]);
        const WindowPlan plan = planner.plan(targets[k]);  // the chunks its bake reads
        uint64_t inputHash = 0;
        if (files.resuming()) {
            inputHash = windowInputHash(source, targets[k], plan.chunks, opt);
            Expected<bool> unchanged = files.unchanged(chunkName, target, inputHash);
            if (!unchanged) return unchanged.error();
            if (*unchanged) {
                ++result.chunksResumed;
                finished(k);
                return Status::ok();
            }
        }
        if (Status s = windows.enter(k, space, result.diagnostics); !s) return s;
        result.peakLoadedChunks = windows.peakLoaded();
        windows.readAhead(k + 1, space);  // the next window's new chunk files, read during this bake
        const ChunkFile& cf = space.chunks.at(targets[k]);
        ChunkVerdicts cv;
        if (Status s = bakeWindow(k, plan, cf, cv); !s) return s;
        // The chunk's part of the results (kept by --resume for a later bake, too).
        std::optional<results::ChunkRecord> record;
        if (files.wantResults()) record = chunkRecord(cv);
        if (opt.write) {
            const auto tw = std::chrono::steady_clock::now();
            if (Status s = files.write(cf, chunkName, target, inputHash, cv, record); !s) return s;
            result.writeSeconds += secondsSince(tw);
        }
        result.totals.add(cv);
        if (record)
            if (Status s = files.addResults(*record); !s) return s;
        if (opt.keepVerdicts) result.chunks.push_back(std::move(cv));
        finished(k);
        return Status::ok();
    }

    // Runs the stages on chunk k's window (loaded), into `cv`.
    Status bakeWindow(size_t k, const WindowPlan& plan, const ChunkFile& cf, ChunkVerdicts& cv) {
        if (planner.wholeSpace()) result.reach.add(plan);
        if (planner.wholeSpace() && opt.keepVerdicts) result.plans[targets[k]] = plan;
        const BakeWindow window = buildWindow(space, targets[k], plan.chunks, terrainMeshes);
        if (Status i = interrupted(); !i) return i;  // the window may be incomplete
        cv = makeChunkVerdicts(space, window);
        if (Status status = runner.bake(window, cv, result.stages); !status) {
            Error e = status.error();
            if (e.file.empty() && e.kind != ErrorKind::Interrupted) e.file = cf.path;
            return e;
        }
        cv.simulated = simulatedEffects(window, cv);
        if (opt.onChunkBaked)
            if (Status s = opt.onChunkBaked(window, cv); !s) return s;
        return Status::ok();
    }
};

// The note on a bake by the original method: its masks are not conservative.
std::string baselineNote(const BakeOptions& opt, const StageRunner& runner) {
    std::string note =
        "--method gpu is the original stencil + occlusion-query method: its masks are NOT conservative (a bit may be "
        "0 where the shadow is seen)";
    if (opt.witnessBaselineCulls)
        note += "; " + std::to_string(runner.baselineCullsWitnessed()) +
                " of the bits it wrote 0 here have a witness ray (a shadow that is seen)";
    return note + "; 'shadowcull check " + opt.spaceDir + "' lists every such bit";
}

Expected<BakeResult> runBakeWriting(const BakeOptions& opt, const Progress& progress, std::vector<std::string>& committed) {
    const auto t0 = std::chrono::steady_clock::now();
    const double cpu0 = processCpuSeconds();
    std::unique_ptr<tbb::global_control> threadLimit;
    if (opt.threads > 0)
        threadLimit = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism, size_t(opt.threads));

    // 1. Which chunks.
    Expected<std::vector<ChunkCoord>> only = namedChunks(opt);
    if (!only) return only.error();

    // 2. Read everything before writing anything: the scan parses every chunk file and loads
    // every resource once, and keeps what the whole bake needs to know (the warnings, the
    // files read, the hashes). The chunks themselves are loaded again when a window needs
    // them and dropped when no window will: memory follows the window.
    // The GPU stages' probe of OpenGL loads the driver (tens of milliseconds on one
    // thread, most of it the dynamic loader): it runs beside the scan, and the stages
    // take its answer below. (A std::async future waits for it wherever the bake returns.)
    std::future<Status> glProbe = std::async(std::launch::async, [&opt] { return StageRunner::probeGl(opt); });
    // --chunk: the original method reads those chunks and their neighbours; the analytic
    // bake the whole space, since their shadows may land anywhere (core/window_plan.h).
    const bool scanOnly = !opt.chunkNames.empty() && !wholeSpaceWindows(opt);
    std::vector<ChunkCoord> plannedTargets;
    Expected<SpaceSource> scanned = openSpace(opt, scanOnly ? &*only : nullptr, plannedTargets);
    if (!scanned) return scanned.error();
    SpaceSource& source = *scanned;
    BakeResult result;
    result.settings = source.settings();
    result.diagnostics = source.diagnostics();
    result.totals = BakeTotals(result.settings.lights.size());
    Expected<std::vector<ChunkCoord>> chosen = chunksToBake(opt, source, *only, plannedTargets, result);
    if (!chosen) return chosen.error();
    std::vector<ChunkCoord>& targets = *chosen;
    result.loadSeconds = secondsSince(t0);
    result.loadCpuSeconds = processCpuSeconds() - cpu0;
    if (Status i = interrupted(); !i) return i.error();

    // 3. Outputs: never an input, and every one writable before any work is done.
    BakeFiles files(opt, result, committed);
    if (Status s = completeInputs(opt, source, targets, files); !s) return s.error();
    result.inputFiles = source.inputFiles();
    if (Status s = files.prepare(source, targets); !s) return s.error();

    // 4. Bake every chunk; stage its new text in a temporary file beside the target.
    StageRunner runner(opt, &glProbe);
    result.notes.insert(result.notes.end(), runner.notes().begin(), runner.notes().end());
    if (!runner.status()) return runner.status().error();
    result.stages = runner.timings();
    // The chunks loaded now: those the windows still to bake need.
    Space space;
    space.settings = source.settings();
    TerrainMeshes terrainMeshes;
    const WindowPlanner planner(source.settings(), source.chunks(), wholeSpaceWindows(opt), source.outline().bounds);
    WindowSequence windows(source, targets, planner);
    if (Status i = interrupted(); !i) return i.error();  // the sequence may be incomplete
    if (Status s = files.open(); !s) return s.error();
    ChunkLoop loop{opt, progress, source, targets, result, files, runner, planner, windows, space, terrainMeshes};
    if (Status s = loop.run(); !s) return s.error();
    if (Status i = interrupted(); !i) return i.error();

    // 5. The results file, complete and synced before any chunk file is renamed: a results
    // file that cannot be written stops the bake with every chunk file as it was.
    if (Status s = files.finishResults(); !s) return s.error();
    // The last moment to stop with nothing written; the renames below take milliseconds
    // and are not interrupted, so that the chunk files end all old or all new.
    if (Status i = interrupted(); !i) return i.error();

    // 6. Commit: one rename per file. Each rename is atomic, so an interruption here leaves
    // every chunk file either as it was or complete.
    const auto tc = std::chrono::steady_clock::now();
    if (Status s = files.commit(); !s) return s.error();
    result.writeSeconds += secondsSince(tc);
    if (opt.gpuBaseline) result.notes.push_back(baselineNote(opt, runner));
    result.gl = runner.glDescription();
    result.totalSeconds = secondsSince(t0);
    return result;
}

}  // namespace

}  // namespace shadowcull::cli
