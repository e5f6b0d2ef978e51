#include "cli/preview_command.h"

#include <cmath>
#include <cstdio>
#include <sstream>
#include <vector>

#include "cli/render_command.h"
#include "cli/staged_outputs.h"
#include "gpu/preview.h"

namespace shadowcull::cli {

namespace {

// The frames show a shadow the masks removed (docs/cli.md), as `check` says of a GPU false cull.
constexpr int kExitFalseCull = 1;

// Six comma-separated finite numbers, or nothing.
std::optional<std::vector<double>> parseCamera(const std::string& text) {
    std::vector<double> v;
    std::stringstream ss(text);
    std::string item;
    while (std::getline(ss, item, ',')) {
        char* end = nullptr;
        const double x = std::strtod(item.c_str(), &end);
        if (item.empty() || end == item.c_str() || *end != '\0' || !std::isfinite(x)) return std::nullopt;
        v.push_back(x);
    }
    if (v.size() != 6) return std::nullopt;
    return v;
}

std::string ms(double v) {
    if (v < 0) return "not measured (the device has no timer query)";
    char b[32];
    std::snprintf(b, sizeof b, "%.3f ms", v);
    return b;
}

std::string pass(const gpu::ShadowPassTiming& t) {
    char cpu[32];
    std::snprintf(cpu, sizeof cpu, "%.3f ms", t.cpuMs);
    return std::to_string(t.casters) + " casters, " + std::to_string(t.drawCalls) + " draw calls, " +
           std::to_string(t.triangles) + " triangles, GPU time " + ms(t.gpuMs) + ", wall " + cpu;
}

}  // namespace

int runPreview(const PreviewOptions& options, std::ostream& out, std::ostream& err) {
    gpu::PreviewRequest rq;
    if (!options.camera.empty()) {
        std::optional<std::vector<double>> cam = parseCamera(options.camera);
        if (!cam) {
            err << "shadowcull: error: --camera " << options.camera
                << ": expected six numbers EYE_X,EYE_Y,EYE_Z,TARGET_X,TARGET_Y,TARGET_Z (world metres)\n";
            return kExitUsage;
        }
        rq.wsEye = glm::dvec3((*cam)[0], (*cam)[1], (*cam)[2]);
        rq.wsTarget = glm::dvec3((*cam)[3], (*cam)[4], (*cam)[5]);
    }
    ChunkBake bake;
    ChunkCoord coord;
    if (int code = bakeChunkForLight(options.bake, options.chunk, options.light, options.outPath, err, bake, coord); code != kExitOk)
        return code;
    const std::vector<Light>& lights = bake.window.lsLights;
    rq.light = options.light - 1;
    rq.shadowResolution = options.shadowResolution;
    rq.pcfRadius = options.pcfRadius;
    rq.timingRepeats = options.repeats;
    StagedOutputs picture;  // renamed into place below: a signal or an error leaves no partial PNG
    Expected<gpu::PreviewReport> r = gpu::renderShadowPreview(bake.window, bake.verdicts, rq, picture.stage(options.outPath));
    if (int code = finishPicture(r.status(), picture, options.outPath, err); code != kExitOk) return code;
    const Light& L = lights[size_t(rq.light)];
    out << "wrote " << options.outPath << " (" << r->pictureWidth << " x " << r->pictureHeight << " px): light "
        << options.light << " '" << L.name << "' over " << chunkFileName(coord) << ", masks from a bake of the chunk (not written)\n";
    out << "camera " << r->wsEye.x << "," << r->wsEye.y << "," << r->wsEye.z << " -> " << r->wsTarget.x << ","
        << r->wsTarget.y << "," << r->wsTarget.z << "\n";
    out << "shadow map " << options.shadowResolution << " x " << options.shadowResolution
        << (r->views > 1 ? " x " + std::to_string(r->views) + " faces" : "") << ", texel " << r->texelSize << " m"
        << (L.type == LightType::Directional ? "" : " at range") << ", PCF radius " << r->pcfRadius
        << (r->pcfDefaulted ? " (default)" : "") << ", footprint " << r->worstFootprint << " m, filterRadius "
        << L.filterRadius << " m\n";
    out << "device: " << r->device << "\n";
    out << "shadow pass, all casters:  " << pass(r->all) << "\n";
    out << "shadow pass, kept casters: " << pass(r->kept) << "\n";
    out << "lit surface pixels: " << r->receiverPixels << " (" << r->coveredPixels
        << " where filterRadius covers the footprint)\n";
    out << "differing pixels: " << r->differingPixels << "\n";
    out << "  on the culled caster's own surface: " << r->differingOnOwnSurfaces
        << " (its self-shadowing as the bias draws it, acne: no witness)\n";
    out << "  in the texel-edge band on kept surfaces: " << r->differingInBand
        << " (a texel's centre ray meets a culled caster that the receiver's own light ray does not)\n";
    out << "  where filterRadius covers the footprint: " << r->differingCovered << "\n";
    out << "differing on kept surfaces: " << r->differingOnKeptSurfaces
        << (r->differingOnKeptSurfaces ? " (a false cull: a shadow the engine draws is missing)" : "") << "\n";
    out << "false culls on the culled caster's own surface (a self-shadow missing): " << r->falseCullsOnOwnSurfaces << "\n";
    for (const gpu::FalseCullCaster& f : r->falseCulls)
        out << "false cull: " << f.caster << ", light " << options.light << " '" << L.name << "': " << f.pixels
            << " pixels [" << f.proof << "]\n";
    for (const gpu::DifferingPixel& d : r->listed) {
        out << "  pixel " << d.x << "," << d.y << " (" << gpu::pixelClassName(d.cls)
            << (d.covered ? ", filterRadius covers the footprint" : "") << "): receiver " << d.receiver << " at "
            << d.wsReceiver.x << "," << d.wsReceiver.y << "," << d.wsReceiver.z << "; caster " << d.caster << " ["
            << d.casterProof << "]";
        if (d.exactWitness) out << "; its lit point on the light's ray " << d.wsP.x << "," << d.wsP.y << "," << d.wsP.z;
        out << "; footprint " << d.footprint << " m\n";
    }
    if (r->falseCullPixels() > 0) return kExitFalseCull;
    return kExitOk;
}

}  // namespace shadowcull::cli
