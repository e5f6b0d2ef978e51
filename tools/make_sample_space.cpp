// Writes the bundled sample space (data/sample/ by default; see
// tests/support/sample_space.cpp for what it holds).
//
//   make_sample_space [OUTPUT_DIR]
//
// An existing OUTPUT_DIR is replaced only when it holds a space.xml (i.e. is an earlier
// sample), so a mistyped path cannot wipe a folder.

#include <filesystem>
#include <fstream>
#include <iostream>

#include "tests/support/sample_space.h"

using namespace shadowcull::testing;
namespace fs = std::filesystem;

int main(int argc, char** argv) {
    const fs::path out = argc > 1 ? argv[1] : "data/sample";
    try {
        if (fs::exists(out) && !fs::is_empty(out)) {
            if (!fs::exists(out / "space.xml")) {
                std::cerr << "make_sample_space: " << out << " is not empty and holds no space.xml; not replacing it\n";
                return 1;
            }
            fs::remove_all(out);
        }
        sampleSpace().write(out.string());
        std::ofstream(out / "README.md") << kSampleSpaceReadme;
    } catch (const std::exception& e) {
        std::cerr << "make_sample_space: " << e.what() << "\n";
        return 1;
    }
    std::cout << "wrote " << out.string() << "\n";
    return 0;
}
