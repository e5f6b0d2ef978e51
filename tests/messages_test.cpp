// What a person reads (issue 15): every bad input gives one message with the file, the line
// and the value, in the user's words, and says what the tool did; option errors give the
// accepted values; --help (golden) lists defaults and exit codes; --version names the
// libraries; libpng never writes to stderr itself.

#include <filesystem>
#include <regex>
#include <set>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "io/png_write.h"
#include "tests/support/gl_available.h"
#include "tests/support/sample_space.h"
#include "tests/support/space_builder.h"
#include "tests/test_files.h"

using namespace shadowcull;
using namespace shadowcull::testing;
namespace fs = std::filesystem;

namespace {

// space.xml with one sun whose values the case sets; line numbers are fixed:
// 6 <direction>, 7 <bias>, 8 <slopeBias>, 9 <filterRadius>.
std::string sunSpace(const std::string& direction, const std::string& bias = "0", const std::string& slopeBias = "0",
                     const std::string& filterRadius = "0") {
    return "<space>\n"
           "  <chunkSize> 100 </chunkSize>\n"
           "  <light>\n"
           "    <name> sun </name>\n"
           "    <type> directional </type>\n"
           "    <direction> " + direction + " </direction>\n"
           "    <bias> " + bias + " </bias>\n"
           "    <slopeBias> " + slopeBias + " </slopeBias>\n"
           "    <filterRadius> " + filterRadius + " </filterRadius>\n"
           "  </light>\n"
           "</space>\n";
}

// space.xml with one point light 'lamp': 5 <position>, 6 <range>.
std::string lampSpace(const std::string& position, const std::string& range) {
    return "<space>\n"
           "  <light>\n"
           "    <name> lamp </name>\n"
           "    <type> point </type>\n"
           "    <position> " + position + " </position>\n"
           "    <range> " + range + " </range>\n"
           "  </light>\n"
           "</space>\n";
}

struct MessageCase {
    const char* name;
    std::function<void(const fs::path&)> spoil;  // spoils a written cubeOnTerrain space
    int exitCode;
    std::vector<std::string> says;     // each must appear in stderr
    std::vector<std::string> never;    // none may appear (the raw text this replaced)
};

// `bake` of a spoiled copy of cubeOnTerrain; the message names file, line and value.
TEST(Messages, BadInputSaysFileLineValueAndWhatWasDone) {
    const std::vector<MessageCase> cases = {
        {"misnamed end tag",
         [](const fs::path& d) { writeText(d / "00000000o.chunk", "<chunk>\n  <model>\n    <fi>\n  </model>\n</chunk>\n"); },
         3,
         {"00000000o.chunk:3: not well-formed XML: the element <fi> that starts here is closed by an end tag of another name",
          "no chunk file was changed"},
         {"XML_ERROR", "ErrorID", "Line number="}},
        {"cut-off element",
         [](const fs::path& d) { writeText(d / "00000000o.chunk", "<chunk>\n  <model>\n  <fi\n"); },
         3,
         {"00000000o.chunk:3: not well-formed XML: the element <fi> is cut off or not closed"},
         {"XML_ERROR", "ErrorID"}},
        {"empty chunk file", [](const fs::path& d) { writeText(d / "00000000o.chunk", ""); }, 3,
         {"00000000o.chunk: the file is empty: no XML element in it"}, {"XML_ERROR"}},
        {"chunk that is a directory", [](const fs::path& d) { fs::create_directory(d / "00010000o.chunk"); }, 3,
         {"00010000o.chunk: chunk file is a directory, not a regular file", "no chunk file was changed"},
         {"malformed XML", "FILE_READ_ERROR"}},
        {"huge direction is a direction", [](const fs::path& d) { writeText(d / "space.xml", sunSpace("1e308 -1e308 1e308")); },
         0, {}, {"zero", "error"}},
        {"direction beyond a double",
         [](const fs::path& d) { writeText(d / "space.xml", sunSpace("1e309 -1 0")); }, 3,
         {"space.xml:6: <direction> value 1e309 is too large to be a number here (more than 1.8e308)"}, {"non-finite"}},
        {"direction too small to tell from zero",
         [](const fs::path& d) { writeText(d / "space.xml", sunSpace("1e-330 0 0")); }, 3,
         {"space.xml:6: light 'sun': <direction> '1e-330 0 0' has no length"}, {}},
        {"negative bias", [](const fs::path& d) { writeText(d / "space.xml", sunSpace("0 -1 0", "-0.25")); }, 3,
         {"space.xml:7: light 'sun': <bias> is -0.25; it must not be negative"}, {"bias, slopeBias and filterRadius"}},
        {"negative slope bias", [](const fs::path& d) { writeText(d / "space.xml", sunSpace("0 -1 0", "0", "-2")); }, 3,
         {"space.xml:8: light 'sun': <slopeBias> is -2; it must not be negative"}, {}},
        {"negative filter radius", [](const fs::path& d) { writeText(d / "space.xml", sunSpace("0 -1 0", "0", "0", "-3")); }, 3,
         {"space.xml:9: light 'sun': <filterRadius> is -3; it must not be negative"}, {}},
        {"negative terrain tolerance",
         [](const fs::path& d) { writeText(d / "space.xml", "<space>\n  <terrainTolerance> -1 </terrainTolerance>\n</space>\n"); }, 3,
         {"space.xml:2: <terrainTolerance> is -1; it must not be negative"}, {}},
        // Issue 35: values printed with the digits that tell them from the bound, and the
        // interval an element accepts (a range must be above 0).
        {"position just beyond the world",
         [](const fs::path& d) { writeText(d / "space.xml", lampSpace("1.0000001e10 0 0", "25")); }, 3,
         {"space.xml:5: <position> value 1.0000001e+10 is outside the accepted range [-1e+10, 1e+10]"}, {"value 1e+10 is"}},
        {"range beyond the limit", [](const fs::path& d) { writeText(d / "space.xml", lampSpace("0 5 0", "-2e5")); }, 3,
         {"space.xml:6: <range> value -200000 is outside the accepted range (0, 100000]"}, {"[-100000"}},
        {"chunk size just beyond the limit",
         [](const fs::path& d) { writeText(d / "space.xml", "<space>\n  <chunkSize> 100000.5 </chunkSize>\n</space>\n"); }, 3,
         {"space.xml:2: <chunkSize> 100000.5 is outside the accepted range [1, 100000] m"}, {}},
        {"bad neighbours attribute",
         [](const fs::path& d) { writeText(d / "space.xml", "<space>\n\n  <neighbours left=\"x\"/>\n</space>\n"); }, 3,
         {"space.xml:3: <neighbours left=\"x\"> must be a whole number from 0 to 64"}, {}},
        {"OBJ missing",
         [](const fs::path& d) { fs::remove(d / "models" / "cube.obj"); }, 1,
         {"models/cube.obj: cannot open OBJ file: no such file or directory; every object using it is skipped", "00000000o.chunk:",
          "object skipped (its <shadow> is left as it was)"},
         {}},
        {"OBJ is a directory",
         [](const fs::path& d) {
             fs::remove(d / "models" / "cube.obj");
             fs::create_directory(d / "models" / "cube.obj");
         },
         1, {"models/cube.obj: OBJ file is a directory, not a regular file", "object skipped"}, {}},
        {"space.xml but no chunk files",
         [](const fs::path& d) {
             for (const auto& e : fs::directory_iterator(d))
                 if (e.path().extension() == ".chunk") fs::remove(e.path());
         },
         3, {"the space has a space.xml but no chunk files (XXXXZZZZo.chunk beside it): nothing to bake"}, {}},
        {"chunk files with other names only",
         [](const fs::path& d) { fs::rename(d / "00000000o.chunk", d / "village.chunk"); }, 3,
         {"the space has no chunk files: 1 file(s) end in .chunk (village.chunk), but none is named XXXXZZZZo.chunk"}, {}},
    };
    for (const MessageCase& c : cases) {
        SCOPED_TRACE(c.name);
        fs::path dir = freshTestDir("-" + std::to_string(&c - cases.data()));
        cubeOnTerrain().write((dir / "space").string());
        c.spoil(dir / "space");
        const int rc = runCli("bake '" + (dir / "space").string() + "' --dry-run --quiet", dir / "o", dir / "e");
        const std::string err = readText(dir / "e");
        EXPECT_EQ(rc, c.exitCode) << err;
        for (const std::string& s : c.says) EXPECT_NE(err.find(s), std::string::npos) << "wanted: " << s << "\ngot: " << err;
        for (const std::string& s : c.never) EXPECT_EQ(err.find(s), std::string::npos) << "unwanted: " << s << "\ngot: " << err;
    }
}

struct OptionCase {
    std::string args;  // after the space for bake/render, as the user types them
    std::string says;
};

// Options outside their range: the accepted values and the value given, never CLI11's
// "not in range 0.000000 to 179769313486..."; exit 2 and where to read more.
TEST(Messages, OptionErrorsGiveTheRangeAndTheValue) {
    fs::path dir = freshTestDir();
    cubeOnTerrain().write((dir / "space").string());
    const std::string space = "'" + (dir / "space").string() + "'";
    const std::vector<OptionCase> cases = {
        {"render " + space + " --chunk 00000000o --light 0 --out x.png", "shadowcull: error: --light: must be 1 or more (got 0)"},
        {"render " + space + " --chunk 00000000o --light two --out x.png", "--light: must be a whole number, 1 or more (got 'two')"},
        {"render " + space + " --chunk 00000000o --out x.png", "--light is required"},
        {"preview " + space + " --chunk 00000000o --light 1 --pcf-radius 9", "--pcf-radius: must be from 0 to 8 (got 9)"},
        {"bake " + space + " --threads -1", "shadowcull: error: --threads: must be 0 or more (got -1)"},
        {"bake " + space + " --samples 0", "--samples: must be from 1 to 1048576 (got 0)"},
        {"bake " + space + " --gpu-resolution 8", "--gpu-resolution: must be from 16 to 16384 (got 8)"},
        {"bake " + space + " --method fast", "--method: must be analytic or gpu (got 'fast')"},
        {"bake " + space + " --stages raycast,volumes", "must be raycast, geometry or gpu (got 'volumes')"},
        {"bake '" + (dir / "nospace").string() + "'", "no such directory: " + (dir / "nospace").string()},
        {"explain " + space + " 00000000o 0 --light 0", "--light: must be 1 or more (got 0)"},
        {"import '" + (dir / "space").string() + "' out", "is a directory, not a file"},
        {"import '" + (dir / "space" / "space.xml").string() + "' out --bias -1", "--bias: must be from 0 to 100000 (got -1)"},
        {"bake " + space + " --gpu-resolution 1e3", "--gpu-resolution: must be a whole number from 16 to 16384 (got '1e3')"},
        {"import '" + (dir / "space" / "space.xml").string() + "' out --scene abc", "--scene: must be a whole number, 0 or more (got 'abc')"},
        {"import '" + (dir / "space" / "space.xml").string() + "' out --chunk-size -5", "--chunk-size: must be from 1 to 100000 (got -5)"},
        {"", "shadowcull: error: no command given (bake, sweep, diff, explain, check, render, preview, import, export, report, plan or merge)"},
        // Issue 35: an unknown command was "no command given".
        {"frobnicate", "shadowcull: error: unknown command 'frobnicate' (the nearest is 'bake'); the commands are bake, sweep, "
                       "diff, explain, check, render, preview, import, export, report, plan or merge\n"},
        {"bkae " + space, "shadowcull: error: unknown command 'bkae' (did you mean 'bake'?); the commands are bake, sweep,"},
    };
    for (const OptionCase& c : cases) {
        const int rc = runCli(c.args, dir / "o", dir / "e");
        const std::string err = readText(dir / "e");
        EXPECT_EQ(rc, 2) << c.args << "\n" << err;
        EXPECT_NE(err.find(c.says), std::string::npos) << c.args << "\nwanted: " << c.says << "\ngot: " << err;
        EXPECT_EQ(err.find("179769313486"), std::string::npos) << err;
        EXPECT_NE(err.find("--help' for the options"), std::string::npos) << err;
    }
    // The command being read is named in the pointer to its help.
    runCli("bake " + space + " --threads -1", dir / "o", dir / "e");
    EXPECT_NE(readText(dir / "e").find("Run 'shadowcull bake --help'"), std::string::npos) << readText(dir / "e");
}

// Reports that cannot be written say why (and that the figures were printed), and a light
// the space does not have is named with the space's lights.
TEST(Messages, ReportsAndLightsSayWhyAndWhat) {
    const fs::path dir = freshTestDir();
    const std::string sample = std::string(SHADOWCULL_SOURCE_DIR) + "/data/sample";
    ASSERT_EQ(runCli("bake '" + sample + "' --dry-run --quiet --stages raycast --results '" + (dir / "r.json").string() + "'",
                     dir / "o", dir / "e"),
              0)
        << readText(dir / "e");
    const std::string missing = (dir / "no-such-dir" / "report.html").string();
    EXPECT_EQ(runCli("diff '" + (dir / "r.json").string() + "' '" + (dir / "r.json").string() + "' --html '" + missing + "'",
                     dir / "o", dir / "e"),
              4);
    std::string err = readText(dir / "e");
    EXPECT_NE(err.find("report.html"), std::string::npos) << err;
    EXPECT_NE(err.find("No such file or directory"), std::string::npos) << err;
    EXPECT_NE(err.find("the report is printed above"), std::string::npos) << err;
    EXPECT_EQ(runCli("render '" + sample + "' --chunk 00000000o --light 7 --out '" + (dir / "x.png").string() + "'", dir / "o",
                     dir / "e"),
              2);
    err = readText(dir / "e");
    EXPECT_NE(err.find("--light 7: " + sample + "/space.xml has 3 lights (1 'sun', 2 'lamp', 3 'torch'); nothing was written"),
              std::string::npos)
        << err;
    EXPECT_FALSE(fs::exists(dir / "x.png"));
}

// docs/format.md's "Accepted ranges" (the table and the paragraph after it) gives every bound
// of core/limits.h: the <neighbours> limit was missing. A bound added to limits.h without
// its line in the docs fails here.
TEST(Messages, AcceptedRangesGiveEveryLimit) {
    const std::string limits = readText(fs::path(SHADOWCULL_SOURCE_DIR) / "core" / "limits.h");
    const std::string docs = readText(fs::path(SHADOWCULL_SOURCE_DIR) / "docs" / "format.md");
    const size_t from = docs.find("## Accepted ranges");
    ASSERT_NE(from, std::string::npos);
    const std::string section = docs.substr(from, docs.find("\n## ", from + 1) - from);
    // Every number the section writes (1e5, 1e-10, 16,385, 64), as a value.
    std::set<double> written;
    const std::regex number(R"((\d+(?:,\d{3})*(?:\.\d+)?(?:e[-+]?\d+)?))");
    for (auto it = std::sregex_iterator(section.begin(), section.end(), number); it != std::sregex_iterator(); ++it) {
        std::string text = (*it)[1];
        text.erase(std::remove(text.begin(), text.end(), ','), text.end());
        written.insert(std::stod(text));
    }
    const std::regex constant(R"(constexpr\s+(?:double|int)\s+(k\w+)\s*=\s*([^;]+);)");
    int constants = 0;
    for (auto it = std::sregex_iterator(limits.begin(), limits.end(), constant); it != std::sregex_iterator(); ++it, ++constants)
        EXPECT_TRUE(written.count(std::stod((*it)[2]))) << (*it)[1] << " = " << (*it)[2] << " is not in docs/format.md's accepted ranges";
    EXPECT_GE(constants, 8);
}

// --help of every command, compared with tests/golden/help.txt: defaults (samples 256,
// resolution 1024, ...) and exit codes. After changing an option, regenerate with
//   SHADOWCULL_UPDATE_GOLDEN=1 build/bin/shadowcull_tests --gtest_filter='Messages.HelpMatchesGolden'
// and read the diff.
TEST(Messages, HelpMatchesGolden) {
    fs::path dir = freshTestDir();
    std::string all;
    for (const std::string command : {"", "bake", "sweep", "diff", "explain", "check", "render", "preview", "import", "export", "report", "merge"}) {
        ASSERT_EQ(runCli(command + " --help", dir / "o", dir / "e"), 0) << command << readText(dir / "e");
        EXPECT_EQ(readText(dir / "e"), "");
        all += "$ shadowcull " + command + (command.empty() ? "" : " ") + "--help\n" + readText(dir / "o") + "\n";
    }
    EXPECT_NE(all.find("Exit codes: 0 baked"), std::string::npos);
    EXPECT_NE(all.find("=256"), std::string::npos) << "the default of --samples";
    EXPECT_NE(all.find("=1024"), std::string::npos) << "the default of --gpu-resolution";
    expectGolden("help.txt", all);
}

TEST(Messages, VersionNamesTheLibraries) {
    fs::path dir = freshTestDir();
    ASSERT_EQ(runCli("--version", dir / "o", dir / "e"), 0) << readText(dir / "e");
    const std::string out = readText(dir / "o");
    for (const char* s : {"shadowcull 0.", "Embree 3.", "CGAL 5.", "oneTBB ", "libpng 1.", "tinyxml2 ", "OpenGL: "})
        EXPECT_NE(out.find(s), std::string::npos) << s << " in\n" << out;
    // Without a context the line says why, and --version still succeeds.
    ASSERT_EQ(runCli("--version", dir / "o", dir / "e"), 0);
    ASSERT_EQ(std::system(("SHADOWCULL_NO_GL=1 " + std::string(SHADOWCULL_BIN) + " --version > '" + (dir / "o").string() + "'").c_str()), 0);
    EXPECT_NE(readText(dir / "o").find("OpenGL: none ("), std::string::npos) << readText(dir / "o");
}

// libpng's default handlers print "libpng error: ..." on stderr; the writer's say nothing
// there and return the reason as the tool's message, with no half-written file left.
TEST(Messages, PngWriterKeepsLibpngOffStderr) {
    fs::path dir = freshTestDir();
    const int wide = 1000001;  // beyond libpng's default user width limit (1e6): IHDR is refused
    std::vector<unsigned char> rgb(size_t(wide) * 3, 0);
    ::testing::internal::CaptureStderr();
    Status s = writeRgbPng((dir / "wide.png").string(), wide, 1, rgb);
    const std::string stderrText = ::testing::internal::GetCapturedStderr();
    ASSERT_FALSE(s);
    EXPECT_EQ(stderrText, "");
    EXPECT_NE(s.error().what().find("wide.png: cannot encode the picture as PNG (libpng: "), std::string::npos) << s.error().what();
    EXPECT_NE(s.error().what().find("no picture written"), std::string::npos);
    EXPECT_FALSE(fs::exists(dir / "wide.png"));
    EXPECT_FALSE(lastPngWarnings().empty()) << "libpng's warning is kept, not printed";

    Status missing = writeRgbPng((dir / "no" / "such" / "dir.png").string(), 1, 1, {0, 0, 0});
    ASSERT_FALSE(missing);
    EXPECT_NE(missing.error().what().find("dir.png: cannot write the picture: no such file or directory"), std::string::npos)
        << missing.error().what();
    ASSERT_TRUE(writeRgbPng((dir / "ok.png").string(), 2, 1, {255, 0, 0, 0, 255, 0})) ;
    EXPECT_EQ(readText(dir / "ok.png").substr(1, 3), "PNG");
}

// The summary says which effects the bake simulated (semantics.md), as --results does.
TEST(Messages, SummaryNamesTheSimulatedEffects) {
    fs::path dir = freshTestDir();
    rangeAndCone().write((dir / "space").string());
    ASSERT_EQ(runCli("bake '" + (dir / "space").string() + "' --dry-run --stages raycast,geometry", dir / "o", dir / "e"), 0)
        << readText(dir / "e");
    const std::string out = readText(dir / "o");
    EXPECT_NE(out.find("simulated:\n"), std::string::npos) << out;
    EXPECT_NE(out.find("  terrain rule (receivers deeper than"), std::string::npos) << out;
    EXPECT_NE(out.find("light 1 'lamp': range 10 m"), std::string::npos) << out;
    EXPECT_NE(out.find("light 2 'torch': cone 30 deg"), std::string::npos) << out;
}

// --method gpu says, on the terminal, that its masks are not conservative and how to check.
TEST(Messages, GpuMethodSaysItIsNotConservative) {
    REQUIRE_GL();
    fs::path dir = freshTestDir();
    cubeOnTerrain().write((dir / "space").string());
    ASSERT_EQ(runCli("bake '" + (dir / "space").string() + "' --dry-run --quiet --method gpu --gpu-resolution 64", dir / "o",
                     dir / "e"),
              0)
        << readText(dir / "e");
    const std::string err = readText(dir / "e");
    EXPECT_NE(err.find("shadowcull: note: --method gpu is the original stencil + occlusion-query method: its masks are NOT "
                       "conservative"),
              std::string::npos)
        << err;
    EXPECT_NE(err.find("'shadowcull check " + (dir / "space").string() + "' lists every such bit"), std::string::npos) << err;
    // How many bits check would flag: the GPU method's 0s that have a witness (the sample's
    // count agrees with check's false culls).
    EXPECT_NE(err.find(" of the bits it wrote 0 here have a witness ray"), std::string::npos) << err;
}

TEST(Messages, GpuMethodCountsTheCullsCheckWouldFlag) {
    REQUIRE_GL();
    fs::path dir = freshTestDir();
    sampleSpace().write((dir / "space").string());
    ASSERT_EQ(runCli("check '" + (dir / "space").string() + "' --gpu-resolution 256 --pictures '" + (dir / "pics").string() + "'",
                     dir / "o", dir / "e"),
              1)
        << readText(dir / "e");
    const std::string checked = readText(dir / "o");
    const size_t at = checked.find(" false culls");
    ASSERT_NE(at, std::string::npos) << checked;
    const std::string count = checked.substr(checked.rfind(' ', at - 1) + 1, at - checked.rfind(' ', at - 1) - 1);
    ASSERT_EQ(runCli("bake '" + (dir / "space").string() + "' --dry-run --quiet --method gpu --gpu-resolution 256", dir / "o",
                     dir / "e"),
              0)
        << readText(dir / "e");
    EXPECT_NE(readText(dir / "e").find("; " + count + " of the bits it wrote 0 here have a witness ray"), std::string::npos)
        << "check: " << checked.substr(0, at + 12) << "\nbake: " << readText(dir / "e");
}

// A dry run clears what a killed bake left (under the output lock), and says so.
TEST(Messages, DryRunClearsStaleTemporaries) {
    fs::path dir = freshTestDir();
    cubeOnTerrain().write((dir / "space").string());
    const auto before = chunkTexts(dir / "space");
    writeText(dir / "space" / ".00000000o.chunk.shadowcull-tmp", "<chunk> half");
    ASSERT_EQ(runCli("bake '" + (dir / "space").string() + "' --dry-run --quiet", dir / "o", dir / "e"), 0) << readText(dir / "e");
    EXPECT_FALSE(fs::exists(dir / "space" / ".00000000o.chunk.shadowcull-tmp"));
    EXPECT_NE(readText(dir / "e").find("note: removed 1 temporary file(s) a killed bake left in"), std::string::npos)
        << readText(dir / "e");
    EXPECT_EQ(chunkTexts(dir / "space"), before);
}

}  // namespace
