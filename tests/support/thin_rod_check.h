// `check` on the thin rod (known_scenes.cpp: thinRod), the scene whose 5 mm rod the GPU
// method misses at a low resolution: what the check tests and the check picture test start
// from.
#pragma once

#include <filesystem>
#include <sstream>
#include <string>

#include "cli/check.h"
#include "tests/support/space_builder.h"

namespace shadowcull::testing {

struct ThinRodCheck {
    cli::CheckOptions opt;  // what it ran with
    int code = -1;          // runCheck's return
    std::string out, err;
};

// Writes thinRod() to `dir`/space and checks it with the GPU method at 256 px, pictures
// into `dir`/pictures.
inline ThinRodCheck checkThinRod(const std::filesystem::path& dir) {
    thinRod().write((dir / "space").string());
    ThinRodCheck c;
    c.opt.spaceDir = (dir / "space").string();
    c.opt.gpuResolution = 256;
    c.opt.outDir = (dir / "pictures").string();
    std::ostringstream out, err;
    c.code = cli::runCheck(c.opt, out, err);
    c.out = out.str();
    c.err = err.str();
    return c;
}

}  // namespace shadowcull::testing
