// Small helpers for tests that write files: a fresh temporary directory per test and
// whole-file read/write.
#pragma once

#include <filesystem>
#include <fstream>
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

}  // namespace shadowcull::testing
