// Ctrl-C (SIGINT) and SIGTERM during a bake (issue 15): the bake stops between steps,
// removes the chunk files and results it had staged, leaves every input as it was and
// exits with 128 + the signal. The signal is sent once the bake has staged a file, so the
// test does not depend on how fast this machine bakes.

#include <fcntl.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <functional>
#include <csignal>
#include <thread>

#include <gtest/gtest.h>

#include "cli/interrupt.h"
#include "cli/pipeline.h"
#include "tests/support/space_builder.h"
#include "tests/test_files.h"

using namespace shadowcull;
using namespace shadowcull::testing;
namespace fs = std::filesystem;

namespace {

// Files whose name says they are a bake's temporaries, anywhere under `dir`.
std::vector<std::string> temporariesUnder(const fs::path& dir) {
    std::vector<std::string> out;
    std::error_code ec;
    for (auto it = fs::recursive_directory_iterator(dir, ec); !ec && it != fs::recursive_directory_iterator(); it.increment(ec))
        if (it->path().filename().string().find(".shadowcull-tmp") != std::string::npos) out.push_back(it->path().string());
    return out;
}

struct Interrupted {
    int exitCode = -1;
    std::string stderrText;
};

// Starts `shadowcull bake WORK extraArgs...`, waits until `ready()` (the bake is under
// way), sends `signal` and waits for it to end.
Interrupted bakeAndInterrupt(const fs::path& work, const std::function<bool()>& ready, const fs::path& errFile, int signal,
                             std::vector<std::string> extraArgs, bool ignoredAtStart = false) {
    std::vector<std::string> args{SHADOWCULL_BIN, "bake", work.string()};
    args.insert(args.end(), extraArgs.begin(), extraArgs.end());
    pid_t pid = fork();
    if (pid == 0) {
        const int err = ::open(errFile.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
        const int devNull = ::open("/dev/null", O_WRONLY);
        ::dup2(err, STDERR_FILENO);
        ::dup2(devNull, STDOUT_FILENO);
        // Ignored as by nohup or a script's background job; else the default, whatever this
        // test inherited (ctest started in the background has SIGINT ignored).
        ::signal(signal, ignoredAtStart ? SIG_IGN : SIG_DFL);
        std::vector<char*> argv;
        for (std::string& a : args) argv.push_back(a.data());
        argv.push_back(nullptr);
        ::execv(argv[0], argv.data());
        _exit(127);
    }
    Interrupted r;
    EXPECT_GT(pid, 0);
    if (pid <= 0) return r;
    int status = 0;
    bool signalled = false;
    for (;;) {
        if (::waitpid(pid, &status, WNOHANG) == pid) break;  // ended before a file was staged
        if (ready()) {
            ::kill(pid, signal);
            signalled = true;
            ::waitpid(pid, &status, 0);
            break;
        }
        std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
    EXPECT_TRUE(signalled) << "the bake ended before the test saw it under way; make the space larger";
    r.exitCode = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
    r.stderrText = readText(errFile);
    return r;
}

// A 144-chunk space in DIR/space and its complete bake in DIR/ref.
void writeSpaceAndReference(const fs::path& dir) {
    manyChunks(12).write((dir / "space").string());
    ASSERT_EQ(runCli("bake '" + (dir / "space").string() + "' --out '" + (dir / "ref").string() + "' --quiet", dir / "o", dir / "e"), 0)
        << readText(dir / "e");
}

class InterruptTest : public ::testing::TestWithParam<int> {};

TEST_P(InterruptTest, RemovesTemporariesAndLeavesInputsAsTheyWere) {
    const int signal = GetParam();
    SpaceBuilder b = manyChunks(12);
    fs::path dir = freshTestDir(signal == SIGINT ? "-int" : "-term");
    b.write((dir / "space").string());
    const auto original = chunkTexts(dir / "space");
    const std::string spaceXml = readText(dir / "space" / "space.xml");
    ASSERT_EQ(original.size(), 144u);

    // Under way: a chunk file is staged.
    auto staged = [&] { return !temporariesUnder(dir / "space").empty(); };
    const Interrupted r = bakeAndInterrupt(dir / "space", staged, dir / "stderr", signal,
                                           {"--results", (dir / "results.json").string()});
    EXPECT_EQ(r.exitCode, 128 + signal) << r.stderrText;
    EXPECT_NE(r.stderrText.find(signal == SIGINT ? "shadowcull: error: interrupted by Ctrl-C (SIGINT); the bake's temporary "
                                                   "files were removed; no chunk file was changed"
                                                 : "shadowcull: error: interrupted by SIGTERM; the bake's temporary files "
                                                   "were removed; no chunk file was changed"),
              std::string::npos)
        << r.stderrText;
    EXPECT_EQ(temporariesUnder(dir), std::vector<std::string>{}) << r.stderrText;
    EXPECT_EQ(chunkTexts(dir / "space"), original) << "an interrupted bake writes nothing";
    EXPECT_EQ(readText(dir / "space" / "space.xml"), spaceXml);
    EXPECT_FALSE(fs::exists(dir / "results.json"));
}

INSTANTIATE_TEST_SUITE_P(Signals, InterruptTest, ::testing::Values(SIGINT, SIGTERM),
                         [](const ::testing::TestParamInfo<int>& p) { return p.param == SIGINT ? "Sigint" : "Sigterm"; });

// With --resume each chunk is committed as it is baked: an interrupt keeps those (each
// complete and recorded), removes the temporaries, and the next --resume bake finishes.
TEST(InterruptResume, KeepsCommittedChunksAndRemovesTemporaries) {
    const fs::path dir = freshTestDir();
    ASSERT_NO_FATAL_FAILURE(writeSpaceAndReference(dir));
    const auto original = chunkTexts(dir / "space");
    const auto complete = chunkTexts(dir / "ref");

    // Under way: a chunk file is committed (each lives as a temporary for microseconds only).
    auto committed = [&] { return chunkTexts(dir / "space") != original; };
    const Interrupted r = bakeAndInterrupt(dir / "space", committed, dir / "stderr", SIGINT, {"--resume", "--quiet"});
    EXPECT_EQ(r.exitCode, 130) << r.stderrText;
    EXPECT_NE(r.stderrText.find("interrupted by Ctrl-C (SIGINT)"), std::string::npos) << r.stderrText;
    EXPECT_EQ(temporariesUnder(dir / "space"), std::vector<std::string>{});
    for (const auto& [name, text] : chunkTexts(dir / "space"))
        EXPECT_TRUE(text == original.at(name) || text == complete.at(name)) << name << " is half written";
    ASSERT_EQ(runCli("bake '" + (dir / "space").string() + "' --resume --quiet", dir / "o", dir / "e"), 0) << readText(dir / "e");
    EXPECT_EQ(chunkTexts(dir / "space"), complete);
}

// A shell that started the bake with SIGINT ignored (a script's background job) keeps it
// ignored: the bake goes on and completes.
TEST(InterruptIgnored, SigintIgnoredAtStartStaysIgnored) {
    const fs::path dir = freshTestDir();
    ASSERT_NO_FATAL_FAILURE(writeSpaceAndReference(dir));
    auto staged = [&] { return !temporariesUnder(dir / "space").empty(); };
    const Interrupted r = bakeAndInterrupt(dir / "space", staged, dir / "stderr", SIGINT, {"--quiet"}, true);
    EXPECT_EQ(r.exitCode, 0) << r.stderrText;
    EXPECT_EQ(chunkTexts(dir / "space"), chunkTexts(dir / "ref"));
}

// In-process: a signal recorded before the bake stops it at the first check, with nothing
// staged and the Interrupted kind (exit code 130).
TEST(InterruptInProcess, StopsBeforeWritingAnything) {
    SpaceBuilder b = cubeOnTerrain();
    fs::path dir = freshTestDir();
    b.write((dir / "space").string());
    const auto original = chunkTexts(dir / "space");
    cli::BakeOptions opt;
    opt.spaceDir = (dir / "space").string();
    cli::simulateInterrupt(SIGINT);
    Expected<cli::BakeResult> r = cli::runBake(opt);
    cli::clearInterrupt();
    ASSERT_FALSE(r);
    EXPECT_EQ(r.error().kind, ErrorKind::Interrupted);
    EXPECT_EQ(cli::exitCodeFor(r.error().kind), 130);
    EXPECT_EQ(chunkTexts(dir / "space"), original);
    EXPECT_EQ(temporariesUnder(dir), std::vector<std::string>{});
}

}  // namespace
