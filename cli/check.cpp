#include "cli/check.h"
#include "cli/output_guard.h"

#include <filesystem>
#include <map>
#include <vector>

#include "cli/pipeline.h"
#include "cli/savings.h"
#include "cli/staged_outputs.h"
#include "gpu/render.h"
#include "util/format.h"

namespace fs = std::filesystem;

namespace shadowcull::cli {

namespace {

std::string vec(const glm::dvec3& v) {
    return "(" + formatNumber(v.x) + " " + formatNumber(v.y) + " " + formatNumber(v.z) + ")";
}

std::string objectName(const ObjectVerdicts& ov) {
    std::string s = (ov.terrain ? "terrain #" : "model #") + std::to_string(ov.elementIndex);
    if (!ov.uuid.empty()) s += " (" + ov.uuid + ")";
    return s;
}

// What `check` keeps of the original method's bake: each chunk's decisions in the order of
// ChunkVerdicts::at (object, group, light), about 50 bytes a bit. The windows, meshes and
// GL buffers go as the bake goes, so that memory follows the window and not the world.
using OriginalBits = std::map<ChunkCoord, std::vector<Decision>>;

struct Tally {
    uint64_t bits = 0, falseCulls = 0, falseKeeps = 0, undecided = 0;
    size_t nonCasters = 0;  // objects the input check culled because they cast no shadow
    std::string lines;      // one entry per disagreement, in bake order
    std::string pictures;   // one line per picture written
};

// Groups to outline per light of one chunk: (object, group) of every disagreement.
using Disagreements = std::map<int, std::vector<std::pair<size_t, int>>>;

// 1. The original method over the whole space, kept as its decisions only.
Expected<BakeResult> bakeOriginal(const BakeOptions& analytic, OriginalBits& bits) {
    BakeOptions original = analytic;
    original.gpuBaseline = true;
    original.onChunkBaked = [&](const BakeWindow&, const ChunkVerdicts& cv) {
        std::vector<Decision>& out = bits[cv.coord];
        for (const ObjectVerdicts& ov : cv.objects) out.insert(out.end(), ov.decisions.begin(), ov.decisions.end());
        return Status::ok();
    };
    return runBake(original);
}

size_t nonCasters(const ChunkVerdicts& cv) {
    size_t n = 0;
    for (size_t oi = 0; oi < cv.objects.size(); ++oi)
        if (cv.objects[oi].groupCount > 0 && cv.lightCount > 0 && cv.at(oi, 0, 0).stage == "input" &&
            cv.at(oi, 0, 0).reason() == savings::kCastsShadowFalse)
            ++n;
    return n;
}

// 2. One chunk of the analytic bake against the original's decisions: counts, the lines
// that explain each disagreement, and the groups to outline per light.
Disagreements compareChunk(const ChunkVerdicts& av, const std::vector<Decision>& original, const SpaceSettings& settings,
                           Tally& tally) {
    Disagreements outlined;
    tally.nonCasters += nonCasters(av);
    size_t next = 0;  // index into `original`, in the order of av.at
    for (size_t oi = 0; oi < av.objects.size(); ++oi) {
        const ObjectVerdicts& ov = av.objects[oi];
        for (int grp = 0; grp < ov.groupCount; ++grp)
            for (int l = 0; l < av.lightCount; ++l, ++next) {
                if (next >= original.size()) return outlined;  // (the space changed between the bakes)
                ++tally.bits;
                const Decision& ad = av.at(oi, grp, l);
                const Decision& gd = original[next];
                const bool gpuOne = gd.verdict != Verdict::Culled;
                std::string kind, evidence;
                if (!gpuOne && ad.verdict == Verdict::Kept) {
                    ++tally.falseCulls;
                    kind = "GPU false cull";
                    evidence = "witness: origin " + vec(ad.witness()->wsOrigin) + " direction " + vec(ad.witness()->wsDirection) +
                               ", p " + vec(ad.witness()->wsP) + ", q " + vec(ad.witness()->wsQ) + " on " + ad.witness()->receiver;
                } else if (gpuOne && ad.verdict == Verdict::Culled) {
                    ++tally.falseKeeps;
                    kind = "GPU false keep";
                    evidence = "proof (" + std::string(ad.stage) + "): " + std::string(ad.reason());
                } else if (ad.verdict == Verdict::Undecided) {
                    ++tally.undecided;
                    if (gpuOne) continue;  // both write 1: nothing to look at
                    kind = "undecided";
                    evidence = "the analytic pipeline could not decide; the GPU method culled it (" + std::string(gd.reason()) + ")";
                } else {
                    continue;
                }
                outlined[l].push_back({oi, grp});
                tally.lines += "  " + chunkFileName(av.coord) + "  " + objectName(ov) + "  group " + std::to_string(grp) +
                               "  light " + std::to_string(l + 1) + " '" + settings.lights[size_t(l)].name + "': " + kind +
                               " (GPU " + (gpuOne ? "1" : "0") + ", analytic " + verdictName(ad.verdict) + ")\n      " +
                               evidence + "\n";
            }
    }
    return outlined;
}

// 3. A picture per light with a disagreement, drawn from the window the analytic bake has
// loaded (no second bake) and staged at once; renamed into place when the check completes.
Status drawPictures(const BakeWindow& window, const ChunkVerdicts& av, const Disagreements& outlined,
                    const CheckOptions& options, const std::vector<std::string>& inputs, StagedOutputs& staged, Tally& tally) {
    for (const auto& [light, groups] : outlined) {
        if (Status s = staged.makeDirectory(options.outDir); !s) return s;
        const std::string png =
            (fs::path(options.outDir) / (chunkFileName(av.coord) + "-light" + std::to_string(light + 1) + ".png")).string();
        if (Status s = refuseInputAsOutput(png, inputs, "--pictures"); !s) return s;
        gpu::RenderRequest rq;
        rq.light = light;
        rq.resolution = options.gpuResolution;
        rq.outlined = groups;
        rq.outlineMeaning = "where the GPU method disagrees";
        Expected<gpu::RenderReport> r = gpu::renderLightView(window, av, rq, staged.stage(png));
        if (!r) return r.error();
        tally.pictures += "picture: " + png + " (" + std::to_string(groups.size()) +
                          (groups.size() == 1 ? " disagreeing group" : " disagreeing groups") + " outlined in magenta)\n";
    }
    return Status::ok();
}

void printTally(const Tally& t, const CheckOptions& options, const std::string& gl, std::ostream& out) {
    out << "bits " << t.bits << "; GPU method at " << options.gpuResolution << ": " << t.falseCulls << " false culls, "
        << t.falseKeeps << " false keeps; " << t.undecided << " bits undecided by the analytic pipeline\n";
    if (!gl.empty()) out << "OpenGL: " << gl << "\n";
    if (const size_t n = t.nonCasters; n > 0)
        out << "note: " << n << (n == 1 ? " object casts" : " objects cast")
            << " no shadow (castsShadow false). The original method draws them as occluders (its reading: never a "
               "caster, still an occluder); an engine never draws them into its shadow map, so they hide nothing, and a "
               "caster hidden only by them that it culls is counted as a GPU false cull\n";
    if (!t.lines.empty()) out << "disagreements:\n" << t.lines;
    out << t.pictures;
}

}  // namespace

int runCheck(const CheckOptions& options, std::ostream& out, std::ostream& err) {
    auto fail = [&](const Error& e) {
        err << "shadowcull: error: " << e.what() << "\n";
        return exitCodeFor(e.kind);
    };
    // Both bakes stream (keepVerdicts false): the original's decisions are kept, compact;
    // the analytic bake is compared and drawn chunk by chunk while its window is loaded.
    BakeOptions analytic;
    analytic.spaceDir = options.spaceDir;
    analytic.resourceRoot = options.resourceRoot;
    analytic.threads = options.threads;
    analytic.raycast.threads = options.threads;
    analytic.gpuResolution = options.gpuResolution;
    analytic.write = false;
    analytic.keepVerdicts = false;

    OriginalBits original;
    Expected<BakeResult> g = bakeOriginal(analytic, original);
    if (!g) return fail(g.error());

    Tally tally;
    StagedOutputs pictures;  // an error or a signal leaves none of them
    analytic.onChunkBaked = [&](const BakeWindow& window, const ChunkVerdicts& av) -> Status {
        const auto it = original.find(av.coord);
        if (it == original.end()) return Status::ok();
        const Disagreements outlined = compareChunk(av, it->second, g->settings, tally);
        original.erase(it);  // compared: let it go
        return options.pictures ? drawPictures(window, av, outlined, options, g->inputFiles, pictures, tally) : Status::ok();
    };
    Expected<BakeResult> a = runBake(analytic);
    if (!a) return fail(a.error());
    if (Status s = pictures.commit(); !s) return fail(s.error().kind == ErrorKind::Interrupted ? interrupted().error() : s.error());

    printTally(tally, options, g->gl, out);
    return tally.falseCulls ? 1 : 0;
}

}  // namespace shadowcull::cli
