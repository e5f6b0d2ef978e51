#include "cli/sweep.h"

#include "cli/output_guard.h"
#include "io/chunk_writer.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <sstream>

#include "cli/sweep_plot.h"
#include "io/scene_reader.h"
#include "util/format.h"

namespace shadowcull::cli {

namespace {

// (chunk, element, group, light) -> decision, for comparing bakes bit by bit.
using BitKey = std::tuple<int32_t, int32_t, int, int, int>;

std::map<BitKey, const Decision*> index(const BakeResult& r) {
    std::map<BitKey, const Decision*> m;
    for (const ChunkVerdicts& cv : r.chunks)
        for (size_t oi = 0; oi < cv.objects.size(); ++oi)
            for (int g = 0; g < cv.objects[oi].groupCount; ++g)
                for (int l = 0; l < cv.lightCount; ++l)
                    m[{cv.coord.x, cv.coord.z, cv.objects[oi].elementIndex, g, l}] = &cv.at(oi, g, l);
    return m;
}

std::string csvEscape(const std::string& s) {
    if (s.find_first_of(",\"") == std::string::npos) return s;
    std::string out = "\"";
    for (char c : s) out += c == '"' ? std::string("\"\"") : std::string(1, c);
    return out + "\"";
}

}  // namespace

std::vector<SweepSetting> analyticLadder(bool quick) {
    std::vector<SweepSetting> ladder;
    const std::vector<int> samples = quick ? std::vector<int>{16, 256} : std::vector<int>{16, 64, 256, 1024};
    for (bool geometry : {false, true})
        for (int n : samples) {
            std::string name = std::string(geometry ? "raycast+geometry" : "raycast") + ", " + std::to_string(n) + " samples";
            ladder.push_back({name, [n, geometry](const BakeOptions& base) {
                                  BakeOptions o = base;
                                  o.raycast.areaSamples = n;
                                  o.useGeometry = geometry;
                                  o.useGpu = false;
                                  return runBake(o);
                              }});
        }
    const std::vector<int> confirm = quick ? std::vector<int>{512} : std::vector<int>{512, 1024, 2048};
    for (int res : confirm)
        ladder.push_back({"raycast+geometry+gpu, 256 samples, " + std::to_string(res) + " px", [res](const BakeOptions& base) {
                              BakeOptions o = base;
                              o.gpuResolution = res;
                              return runBake(o);
                          }});
    return ladder;
}

std::vector<SweepSetting> gpuBaselineLadder(bool quick) {
    std::vector<SweepSetting> ladder;
    const std::vector<int> res = quick ? std::vector<int>{512, 1024} : std::vector<int>{512, 1024, 2048, 4096};
    for (int r : res)
        ladder.push_back({"original GPU method, " + std::to_string(r) + " px", [r](const BakeOptions& base) {
                              BakeOptions o = base;
                              o.gpuBaseline = true;
                              o.gpuResolution = r;
                              return runBake(o);
                          }});
    return ladder;
}

Expected<std::vector<SweepRow>> runSweep(const SweepOptions& options, const std::vector<SweepSetting>& ladder,
                                         BakeResult* referenceOut) {
    BakeOptions base;
    base.spaceDir = options.spaceDir;
    base.resourceRoot = options.resourceRoot;
    base.threads = options.threads;
    base.raycast.threads = options.threads;
    base.write = false;

    BakeOptions refOpt = base;
    refOpt.gpuResolution = 2048;
    refOpt.raycast.areaSamples = options.referenceSamples;
    refOpt.raycast.maxFeatureSamples = 4 * options.referenceSamples;
    // Outputs are checked before the hours of baking, against every file the space reads.
    {
        Expected<Space> space = loadSpace(options.spaceDir, options.resourceRoot);
        if (!space) return space.error();
        for (const auto& [path, option] : {std::pair{options.csvPath, "--csv"}, std::pair{options.svgPath, "--svg"}})
            if (Status s = refuseInputAsOutput(path, space->inputFiles(), option); !s) return s.error();
    }
    // Progress: a line before the reference and after each setting, so that a long sweep
    // shows where it is and how long the settings take.
    const auto start = std::chrono::steady_clock::now();
    auto say = [&](const std::string& line) {
        if (!options.progress) return;
        char t[32];
        std::snprintf(t, sizeof t, "%.1f s", std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
        *options.progress << "shadowcull: sweep: " << line << " (" << t << " elapsed)\n" << std::flush;
    };
    say("reference bake (every analytic stage, GPU confirmation at 2048 px, " +
        std::to_string(options.referenceSamples) + " samples), then " + std::to_string(ladder.size()) + " settings");
    Expected<BakeResult> reference = runBake(refOpt);
    if (!reference) return reference.error();
    const auto ref = index(*reference);
    say("reference done");

    std::vector<SweepRow> rows;
    for (const SweepSetting& s : ladder) {
        const auto t0 = std::chrono::steady_clock::now();
        Expected<BakeResult> r = s.bake(base);
        if (!r) return r.error();
        SweepRow row;
        row.setting = s.name;
        row.gl = r->gl;
        row.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
        say(std::to_string(rows.size() + 1) + "/" + std::to_string(ladder.size()) + " " + s.name + ": " +
            formatNumber(std::round(row.seconds * 100) / 100) + " s");
        for (const auto& [key, d] : index(*r)) {
            ++row.bits;
            const bool one = d->verdict != Verdict::Culled;
            (one ? row.written1 : row.written0)++;
            auto it = ref.find(key);
            if (it == ref.end()) continue;
            const Decision& rd = *it->second;
            if (rd.verdict == Verdict::Undecided) ++row.referenceUndecided;
            else if (rd.verdict == Verdict::Kept && !one) ++row.falseCulls;
            else if (rd.verdict == Verdict::Culled && one) ++row.falseKeeps;
        }
        rows.push_back(row);
    }
    if (referenceOut) *referenceOut = std::move(*reference);
    return rows;
}

int reportSweep(const SweepOptions& options, const std::vector<SweepRow>& rows, std::ostream& out, std::ostream& err) {
    out << "| setting | seconds | bits | written 0 | written 1 | false culls | false keeps | reference undecided |\n";
    out << "|---|---:|---:|---:|---:|---:|---:|---:|\n";
    char buf[64];
    for (const SweepRow& r : rows) {
        std::snprintf(buf, sizeof buf, "%.3f", r.seconds);
        out << "| " << r.setting << " | " << buf << " | " << r.bits << " | " << r.written0 << " | " << r.written1 << " | "
            << r.falseCulls << " | " << r.falseKeeps << " | " << r.referenceUndecided << " |\n";
    }
    out << "\nReference: every analytic stage (GPU confirmation at 2048 px) at " << options.referenceSamples
        << " samples per group. False cull: written 0 where the reference has a witness. False keep: written 1 where "
           "the reference proved 0. Bits the reference could not decide are counted apart.\n";
    for (const SweepRow& r : rows)
        if (!r.gl.empty()) {
            out << "OpenGL (GPU settings): " << r.gl << "\n";
            break;
        }
    // Written whole or not at all (a temporary beside it, renamed); a failure says why.
    if (!options.csvPath.empty()) {
        std::ostringstream csv;
        csv << "setting,seconds,bits,written0,written1,false_culls,false_keeps,reference_undecided\n";
        for (const SweepRow& r : rows) {
            std::snprintf(buf, sizeof buf, "%.6f", r.seconds);
            csv << csvEscape(r.setting) << "," << buf << "," << r.bits << "," << r.written0 << "," << r.written1 << ","
                << r.falseCulls << "," << r.falseKeeps << "," << r.referenceUndecided << "\n";
        }
        if (Status s = writeFileAtomic(options.csvPath, csv.str()); !s) {
            err << "shadowcull: error: " << s.error().what() << "; the sweep's figures are printed above\n";
            return kExitIo;
        }
    }
    if (!options.svgPath.empty())
        if (Status s = writeFileAtomic(options.svgPath, sweepSvg(rows)); !s) {
            err << "shadowcull: error: " << s.error().what() << "; the sweep's figures are printed above\n";
            return kExitIo;
        }
    return kExitOk;
}

}  // namespace shadowcull::cli
