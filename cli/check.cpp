#include "cli/check.h"
#include "cli/output_guard.h"

#include <filesystem>
#include <map>
#include <optional>
#include <set>

#include "cli/pipeline.h"
#include "core/format.h"
#include "core/savings.h"
#include "gpu/render.h"

namespace fs = std::filesystem;

namespace shadowcull::cli {

namespace {

std::string vec(const glm::dvec3& v) {
    return "(" + formatNumber(v.x) + " " + formatNumber(v.y) + " " + formatNumber(v.z) + ")";
}

// Objects the input check culled because they cast no shadow (castsShadow false).
size_t nonCasters(const BakeResult& r) {
    size_t n = 0;
    for (const ChunkVerdicts& cv : r.chunks)
        for (size_t oi = 0; oi < cv.objects.size(); ++oi)
            if (cv.objects[oi].groupCount > 0 && cv.lightCount > 0 && cv.at(oi, 0, 0).stage == "input" &&
                cv.at(oi, 0, 0).reason() == savings::kCastsShadowFalse)
                ++n;
    return n;
}

std::string objectName(const ObjectVerdicts& ov) {
    std::string s = (ov.terrain ? "terrain #" : "model #") + std::to_string(ov.elementIndex);
    if (!ov.uuid.empty()) s += " (" + ov.uuid + ")";
    return s;
}

}  // namespace

int runCheck(const CheckOptions& options, std::ostream& out, std::ostream& err) {
    BakeOptions analytic;
    analytic.spaceDir = options.spaceDir;
    analytic.resourceRoot = options.resourceRoot;
    analytic.threads = options.threads;
    analytic.raycast.threads = options.threads;
    analytic.gpuResolution = options.gpuResolution;
    analytic.write = false;
    BakeOptions original = analytic;
    original.gpuBaseline = true;

    Expected<BakeResult> a = runBake(analytic);
    if (!a) {
        err << "shadowcull: error: " << a.error().what() << "\n";
        return exitCodeFor(a.error().kind);
    }
    Expected<BakeResult> g = runBake(original);
    if (!g) {
        err << "shadowcull: error: " << g.error().what() << "\n";
        return exitCodeFor(g.error().kind);
    }

    uint64_t bits = 0, falseCulls = 0, falseKeeps = 0, undecided = 0;
    // (chunk, light) with a disagreement -> the (object, group) pairs that disagree there.
    std::map<std::pair<ChunkCoord, int>, std::vector<std::pair<size_t, int>>> pictures;
    std::string lines;
    for (size_t c = 0; c < a->chunks.size() && c < g->chunks.size(); ++c) {
        const ChunkVerdicts& av = a->chunks[c];
        const ChunkVerdicts& gv = g->chunks[c];
        for (size_t oi = 0; oi < av.objects.size(); ++oi) {
            const ObjectVerdicts& ov = av.objects[oi];
            for (int grp = 0; grp < ov.groupCount; ++grp)
                for (int l = 0; l < av.lightCount; ++l) {
                    ++bits;
                    const Decision& ad = av.at(oi, grp, l);
                    const Decision& gd = gv.at(oi, grp, l);
                    const bool gpuOne = gd.verdict != Verdict::Culled;
                    std::string kind, evidence;
                    if (!gpuOne && ad.verdict == Verdict::Kept) {
                        ++falseCulls;
                        kind = "GPU false cull";
                        evidence = "witness: origin " + vec(ad.witness()->wsOrigin) + " direction " + vec(ad.witness()->wsDirection) +
                                   ", p " + vec(ad.witness()->wsP) + ", q " + vec(ad.witness()->wsQ) + " on " + ad.witness()->receiver;
                    } else if (gpuOne && ad.verdict == Verdict::Culled) {
                        ++falseKeeps;
                        kind = "GPU false keep";
                        evidence = "proof (" + std::string(ad.stage) + "): " + std::string(ad.reason());
                    } else if (ad.verdict == Verdict::Undecided) {
                        ++undecided;
                        if (gpuOne) continue;  // both write 1: nothing to look at
                        kind = "undecided";
                        evidence = "the analytic pipeline could not decide; the GPU method culled it (" + std::string(gd.reason()) + ")";
                    } else {
                        continue;
                    }
                    pictures[{av.coord, l}].push_back({oi, grp});
                    lines += "  " + chunkFileName(av.coord) + "  " + objectName(ov) + "  group " + std::to_string(grp) +
                             "  light " + std::to_string(l + 1) + " '" + a->settings.lights[size_t(l)].name + "': " + kind +
                             " (GPU " + (gpuOne ? "1" : "0") + ", analytic " + verdictName(ad.verdict) + ")\n      " +
                             evidence + "\n";
                }
        }
    }
    out << "bits " << bits << "; GPU method at " << options.gpuResolution << ": " << falseCulls << " false culls, "
        << falseKeeps << " false keeps; " << undecided << " bits undecided by the analytic pipeline\n";
    if (!g->gl.empty()) out << "OpenGL: " << g->gl << "\n";
    if (const size_t n = nonCasters(*a); n > 0)
        out << "note: " << n << (n == 1 ? " object casts" : " objects cast")
            << " no shadow (castsShadow false). The original method draws them as occluders (its reading: never a "
               "caster, still an occluder); an engine never draws them into its shadow map, so they hide nothing, and a "
               "caster hidden only by them that it culls is counted as a GPU false cull\n";
    if (!lines.empty()) out << "disagreements:\n" << lines;

    if (options.pictures && !pictures.empty()) {
        std::error_code ec;
        fs::create_directories(options.outDir, ec);
        // One bake per chunk, however many of its lights disagree (pictures is sorted by chunk).
        std::optional<ChunkCoord> bakedAt;
        Expected<ChunkBake> cb = makeError(ErrorKind::Internal, "", 0, "no chunk baked yet");
        for (const auto& [where, groups] : pictures) {
            const auto& [coord, light] = where;
            if (!bakedAt || !(*bakedAt == coord)) {
                cb = bakeChunk(analytic, coord);
                bakedAt = coord;
            }
            if (!cb) {
                err << "shadowcull: error: " << cb.error().what() << "\n";
                return exitCodeFor(cb.error().kind);
            }
            const std::string png = (fs::path(options.outDir) / (chunkFileName(coord) + "-light" + std::to_string(light + 1) + ".png")).string();
            Status s = refuseInputAsOutput(png, cb->space->inputFiles(), "--pictures");
            if (!s) {
                err << "shadowcull: error: " << s.error().what() << "\n";
                return exitCodeFor(s.error().kind);
            }
            gpu::RenderRequest rq;
            rq.light = light;
            rq.resolution = options.gpuResolution;
            rq.outlined = groups;
            rq.outlineMeaning = "where the GPU method disagrees";
            Expected<gpu::RenderReport> r = gpu::renderLightView(cb->window, cb->verdicts, rq, png);
            if (!r) {
                err << "shadowcull: error: " << r.error().what() << "\n";
                return exitCodeFor(r.error().kind);
            }
            out << "picture: " << png << " (" << groups.size() << (groups.size() == 1 ? " disagreeing group" : " disagreeing groups")
                << " outlined in magenta)\n";
        }
    }
    return falseCulls ? 1 : 0;
}

}  // namespace shadowcull::cli
