// Per-stage figures on the bundled sample space and a generated world: bits each stage
// examined and proved, and its time per examined bit. Prints a Markdown table (quoted in
// docs/performance.md). All worlds are baked in one run, side by side.
//
//   stage_figures [WORK_DIR]

#include <cstdio>
#include <filesystem>
#include <functional>
#include <string>
#include <vector>

#include "cli/pipeline.h"
#include "cli/report.h"
#include "tests/support/sample_space.h"
#include "tests/support/space_builder.h"

using namespace shadowcull;
using namespace shadowcull::testing;
namespace fs = std::filesystem;

int main(int argc, char** argv) {
    const fs::path work = argc > 1 ? fs::path(argv[1]) : fs::temp_directory_path() / "shadowcull-stage-figures";
    fs::remove_all(work);
    const std::vector<std::pair<std::string, std::function<SpaceBuilder()>>> worlds = {
        {"sample (3x3 chunks)", sampleSpace},
        {"generated 10x10 chunks", [] { return manyChunks(10); }},
    };
    std::printf("| world | stage | bits examined | proved 0 | proved 1 | seconds | us per examined bit | rays | exact tests | GPU passes |\n");
    std::printf("|---|---|---:|---:|---:|---:|---:|---:|---:|---:|\n");
    for (size_t w = 0; w < worlds.size(); ++w) {
        const fs::path dir = work / std::to_string(w);
        worlds[w].second().write(dir.string());
        cli::BakeOptions opt;
        opt.spaceDir = dir.string();
        opt.write = false;
        Expected<cli::BakeResult> r = cli::runBake(opt);
        if (!r) {
            std::fprintf(stderr, "stage_figures: %s\n", r.error().what().c_str());
            return 1;
        }
        for (const cli::StageTiming& st : r->stages) {
            const StageStats& s = st.stats;
            const double perBit = s.bitsExamined ? 1e6 * s.seconds / double(s.bitsExamined) : 0.0;
            std::printf("| %s | %s | %llu | %llu | %llu | %.3f | %.1f | %llu | %llu | %llu |\n", worlds[w].first.c_str(),
                        st.name.c_str(), (unsigned long long)s.bitsExamined, (unsigned long long)s.provedCulled,
                        (unsigned long long)s.provedKept, s.seconds, perBit, (unsigned long long)s.raysCast,
                        (unsigned long long)s.exactTests, (unsigned long long)s.gpuPasses);
        }
        const cli::BitCounts c = cli::countBits(*r);
        std::printf("| %s | **all** | %llu bits | %llu | %llu | %.3f | | | undecided %llu | |\n", worlds[w].first.c_str(),
                    (unsigned long long)c.bits, (unsigned long long)c.culled, (unsigned long long)c.provedKept,
                    r->totalSeconds, (unsigned long long)c.undecided);
    }
    fs::remove_all(work);
    return 0;
}
