#include "cli/pipeline.h"

#include <fcntl.h>
#include <sys/file.h>
#include <sys/resource.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <csignal>
#include <cmath>
#include <cstring>

#include <glm/geometric.hpp>
#include <filesystem>
#include <fstream>
#include <memory>
#include <set>
#include <unordered_map>
#include <unordered_set>
#include <sstream>

#include <tbb/global_control.h>

#include "cli/interrupt.h"
#include "cli/output_guard.h"
#include "cli/report.h"
#include "cli/resume.h"
#include "cli/shard.h"
#include "core/chunk_writer.h"
#include "core/file_read.h"
#include "core/hash.h"
#include "core/format.h"
#include "core/results_file.h"
#include "core/space_source.h"
#include "core/stop_request.h"
#include "core/window.h"
#include "gpu/baseline.h"
#include "gpu/confirm_stage.h"
#include "gpu/gl_context.h"

namespace fs = std::filesystem;

namespace shadowcull::cli {

int exitCodeFor(ErrorKind kind) {
    switch (kind) {
        case ErrorKind::BadInput:
        case ErrorKind::MissingResource: return kExitBadInput;
        case ErrorKind::Io: return kExitIo;
        case ErrorKind::Internal: return kExitInternal;
        case ErrorKind::Busy: return kExitBusy;
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

// The masks to write for one chunk, in element order. Skipped objects keep their old <shadow>.
std::vector<ShadowWrite> shadowWrites(const ChunkVerdicts& cv) {
    std::vector<ShadowWrite> out;
    for (size_t oi = 0; oi < cv.objects.size(); ++oi) {
        const ObjectVerdicts& ov = cv.objects[oi];
        ShadowWrite w;
        w.write = ov.windowObject >= 0;
        w.terrain = ov.terrain;
        for (int g = 0; g < ov.groupCount; ++g) {
            uint32_t m = cv.groupMask(oi, g);
            w.mask |= m;
            if (!ov.terrain) w.groupMasks.push_back(m);
        }
        out.push_back(std::move(w));
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

// The output directory's lock (docs/cli.md): one writing bake per directory at a time, so
// that a second bake can neither remove the first one's staged files nor interleave its
// renames with them. flock() locks die with the process, so a killed bake never leaves a
// stale lock behind; the file itself stays (removing it would race with the next bake).
class OutputLock {
public:
    ~OutputLock() {
        if (fd_ >= 0) ::close(fd_);  // releases the lock
    }
    // `shared`: a shard's hold on the directory (bake --shard): shards of one bake hold it
    // together, each with its own exclusive lock as well, while a whole bake needs it alone.
    Status acquire(const std::string& dir, const std::string& name = ".shadowcull-bake.lock", bool shared = false) {
        const std::string path = (fs::path(dir) / name).string();
        // Never through a symbolic link: the pid written below would land in its target.
        fd_ = ::open(path.c_str(), O_RDWR | O_CREAT | O_NOFOLLOW | O_CLOEXEC, 0644);
        if (fd_ < 0 && errno == ELOOP)
            return makeError(ErrorKind::BadInput, path, 0,
                             "the bake lock is a symbolic link; a bake never writes through one (remove it)");
        if (fd_ < 0) return makeError(ErrorKind::Io, path, 0, std::string("cannot create the bake lock: ") + std::strerror(errno));
        if (::flock(fd_, (shared ? LOCK_SH : LOCK_EX) | LOCK_NB) != 0) {
            char pid[32] = {};
            const ssize_t n = ::pread(fd_, pid, sizeof pid - 1, 0);
            std::string holder = n > 0 ? std::string(pid, size_t(n)) : "";
            holder.erase(holder.find_last_not_of(" \n") + 1);
            return makeError(ErrorKind::Busy, path, 0,
                             "another shadowcull bake is writing " + dir +
                                 (holder.empty() ? "" : " (process " + holder + ")") + "; wait for it to finish");
        }
        if (shared) return Status::ok();  // the pid is the exclusive holder's
        const std::string me = std::to_string(::getpid()) + "\n";
        if (::ftruncate(fd_, 0) == 0 && ::pwrite(fd_, me.data(), me.size(), 0) < 0) {
            // The pid is for messages only.
        }
        return Status::ok();
    }

private:
    int fd_ = -1;
};

// A chunk file baked and staged, waiting for its rename.
struct StagedChunk {
    std::string name;    // chunk file name, for messages
    std::string source;  // the chunk file the verdicts were computed from
    uint64_t sourceHash = 0;
    std::string temp, target;
};

const char* const kEditedDuringBake =
    "changed on disk while the bake ran (someone's edit?); not written, so the edit is kept: bake it again";

// Why `source` must not be replaced now: it no longer holds the bytes the bake read (an
// edit made while the bake ran). Empty when it still does.
std::string changedSince(const std::string& source, uint64_t hash) {
    Expected<std::string> now = readRegularFile(source, "chunk file", ErrorKind::Io);
    if (!now) return "cannot be read again (" + now.error().message + ")";
    if (Hasher().str(*now).value() != hash) return kEditedDuringBake;
    return {};
}

// "; no chunk file was changed" or "; updated (each file complete): a, b".
std::string writtenNote(const std::vector<std::string>& committed) {
    if (committed.empty()) return "; no chunk file was changed";
    std::string s = "; " + std::to_string(committed.size()) + " chunk file(s) were updated before it, each completely:";
    for (const std::string& c : committed) s += " " + c;
    return s;
}

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

// Where a chunk's bytes go: in place (through a symlink, to its target), or a copy under
// --out, by name: a symbolic link there is never followed (writableTargets refuses it).
std::string outputPathFor(const BakeOptions& opt, const std::string& chunkPath) {
    return opt.outDir.empty() ? writeTargetFor(chunkPath) : (fs::path(opt.outDir) / fs::path(chunkPath).filename()).string();
}

// The chunks of `targets` whose output may be written. An output under --out that is a
// symbolic link (a copy of the space made with `cp -as` holds one per chunk, each leading
// back to the space) or one of the bake's inputs stops the bake before anything is
// written; a chunk whose file may not be replaced (read-only, another owner) is left out
// with a warning in `diagnostics`, unless --force-write.
Expected<std::vector<ChunkCoord>> writableTargets(const BakeOptions& opt, const SpaceSource& source,
                                                  const std::vector<ChunkCoord>& targets,
                                                  const std::vector<std::string>& inputs,
                                                  std::vector<Diagnostic>& diagnostics) {
    const bool inPlace = opt.outDir.empty();
    std::vector<ChunkCoord> writable;
    for (ChunkCoord c : targets) {
        const std::string& path = source.chunks().at(c).path;
        const std::string target = outputPathFor(opt, path);
        if (!inPlace) {
            std::error_code ec;
            if (fs::is_symlink(target, ec))
                return makeError(ErrorKind::BadInput, target, 0,
                                 "--out: the output is a symbolic link (to " + fs::read_symlink(target, ec).string() +
                                     "); --out writes copies and never writes through a link (remove it)");
            if (Status s = refuseInputAsOutput(target, inputs, "--out"); !s) return s.error();
        }
        if (std::string why = opt.forceWrite ? "" : replaceRefusal(target); !why.empty()) {
            diagnostics.push_back({path, 0, (inPlace ? "the chunk file is " : "the output " + target + " is ") + why +
                                                "; not baked (--force-write replaces it anyway)"});
            continue;
        }
        // A symlinked chunk is staged beside its target, which may lie outside the
        // output directory: clear a temporary a killed bake left there too.
        if (std::error_code tec; fs::is_regular_file(fs::symlink_status(tempPathFor(target), tec)))
            fs::remove(tempPathFor(target), tec);
        writable.push_back(c);
    }
    return writable;
}

// User and system time of the process so far, every thread (seconds).
double processCpuSeconds() {
    rusage ru{};
    getrusage(RUSAGE_SELF, &ru);
    return double(ru.ru_utime.tv_sec + ru.ru_stime.tv_sec) + 1e-6 * double(ru.ru_utime.tv_usec + ru.ru_stime.tv_usec);
}

Expected<BakeResult> runBakeWriting(const BakeOptions& opt, const Progress& progress, std::vector<std::string>& committed) {
    const auto t0 = std::chrono::steady_clock::now();
    const double cpu0 = processCpuSeconds();
    auto since = [](auto t) { return std::chrono::duration<double>(std::chrono::steady_clock::now() - t).count(); };
    std::unique_ptr<tbb::global_control> threadLimit;
    if (opt.threads > 0)
        threadLimit = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism, size_t(opt.threads));

    // 1. Which chunks.
    std::vector<ChunkCoord> only;
    for (const std::string& name : opt.chunkNames) {
        std::optional<ChunkCoord> c = parseChunkArgument(name);
        if (!c) return makeError(ErrorKind::BadInput, name, 0, "not a chunk name (XXXXZZZZo.chunk, 16-bit hex)");
        only.push_back(*c);
    }

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
    Expected<SpaceSource> scanned = SpaceSource::scan(opt.spaceDir, opt.resourceRoot, scanOnly ? &only : nullptr, opt.onScanned);
    if (!scanned) return scanned.error();
    SpaceSource& source = *scanned;
    BakeResult result;
    result.settings = source.settings();
    result.diagnostics = source.diagnostics();
    result.totals = BakeTotals(result.settings.lights.size());
    std::vector<ChunkCoord> targets;
    auto mustExist = [&](ChunkCoord c) -> Status {
        if (source.chunks().count(c)) return Status::ok();
        return makeError(ErrorKind::BadInput, (fs::path(opt.spaceDir) / chunkFileName(c)).string(), 0, "no such chunk file in the space");
    };
    if (opt.chunkNames.empty() && opt.bakeOnly.empty()) {
        for (const auto& [c, e] : source.chunks()) targets.push_back(c);
    } else {
        for (ChunkCoord c : opt.chunkNames.empty() ? opt.bakeOnly : only) {
            if (Status s = mustExist(c); !s) return s.error();
            targets.push_back(c);
        }
        // Grid order, once each: the order of the results file.
        std::sort(targets.begin(), targets.end());
        targets.erase(std::unique(targets.begin(), targets.end()), targets.end());
    }
    const bool sharded = opt.shardCount > 0;
    if (sharded) {
        // Every shard scans the same space and computes the same partition.
        if (!opt.chunkNames.empty()) return makeError(ErrorKind::BadInput, "", 0, "--shard bakes a part of the whole space: not with --chunk");
        targets = partitionChunks(source, opt.shardCount)[size_t(opt.shardIndex - 1)];
        results::ShardRecord sh;
        sh.index = opt.shardIndex, sh.count = opt.shardCount;
        sh.inputs = hexHash(spaceInputHash(source, opt));
        sh.spaceChunks = source.chunks().size();
        for (ChunkCoord c : targets) sh.assigned.push_back(chunkFileName(c));
        sh.spaceWarnings = source.diagnostics().size();
        result.shard = std::move(sh);
    }
    result.loadSeconds = since(t0);
    result.loadCpuSeconds = processCpuSeconds() - cpu0;
    if (Status i = interrupted(); !i) return i.error();

    // 3. Outputs: never an input, and every one writable before any work is done.
    result.inputFiles = source.inputFiles();
    const std::vector<std::string>& inputs = result.inputFiles;
    const std::string outDir = opt.outDir.empty() ? opt.spaceDir : opt.outDir;
    if (opt.write && !opt.outDir.empty()) {
        // Before the results are probed: they may go into --out too.
        std::error_code ec;
        fs::create_directories(opt.outDir, ec);
        if (ec) return makeError(ErrorKind::Io, opt.outDir, 0, "cannot create output directory: " + ec.message());
    }
    if (Status s = refuseInputAsOutput(opt.resultsPath, inputs, "--results"); !s) return s.error();
    if (!opt.resultsPath.empty()) {
        Expected<std::string> probe = stageFile(opt.resultsPath, "");
        if (!probe) return probe.error();
        fs::remove(*probe);
    }
    OutputLock lock, shardLock;
    if (opt.write && sharded) {
        // Other shards may be staging files in this directory: only this shard's own
        // temporaries are cleared (below, per chunk).
        if (Status s = lock.acquire(outDir, ".shadowcull-bake.lock", true); !s) return s.error();
        const std::string name = ".shadowcull-bake.shard-" + std::to_string(opt.shardIndex) + "-of-" + std::to_string(opt.shardCount) + ".lock";
        if (Status s = shardLock.acquire(outDir, name); !s) return s.error();
    } else if (opt.write) {
        if (Status s = lock.acquire(outDir); !s) return s.error();
        // Temporaries of a bake that was killed are never chunk files; clear them away
        // (only now: the lock guarantees they are no running bake's).
        if (const int n = removeStaleTempFiles(outDir))
            result.notes.push_back("removed " + std::to_string(n) + " temporary file(s) a killed bake left in " + outDir);
    } else if (!sharded && !staleTempFiles(outDir).empty()) {
        // A dry run writes nothing, but clears what a killed bake left, under the same lock
        // (taken only when there is something to clear; a running bake's files stay).
        if (Status s = lock.acquire(outDir); !s)
            result.notes.push_back("temporary files in " + outDir + " left alone: " + s.error().message);
        else if (const int n = removeStaleTempFiles(outDir))
            result.notes.push_back("removed " + std::to_string(n) + " temporary file(s) a killed bake left in " + outDir);
    }
    auto targetOf = [&](const std::string& chunkPath) { return outputPathFor(opt, chunkPath); };
    auto refuse = [&](const std::string& chunkPath, const std::string& why) { result.diagnostics.push_back({chunkPath, 0, why}); };
    if (opt.write) {
        Expected<std::vector<ChunkCoord>> writable = writableTargets(opt, source, targets, inputs, result.diagnostics);
        if (!writable) return writable.error();
        targets = std::move(*writable);
    }

    // 4. Bake every chunk; stage its new text in a temporary file beside the target.
    StageRunner runner(opt, &glProbe);
    result.notes.insert(result.notes.end(), runner.notes().begin(), runner.notes().end());
    if (!runner.status()) return runner.status().error();

    result.stages = runner.timings();
    // The chunks loaded now: those the windows still to bake need.
    Space space;
    space.settings = source.settings();
    TerrainMeshes terrainMeshes;
    const WindowPlanner planner(source.settings(), source.chunks(), wholeSpaceWindows(opt));
    WindowSequence windows(source, targets, planner);
    if (Status i = interrupted(); !i) return i.error();  // the sequence may be incomplete
    auto release = [&](size_t k) {
        const std::vector<std::shared_ptr<const Mesh>> gone = windows.leave(k, space, terrainMeshes);
        if (gone.empty()) return;
        std::unordered_set<const Mesh*> meshes;
        for (const auto& m : gone) meshes.insert(m.get());
        runner.forgetMeshes(meshes);  // before the addresses can be reused
    };
    std::vector<StagedChunk> staged;
    auto discardStaged = [&] {
        for (const StagedChunk& s : staged) fs::remove(s.temp);
    };
    const bool resume = opt.resume && opt.write;
    ResumeState state;
    const std::string statePath = ResumeState::pathIn(outDir, opt.shardIndex, opt.shardCount);
    const bool wantResults = !opt.resultsPath.empty();
    if (resume)
        if (Status s = state.open(statePath); !s) return s.error();
    // The results file, one chunk at a time as the chunks are done (staged beside it until
    // the chunk files are committed): the same bytes as results::writeResults of the whole.
    StagedFile resultsOut;
    ResultsBuilder resultsBuilder(result.settings);
    bool anyResults = false;
    if (wantResults) {
        Expected<StagedFile> f = StagedFile::open(opt.resultsPath);
        if (!f) return f.error();
        resultsOut = std::move(*f);
        if (Status s = resultsOut.append(results::resultsHead()); !s) return s.error();
    }
    auto addResults = [&](results::ChunkRecord& record) -> Status {
        resultsBuilder.add(record);
        const Status s = resultsOut.append((anyResults ? ",\n" : "\n") + results::chunkJson(record));
        anyResults = true;
        return s;
    };
    // Renames one staged chunk unless its source changed since it was read (the check and
    // the rename are microseconds apart; the lock keeps other bakes out of that window).
    auto commit = [&](const StagedChunk& s) -> Status {
        if (std::string why = changedSince(s.source, s.sourceHash); !why.empty()) {
            fs::remove(s.temp);
            result.diagnostics.push_back({s.source, 0, why});
            return Status::ok();
        }
        if (Status st = commitStagedFile(s.temp, s.target); !st) return st;
        committed.push_back(s.name);
        ++result.chunksWritten;
        return Status::ok();
    };
    auto stopWith = [&](Error e) {
        discardStaged();  // (what --resume committed is recorded already)
        return e;
    };
    size_t done = 0;
    for (size_t k = 0; k < targets.size(); ++k) {
        if (Status i = interrupted(); !i) return stopWith(i.error());
        const ChunkEntry& entry = source.chunks().at(targets[k]);
        const std::string target = targetOf(entry.path);
        const std::string chunkName = chunkFileName(targets[k]);
        const WindowPlan plan = planner.plan(targets[k]);  // the chunks its bake reads
        uint64_t inputHash = 0;
        if (resume) {
            inputHash = windowInputHash(source, targets[k], plan.chunks, opt);
            Expected<std::string> current = readRegularFile(target, "chunk file", ErrorKind::Io);
            // With --results, its part of the results as recorded; unreadable (an edited
            // state): bake it again.
            bool skip = current && state.upToDate(chunkName, inputHash, *current, wantResults);
            if (skip && wantResults) {
                Expected<results::ChunkRecord> record = results::parseChunkJson(statePath, state.results(chunkName));
                skip = bool(record);
                if (record) {
                    if (opt.keepVerdicts) result.resumedRecords.push_back(*record);
                    if (Status s = addResults(*record); !s) return stopWith(s.error());
                }
            }
            if (skip) {
                ++result.chunksResumed;
                release(k);
                if (progress) progress({++done, targets.size(), size_t(result.chunksResumed)});
                continue;
            }
        }
        if (Status s = windows.enter(k, space, result.diagnostics); !s) return stopWith(s.error());
        result.peakLoadedChunks = windows.peakLoaded();
        const ChunkFile& cf = space.chunks.at(targets[k]);
        ChunkVerdicts cv;
        {
            if (planner.wholeSpace()) result.reach.add(plan);
            if (planner.wholeSpace() && opt.keepVerdicts) result.plans[targets[k]] = plan;
            const BakeWindow window = buildWindow(space, targets[k], plan.chunks, terrainMeshes);
            if (Status i = interrupted(); !i) return stopWith(i.error());  // the window may be incomplete
            cv = makeChunkVerdicts(space, window);
            if (Status status = runner.bake(window, cv, result.stages); !status) {
                Error e = status.error();
                if (e.file.empty() && e.kind != ErrorKind::Interrupted) e.file = cf.path;
                return stopWith(e);
            }
            cv.simulated = simulatedEffects(window, cv);
            if (opt.onChunkBaked)
                if (Status s = opt.onChunkBaked(window, cv); !s) return stopWith(s.error());
        }
        // The chunk's part of the results (kept by --resume for a later bake, too).
        std::optional<results::ChunkRecord> record;
        if (wantResults) record = chunkRecord(cv);
        if (opt.write) {
            const auto tw = std::chrono::steady_clock::now();
            // The text to rewrite is the text the objects were read from, or nothing.
            Expected<std::string> text = readRegularFile(cf.path, "chunk file", ErrorKind::Io);
            if (!text) return stopWith(text.error());
            if (Hasher().str(*text).value() != cf.contentHash) {
                refuse(cf.path, kEditedDuringBake);
            } else {
                Expected<std::string> rewritten = rewriteChunkShadows(*text, cf.path, shadowWrites(cv));
                if (!rewritten) return stopWith(rewritten.error());
                // Complete and synced before any target is replaced.
                Expected<std::string> temp = stageFile(target, *rewritten, !opt.forceWrite);
                if (!temp) return stopWith(temp.error());
                StagedChunk sc{chunkName, cf.path, cf.contentHash, *temp, target};
                if (resume) {
                    // Long-bake mode: commit now, then record it (a kill between the two only
                    // costs baking this chunk again).
                    const int before = result.chunksWritten;
                    if (Status s = commit(sc); !s) return stopWith(s.error());
                    if (result.chunksWritten > before)
                        if (Status s = state.record(chunkName, inputHash, *rewritten, record ? results::chunkJson(*record) : ""); !s)
                            return stopWith(s.error());
                } else {
                    staged.push_back(std::move(sc));
                }
            }
            result.writeSeconds += since(tw);
        }
        result.totals.add(cv);
        if (record)
            if (Status s = addResults(*record); !s) return stopWith(s.error());
        if (opt.keepVerdicts) result.chunks.push_back(std::move(cv));
        release(k);
        if (progress) progress({++done, targets.size(), size_t(result.chunksResumed)});
    }

    if (Status i = interrupted(); !i) return stopWith(i.error());

    // 5. The results file, complete and synced before any chunk file is renamed: a results
    // file that cannot be written stops the bake with every chunk file as it was.
    const size_t warningsInResults = result.diagnostics.size();
    const uint64_t chunksEnd = resultsOut.size();
    auto finishResults = [&]() -> Status {
        if (!wantResults) return Status::ok();
        if (Status s = resultsOut.truncate(chunksEnd); !s) return s;
        if (Status s = resultsOut.append(results::resultsTail(resultsBuilder.tail(result.diagnostics, result.shard), anyResults)); !s)
            return s;
        return resultsOut.sync();
    };
    if (Status s = finishResults(); !s) return stopWith(s.error());
    // The last moment to stop with nothing written; the renames below take milliseconds
    // and are not interrupted, so that the chunk files end all old or all new.
    if (Status i = interrupted(); !i) return stopWith(i.error());

    // 6. Commit: one rename per file. Each rename is atomic, so an interruption here leaves
    // every chunk file either as it was or complete.
    const auto tc = std::chrono::steady_clock::now();
    for (size_t k = 0; k < staged.size(); ++k) {
        if (Status s = commit(staged[k]); !s) {
            staged.erase(staged.begin(), staged.begin() + std::ptrdiff_t(k + 1));
            return stopWith(s.error());
        }
    }
    staged.clear();
    if (wantResults) {
        // Refused chunks (edited during the commit) were added to the diagnostics after the
        // results were finished: write the end again so the file lists every warning.
        if (result.diagnostics.size() != warningsInResults)
            if (Status s = finishResults(); !s) return stopWith(s.error());
        if (Status s = resultsOut.commit(); !s) return stopWith(s.error());
    }
    result.writeSeconds += since(tc);
    if (opt.gpuBaseline) {
        std::string note =
            "--method gpu is the original stencil + occlusion-query method: its masks are NOT conservative (a bit may be "
            "0 where the shadow is seen)";
        if (opt.witnessBaselineCulls)
            note += "; " + std::to_string(runner.baselineCullsWitnessed()) +
                    " of the bits it wrote 0 here have a witness ray (a shadow that is seen)";
        result.notes.push_back(note + "; 'shadowcull check " + opt.spaceDir + "' lists every such bit");
    }
    result.gl = runner.glDescription();
    result.totalSeconds = since(t0);
    return result;
}

}  // namespace

}  // namespace shadowcull::cli
