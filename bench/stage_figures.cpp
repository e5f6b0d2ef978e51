// Per-stage figures on the bundled sample space and a generated world: bits each stage
// examined and proved, and its time per examined bit. Prints a Markdown table (quoted in
// docs/performance.md). All worlds are baked in one run, side by side. Also the sample
// with one rock (models/rock_c.obj, 128 triangles, 7 instances) replaced by a scanned,
// jagged 4 m x 4 m sheet of 80,000 triangles (issue 13: its geometry stage within 10x of
// the plain sample's), and that ratio.
//
//   stage_figures [WORK_DIR]

#include <cstdio>
#include <filesystem>
#include <fstream>
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

// A 200 x 200-quad open grid, 2 cm cells, heights 0 / 3 cm in a checkerboard (a scanned,
// jagged surface), material "stone" as the rock it replaces.
void writeJaggedRock(const fs::path& obj) {
    std::ofstream f(obj, std::ios::binary);
    f << "mtllib rock_c.mtl\nusemtl stone\n";
    const int n = 200;
    char line[96];
    for (int j = 0; j <= n; ++j)
        for (int i = 0; i <= n; ++i) {
            std::snprintf(line, sizeof line, "v %.6f %.6f %.6f\n", -2.0 + 0.02 * i, ((i + j) % 2) * 0.03, -2.0 + 0.02 * j);
            f << line;
        }
    for (int j = 0; j < n; ++j)
        for (int i = 0; i < n; ++i) {
            const int a = j * (n + 1) + i + 1, b = a + 1, c = a + n + 1, d = c + 1;
            f << "f " << a << " " << c << " " << b << "\nf " << b << " " << c << " " << d << "\n";
        }
}

int main(int argc, char** argv) {
    const fs::path work = argc > 1 ? fs::path(argv[1]) : fs::temp_directory_path() / "shadowcull-stage-figures";
    fs::remove_all(work);
    struct World {
        std::string name;
        std::function<SpaceBuilder()> make;
        std::function<void(const fs::path&)> edit;  // after writing, or nothing
    };
    const std::vector<World> worlds = {
        {"sample (3x3 chunks)", sampleSpace, {}},
        {"generated 10x10 chunks", [] { return manyChunks(10); }, {}},
        {"sample, rock_c an 80k-triangle jagged sheet", sampleSpace,
         [](const fs::path& dir) { writeJaggedRock(dir / "models" / "rock_c.obj"); }},
    };
    double geometrySeconds[3] = {0, 0, 0};
    std::printf("| world | stage | bits examined | proved 0 | proved 1 | seconds | us per examined bit | rays | exact tests | GPU passes |\n");
    std::printf("|---|---|---:|---:|---:|---:|---:|---:|---:|---:|\n");
    for (size_t w = 0; w < worlds.size(); ++w) {
        const fs::path dir = work / std::to_string(w);
        worlds[w].make().write(dir.string());
        if (worlds[w].edit) worlds[w].edit(dir);
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
            if (st.name == "geometry") geometrySeconds[w] = s.seconds;
            const double perBit = s.bitsExamined ? 1e6 * s.seconds / double(s.bitsExamined) : 0.0;
            std::printf("| %s | %s | %llu | %llu | %llu | %.3f | %.1f | %llu | %llu | %llu |\n", worlds[w].name.c_str(),
                        st.name.c_str(), (unsigned long long)s.bitsExamined, (unsigned long long)s.provedCulled,
                        (unsigned long long)s.provedKept, s.seconds, perBit, (unsigned long long)s.raysCast,
                        (unsigned long long)s.exactTests, (unsigned long long)s.gpuPasses);
        }
        const cli::BitCounts c = cli::countBits(*r);
        std::printf("| %s | **all** | %llu bits | %llu | %llu | %.3f | | | undecided %llu | |\n", worlds[w].name.c_str(),
                    (unsigned long long)c.bits, (unsigned long long)c.culled, (unsigned long long)c.provedKept,
                    r->totalSeconds, (unsigned long long)c.undecided);
    }
    std::printf("\nGeometry stage, sample with the jagged rock against the plain sample (one run): %.3f s / %.3f s = %.1fx "
                "(issue 13: at most 10x)\n",
                geometrySeconds[2], geometrySeconds[0], geometrySeconds[0] > 0 ? geometrySeconds[2] / geometrySeconds[0] : 0.0);
    fs::remove_all(work);
    return 0;
}
