// `shadowcull preview SPACE --chunk NAME --light N [--camera EX,EY,EZ,TX,TY,TZ]
// [--shadow-resolution N] [--pcf-radius R] [--out FILE.png]`: bakes the chunk (a dry run,
// nothing written but the picture: the masks are the ones the bake would write) and renders
// the camera's view shadowed by the light as an engine does it, with every caster and with
// the kept ones (gpu/preview.h). Prints `differing pixels: N` and each shadow pass's cost.
#pragma once

#include <optional>
#include <ostream>
#include <string>

#include "cli/pipeline.h"

namespace shadowcull::cli {

struct PreviewOptions {
    BakeOptions bake;            // spaceDir, resourceRoot
    std::string chunk;           // XXXXZZZZo or XXXXZZZZo.chunk
    std::string outPath = "shadowcull-preview.png";
    int light = 1;               // 1-based
    std::string camera;          // "EX,EY,EZ,TX,TY,TZ" (world metres); empty: from above
    int shadowResolution = 2048;
    int pcfRadius = -1;          // < 0: the default (gpu::defaultPcfRadius)
    int repeats = 5;             // shadow passes timed per frame
};

int runPreview(const PreviewOptions& options, std::ostream& out, std::ostream& err);

}  // namespace shadowcull::cli
