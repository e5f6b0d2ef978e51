// main() for the ordinary build: runs every file of the directories (or the files) named
// on the command line through the fuzz target's LLVMFuzzerTestOneInput, in name order.
// So the seed corpus and every crash once found (fuzz/regressions/) stay tests in ctest
// without clang or libFuzzer. A crash ends the process, after the input's name is printed.
// Files whose names start with '.' are skipped (.gitkeep); a directory that does not exist
// holds no inputs, but a run that replays nothing at all fails (a wrong path).

#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

namespace fs = std::filesystem;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size);

int main(int argc, char** argv) {
    std::vector<fs::path> inputs;
    for (int a = 1; a < argc; ++a) {
        const fs::path arg = argv[a];
        std::error_code ec;
        if (!fs::is_directory(arg, ec)) {
            if (fs::exists(arg, ec)) inputs.push_back(arg);
            else std::printf("%s: does not exist, nothing to replay from it\n", argv[a]);
            continue;
        }
        std::vector<fs::path> files;
        for (const fs::directory_entry& e : fs::directory_iterator(arg))
            if (e.is_regular_file() && e.path().filename().string().rfind('.', 0) != 0) files.push_back(e.path());
        std::sort(files.begin(), files.end());
        inputs.insert(inputs.end(), files.begin(), files.end());
    }
    for (const fs::path& p : inputs) {
        std::printf("replaying %s\n", p.string().c_str());
        std::fflush(stdout);  // the name must be out before a crash
        std::ifstream in(p, std::ios::binary);
        const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
        LLVMFuzzerTestOneInput(reinterpret_cast<const uint8_t*>(bytes.data()), bytes.size());
    }
    std::printf("%zu inputs replayed, none crashed\n", inputs.size());
    return inputs.empty() ? 1 : 0;
}
