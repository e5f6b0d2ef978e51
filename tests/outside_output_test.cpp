// Issue 35: nothing outside the output is written. Each case plants what a user's tree or
// an attacker may hold (symbolic links where a bake writes its temporaries, its lock or its
// copies; a directory where a file is to be written) and checks that the bake stops before
// writing anything, or writes only its own files, and that every file the links lead to is
// unchanged. Each wrote outside the output before it was fixed.

#include <sys/stat.h>

#include <functional>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "tests/test_files.h"

using namespace shadowcull::testing;
namespace fs = std::filesystem;

namespace {

const fs::path kSample = fs::path(SHADOWCULL_SOURCE_DIR) / "data" / "sample";
const std::string kVictimText = "a file outside the output, to be kept\n";

struct Trap {
    const char* name;
    // Plants the trap in `dir` (the space is dir/space, the victim dir/victim.txt); returns
    // the arguments after "bake SPACE --quiet".
    std::function<std::string(const fs::path& dir)> plant;
    int exitCode;
    std::string message;  // in stderr ("" when the bake succeeds)
};

std::string quoted(const fs::path& p) { return "'" + p.string() + "'"; }

}  // namespace

TEST(OutsideOutput, NoTrapMakesABakeWriteOutsideItsOutput) {
    const std::vector<Trap> traps = {
        {"--out holding links to the space (cp -as)",
         [](const fs::path& dir) {
             fs::create_directories(dir / "copy");
             for (const fs::directory_entry& e : fs::directory_iterator(dir / "space"))
                 if (e.path().extension() == ".chunk") fs::create_symlink(e.path(), dir / "copy" / e.path().filename());
             return "--out " + quoted(dir / "copy");
         },
         3, "never writes through a link"},
        {"--out naming the space itself",
         [](const fs::path& dir) { return "--out " + quoted(dir / "space"); }, 3, "--out names an input of this command"},
        {"a stale chunk temporary that is a link",
         [](const fs::path& dir) {
             fs::create_symlink(dir / "victim.txt", dir / "space" / ".00000000o.chunk.shadowcull-tmp");
             return std::string();
         },
         0, ""},
        {"a stale results temporary that is a link",
         [](const fs::path& dir) {
             fs::create_symlink(dir / "victim.txt", dir / ".r.json.shadowcull-tmp");
             return "--results " + quoted(dir / "r.json");
         },
         0, ""},
        {"a bake lock that is a link",
         [](const fs::path& dir) {
             fs::create_symlink(dir / "victim.txt", dir / "space" / ".shadowcull-bake.lock");
             return std::string();
         },
         3, "the bake lock is a symbolic link"},
        {"a bake lock in --out that is a link",
         [](const fs::path& dir) {
             fs::create_directories(dir / "out");
             fs::create_symlink(dir / "victim.txt", dir / "out" / ".shadowcull-bake.lock");
             return "--out " + quoted(dir / "out");
         },
         3, "the bake lock is a symbolic link"},
        {"--results naming a directory",
         [](const fs::path& dir) { return "--results " + quoted(dir); }, 3, "--results names a directory"},
        {"--results naming the space",
         [](const fs::path& dir) { return "--results " + quoted(dir / "space"); }, 3, "--results names a directory"},
    };
    for (const Trap& t : traps) {
        SCOPED_TRACE(t.name);
        const fs::path dir = freshTestDir("-" + std::to_string(&t - traps.data()));
        fs::copy(kSample, dir / "space", fs::copy_options::recursive);
        writeText(dir / "victim.txt", kVictimText);
        const std::string args = t.plant(dir);
        const auto before = chunkTexts(dir / "space");
        const int rc = runCli("bake " + quoted(dir / "space") + " --quiet --stages raycast " + args, dir / "out.txt", dir / "err.txt");
        const std::string err = readText(dir / "err.txt");
        EXPECT_EQ(rc, t.exitCode) << err;
        if (!t.message.empty()) {
            EXPECT_NE(err.find(t.message), std::string::npos) << err;
            EXPECT_NE(err.find("no chunk file was changed"), std::string::npos) << err;
            EXPECT_EQ(chunkTexts(dir / "space"), before) << "a stopped bake writes nothing";
        }
        EXPECT_EQ(readText(dir / "victim.txt"), kVictimText) << "written through a link";
        // Every chunk file is still a regular file of the space (none became a link).
        for (const fs::directory_entry& e : fs::directory_iterator(dir / "space")) {
            if (e.path().extension() == ".chunk") {
                EXPECT_FALSE(fs::is_symlink(e.symlink_status())) << e.path();
            }
        }
    }
}
