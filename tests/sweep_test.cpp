// sweep: the dense reference agrees with the known answers of the generated scenes, and
// the analytic ladder never culls falsely against it; CSV and SVG are written.

#include <algorithm>
#include <sstream>

#include <gtest/gtest.h>

#include "cli/sweep.h"
#include "tests/support/space_builder.h"
#include "tests/test_files.h"

using namespace shadowcull;
using namespace shadowcull::testing;
namespace fs = std::filesystem;

TEST(Sweep, ReferenceAgreesWithKnownAnswersAndLadderNeverCullsFalsely) {
    for (auto make : {cubeOnTerrain, twoFloatingCubes, rangeAndCone, thinRod, twoLightsMasks}) {
        SpaceBuilder b = make();
        fs::path dir = freshTestDir("-" + std::to_string(reinterpret_cast<uintptr_t>(make) % 100000));
        b.write((dir / "space").string());
        cli::SweepOptions opt;
        opt.spaceDir = (dir / "space").string();
        opt.referenceSamples = 1024;
        opt.quick = true;
        opt.csvPath = (dir / "sweep.csv").string();
        opt.svgPath = (dir / "sweep.svg").string();
        std::ostringstream progress;
        opt.progress = &progress;
        cli::BakeResult reference;
        Expected<std::vector<cli::SweepRow>> rows = cli::runSweep(opt, cli::analyticLadder(true), &reference);
        ASSERT_TRUE(rows) << rows.error().what();
        ASSERT_EQ(rows->size(), 5u);
        // A line before and after the reference, one per setting with its time.
        const std::string p = progress.str();
        EXPECT_EQ(std::count(p.begin(), p.end(), '\n'), 7) << p;
        EXPECT_NE(p.find("shadowcull: sweep: 5/5 raycast+geometry+gpu, 256 samples, 512 px: "), std::string::npos) << p;
        for (const cli::SweepRow& r : *rows) EXPECT_EQ(r.falseCulls, 0u) << r.setting;

        auto where = b.locateObjects();
        for (const KnownAnswer& a : b.expectations()) {
            const ObjectLocation& loc = where.at(a.key);
            for (const ChunkVerdicts& cv : reference.chunks) {
                if (chunkFileName(cv.coord) != loc.chunkFile) continue;
                for (size_t oi = 0; oi < cv.objects.size(); ++oi) {
                    if (cv.objects[oi].elementIndex != loc.elementIndex) continue;
                    for (int l = 0; l < cv.lightCount; ++l) {
                        const Verdict v = cv.at(oi, a.group, l).verdict;
                        if ((a.mask >> l) & 1u) EXPECT_EQ(v, Verdict::Kept) << a.key << " " << a.why;
                        else EXPECT_EQ(v, Verdict::Culled) << a.key << " light " << l + 1 << " " << a.why;
                    }
                }
            }
        }
        std::ostringstream out, err;
        EXPECT_EQ(cli::reportSweep(opt, *rows, out, err), 0) << err.str();
        EXPECT_NE(out.str().find("| raycast+geometry, 256 samples |"), std::string::npos) << out.str();
        const std::string csv = readText(opt.csvPath);
        EXPECT_EQ(std::count(csv.begin(), csv.end(), '\n'), 6);
        const std::string svg = readText(opt.svgPath);
        EXPECT_NE(svg.find("<svg"), std::string::npos);
        EXPECT_NE(svg.find("<circle"), std::string::npos);
    }
}
