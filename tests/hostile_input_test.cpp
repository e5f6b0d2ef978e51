// Issue 11: bad input never crashes the bake, never silently changes a mask, and never
// loses an edit. Each case is a defect found on a copy of data/sample; every one of them
// crashed, hung, or wrote a wrong mask before it was fixed.

#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdlib>
#include <functional>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "cli/pipeline.h"
#include "tests/test_files.h"

using namespace shadowcull;
using namespace shadowcull::testing;
namespace fs = std::filesystem;

namespace {

const fs::path kSample = fs::path(SHADOWCULL_SOURCE_DIR) / "data" / "sample";

fs::path copySample(const fs::path& dir) {
    fs::copy(kSample, dir / "space", fs::copy_options::recursive);
    return dir / "space";
}

// Replaces the first match of `from` in `file` by `to` (the test fails when none).
void replaceIn(const fs::path& file, const std::string& from, const std::string& to) {
    std::string text = readText(file);
    const size_t at = text.find(from);
    ASSERT_NE(at, std::string::npos) << from << " in " << file;
    text.replace(at, from.size(), to);
    writeText(file, text);
}

// The first transform row `row` (e.g. "row3") of a chunk file, element and all.
std::string firstRow(const fs::path& chunk, const std::string& row) {
    const std::string text = readText(chunk);
    const size_t a = text.find("<" + row + ">"), b = text.find("</" + row + ">");
    return text.substr(a, b + row.size() + 3 - a);
}

struct HostileCase {
    const char* name;
    std::function<void(const fs::path& space)> spoil;
    std::string args;  // after "bake SPACE"
    int exitCode;
    std::string message;  // in stderr
    bool skipsObjects = true;  // exit 1: some object is skipped (else only warned about)
};

}  // namespace

TEST(HostileInput, EveryCaseIsReportedWithFileAndLineNeverACrashOrAHang) {
    const std::vector<HostileCase> cases = {
        // Silent wrong masks before: the leaves baked opaque.
        {"missing mtllib", [](const fs::path& s) { fs::remove(s / "models/tree.mtl"); }, "", 1,
         "models/tree.obj:2: mtllib 'tree.mtl': cannot open"},
        {"binary mtllib", [](const fs::path& s) { writeText(s / "models/tree.mtl", std::string("newmtl a\0\x7f", 10)); }, "", 1,
         "models/tree.mtl:1: binary data"},
        {"undefined material", [](const fs::path& s) { replaceIn(s / "models/tree.mtl", "newmtl leaves", "newmtl leaf"); }, "",
         1, "material 'leaves' is not defined"},
        {"two names for one chunk", [](const fs::path& s) { fs::copy(s / "0000ffffo.chunk", s / "0000FFFFo.chunk"); }, "", 3,
         "names the same chunk as"},
        // Crashes before (Embree assertion, SIGFPE in GMP).
        {"translation 7e9",
         [](const fs::path& s) { replaceIn(s / "00000000o.chunk", firstRow(s / "00000000o.chunk", "row3"), "<row3> 7e9 0 0 </row3>"); },
         "", 1, "<row3> value 7e+09 is outside the accepted range"},
        {"matrix entry -1e308",
         [](const fs::path& s) { replaceIn(s / "00000000o.chunk", firstRow(s / "00000000o.chunk", "row0"), "<row0> -1e308 0 0 </row0>"); },
         "--stages geometry", 1, "<row0> value -1e+308 is outside the accepted range"},
        {"chunk size 1e20", [](const fs::path& s) { replaceIn(s / "space.xml", "<chunkSize> 100 ", "<chunkSize> 1e20 "); }, "", 3,
         "space.xml:2: <chunkSize> 1e+20 is outside the accepted range"},
        {"vertex 2e18", [](const fs::path& s) { writeText(s / "models/rock_a.obj", "v 0 0 0\nv 2e18 0 0\nv 0 1 0\nf 1 2 3\n"); },
         "", 1, "models/rock_a.obj:2: number '2e18' is outside the accepted range"},
        // Stopped the whole bake with "Embree error 3", naming a chunk.
        {"empty OBJ", [](const fs::path& s) { writeText(s / "models/rock_a.obj", ""); }, "", 1,
         "models/rock_a.obj: the mesh has no triangles"},
        {"vertices without faces", [](const fs::path& s) { writeText(s / "models/rock_a.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\n"); }, "",
         1, "models/rock_a.obj: the mesh has no triangles (3 vertices)"},
        {"binary junk", [](const fs::path& s) { writeText(s / "models/rock_a.obj", std::string("\x89\x01\x00\xff junk\n", 10)); },
         "", 1, "models/rock_a.obj:1: binary data"},
        // A 92 s bake, a bake blocked forever.
        {"chunk size 1e-300", [](const fs::path& s) { replaceIn(s / "space.xml", "<chunkSize> 100 ", "<chunkSize> 1e-300 "); }, "",
         3, "<chunkSize> 1e-300 is outside the accepted range"},
        {"FIFO named like a chunk", [](const fs::path& s) { ASSERT_EQ(::mkfifo((s / "00050005o.chunk").c_str(), 0644), 0); }, "",
         3, "00050005o.chunk: chunk file is a FIFO, not a regular file"},
        // About a hundred warnings before, one error now.
        {"missing resource root", [](const fs::path&) {}, "--res /nonexistent-shadowcull-root", 3,
         "resource root /nonexistent-shadowcull-root cannot be used"},
        {"resource root in a symlink loop",
         [](const fs::path& s) {
             fs::create_symlink(s / "loop-b", s / "loop-a");
             fs::create_symlink(s / "loop-a", s / "loop-b");
         },
         "--res loop-a", 3, "Too many levels of symbolic links"},
        // Issue 35: accepted silently before. Hex numbers (strtod's "0x10" is 16 m).
        {"hex filter radius", [](const fs::path& s) { replaceIn(s / "space.xml", "<filterRadius> 0 ", "<filterRadius> 0x10 "); }, "",
         3, "space.xml:11: <filterRadius> value '0x10' is not a decimal number"},
        {"hex float in a transform",
         [](const fs::path& s) { replaceIn(s / "00000000o.chunk", firstRow(s / "00000000o.chunk", "row3"), "<row3> 0x1.8p1 0 0 </row3>"); },
         "", 1, "<row3> value '0x1.8p1' is not a decimal number"},
        {"hex terrain height", [](const fs::path& s) { replaceIn(s / "terrain/00000000.terrain", "<maxHeight> 20 ", "<maxHeight> 0x14 "); },
         "", 1, "00000000.terrain:4: <maxHeight> value '0x14' is not a decimal number"},
        // Duplicates: the last won for <direction>, <chunkSize>, <transform>, <resource>; the
        // first for <row3> and a terrain's <maxHeight>.
        {"a light's direction twice",
         [](const fs::path& s) { replaceIn(s / "space.xml", "<direction> 0.3 -1 0.2 </direction>", "<direction> 0.3 -1 0.2 </direction><direction> 0 -1 0 </direction>"); },
         "", 3, "space.xml:8: <direction> given again in <light> (first at line 8)"},
        {"chunk size twice", [](const fs::path& s) { replaceIn(s / "space.xml", "<chunkSize> 100 </chunkSize>", "<chunkSize> 100 </chunkSize>\n  <chunkSize> 50 </chunkSize>"); },
         "", 3, "space.xml:3: <chunkSize> given again in <space> (first at line 2)"},
        {"a model's resource twice",
         [](const fs::path& s) { replaceIn(s / "00000000o.chunk", "<uuid>", "<resource> models/rock_b.obj </resource>\n    <uuid>"); },
         "", 1, "<resource> given again in <model>"},
        {"row3 twice",
         [](const fs::path& s) { replaceIn(s / "00000000o.chunk", "</row3>", "</row3>\n      <row3> 5 0 5 </row3>"); },
         "", 1, "<row3> given again in <transform>"},
        {"a terrain's maxHeight twice",
         [](const fs::path& s) { replaceIn(s / "terrain/00000000.terrain", "<maxHeight> 20 </maxHeight>", "<maxHeight> 20 </maxHeight><maxHeight> 40 </maxHeight>"); },
         "", 1, "<maxHeight> given again in <terrain>"},
        // A second root element, a stray end tag (chunk files refused both already).
        {"space.xml with a second root", [](const fs::path& s) { writeText(s / "space.xml", readText(s / "space.xml") + "<space/>\n"); },
         "", 3, "second root element <space>"},
        {"a terrain with a stray end tag",
         [](const fs::path& s) { writeText(s / "terrain/00000000.terrain", readText(s / "terrain/00000000.terrain") + "</terrain>\n"); },
         "", 1, "end tag </terrain> without a start tag"},
        // Unknown elements were ignored without a word: a misspelt filter radius baked as 0.
        {"a misspelt filterRadius in a light",
         [](const fs::path& s) { replaceIn(s / "space.xml", "<filterRadius> 0 </filterRadius>", "<filterRadious> 0.3 </filterRadious>"); },
         "", 3, "space.xml:11: unknown element <filterRadious> in <light> (did you mean <filterRadius>?)"},
        {"an engine's element in a light",
         [](const fs::path& s) { replaceIn(s / "space.xml", "<bias> 0.05 </bias>", "<bias> 0.05 </bias> <intensity> 3 </intensity>"); },
         "", 3, "space.xml:9: unknown element <intensity> in <light> (<light> holds <name>, <type>"},
        {"a misspelt light", [](const fs::path& s) { replaceIn(s / "space.xml", "<light>", "<ligth>"); replaceIn(s / "space.xml", "</light>", "</ligth>"); },
         "", 3, "space.xml:5: unknown element <ligth> in <space> (did you mean <light>?)"},
        {"an engine's namespaced elements", [](const fs::path& s) {
             replaceIn(s / "space.xml", "<bias> 0.05 </bias>", "<bias> 0.05 </bias> <engine:intensity> 3 </engine:intensity>");
             replaceIn(s / "space.xml", "</space>", "<engine:sky> dusk </engine:sky>\n</space>");
             replaceIn(s / "models/sign.model", "</model>", "<engine:lod> 2 </engine:lod>\n</model>");
             replaceIn(s / "terrain/00000000.terrain", "</terrain>", "<engine:grass> 1 </engine:grass>\n</terrain>");
             replaceIn(s / "00000000o.chunk", "</row3>", "</row3>\n      <engine:pivot> 0 0 0 </engine:pivot>");
         }, "", 0, ""},
        {"an unknown element in a .model", [](const fs::path& s) { replaceIn(s / "models/sign.model", "</model>", "  <lod> 2 </lod>\n</model>"); },
         "", 1, "models/sign.model:4: unknown element <lod> in <model> (<model> holds <visual> and <primitiveGroup>; another "
         "program's data may go in a namespaced element, e.g. <engine:lod>); ignored", false},
        {"a misspelt primitiveGroup in a .model",
         [](const fs::path& s) { replaceIn(s / "models/sign.model", "<primitiveGroup index", "<primitivegroup index"); }, "", 1,
         "models/sign.model:3: unknown element <primitivegroup> in <model> (did you mean <primitiveGroup>?); every object using it is skipped"},
        {"a misspelt attribute of a primitiveGroup",
         [](const fs::path& s) { replaceIn(s / "models/sign.model", "doubleSided=", "doublesided="); }, "", 1,
         "models/sign.model:3: unknown attribute doublesided= of <primitiveGroup> (did you mean doubleSided=?); every object "
         "using it is skipped"},
        {"a misspelt neighbours attribute",
         [](const fs::path& s) { replaceIn(s / "space.xml", "<neighbours> 1 </neighbours>", "<neighbours lfet=\"2\"/>"); }, "", 3,
         "space.xml:3: unknown attribute lfet= of <neighbours> (did you mean left=?)"},
        {"an unknown element in a .terrain",
         [](const fs::path& s) { replaceIn(s / "terrain/00000000.terrain", "</terrain>", "  <grass> 1 </grass>\n</terrain>"); }, "", 1,
         "terrain/00000000.terrain:5: unknown element <grass> in <terrain>", false},
        {"an unknown element in a transform",
         [](const fs::path& s) { replaceIn(s / "00000000o.chunk", "</row3>", "</row3>\n      <scale> 2 2 2 </scale>"); }, "", 1,
         "00000000o.chunk:14: unknown element <scale> in <transform> (<transform> holds <row0>, <row1>, <row2> and <row3>"},
    };
    for (const HostileCase& c : cases) {
        SCOPED_TRACE(c.name);
        const fs::path dir = freshTestDir("-" + std::to_string(&c - cases.data()));
        const fs::path space = copySample(dir);
        c.spoil(space);
        std::string args = c.args;
        if (args == "--res loop-a") args = "--res '" + (space / "loop-a").string() + "'";
        const auto before = chunkTexts(space);
        const int rc = runCli("bake '" + space.string() + "' --quiet --results '" + (dir / "r.json").string() + "' " + args,
                              dir / "out", dir / "err");
        const std::string err = readText(dir / "err");
        EXPECT_EQ(rc, c.exitCode) << err;
        EXPECT_NE(err.find(c.message), std::string::npos) << err;
        if (c.exitCode == 3) {
            EXPECT_EQ(chunkTexts(space), before) << "a stopped bake writes nothing";
            EXPECT_NE(err.find("no chunk file was changed"), std::string::npos) << err;
            EXPECT_EQ(std::count(err.begin(), err.end(), '\n'), 1) << "one error, not a warning per object: " << err;
        } else if (c.exitCode == 0) {
            EXPECT_EQ(err, "");
        } else {
            // The objects of the bad resource are skipped: no verdicts, <shadow> untouched.
            const nlohmann::json r = nlohmann::json::parse(readText(dir / "r.json"));
            int skipped = 0;
            for (const auto& ch : r["chunks"])
                for (const auto& o : ch["objects"]) skipped += o.value("skipped", false);
            if (c.skipsObjects) EXPECT_GT(skipped, 0);
            else EXPECT_EQ(skipped, 0);
            EXPECT_FALSE(r["warnings"].empty());
        }
    }
}

// --results, render --out, diff --html and sweep --csv named an input and overwrote it.
TEST(HostileInput, OutputsNeverReplaceInputs) {
    const fs::path dir = freshTestDir();
    const fs::path space = copySample(dir);
    const auto before = chunkTexts(space);
    const std::string xml = readText(space / "space.xml");
    const std::string s = "'" + space.string() + "'";
    const std::string chunk = "'" + (space / "00000000o.chunk").string() + "'";
    fs::create_symlink(space / "models/rock_a.obj", dir / "link.obj");
    for (const auto& [args, option] : std::vector<std::pair<std::string, std::string>>{
             {"bake " + s + " --results " + chunk, "--results"},
             {"bake " + s + " --results '" + (dir / "link.obj").string() + "'", "--results"},  // a link to a mesh
             {"bake " + s + " --results '" + (space / "models/tree.mtl").string() + "'", "--results"},
             {"render " + s + " --chunk 00000000o --light 1 --out " + chunk, "--out"},
             {"diff " + s + " " + s + " --html '" + (space / "space.xml").string() + "'", "--html"},
             {"diff " + s + " " + s + " --json " + chunk, "--json"},
             {"sweep " + s + " --quick --no-gpu --csv '" + (space / "terrain/00000000.png").string() + "'", "--csv"}}) {
        SCOPED_TRACE(args);
        EXPECT_EQ(runCli(args, dir / "out", dir / "err"), 3) << readText(dir / "err");
        EXPECT_NE(readText(dir / "err").find(option + " names an input of this command"), std::string::npos)
            << readText(dir / "err");
    }
    EXPECT_EQ(chunkTexts(space), before);
    EXPECT_EQ(readText(space / "space.xml"), xml);
    EXPECT_EQ(readText(space / "models/rock_a.obj"), readText(kSample / "models/rock_a.obj"));
    EXPECT_EQ(readText(space / "models/tree.mtl"), readText(kSample / "models/tree.mtl"));
}

// After `--results /nonexistent/r.json` every chunk file had been rewritten and the
// message named none.
TEST(HostileInput, ResultsThatCannotBeWrittenStopTheBakeBeforeAnyChunkIsWritten) {
    const fs::path dir = freshTestDir();
    const fs::path space = copySample(dir);
    const auto before = chunkTexts(space);
    EXPECT_EQ(runCli("bake '" + space.string() + "' --quiet --results /nonexistent-shadowcull/r.json", dir / "out", dir / "err"),
              4);
    EXPECT_NE(readText(dir / "err").find("no chunk file was changed"), std::string::npos) << readText(dir / "err");
    EXPECT_EQ(chunkTexts(space), before);
    // Results inside an --out directory the bake creates (the README's sample command):
    // the directory is made before the results are checked writable.
    const fs::path out = dir / "new-out";
    EXPECT_EQ(runCli("bake '" + space.string() + "' --quiet --stages raycast --out '" + out.string() + "' --results '" +
                         (out / "r.json").string() + "'",
                     dir / "out", dir / "err"),
              0)
        << readText(dir / "err");
    EXPECT_TRUE(fs::exists(out / "r.json"));
    EXPECT_EQ(chunkTexts(out).size(), before.size());
}

// With --resume chunks are committed as they are baked: a failure after some of them names
// exactly those (it said none before).
TEST(HostileInput, AFailureAfterResumeCommitsNamesEveryUpdatedChunk) {
    const fs::path dir = freshTestDir();
    const fs::path space = copySample(dir);
    const auto before = chunkTexts(space);
    fs::create_directories(dir / "results");
    cli::BakeOptions opt;
    opt.spaceDir = space.string();
    opt.resume = true;
    opt.useGpu = false;
    opt.resultsPath = (dir / "results" / "r.json").string();
    // The results directory disappears while the bake runs (a full or unmounted disk).
    Expected<cli::BakeResult> r = cli::runBake(opt, [&](const cli::BakeProgress& p) {
        if (p.done == 4) fs::remove_all(dir / "results");
    });
    ASSERT_FALSE(r);
    EXPECT_EQ(r.error().kind, ErrorKind::Io);
    const std::string message = r.error().what();
    const auto after = chunkTexts(space);
    int updated = 0;
    for (const auto& [name, text] : after) {
        const bool changed = text != before.at(name);
        updated += changed;
        EXPECT_EQ(message.find(" " + name) != std::string::npos, changed) << name << ": " << message;
    }
    EXPECT_EQ(updated, 9);
    EXPECT_NE(message.find("9 chunk file(s) were updated before it"), std::string::npos) << message;
}

// An edit made to a chunk file while a bake ran was lost: the file had been staged earlier
// and was renamed over the edit at the end.
TEST(HostileInput, AnEditMadeDuringTheBakeIsNeverOverwritten) {
    for (const bool resume : {false, true}) {
        SCOPED_TRACE(resume ? "--resume" : "staged");
        const fs::path dir = freshTestDir(resume ? "-resume" : "");
        const fs::path space = copySample(dir);
        cli::BakeOptions opt;
        opt.spaceDir = space.string();
        opt.resume = resume;
        opt.useGpu = false;
        const std::string edit = "<!-- someone's edit -->\n";
        // After the first chunk (in grid order ffffffffo) is baked: edit it (staged or, with
        // --resume, committed already) and a chunk still to come (00010001o).
        const std::string first = "ffffffffo.chunk", later = "00010001o.chunk";
        Expected<cli::BakeResult> r = cli::runBake(opt, [&](const cli::BakeProgress& p) {
            if (p.done != 1) return;
            for (const std::string& name : {first, later}) writeText(space / name, readText(space / name) + edit);
        });
        ASSERT_TRUE(r) << r.error().what();
        EXPECT_EQ(readText(space / later), readText(kSample / later) + edit) << "not baked over";
        EXPECT_NE(readText(space / first).find(edit), std::string::npos);
        std::string warnings;
        for (const Diagnostic& d : r->diagnostics) warnings += d.what() + "\n";
        EXPECT_NE(warnings.find(later + ": changed on disk while the bake ran"), std::string::npos) << warnings;
        // Staged, the first chunk's edit is caught before its rename; with --resume it was
        // committed before the edit, so the edit simply stays.
        EXPECT_EQ(warnings.find(first + ": changed on disk") != std::string::npos, !resume) << warnings;
        EXPECT_EQ(r->chunksWritten, resume ? 8 : 7);
    }
}

// A second bake on the same space deleted the first one's temporaries and made it fail
// after the work. Now it waits for nothing: it stops at once, with exit code 6.
TEST(HostileInput, ASecondBakeOfTheSameOutputStopsAtOnce) {
    const fs::path dir = freshTestDir();
    const fs::path space = copySample(dir);
    cli::BakeOptions opt;
    opt.spaceDir = space.string();
    opt.useGpu = false;
    int second = -1;
    Expected<cli::BakeResult> r = cli::runBake(opt, [&](const cli::BakeProgress& p) {
        if (p.done == 2) second = runCli("bake '" + space.string() + "' --quiet", dir / "out", dir / "err");
    });
    ASSERT_TRUE(r) << r.error().what();
    EXPECT_EQ(r->chunksWritten, 9);
    EXPECT_EQ(second, 6);
    EXPECT_NE(readText(dir / "err").find("another shadowcull bake is writing"), std::string::npos) << readText(dir / "err");
    EXPECT_NE(readText(dir / "err").find("(process " + std::to_string(::getpid()) + ")"), std::string::npos)
        << readText(dir / "err");
    // Once the first bake is done, the lock is free again (a kill frees it too: flock).
    EXPECT_EQ(runCli("bake '" + space.string() + "' --quiet --stages raycast", dir / "out", dir / "err"), 0)
        << readText(dir / "err");
}

// A 0444 chunk file was replaced, a symlinked one became a regular file, the owner was lost.
TEST(HostileInput, ReadOnlySymlinkedAndForeignOwnedChunkFiles) {
    const fs::path dir = freshTestDir();
    const fs::path space = copySample(dir);
    const std::string bake = "bake '" + space.string() + "' --quiet --stages raycast";
    auto modeOf = [](const fs::path& p) {
        struct stat st {};
        ::stat(p.c_str(), &st);
        return st.st_mode & 07777;
    };
    const fs::path ro = space / "00000000o.chunk";
    ::chmod(ro.c_str(), 0444);
    EXPECT_EQ(runCli(bake, dir / "out", dir / "err"), 1);
    EXPECT_NE(readText(dir / "err").find("00000000o.chunk: the chunk file is read-only (mode 0444); not baked"), std::string::npos)
        << readText(dir / "err");
    EXPECT_EQ(readText(ro), readText(kSample / "00000000o.chunk"));
    EXPECT_NE(readText(space / "00010000o.chunk").find("<shadow>"), std::string::npos) << "the others are baked";
    EXPECT_EQ(runCli(bake + " --force-write", dir / "out", dir / "err"), 0) << readText(dir / "err");
    EXPECT_NE(readText(ro).find("<shadow>"), std::string::npos);
    EXPECT_EQ(modeOf(ro), 0444u) << "the mode is kept";
    ::chmod(ro.c_str(), 0644);

    // A symlinked chunk: the link stays a link, its target gets the masks.
    const fs::path real = dir / "elsewhere" / "real.chunk";
    fs::create_directories(real.parent_path());
    fs::copy_file(kSample / "00010000o.chunk", real);
    fs::remove(space / "00010000o.chunk");
    fs::create_symlink(real, space / "00010000o.chunk");
    writeText(dir / "elsewhere" / ".real.chunk.shadowcull-tmp", "left by a killed bake");
    EXPECT_EQ(runCli(bake, dir / "out", dir / "err"), 0) << readText(dir / "err");
    EXPECT_FALSE(fs::exists(dir / "elsewhere" / ".real.chunk.shadowcull-tmp")) << "cleared beside the target too";
    EXPECT_TRUE(fs::is_symlink(space / "00010000o.chunk"));
    EXPECT_NE(readText(real).find("<shadow>"), std::string::npos);
    EXPECT_FALSE(fs::exists(space / ".00010000o.chunk.shadowcull-tmp"));

    if (::geteuid() == 0) {
        // Root can keep any owner; a user who cannot is refused unless --force-write.
        const fs::path foreign = space / "00010001o.chunk";
        ASSERT_EQ(::chown(foreign.c_str(), 12345, 23456), 0);
        writeText(foreign, readText(kSample / "00010001o.chunk"));
        EXPECT_EQ(runCli(bake, dir / "out", dir / "err"), 0) << readText(dir / "err");
        struct stat st {};
        ASSERT_EQ(::stat(foreign.c_str(), &st), 0);
        EXPECT_EQ(st.st_uid, 12345u);
        EXPECT_EQ(st.st_gid, 23456u);
        EXPECT_NE(readText(foreign).find("<shadow>"), std::string::npos);
    }
}

// The same as a user who is not root (run through setpriv when the tests run as root): a
// chunk file this user may not write, or whose owner this user could not keep, is not
// replaced unless --force-write (a rename would give it to this user).
TEST(HostileInput, AsAnotherUserFilesItCannotKeepAreRefused) {
    if (::geteuid() != 0 || std::system("command -v setpriv > /dev/null") != 0)
        GTEST_SKIP() << "needs root and setpriv to run the bake as another user";
    const fs::path dir = freshTestDir();
    const fs::path space = copySample(dir);
    const uid_t nobody = 65534;
    for (const auto& e : fs::recursive_directory_iterator(space)) ASSERT_EQ(::lchown(e.path().c_str(), nobody, nobody), 0);
    ASSERT_EQ(::chown(space.c_str(), nobody, nobody), 0);
    const fs::path foreign = space / "00000000o.chunk", locked = space / "00010000o.chunk";
    ASSERT_EQ(::chown(foreign.c_str(), 0, 0), 0);
    ASSERT_EQ(::chmod(foreign.c_str(), 0666), 0);  // writable, but owned by root
    ASSERT_EQ(::chown(locked.c_str(), 0, 0), 0);
    ASSERT_EQ(::chmod(locked.c_str(), 0644), 0);  // not writable by nobody
    // The checkout or the scratch directory may be out of another user's reach (e.g. under
    // a 0700 home): then there is nothing to test here.
    const std::string reach = "setpriv --reuid=65534 --regid=65534 --clear-groups sh -c \"test -x '" +
                              std::string(SHADOWCULL_BIN) + "' && test -w '" + space.string() + "'\"";
    if (std::system(reach.c_str()) != 0) GTEST_SKIP() << "the binary or the scratch space is out of another user's reach";
    const std::string bake = "bake '" + space.string() + "' --quiet --stages raycast";
    auto asNobody = [&](const std::string& args) {
        const std::string cmd = "setpriv --reuid=65534 --regid=65534 --clear-groups " + std::string(SHADOWCULL_BIN) +
                                " " + args + " > '" + (dir / "out").string() + "' 2> '" + (dir / "err").string() + "'";
        const int rc = std::system(cmd.c_str());
        return WIFEXITED(rc) ? WEXITSTATUS(rc) : -1;
    };
    EXPECT_EQ(asNobody(bake), 1) << readText(dir / "err");
    const std::string err = readText(dir / "err");
    EXPECT_NE(err.find("00000000o.chunk: the chunk file is owned by another user (uid 0)"), std::string::npos) << err;
    EXPECT_NE(err.find("00010000o.chunk: the chunk file is not writable by this user"), std::string::npos) << err;
    EXPECT_EQ(readText(foreign), readText(kSample / "00000000o.chunk"));
    EXPECT_EQ(readText(locked), readText(kSample / "00010000o.chunk"));
    EXPECT_NE(readText(space / "00000001o.chunk").find("<shadow>"), std::string::npos) << "the others are baked";

    EXPECT_EQ(asNobody(bake + " --force-write"), 0) << readText(dir / "err");
    EXPECT_NE(readText(foreign).find("<shadow>"), std::string::npos);
    EXPECT_NE(readText(locked).find("<shadow>"), std::string::npos);
    struct stat st {};
    ASSERT_EQ(::stat(foreign.c_str(), &st), 0);
    EXPECT_EQ(st.st_uid, nobody) << "forced: the replacement is this user's";
    EXPECT_EQ(st.st_mode & 07777, 0666u);
}
