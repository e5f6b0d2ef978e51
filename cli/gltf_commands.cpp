#include "cli/gltf_commands.h"

#include <cmath>
#include <cstdlib>

#include "cli/output_guard.h"
#include "cli/pipeline.h"
#include "io/gltf_document.h"
#include "util/format.h"

namespace shadowcull::cli {

namespace {

bool parseSun(const std::string& text, gltf::SunAngles& sun) {
    const size_t comma = text.find(',');
    if (comma == std::string::npos) return false;
    char* end = nullptr;
    const std::string a = text.substr(0, comma), e = text.substr(comma + 1);
    sun.azimuthDeg = std::strtod(a.c_str(), &end);
    if (a.empty() || *end) return false;
    sun.elevationDeg = std::strtod(e.c_str(), &end);
    if (e.empty() || *end) return false;
    return std::isfinite(sun.azimuthDeg) && sun.elevationDeg > 0 && sun.elevationDeg <= 90;
}

// "1 light", "3 lights".
std::string count(size_t n, const std::string& one, const std::string& many = "") {
    return std::to_string(n) + " " + (n == 1 ? one : many.empty() ? one + "s" : many);
}

}  // namespace

int runImport(gltf::ImportOptions opt, const std::string& sun, std::ostream& out, std::ostream& err) {
    if (!sun.empty()) {
        gltf::SunAngles angles;
        if (!parseSun(sun, angles)) {
            err << "shadowcull: error: --sun '" << sun << "': AZIMUTH,ELEVATION in degrees expected, elevation in (0, 90]\n";
            return kExitUsage;
        }
        opt.sun = angles;
    }
    Expected<gltf::ImportReport> r = gltf::importScene(opt);
    if (!r) {
        err << "shadowcull: error: " << r.error().what() << "\n";
        return exitCodeFor(r.error().kind);
    }
    for (const Diagnostic& d : r->warnings) err << "shadowcull: warning: " << d.what() << "\n";
    out << "imported " << opt.scenePath << " into " << opt.outDir << ": " << count(r->models, "model") << " ("
        << count(r->triangles, "placed triangle") << ") in " << count(r->chunks, "chunk") << " of "
        << formatNumber(r->chunkSize) << " m, " << count(r->meshes, "unique mesh", "unique meshes") << " in models/, "
        << count(r->lights, "light") << " (" << r->sceneLights << " from the scene" << (opt.sun ? ", 1 from --sun" : "")
        << ")\n";
    out << "windows: " << r->layout << "\n";
    return kExitOk;
}

int runExport(const gltf::ExportOptions& opt, std::ostream& out, std::ostream& err) {
    if (Status s = refuseInputAsOutput(opt.outPath, {opt.scenePath, opt.resultsPath}, "--out"); !s) {
        err << "shadowcull: error: " << s.error().what() << "\n";
        return exitCodeFor(s.error().kind);
    }
    Expected<gltf::ExportReport> r = gltf::exportMasks(opt);
    if (!r) {
        err << "shadowcull: error: " << r.error().what() << "\n";
        return exitCodeFor(r.error().kind);
    }
    out << "wrote " << opt.outPath << ": masks of " << r->primitives << " primitives on " << r->nodes << " nodes, "
        << r->culledBits << " of " << r->bits << " bits 0 (shadow pass may skip), " << r->lights
        << " lights listed in extras.shadowcull.lights\n";
    if (r->unbakedNodes)
        err << "shadowcull: warning: " << r->unbakedNodes
            << " mesh nodes of the space are in chunks the results do not hold: they get no extras.shadowcull (an engine "
               "keeps all their shadows)\n";
    return r->unbakedNodes ? kExitSkippedInput : kExitOk;
}

}  // namespace shadowcull::cli
