// `shadowcull render SPACE --chunk NAME --light N --out FILE.png`: bakes the chunk (dry run)
// and writes the light's view coloured by verdict (gpu/render.h), then says on stdout which
// file it wrote and what the picture counts.
#pragma once

#include <ostream>
#include <string>

#include "cli/pipeline.h"
#include "cli/staged_outputs.h"

namespace shadowcull::cli {

struct RenderOptions {
    BakeOptions bake;       // spaceDir, resourceRoot, gpuResolution, gpuBaseline
    std::string chunk;      // XXXXZZZZo or XXXXZZZZo.chunk
    std::string outPath;    // the PNG
    int light = 1;          // 1-based
};

int runRender(const RenderOptions& options, std::ostream& out, std::ostream& err);

// A rendered picture's end, for render and preview: prints the rendering's error, or moves
// the staged picture into place (a failure leaves no partial file and names `path`).
// kExitOk when the picture is in place, else the exit code of the error.
int finishPicture(const Status& rendered, StagedOutputs& picture, const std::string& path, std::ostream& err);

// What `render` and `preview` share: parses the chunk name, bakes it (dry run), refuses an
// output that is one of the bake's inputs and a light the space does not have (1-based),
// saying why on `err`. Returns kExitOk with `cb` and `coord` set, or the exit code.
int bakeChunkForLight(const BakeOptions& options, const std::string& chunk, int light, const std::string& outPath,
                      std::ostream& err, ChunkBake& cb, ChunkCoord& coord);

}  // namespace shadowcull::cli
