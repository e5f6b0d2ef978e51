#include "cli/render_command.h"

#include "cli/output_guard.h"
#include "gpu/render.h"

namespace shadowcull::cli {

int runRender(const RenderOptions& options, std::ostream& out, std::ostream& err) {
    std::optional<ChunkCoord> c = parseChunkArgument(options.chunk);
    if (!c) {
        err << "shadowcull: error: " << options.chunk << ": not a chunk name (XXXXZZZZo.chunk)\n";
        return kExitUsage;
    }
    BakeOptions bake = options.bake;
    bake.write = false;
    Expected<ChunkBake> cb = bakeChunk(bake, *c);
    if (!cb) {
        err << "shadowcull: error: " << cb.error().what() << "\n";
        return exitCodeFor(cb.error().kind);
    }
    if (Status s = refuseInputAsOutput(options.outPath, cb->space->inputFiles(), "--out"); !s) {
        err << "shadowcull: error: " << s.error().what() << "\n";
        return exitCodeFor(s.error().kind);
    }
    gpu::RenderRequest rq;
    rq.light = options.light - 1;
    rq.resolution = bake.gpuResolution;
    rq.colouredBy = bake.gpuBaseline ? "the original GPU method's verdicts" : "analytic verdicts";
    Expected<gpu::RenderReport> r = gpu::renderLightView(cb->window, cb->verdicts, rq, options.outPath);
    if (!r) {
        err << "shadowcull: error: " << r.error().what() << "\n";
        return exitCodeFor(r.error().kind);
    }
    out << "wrote " << options.outPath << " (" << r->width << " x " << r->height << " px): light " << options.light
        << " '" << cb->window.lsLights[size_t(rq.light)].name << "' over " << chunkFileName(*c) << ", groups "
        << r->culled << " culled, " << r->kept << " kept, " << r->undecided << " undecided";
    if (r->outsideFrame) out << ", " << r->outsideFrame << " outside the frame";
    out << "\n";
    return kExitOk;
}

}  // namespace shadowcull::cli
