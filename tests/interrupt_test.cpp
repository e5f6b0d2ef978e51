// Ctrl-C (SIGINT) and SIGTERM during a bake (issue 15): the bake stops between steps,
// removes the chunk files and results it had staged, leaves every input as it was and
// exits with 128 + the signal. The signal is sent once the bake has staged a file, so the
// test does not depend on how fast this machine bakes.

#include <fcntl.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <fstream>
#include <functional>
#include <optional>
#include <thread>

#include <gtest/gtest.h>

#include "cli/interrupt.h"
#include "cli/pipeline.h"
#include "cli/progress_reporter.h"
#include "cli/staged_outputs.h"
#include "geometry/geometry_stage.h"
#include "io/scene_reader.h"
#include "io/space_source.h"
#include "raycast/raycast_stage.h"
#include "tests/support/gltf_scenes.h"
#include "tests/support/space_builder.h"
#include "tests/test_files.h"
#include "util/stop_request.h"

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

// Starts `shadowcull args...` with stderr to `errFile` and `signal` as the shell would
// leave it; waits until `ready(pid)` (the command is under way), sends `signal` and waits
// for it to end.
Interrupted runAndInterrupt(std::vector<std::string> args, const std::function<bool(pid_t)>& ready, const fs::path& errFile,
                            int signal, bool ignoredAtStart = false) {
    args.insert(args.begin(), SHADOWCULL_BIN);
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
        if (::waitpid(pid, &status, WNOHANG) == pid) break;  // ended before it was seen under way
        if (ready(pid)) {
            ::kill(pid, signal);
            signalled = true;
            ::waitpid(pid, &status, 0);
            break;
        }
        std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
    EXPECT_TRUE(signalled) << "the command ended before the test saw it under way; make its input larger";
    r.exitCode = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
    r.stderrText = readText(errFile);
    return r;
}

// Starts `shadowcull bake WORK extraArgs...`, waits until `ready()` (the bake is under
// way), sends `signal` and waits for it to end.
Interrupted bakeAndInterrupt(const fs::path& work, const std::function<bool()>& ready, const fs::path& errFile, int signal,
                             std::vector<std::string> extraArgs, bool ignoredAtStart = false) {
    std::vector<std::string> args{"bake", work.string()};
    args.insert(args.end(), extraArgs.begin(), extraArgs.end());
    return runAndInterrupt(args, [&](pid_t) { return ready(); }, errFile, signal, ignoredAtStart);
}

// Whether process `pid` has a handler for `signal` (its SigCgt mask in /proc).
bool catches(pid_t pid, int signal) {
    std::ifstream status("/proc/" + std::to_string(pid) + "/status");
    for (std::string line; std::getline(status, line);)
        if (line.rfind("SigCgt:", 0) == 0) return (std::stoull(line.substr(7), nullptr, 16) >> (signal - 1)) & 1;
    return false;
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

namespace {

// A scene of `nodes` cubes on a grid 10 m apart under a sun: its import takes a while.
std::string cubeField(int nodes) {
    GltfSceneBuilder b;
    const size_t cube = b.mesh("cube", {cubePrimitive()});
    for (int k = 0; k < nodes; ++k) b.setMesh(b.node("cube" + std::to_string(k), -1, glm::dvec3(10.0 * (k % 100), 0.5, 10.0 * (k / 100))), cube);
    const size_t sun = b.node("sun", -1, glm::dvec3(0.0), aimMinusZ(glm::normalize(glm::dvec3(0.3, -1.0, 0.2))));
    b.setLight(sun, {{"type", "directional"}});
    return b.glb();
}

// Entries of `dir` whose names start with `prefix`.
std::vector<std::string> namesStarting(const fs::path& dir, const std::string& prefix) {
    std::vector<std::string> out;
    for (const fs::directory_entry& de : fs::directory_iterator(dir))
        if (de.path().filename().string().rfind(prefix, 0) == 0) out.push_back(de.path().filename().string());
    std::sort(out.begin(), out.end());
    return out;
}

// In-process tests request a stop and must forget it whatever they assert.
struct StopRequested {
    explicit StopRequested(int signal) { cli::simulateInterrupt(signal); }
    ~StopRequested() { cli::clearInterrupt(); }
};

}  // namespace

// Issue 35: the handlers were installed only by `bake`, and only once its options were
// parsed; `import` died of the signal and left its ~32 MB staging directory. Now every
// command catches both signals from the start of main: the signal is sent as soon as the
// process catches it, wherever it is then (still starting, or importing), and the import
// ends with 128 + signal, a message, and nothing written.
class InterruptImportTest : public ::testing::TestWithParam<int> {};

TEST_P(InterruptImportTest, CatchesTheSignalFromTheStartAndLeavesNothing) {
    const int signal = GetParam();
    const fs::path dir = freshTestDir(signal == SIGINT ? "-int" : "-term");
    writeText(dir / "field.glb", cubeField(20000));
    auto caught = [&](pid_t pid) { return catches(pid, SIGINT) && catches(pid, SIGTERM); };
    const Interrupted r = runAndInterrupt({"import", (dir / "field.glb").string(), (dir / "out").string()}, caught,
                                          dir / "stderr", signal);
    EXPECT_EQ(r.exitCode, 128 + signal) << r.stderrText;
    EXPECT_NE(r.stderrText.find(signal == SIGINT ? "interrupted by Ctrl-C (SIGINT)" : "interrupted by SIGTERM"), std::string::npos)
        << r.stderrText;
    EXPECT_FALSE(fs::exists(dir / "out"));
    EXPECT_EQ(namesStarting(dir, "out."), std::vector<std::string>{}) << "a staging directory was left";
}

// Caught while it writes its staging directory: removed, nothing written.
TEST(InterruptImport, RemovesItsStagingDirectory) {
    const fs::path dir = freshTestDir();
    writeText(dir / "field.glb", cubeField(20000));
    auto staging = [&](pid_t) { return !namesStarting(dir, "out.import-").empty(); };
    const Interrupted r = runAndInterrupt({"import", (dir / "field.glb").string(), (dir / "out").string()}, staging,
                                          dir / "stderr", SIGINT);
    EXPECT_EQ(r.exitCode, 130) << r.stderrText;
    EXPECT_NE(r.stderrText.find("interrupted by Ctrl-C (SIGINT); the staging directory was removed (nothing written)"),
              std::string::npos)
        << r.stderrText;
    EXPECT_FALSE(fs::exists(dir / "out"));
    EXPECT_EQ(namesStarting(dir, "out."), std::vector<std::string>{});
}

INSTANTIATE_TEST_SUITE_P(Signals, InterruptImportTest, ::testing::Values(SIGINT, SIGTERM),
                         [](const ::testing::TestParamInfo<int>& p) { return p.param == SIGINT ? "Sigint" : "Sigterm"; });

// An import killed outright (a second Ctrl-C, SIGKILL) cannot remove its staging
// directory: the next import into the same place removes those whose process is gone, and
// leaves a running import's.
TEST(InterruptImport, RemovesStagingDirectoriesOfDeadImports) {
    const fs::path dir = freshTestDir();
    writeText(dir / "field.glb", cubeField(4));
    const pid_t dead = fork();
    if (dead == 0) _exit(0);
    ASSERT_GT(dead, 0);
    ::waitpid(dead, nullptr, 0);
    const std::string deadStaging = "out.import-" + std::to_string(dead), liveStaging = "out.import-" + std::to_string(::getpid());
    for (const std::string& name : {deadStaging, liveStaging}) writeText(dir / name / "models" / "mesh0.glb", "staged");
    ASSERT_EQ(runCli("import '" + (dir / "field.glb").string() + "' '" + (dir / "out").string() + "'", dir / "o", dir / "e"), 0)
        << readText(dir / "e");
    EXPECT_EQ(namesStarting(dir, "out."), std::vector<std::string>{liveStaging});
}

// Staged outputs (check's pictures, render's PNG): renamed into place at the end, or, after
// a signal, removed with the directories made for them.
TEST(StagedOutputs, ASignalLeavesNoFileAndNoDirectory) {
    const fs::path dir = freshTestDir();
    for (const bool signalled : {false, true}) {
        SCOPED_TRACE(signalled ? "signalled" : "completed");
        const fs::path pictures = dir / (signalled ? "a" : "b") / "pictures";
        cli::StagedOutputs staged;
        ASSERT_TRUE(staged.makeDirectory(pictures.string()));
        writeText(staged.stage((pictures / "one.png").string()), "png");
        std::optional<StopRequested> stop;
        if (signalled) stop.emplace(SIGTERM);
        const Status s = staged.commit();
        if (signalled) {
            ASSERT_FALSE(s);
            EXPECT_EQ(s.error().kind, ErrorKind::Interrupted);
            EXPECT_FALSE(fs::exists(dir / "a")) << "the directories made for the pictures are removed";
        } else {
            ASSERT_TRUE(s) << s.error().what();
            EXPECT_EQ(readText(pictures / "one.png"), "png");
            EXPECT_EQ(namesStarting(pictures, "."), std::vector<std::string>{});
        }
    }
}

// The commands that end at once on a signal (diff, merge, report, sweep's files) write one
// file atomically; a signal while its temporary is in hand removed nothing and left
// `.NAME.shadowcull-tmp` beside it. The handler now removes the held temporary.
TEST(InterruptAtOnce, RemovesTheTemporaryOfTheFileInHand) {
    const fs::path dir = freshTestDir();
    const fs::path temp = dir / ".report.html.shadowcull-tmp";
    writeText(temp, "half a report");
    const pid_t child = fork();
    if (child == 0) {
        cli::installInterruptHandlers(cli::InterruptMode::ExitAtOnce);
        if (!holdTemporary(temp.c_str())) _exit(2);
        ::raise(SIGTERM);
        _exit(3);  // not reached: the handler ends the process
    }
    ASSERT_GT(child, 0);
    int status = 0;
    ASSERT_EQ(::waitpid(child, &status, 0), child);
    ASSERT_TRUE(WIFEXITED(status));
    EXPECT_EQ(WEXITSTATUS(status), 143);
    EXPECT_FALSE(fs::exists(temp)) << "the temporary in hand is removed";
    // Released (the file renamed into place), nothing is removed.
    ASSERT_TRUE(holdTemporary(temp.c_str()));
    releaseTemporary();
    writeText(temp, "another");
    removeHeldTemporary();
    EXPECT_TRUE(fs::exists(temp));
}

// Issue 35: after Ctrl-C a 200,000-node bake took 45 s to stop: the scan, the window's
// loads and the stages' loops never looked at the signal. Each now stops at its next
// step with an Interrupted error, its bits left undecided.
TEST(InterruptInProcess, TheScanStopsBeforeTheNextChunkFile) {
    const fs::path dir = freshTestDir();
    manyChunks(12).write((dir / "space").string());
    size_t scanned = 0, total = 0;
    const StopRequested stop(SIGINT);
    Expected<SpaceSource> s = SpaceSource::scan((dir / "space").string(), "", nullptr, [&](size_t n, size_t t) {
        scanned = n;
        total = t;
    });
    ASSERT_FALSE(s);
    EXPECT_EQ(s.error().kind, ErrorKind::Interrupted);
    EXPECT_EQ(s.error().message, "interrupted by Ctrl-C (SIGINT)");
    EXPECT_EQ(total, 144u);
    EXPECT_EQ(scanned, 0u);
}

TEST(InterruptInProcess, EveryStageStopsWithItsBitsUndecided) {
    const fs::path dir = freshTestDir();
    cubeOnTerrain().write(dir.string());
    Expected<Space> space = loadSpace(dir.string(), "");
    ASSERT_TRUE(space) << space.error().what();
    TerrainMeshes terrain;
    const BakeWindow window = buildWindow(*space, ChunkCoord{0, 0}, terrain);
    ASSERT_FALSE(window.objects.empty());
    ReachStage reach;
    raycast::RaycastStage rays;
    geometry::GeometryStage volumes;
    const StopRequested stop(SIGTERM);
    for (Stage* stage : std::initializer_list<Stage*>{&reach, &rays, &volumes}) {
        SCOPED_TRACE(stage->name());
        ChunkVerdicts cv = makeChunkVerdicts(*space, window);
        StageStats stats;
        const Status s = stage->run(window, cv, stats);
        ASSERT_FALSE(s);
        EXPECT_EQ(s.error().kind, ErrorKind::Interrupted);
        for (const ObjectVerdicts& ov : cv.objects)
            for (const Decision& d : ov.decisions) EXPECT_EQ(d.verdict, Verdict::Undecided);
    }
    // The window itself stops too (its caller checks before using it).
    EXPECT_TRUE(buildWindow(*space, ChunkCoord{0, 0}, terrain).objects.empty());
}

// Issue 35: a bake logging to a pipe printed nothing for the minute its scan and first
// dense chunk took. The first line comes at once, then one every interval whether or not
// the bake calls back; nothing after a signal (the handler's message stands).
TEST(Progress, ALineAtOnceThenEveryIntervalWithoutCallbacks) {
    const fs::path dir = freshTestDir();
    const fs::path log = dir / "log";
    std::FILE* out = std::fopen(log.c_str(), "w");
    ASSERT_NE(out, nullptr);
    {
        cli::ProgressReporter progress(out, false, std::chrono::milliseconds(20));
        progress.scanned(0, 7);
        EXPECT_EQ(readText(log), "shadowcull: scanning the space: 0/7 chunk files, 0 s elapsed\n");
        progress.scanned(7, 7);
        // No callback while "the first chunk" bakes: the ticker's lines (10 s is far beyond 20 ms).
        for (int k = 0; k < 1000 && readText(log).find("; baking the first chunk") == std::string::npos; ++k)
            std::this_thread::sleep_for(std::chrono::milliseconds(10));
        EXPECT_NE(readText(log).find("shadowcull: scanned 7 chunk files; baking the first chunk, "), std::string::npos)
            << readText(log);
        progress.baked({1, 2, 0});
        const StopRequested stop(SIGINT);
        const std::string before = readText(log);
        progress.baked({2, 2, 0});
        std::this_thread::sleep_for(std::chrono::milliseconds(100));
        EXPECT_EQ(readText(log), before) << "quiet after a signal";
    }
    std::fclose(out);
}
