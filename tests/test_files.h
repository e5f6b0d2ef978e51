// Small helpers for tests that write files: a fresh temporary directory per test and
// whole-file read/write.
#pragma once

#include <sys/wait.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <string>

#include <unistd.h>

#include <gtest/gtest.h>

namespace shadowcull::testing {

// This process's scratch root: concurrent test runs (ctest -j, two checkouts) never share it.
inline std::filesystem::path testRoot() {
    return std::filesystem::temp_directory_path() / "shadowcull-tests" / std::to_string(::getpid());
}

// Removes the scratch root after a run in which every test passed (kept for a look otherwise).
class ScratchCleanup : public ::testing::Environment {
public:
    void TearDown() override {
        if (::testing::UnitTest::GetInstance()->Passed()) {
            std::error_code ec;
            std::filesystem::remove_all(testRoot(), ec);
        }
    }
};
inline ::testing::Environment* const kScratchCleanup = ::testing::AddGlobalTestEnvironment(new ScratchCleanup);

// A directory unique to the running test, emptied at creation.
inline std::filesystem::path freshTestDir(const std::string& suffix = "") {
    const ::testing::TestInfo* info = ::testing::UnitTest::GetInstance()->current_test_info();
    std::filesystem::path dir = testRoot() / (std::string(info->test_suite_name()) + "." + info->name() + suffix);
    std::filesystem::remove_all(dir);
    std::filesystem::create_directories(dir);
    return dir;
}

inline void writeText(const std::filesystem::path& p, const std::string& text) {
    std::filesystem::create_directories(p.parent_path());
    std::ofstream out(p, std::ios::binary);
    out << text;
}

inline std::string readText(const std::filesystem::path& p) {
    std::ifstream in(p, std::ios::binary);
    std::ostringstream ss;
    ss << in.rdbuf();
    return ss.str();
}

#ifdef SHADOWCULL_BIN
// Runs the shadowcull executable with `args` (already quoted for the shell), stdout and
// stderr into files; returns the exit code (-1 when it did not exit normally, e.g. a signal).
inline int runCli(const std::string& args, const std::filesystem::path& outFile, const std::filesystem::path& errFile) {
    std::string cmd = std::string(SHADOWCULL_BIN) + " " + args + " > '" + outFile.string() + "' 2> '" + errFile.string() + "'";
    int rc = std::system(cmd.c_str());
    return WIFEXITED(rc) ? WEXITSTATUS(rc) : -1;
}
#endif

#ifdef SHADOWCULL_SOURCE_DIR
// Compares `actual` with tests/golden/NAME. SHADOWCULL_UPDATE_GOLDEN=1 rewrites the file
// instead (then read the diff before committing it).
inline void expectGolden(const std::string& name, const std::string& actual) {
    const std::filesystem::path golden = std::filesystem::path(SHADOWCULL_SOURCE_DIR) / "tests" / "golden" / name;
    if (const char* u = std::getenv("SHADOWCULL_UPDATE_GOLDEN"); u && std::string(u) == "1") writeText(golden, actual);
    ASSERT_TRUE(std::filesystem::exists(golden)) << golden << " is missing (run with SHADOWCULL_UPDATE_GOLDEN=1 to create it)";
    EXPECT_EQ(readText(golden), actual) << "differs from " << golden;
}
#endif

// Every *.chunk regular file of `dir` (never a FIFO a test made): name -> bytes.
inline std::map<std::string, std::string> chunkTexts(const std::filesystem::path& dir) {
    std::map<std::string, std::string> m;
    for (const auto& e : std::filesystem::directory_iterator(dir))
        if (e.path().extension() == ".chunk" && e.is_regular_file()) m[e.path().filename().string()] = readText(e.path());
    return m;
}

}  // namespace shadowcull::testing
