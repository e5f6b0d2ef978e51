#include "cli/render_command.h"

#include <filesystem>

#include "cli/output_guard.h"
#include "cli/staged_outputs.h"
#include "gpu/render.h"

namespace shadowcull::cli {

namespace fs = std::filesystem;

int bakeChunkForLight(const BakeOptions& options, const std::string& chunk, int light, const std::string& outPath,
                      std::ostream& err, ChunkBake& result, ChunkCoord& coord) {
    std::optional<ChunkCoord> c = parseChunkArgument(chunk);
    if (!c) {
        err << "shadowcull: error: " << chunk << ": not a chunk name (XXXXZZZZo.chunk)\n";
        return kExitUsage;
    }
    BakeOptions bake = options;
    bake.write = false;
    Expected<ChunkBake> cb = bakeChunk(bake, *c);
    if (!cb) {
        err << "shadowcull: error: " << cb.error().what() << "\n";
        return exitCodeFor(cb.error().kind);
    }
    if (Status s = refuseInputAsOutput(outPath, cb->space->inputFiles(), "--out"); !s) {
        err << "shadowcull: error: " << s.error().what() << "\n";
        return exitCodeFor(s.error().kind);
    }
    const std::vector<Light>& lights = cb->window.lsLights;
    if (light < 1 || size_t(light) > lights.size()) {
        std::string names;
        for (size_t k = 0; k < lights.size(); ++k) names += (k ? ", " : "") + std::to_string(k + 1) + " '" + lights[k].name + "'";
        err << "shadowcull: error: --light " << light << ": " << (fs::path(bake.spaceDir) / "space.xml").string()
            << " has " << lights.size() << (lights.size() == 1 ? " light" : " lights") << " (" << names
            << "); nothing was written\n";
        return kExitUsage;
    }
    result = std::move(*cb);
    coord = *c;
    return kExitOk;
}

int finishPicture(const Status& rendered, StagedOutputs& picture, const std::string& path, std::ostream& err) {
    if (!rendered) {
        err << "shadowcull: error: " << rendered.error().what() << "\n";
        return exitCodeFor(rendered.error().kind);
    }
    if (Status s = picture.commit(); !s) {
        err << "shadowcull: error: " << s.error().what() << "; " << path << " was not written\n";
        return exitCodeFor(s.error().kind);
    }
    return kExitOk;
}

int runRender(const RenderOptions& options, std::ostream& out, std::ostream& err) {
    ChunkBake bake;
    ChunkCoord coord;
    if (int code = bakeChunkForLight(options.bake, options.chunk, options.light, options.outPath, err, bake, coord); code != kExitOk)
        return code;
    gpu::RenderRequest rq;
    rq.light = options.light - 1;
    rq.resolution = options.bake.gpuResolution;
    rq.colouredBy = options.bake.gpuBaseline ? "the original GPU method's verdicts" : "analytic verdicts";
    StagedOutputs picture;  // renamed into place below: a signal or an error leaves no partial PNG
    Expected<gpu::RenderReport> r = gpu::renderLightView(bake.window, bake.verdicts, rq, picture.stage(options.outPath));
    if (int code = finishPicture(r.status(), picture, options.outPath, err); code != kExitOk) return code;
    out << "wrote " << options.outPath << " (" << r->width << " x " << r->height << " px): light " << options.light
        << " '" << bake.window.lsLights[size_t(rq.light)].name << "' over " << chunkFileName(coord) << ", groups "
        << r->culled << " culled, " << r->kept << " kept, " << r->undecided << " undecided";
    if (r->outsideFrame) out << ", " << r->outsideFrame << " outside the frame";
    out << "\n";
    out << "OpenGL: " << r->gl << "\n";
    return kExitOk;
}

}  // namespace shadowcull::cli
