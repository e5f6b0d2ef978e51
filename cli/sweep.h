// `shadowcull sweep SPACE`: what accuracy costs in time. Bakes the space at a ladder of
// settings and compares each with a dense reference bake: false culls (written 0 where the
// reference has a witness), false keeps (written 1 where the reference proved 0), and
// bits the reference itself could not decide, counted apart. Prints a table, writes CSV
// and an SVG plot (false keeps against seconds).
#pragma once

#include <functional>
#include <ostream>
#include <string>
#include <vector>

#include "cli/pipeline.h"

namespace shadowcull::cli {

struct SweepOptions {
    std::string spaceDir, resourceRoot;
    std::string csvPath, svgPath;  // empty: not written
    int threads = 0;
    int referenceSamples = 4096;   // area samples of the reference bake
    bool quick = false;            // a shorter ladder (tests)
    std::ostream* progress = nullptr;  // a line per bake of the sweep (the command: stderr)
};

struct SweepRow {
    std::string setting;
    double seconds = 0;
    uint64_t bits = 0, written0 = 0, written1 = 0;
    uint64_t falseCulls = 0;       // 0 where the reference has a witness
    uint64_t falseKeeps = 0;       // 1 where the reference proved 0
    uint64_t referenceUndecided = 0;  // bits the reference left undecided (neither counted)
    std::string gl;                   // the OpenGL context its GPU stages ran on, "" if none ran
};

// A setting of the ladder: a name and a function that bakes the space with it.
struct SweepSetting {
    std::string name;
    std::function<Expected<BakeResult>(const BakeOptions& base)> bake;
};

// The analytic settings: samples per group x stages (raycast; + geometry; + GPU
// confirmation at several resolutions).
std::vector<SweepSetting> analyticLadder(bool quick);
// The original GPU method at 512..4096 px (needs an OpenGL context).
std::vector<SweepSetting> gpuBaselineLadder(bool quick);

// Runs every setting and the reference; rows in ladder order. The reference bake is moved
// into `reference` when given.
Expected<std::vector<SweepRow>> runSweep(const SweepOptions& options, const std::vector<SweepSetting>& ladder,
                                         BakeResult* reference = nullptr);

// Writes the table (Markdown), and the CSV and SVG when asked. Returns the exit code.
int reportSweep(const SweepOptions& options, const std::vector<SweepRow>& rows, std::ostream& out, std::ostream& err);

}  // namespace shadowcull::cli
