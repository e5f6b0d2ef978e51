#include "cli/pipeline.h"

#include <chrono>
#include <cmath>

#include <glm/geometric.hpp>
#include <filesystem>
#include <fstream>
#include <memory>
#include <set>
#include <unordered_map>
#include <sstream>

#include <tbb/global_control.h>

#include "cli/resume.h"
#include "core/chunk_writer.h"
#include "core/format.h"
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
    }
    return out;
}

namespace {

std::string readFile(const std::string& path, bool& ok) {
    std::ifstream in(path, std::ios::binary);
    std::ostringstream ss;
    ss << in.rdbuf();
    ok = bool(in) || in.eof();
    return ss.str();
}

// Targets for a dense witness search around the pixels where the GPU confirmation saw
// samples pass: each pixel's ray and four rays a third of its footprint to the sides.
std::vector<raycast::WitnessSearch> denseSearches(const std::vector<gpu::GroupPixels>& passed, const ChunkVerdicts& cv) {
    std::vector<raycast::WitnessSearch> out;
    for (const gpu::GroupPixels& gp : passed) {
        if (gp.pixels.empty() || cv.at(gp.object, gp.group, gp.light).verdict != Verdict::Undecided) continue;
        raycast::WitnessSearch ws{gp.object, gp.group, gp.light, {}};
        for (const gpu::PassedPixel& px : gp.pixels) {
            const glm::dvec3 d = px.lsDirection;
            const glm::dvec3 u = glm::normalize(std::abs(d.y) < 0.9 ? glm::cross(d, glm::dvec3(0, 1, 0)) : glm::cross(d, glm::dvec3(1, 0, 0)));
            const glm::dvec3 v = glm::cross(d, u);
            const double r = px.footprint / 3.0;
            for (const glm::dvec3& off : {glm::dvec3(0.0), r * u, -r * u, r * v, -r * v}) ws.targets.push_back(px.lsPoint + off);
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

StageRunner::StageRunner(const BakeOptions& opt)
    : rays_(opt.raycast),
      volumes_(opt.geometry),
      confirm_([&] {
          gpu::GpuConfirmOptions o;
          o.resolution = opt.gpuResolution;
          o.includeTerrain = opt.gpuTerrain;
          return o;
      }()),
      baseline_(gpu::GpuBaselineOptions{opt.gpuResolution}) {
    bool useGpu = opt.useGpu && !opt.gpuBaseline;
    if (useGpu || opt.gpuBaseline) {
        // The GPU passes need an OpenGL context; without one the confirmation is skipped
        // (its bits stay undecided, kept) and the baseline cannot run at all.
        Expected<std::unique_ptr<gpu::GlContext>> probe = gpu::createOffscreenContext(16, 16);
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
    densePass_ = useGpu && opt.useRaycast;
}

std::vector<StageTiming> StageRunner::timings() const {
    std::vector<StageTiming> t;
    for (Stage* s : stages_) t.push_back({s->name(), {}});
    if (densePass_) t.push_back({"raycast (gpu pixels)", {}});
    return t;
}

Status StageRunner::bake(const BakeWindow& window, ChunkVerdicts& cv, std::vector<StageTiming>& timings) {
    for (size_t s = 0; s < stages_.size(); ++s) {
        StageStats st;
        if (Status status = stages_[s]->run(window, cv, st); !status) return status;
        timings[s].stats.add(st);
    }
    if (densePass_) {
        // The dense witness search where the GPU confirmation saw samples pass.
        StageStats st;
        if (Status status = rays_.searchAt(window, cv, denseSearches(confirm_.passedPixels(), cv), st); !status)
            return status;
        timings.back().stats.add(st);
    }
    return Status::ok();
}

Expected<ChunkBake> bakeChunk(const BakeOptions& opt, ChunkCoord chunk) {
    std::vector<ChunkCoord> only{chunk};
    Expected<Space> loaded = loadSpace(opt.spaceDir, opt.resourceRoot, &only);
    if (!loaded) return loaded.error();
    ChunkBake out;
    out.space = std::make_unique<Space>(std::move(*loaded));
    if (!out.space->chunks.count(chunk))
        return makeError(ErrorKind::BadInput, (fs::path(opt.spaceDir) / chunkFileName(chunk)).string(), 0,
                         "no such chunk file in the space");
    StageRunner runner(opt);
    if (!runner.status()) return runner.status().error();
    out.window = buildWindow(*out.space, chunk, out.terrainMeshes);
    out.verdicts = makeChunkVerdicts(*out.space, out.window);
    out.stages = runner.timings();
    if (Status s = runner.bake(out.window, out.verdicts, out.stages); !s) return s.error();
    out.verdicts.simulated = simulatedEffects(out.window, out.verdicts);
    out.notes = runner.notes();
    return out;
}

Expected<BakeResult> runBake(const BakeOptions& opt, const Progress& progress) {
    const auto t0 = std::chrono::steady_clock::now();
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

    // 2. Load everything before writing anything.
    Expected<Space> loaded = loadSpace(opt.spaceDir, opt.resourceRoot, opt.chunkNames.empty() ? nullptr : &only);
    if (!loaded) return loaded.error();
    Space& space = *loaded;
    BakeResult result;
    result.settings = space.settings;
    result.diagnostics = space.diagnostics;
    std::vector<ChunkCoord> targets;
    if (opt.chunkNames.empty()) {
        for (const auto& [c, cf] : space.chunks) targets.push_back(c);
    } else {
        std::set<ChunkCoord> seen;
        for (ChunkCoord c : only) {
            if (!space.chunks.count(c))
                return makeError(ErrorKind::BadInput, (fs::path(opt.spaceDir) / chunkFileName(c)).string(), 0,
                                 "no such chunk file in the space");
            if (seen.insert(c).second) targets.push_back(c);
        }
    }
    result.loadSeconds = since(t0);

    // 3. Bake every chunk; stage its new text in a temporary file beside the target.
    // Cheap to expensive; each stage skips what an earlier one decided. Witness rays come
    // before shadow volumes: most bits of a real world are 1s, found after a few rays.
    StageRunner runner(opt);
    result.notes = runner.notes();
    if (!runner.status()) return runner.status().error();
    result.stages = runner.timings();
    TerrainMeshes terrainMeshes;
    struct Staged {
        std::string temp, target;
    };
    std::vector<Staged> staged;
    auto discardStaged = [&] {
        for (const Staged& s : staged) fs::remove(s.temp);
    };
    if (opt.write && !opt.outDir.empty()) {
        std::error_code ec;
        fs::create_directories(opt.outDir, ec);
        if (ec) return makeError(ErrorKind::Io, opt.outDir, 0, "cannot create output directory: " + ec.message());
    }
    // Temporaries of a bake that was killed are never chunk files; clear them away.
    const std::string outDir = opt.outDir.empty() ? opt.spaceDir : opt.outDir;
    if (opt.write) removeStaleTempFiles(outDir);
    const bool resume = opt.resume && opt.write;
    ResumeState state;
    const std::string statePath = ResumeState::pathIn(outDir);
    if (resume) state.load(statePath);
    std::unordered_map<const void*, uint64_t> meshHashes;
    auto lastSave = std::chrono::steady_clock::now();
    for (size_t k = 0; k < targets.size(); ++k) {
        const ChunkFile& cf = space.chunks.at(targets[k]);
        const std::string target =
            opt.outDir.empty() ? cf.path : (fs::path(opt.outDir) / fs::path(cf.path).filename()).string();
        const std::string chunkName = chunkFileName(targets[k]);
        uint64_t inputHash = 0;
        if (resume) {
            inputHash = windowInputHash(space, targets[k], opt, meshHashes);
            bool ok = false;
            const std::string current = readFile(target, ok);
            if (ok && state.upToDate(chunkName, inputHash, current)) {
                ++result.chunksResumed;
                if (progress) progress({k + 1, targets.size(), size_t(result.chunksResumed)});
                continue;
            }
        }
        BakeWindow window = buildWindow(space, targets[k], terrainMeshes);
        ChunkVerdicts cv = makeChunkVerdicts(space, window);
        if (Status status = runner.bake(window, cv, result.stages); !status) {
            discardStaged();
            Error e = status.error();
            if (e.file.empty()) e.file = cf.path;
            return e;
        }
        cv.simulated = simulatedEffects(window, cv);
        if (opt.write) {
            const auto tw = std::chrono::steady_clock::now();
            bool ok = false;
            const std::string text = readFile(cf.path, ok);
            if (!ok) {
                discardStaged();
                return makeError(ErrorKind::Io, cf.path, 0, "cannot read the chunk file again for writing");
            }
            Expected<std::string> rewritten = rewriteChunkShadows(text, cf.path, shadowWrites(cv));
            if (!rewritten) {
                discardStaged();
                return rewritten.error();
            }
            // Complete and synced before any target is replaced.
            Expected<std::string> temp = stageFile(target, *rewritten);
            if (!temp) {
                discardStaged();
                return temp.error();
            }
            if (resume) {
                // Long-bake mode: commit now, then record it (a kill between the two only
                // costs baking this chunk again).
                if (Status s = commitStagedFile(*temp, target); !s) return s.error();
                ++result.chunksWritten;
                state.record(chunkName, inputHash, *rewritten);
                if (std::chrono::steady_clock::now() - lastSave > std::chrono::seconds(2)) {
                    if (Status s = state.save(statePath); !s) return s.error();
                    lastSave = std::chrono::steady_clock::now();
                }
            } else {
                staged.push_back({*temp, target});
            }
            result.writeSeconds += since(tw);
        }
        result.chunks.push_back(std::move(cv));
        if (progress) progress({k + 1, targets.size(), size_t(result.chunksResumed)});
    }

    // 4. Commit: one rename per file. Each rename is atomic, so an interruption here leaves
    // every chunk file either as it was or complete.
    const auto tc = std::chrono::steady_clock::now();
    for (size_t k = 0; k < staged.size(); ++k) {
        if (Status s = commitStagedFile(staged[k].temp, staged[k].target); !s) {
            for (size_t j = k + 1; j < staged.size(); ++j) fs::remove(staged[j].temp);
            Error e = s.error();
            e.message += " (" + std::to_string(k) + " of " + std::to_string(staged.size()) +
                         " chunk files were updated, each completely)";
            return e;
        }
        ++result.chunksWritten;
    }
    if (resume)
        if (Status s = state.save(statePath); !s) return s.error();
    result.writeSeconds += since(tc);
    result.totalSeconds = since(t0);
    return result;
}

}  // namespace shadowcull::cli
