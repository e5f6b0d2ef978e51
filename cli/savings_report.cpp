#include "cli/savings_report.h"

#include <algorithm>
#include <charconv>
#include <cstdio>
#include <tuple>
#include <ostream>
#include <set>

#include "cli/output_guard.h"
#include "cli/pipeline.h"
#include "cli/report.h"
#include "cli/savings_model.h"
#include "core/scene.h"
#include "io/chunk_writer.h"
#include "io/scene_reader.h"

namespace shadowcull::cli {

namespace savings_detail {

std::string objectLabel(const results::ObjectRecord& o) {
    return o.kind + " #" + std::to_string(o.element) + (o.uuid.empty() ? "" : " " + o.uuid);
}

std::string lightLabel(const results::LightRecord& L) {
    return "light " + std::to_string(L.index) + " '" + L.name + "' (" + L.type + ")";
}

std::string proofText(const results::BitRecord& b) {
    return b.verdict + ", stage " + b.stage + "; proof: " + b.reason;
}

std::string grouped(uint64_t n) {
    std::string s = std::to_string(n);
    for (int k = int(s.size()) - 3; k > 0; k -= 3) s.insert(size_t(k), ",");
    return s;
}

std::string percent(uint64_t a, uint64_t b) {
    if (b == 0) return "-";
    char buf[32];
    std::snprintf(buf, sizeof buf, "%.1f %%", 100.0 * double(a) / double(b));
    return buf;
}

}  // namespace savings_detail

using namespace savings_detail;
using results::LightSavingsRecord;
using results::WorkRecord;

namespace {

std::string pair(const WorkRecord& w) { return grouped(w.casters) + " | " + grouped(w.triangles); }

// Rows of cells, each column padded to its widest cell; the first column left-aligned, the
// others right-aligned, and "casters | triangles" pairs aligned on their bar.
std::string textTable(std::vector<std::vector<std::string>> rows, const std::string& indent) {
    const std::string bar = " | ";
    std::vector<size_t> left, right;  // per column: widest part before and after the bar
    for (const auto& r : rows)
        for (size_t c = 0; c < r.size(); ++c) {
            if (left.size() <= c) left.push_back(0), right.push_back(0);
            if (size_t k = r[c].find(bar); k != std::string::npos) {
                left[c] = std::max(left[c], k);
                right[c] = std::max(right[c], r[c].size() - k - bar.size());
            }
        }
    for (auto& r : rows)
        for (size_t c = 0; c < r.size(); ++c)
            if (size_t k = r[c].find(bar); k != std::string::npos) {
                const std::string a = r[c].substr(0, k), b = r[c].substr(k + bar.size());
                r[c] = std::string(left[c] - a.size(), ' ') + a + bar + std::string(right[c] - b.size(), ' ') + b;
            }
    std::vector<size_t> width;
    for (const auto& r : rows)
        for (size_t c = 0; c < r.size(); ++c) {
            if (width.size() <= c) width.push_back(0);
            width[c] = std::max(width[c], r[c].size());
        }
    std::string s;
    for (const auto& r : rows) {
        std::string line = indent;
        for (size_t c = 0; c < r.size(); ++c) {
            const std::string pad(width[c] - r[c].size(), ' ');
            line += c == 0 ? r[c] + pad : "  " + pad + r[c];
        }
        while (!line.empty() && line.back() == ' ') line.pop_back();
        s += line + "\n";
    }
    return s;
}

std::vector<std::string> savingsRow(std::string label, const LightSavingsRecord& s) {
    const WorkRecord left = savings::afterEngine(s);
    return {std::move(label),
            pair(s.all),
            pair(s.engineCulls),
            pair(left),
            pair(s.bakeCulls),
            percent(s.bakeCulls.triangles, left.triangles),
            pair(savings::afterBake(s)),
            pair(s.undecided)};
}

const std::vector<std::string> kHeader{"",          "all casters",     "(a) engine culls", "left after (a)",
                                       "(b) bake culls", "(b) of left", "left after (b)",   "undecided"};

// Where a results file and the space disagree: the results are of another space, or of
// this space before it changed.
struct Mismatch {
    std::string message;
};

// Lights that are not the space's at all (another count, name or type).
struct OtherSpace {
    std::string message;
};

// Shortest text that reads back as the same double: two settings that differ never print
// alike.
std::string exactNumber(double v) {
    char buf[32];
    const auto r = std::to_chars(buf, buf + sizeof buf, v);
    return std::string(buf, r.ptr);
}

std::string exactVec(const glm::dvec3& v) {
    return "(" + exactNumber(v.x) + ", " + exactNumber(v.y) + ", " + exactNumber(v.z) + ")";
}

// Every setting `baked` (a results file's light) records differently from `now` (the
// space's), as "range 60 m in the results, 25 m in SPACE/space.xml". The verdicts depend on
// each of them; one an older file does not record is not compared.
std::vector<std::string> settingChanges(const results::LightRecord& baked, const results::LightRecord& now,
                                        const std::string& spaceXml) {
    std::vector<std::string> changes;
    auto add = [&](const char* what, const std::string& a, const std::string& b) {
        changes.push_back(std::string(what) + " " + a + " in the results, " + b + " in " + spaceXml);
    };
    for (const auto& [what, a, b] : {std::tuple{"position", &baked.position, &now.position},
                                     std::tuple{"direction", &baked.direction, &now.direction}})
        if (*a && *b && **a != **b) add(what, exactVec(**a), exactVec(**b));
    for (const auto& [what, a, b, unit] :
         {std::tuple{"range", &baked.range, &now.range, " m"}, std::tuple{"cone angle", &baked.coneAngle, &now.coneAngle, " deg"},
          std::tuple{"bias", &baked.bias, &now.bias, " m"}, std::tuple{"slope bias", &baked.slopeBias, &now.slopeBias, " m"},
          std::tuple{"filter radius", &baked.filterRadius, &now.filterRadius, " m"},
          std::tuple{"normal bias", &baked.normalBias, &now.normalBias, " m"}})
        if (*a && *b && **a != **b) add(what, exactNumber(**a) + unit, exactNumber(**b) + unit);
    return changes;
}

// The results' lights against the space's: another count, name or type is another space
// (OtherSpace); another setting is this space before it changed (Mismatch), every changed
// setting named.
void checkLights(const std::vector<results::LightRecord>& baked, const std::vector<Light>& now, const std::string& spaceDir) {
    if (baked.size() != now.size())
        throw OtherSpace{"they have " + std::to_string(baked.size()) + " lights, " + spaceDir + " has " +
                         std::to_string(now.size())};
    std::string changed;
    for (size_t l = 0; l < baked.size(); ++l) {
        const results::LightRecord& a = baked[l];
        const results::LightRecord b = lightRecord(now[l], l);
        if (a.name != b.name || a.type != b.type)
            throw OtherSpace{"their light " + std::to_string(l + 1) + " is '" + a.name + "' (" + a.type + "), " + spaceDir +
                             " has '" + b.name + "' (" + b.type + ")"};
        for (const std::string& c : settingChanges(a, b, spaceDir + "/space.xml"))
            changed += (changed.empty() ? "" : "; ") + ("light " + std::to_string(l + 1) + " '" + b.name + "': " + c);
    }
    if (!changed.empty()) throw Mismatch{changed};
}

// Fills in every group's placed triangles from the space, checking that each chunk,
// object and group of the results is there.
void countTriangles(results::ResultsFile& file, const Space& space) {
    for (results::ChunkRecord& c : file.chunks) {
        const std::optional<ChunkCoord> coord = parseChunkName(c.chunk);
        auto it = coord ? space.chunks.find(*coord) : space.chunks.end();
        if (it == space.chunks.end()) throw Mismatch{"the space has no chunk " + c.chunk};
        const ChunkFile& cf = it->second;
        if (cf.objects.size() != c.objects.size())
            throw Mismatch{c.chunk + " holds " + std::to_string(cf.objects.size()) + " models and terrains, the results " +
                           std::to_string(c.objects.size())};
        for (size_t k = 0; k < c.objects.size(); ++k) {
            results::ObjectRecord& o = c.objects[k];
            const ChunkObject& so = cf.objects[k];
            const std::string kind = so.kind == ChunkObject::Kind::Terrain ? "terrain" : "model";
            if (o.element != so.elementIndex || o.kind != kind || o.uuid != so.uuid)
                throw Mismatch{c.chunk + " element " + std::to_string(k) + " is " + kind + " #" + std::to_string(so.elementIndex) +
                               (so.uuid.empty() ? "" : " " + so.uuid) + " in the space, " + objectLabel(o) + " in the results"};
            if (o.skipped) continue;
            std::vector<uint64_t> tris;
            if (so.kind == ChunkObject::Kind::Terrain && so.heightfield) {
                // Heightfield::toMesh: two triangles per cell, one group.
                const uint64_t cells = uint64_t(so.heightfield->n - 1);
                tris.assign(1, 2 * cells * cells);
            } else if (so.mesh) {
                tris.assign(so.mesh->groups.size(), 0);
                for (uint32_t g : so.mesh->triangleGroup)
                    if (g < tris.size()) ++tris[g];
            }
            if (tris.size() != o.groups.size())
                throw Mismatch{c.chunk + " " + objectLabel(o) + " has " + std::to_string(tris.size()) +
                               " groups in the space, " + std::to_string(o.groups.size()) + " in the results"};
            for (size_t g = 0; g < tris.size(); ++g) {
                if (o.groups[g].triangles && *o.groups[g].triangles != tris[g])
                    throw Mismatch{c.chunk + " " + objectLabel(o) + " group " + std::to_string(g) + " has " +
                                   std::to_string(tris[g]) + " triangles in the space, " +
                                   std::to_string(*o.groups[g].triangles) + " in the results"};
                o.groups[g].triangles = tris[g];
            }
        }
    }
}

// Per object and light, the triangles only the bake removed; most first (ties: file order).
std::vector<BigSaving> biggestSavings(const results::ResultsFile& file) {
    std::vector<BigSaving> v;
    for (size_t ci = 0; ci < file.chunks.size(); ++ci)
        for (size_t oi = 0; oi < file.chunks[ci].objects.size(); ++oi) {
            const results::ObjectRecord& o = file.chunks[ci].objects[oi];
            for (size_t l = 0; l < file.lights.size(); ++l) {
                BigSaving b{ci, oi, int(l) + 1, {}};
                for (const results::GroupRecord& g : o.groups)
                    if (l < g.lights.size() && savings::classify(g.lights[l].verdict, g.lights[l].stage, g.lights[l].reason) ==
                                                   savings::Why::BakeCulls)
                        b.removed += WorkRecord{1, g.triangles.value_or(0)};
                if (b.removed.casters) v.push_back(b);
            }
        }
    std::stable_sort(v.begin(), v.end(), [](const BigSaving& a, const BigSaving& b) { return a.removed.triangles > b.removed.triangles; });
    return v;
}

std::string textReport(const ReportModel& m) {
    const results::ResultsFile& f = m.file;
    std::vector<std::string> names;
    for (const results::LightRecord& L : f.lights) names.push_back(L.name);
    uint64_t groups = 0, tris = 0;
    for (const results::ChunkRecord& c : f.chunks)
        for (const results::ObjectRecord& o : c.objects)
            for (const results::GroupRecord& g : o.groups) ++groups, tris += g.triangles.value_or(0);
    std::string s = "report: " + m.resultsPath + " (space " + m.spaceDir + "): " + std::to_string(f.chunks.size()) +
                    " chunks, " + std::to_string(f.lights.size()) + " lights, " + grouped(groups) + " caster groups, " +
                    grouped(tris) + " placed triangles\n";
    s += formatSavingsTable(m.tally.world(), names);

    // Per chunk, every light together: a shadow pass per light, added up.
    s += "per chunk, all lights added up (casters | triangles):\n";
    std::vector<std::vector<std::string>> rows{kHeader};
    rows[0][0] = "chunk";
    for (size_t k = 0; k < f.chunks.size(); ++k) {
        LightSavingsRecord sum;
        for (const LightSavingsRecord& l : m.tally.chunks()[k]) {
            sum.all += l.all, sum.engineCulls += l.engineCulls, sum.bakeCulls += l.bakeCulls, sum.undecided += l.undecided;
        }
        rows.push_back(savingsRow(f.chunks[k].chunk, sum));
    }
    s += textTable(rows, "  ");

    const size_t n = std::min<size_t>(10, m.biggest.size());
    s += "biggest single savings beyond the engine's culling (of " + grouped(m.biggestPairs) + " object-light pairs):";
    s += m.biggest.empty() ? " none\n" : "\n";
    for (size_t k = 0; k < n; ++k) {
        const BigSaving& b = m.biggest[k];
        const results::ChunkRecord& c = f.chunks[b.chunk];
        const results::ObjectRecord& o = c.objects[b.object];
        s += "  " + grouped(b.removed.triangles) + " triangles (" + std::to_string(b.removed.casters) + (b.removed.casters == 1 ? " group): " : " groups): ") + c.chunk +
             " " + objectLabel(o) + ", " + lightLabel(f.lights[size_t(b.light - 1)]) + "\n";
        for (const results::GroupRecord& g : o.groups) {
            const results::BitRecord& bit = g.lights[size_t(b.light - 1)];
            if (savings::classify(bit.verdict, bit.stage, bit.reason) != savings::Why::BakeCulls) continue;
            s += "    group " + std::to_string(g.group) + " (" + grouped(g.triangles.value_or(0)) + " triangles): " + proofText(bit) + "\n";
        }
    }
    return s;
}

}  // namespace

std::string formatSavingsTable(const std::vector<LightSavingsRecord>& lights, const std::vector<std::string>& lightNames) {
    if (lights.empty()) return {};
    std::string s =
        "shadow pass per light, casters | triangles: (a) the engine's own culling (castsShadow false, range, cone), "
        "(b) only this bake:\n";
    std::vector<std::vector<std::string>> rows{kHeader};
    rows[0][0] = "light";
    for (const LightSavingsRecord& l : lights) {
        const size_t k = size_t(l.light - 1);
        rows.push_back(savingsRow(std::to_string(l.light) + (k < lightNames.size() ? " '" + lightNames[k] + "'" : ""), l));
    }
    return s + textTable(rows, "  ");
}

int runReport(const ReportOptions& opt, std::ostream& out, std::ostream& err) {
    auto fail = [&](const Error& e) {
        err << "shadowcull: error: " << e.what() << "\n";
        return exitCodeFor(e.kind);
    };
    if (Status s = refuseInputAsOutput(opt.htmlPath, {opt.resultsPath}, "--html"); !s) return fail(s.error());
    Expected<results::ResultsFile> file = results::readResultsFile(opt.resultsPath);
    if (!file) return fail(file.error());

    std::vector<ChunkCoord> coords;
    for (const results::ChunkRecord& c : file->chunks)
        if (std::optional<ChunkCoord> cc = parseChunkName(c.chunk)) coords.push_back(*cc);
    Expected<Space> space = loadSpace(opt.spaceDir, opt.resourceRoot, &coords);
    if (!space) return fail(space.error());
    if (Status s = refuseInputAsOutput(opt.htmlPath, space->inputFiles(), "--html"); !s) return fail(s.error());
    try {
        checkLights(file->lights, space->settings.lights, opt.spaceDir);
        countTriangles(*file, *space);
    } catch (const OtherSpace& e) {
        return fail(makeError(ErrorKind::BadInput, opt.resultsPath, 0, "results of another space: " + e.message));
    } catch (const Mismatch& e) {
        return fail(makeError(ErrorKind::BadInput, opt.resultsPath, 0,
                              "results of another space, or of " + opt.spaceDir + " before it changed (bake it again): " +
                                  e.message));
    }

    ReportModel m;
    m.spaceDir = opt.spaceDir;
    m.resultsPath = opt.resultsPath;
    m.chunkSize = space->settings.chunkSize;
    m.file = std::move(*file);
    m.tally = savings::tallyResults(m.file);
    m.biggest = biggestSavings(m.file);
    m.biggestPairs = m.biggest.size();
    if (m.biggest.size() > size_t(std::max(opt.top, 10))) m.biggest.resize(size_t(std::max(opt.top, 10)));
    out << textReport(m);
    if (!opt.htmlPath.empty()) {
        // Written whole or not at all (a temporary beside it, renamed); a failure says why.
        if (Status s = writeFileAtomic(opt.htmlPath, htmlReport(m)); !s) {
            err << "shadowcull: error: " << s.error().what() << "; the report is printed above\n";
            return kExitIo;
        }
        out << "wrote " << opt.htmlPath << "\n";
    }
    return kExitOk;
}

}  // namespace shadowcull::cli
