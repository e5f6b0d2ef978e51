// `shadowcull check SPACE`: cross-checks the original GPU method against the analytic
// pipeline, bit by bit. Each disagreement is classified:
//   GPU false cull  - the GPU method wrote 0 where the analytic side has a witness (a
//                     shadow the player would miss);
//   GPU false keep  - the GPU method wrote 1 where the analytic side proved 0;
//   undecided       - the analytic side could not decide (no judgement possible).
// A picture of the light's view (the colours of `render`) is written for every chunk and
// light with a disagreement. Exit 1 when the GPU method culled something with a witness,
// else 0.
#pragma once

#include <ostream>
#include <string>

namespace shadowcull::cli {

struct CheckOptions {
    std::string spaceDir, resourceRoot;
    std::string outDir = "shadowcull-check";  // pictures
    int gpuResolution = 1024;
    int threads = 0;
    bool pictures = true;
};

int runCheck(const CheckOptions& options, std::ostream& out, std::ostream& err);

}  // namespace shadowcull::cli
