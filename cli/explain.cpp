#include "cli/explain.h"

#include <algorithm>
#include <cctype>
#include <cstdio>
#include <filesystem>
#include <ostream>

#include <glm/geometric.hpp>

#include "cli/pipeline.h"
#include "cli/report.h"

namespace shadowcull::cli {

namespace {

namespace fs = std::filesystem;

std::string num(double v) {
    if (v == 0) v = 0;  // no "-0"
    char buf[32];
    std::snprintf(buf, sizeof buf, "%.6g", v);
    return buf;
}

std::string vecText(const glm::dvec3& v) { return "(" + num(v.x) + ", " + num(v.y) + ", " + num(v.z) + ")"; }

std::string lower(std::string s) {
    std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return char(std::tolower(c)); });
    return s;
}

std::string objectName(const ObjectVerdicts& ov) {
    return std::string(ov.terrain ? "terrain" : "model") + " #" + std::to_string(ov.elementIndex) +
           (ov.uuid.empty() ? "" : " " + ov.uuid);
}

// The chunk files of the space, sorted (for "no such chunk" messages).
std::vector<std::string> chunkFiles(const std::string& spaceDir) {
    std::vector<std::string> names;
    std::error_code ec;
    for (const fs::directory_entry& e : fs::directory_iterator(spaceDir, ec))
        if (parseChunkName(e.path().filename().string())) names.push_back(e.path().filename().string());
    std::sort(names.begin(), names.end());
    return names;
}

void explainBit(const Decision& d, std::ostream& out) {
    switch (d.verdict) {
        case Verdict::Undecided:
            out << "undecided, kept as 1 (no stage could decide)\n";
            if (d.notes().empty()) out << "    no stage recorded what it saw\n";
            for (const StageNote& n : d.notes()) out << "    " << n.stage << ": " << n.text << "\n";
            return;
        case Verdict::Culled: out << "culled, stage " << d.stage << "\n    proof: " << d.reason() << "\n"; return;
        case Verdict::Kept: break;
    }
    out << "kept, stage " << d.stage << "\n";
    if (!d.witness()) {
        out << "    " << (d.reason().empty() ? std::string_view("no witness recorded") : d.reason()) << "\n";
        return;
    }
    const Witness& w = *d.witness();
    const glm::dvec3 dir = glm::length(w.wsDirection) > 0 ? glm::normalize(w.wsDirection) : w.wsDirection;
    out << "    witness ray: origin " << vecText(w.wsOrigin) << ", direction " << vecText(w.wsDirection) << "\n"
        << "      p " << vecText(w.wsP) << ": first hit on the group, lit\n"
        << "      q " << vecText(w.wsQ) << ": on " << w.receiver << "\n"
        << "      depth gap |q-p| along the ray: " << num(glm::dot(w.wsQ - w.wsP, dir)) << " m\n";
}

}  // namespace

int runExplain(const ExplainOptions& opt, std::ostream& out, std::ostream& err) {
    // Check the chunk first, so that a typo gets the list of chunks rather than a bake error.
    const std::optional<ChunkCoord> coord = parseChunkArgument(opt.chunk);
    if (!coord) {
        err << "shadowcull: error: " << opt.chunk << ": not a chunk name (XXXXZZZZo or XXXXZZZZo.chunk, 16-bit hex)\n";
        return kExitBadInput;
    }
    const std::vector<std::string> chunks = chunkFiles(opt.spaceDir);
    if (std::none_of(chunks.begin(), chunks.end(), [&](const std::string& n) { return parseChunkName(n) == coord; })) {
        err << "shadowcull: error: " << opt.spaceDir << ": no chunk " << chunkFileName(*coord)
            << " in the space; chunks:";
        for (const std::string& n : chunks) err << " " << n;
        err << (chunks.empty() ? " none\n" : "\n");
        return kExitBadInput;
    }

    BakeOptions bo;
    bo.spaceDir = opt.spaceDir;
    bo.resourceRoot = opt.resourceRoot;
    bo.chunkNames = {chunkFileName(*coord)};
    bo.write = false;
    Expected<BakeResult> r = runBake(bo);
    if (!r) {
        err << "shadowcull: error: " << r.error().what() << "\n";
        return exitCodeFor(r.error().kind);
    }
    const std::vector<Light>& lights = r->settings.lights;
    if (opt.light < 0 || opt.light > int(lights.size())) {
        err << "shadowcull: error: no light " << opt.light << " (the space has " << lights.size()
            << " lights, numbered from 1)\n";
        return kExitUsage;
    }
    const ChunkVerdicts& cv = r->chunks.at(0);

    // OBJECT: a uuid (any case), else an element index.
    const ObjectVerdicts* found = nullptr;
    for (const ObjectVerdicts& ov : cv.objects)
        if (!ov.uuid.empty() && lower(ov.uuid) == lower(opt.object)) found = found ? found : &ov;
    const bool isIndex =
        !opt.object.empty() && opt.object.size() < 9 &&
        std::all_of(opt.object.begin(), opt.object.end(), [](unsigned char c) { return std::isdigit(c); });
    if (!found && isIndex)
        for (const ObjectVerdicts& ov : cv.objects)
            if (ov.elementIndex == std::stoi(opt.object)) found = &ov;
    if (!found) {
        err << "shadowcull: error: " << chunkFileName(cv.coord) << " has no object '" << opt.object
            << "' (give a uuid or an element index); its objects:\n";
        for (const ObjectVerdicts& ov : cv.objects) err << "  " << objectName(ov) << "\n";
        if (cv.objects.empty()) err << "  none\n";
        return kExitBadInput;
    }
    const ObjectVerdicts& ov = *found;
    const size_t oi = size_t(found - cv.objects.data());

    auto count = [](size_t n, const char* what) { return std::to_string(n) + " " + what + (n == 1 ? "" : "s"); };
    out << chunkFileName(cv.coord) << ", " << objectName(ov) << ": " << count(size_t(ov.groupCount), "group") << ", "
        << count(lights.size(), "light") << "\n";
    if (ov.windowObject < 0) {
        out << "skipped by the bake (see the warnings): no verdicts, its <shadow> is left as it was\n";
    } else {
        uint32_t mask = 0;
        for (int g = 0; g < ov.groupCount; ++g) mask |= cv.groupMask(oi, g);
        out << "mask " << mask << "\n";
        for (int g = 0; g < ov.groupCount; ++g) {
            out << "group " << g << " (mask " << cv.groupMask(oi, g) << ")\n";
            for (int l = 0; l < cv.lightCount; ++l) {
                if (opt.light && l + 1 != opt.light) continue;
                const Decision& d = cv.at(oi, g, l);
                const Light& L = lights[size_t(l)];
                out << "  light " << l + 1 << " '" << L.name << "' (" << lightTypeName(L.type) << "): bit "
                    << (d.verdict == Verdict::Culled ? 0 : 1) << ", ";
                explainBit(d, out);
            }
        }
    }
    out << "simulated for this chunk:" << (cv.simulated.empty() ? " nothing beyond the plain definition\n" : "\n");
    for (const std::string& s : cv.simulated) out << "  " << s << "\n";
    if (auto plan = r->plans.find(cv.coord); plan != r->plans.end()) out << formatWindow(plan->second, r->settings);
    out << "warnings:" << (r->diagnostics.empty() ? " none\n" : "\n");
    for (const Diagnostic& d : r->diagnostics) out << "  " << d.what() << "\n";
    return kExitOk;
}

}  // namespace shadowcull::cli
