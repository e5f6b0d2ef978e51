// Fuzz target: the whole bake of a tiny space (runBake: input/reach, witness rays, shadow
// volumes; no GPU, nothing written, one thread), to catch what the readers let through
// and Embree or CGAL then trip over. Input, split by kFuzzSeparator (fuzz_support.h):
//   space.xml, 00000000o.chunk, 00010000o.chunk, m.obj, t.terrain, t.png
// Chunk files name m.obj and t.terrain as resources (the resource root is the space).
// The PNG's CRCs are made right before it is written (withPngCrcsFixed).

#include "cli/pipeline.h"
#include "fuzz/fuzz_support.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    std::vector<std::string> parts = splitInput(data, size, 6);
    if (parts.size() == 6) parts[5] = withPngCrcsFixed(std::move(parts[5]));
    writeFiles(parts, {"space.xml", "00000000o.chunk", "00010000o.chunk", "m.obj", "t.terrain", "t.png"});
    shadowcull::cli::BakeOptions opt;
    opt.spaceDir = scratchDir();
    opt.threads = 1;
    opt.useGpu = false;
    opt.write = false;
    // Few samples: a run must stay fast; the crashes sought do not depend on their number.
    opt.raycast.areaSamples = 8;
    opt.raycast.maxFeatureSamples = 32;
    opt.raycast.threads = 1;
    (void)shadowcull::cli::runBake(opt);
    return 0;
}
