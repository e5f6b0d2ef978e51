// `shadowcull render SPACE --chunk NAME --light N --out image.png`: the light's view of a
// bake window, coloured as in the original tool:
//   grey   - neighbour chunks (loaded as occluders and receivers, not baked)
//   red    - centre-chunk groups culled for this light (proved 0)
//   green  - centre-chunk groups kept (proved 1: a witness, or the baseline's samples)
//   yellow - centre-chunk groups undecided (written 1 without a proof)
// Shaded by the angle to the light so that shapes read. A directional light gives one
// resolution x resolution view framed on the baked chunk (its ground square and the
// content standing on it; neighbours and anything far above, e.g. a balloon, are cropped
// and counted in the legend); a point light (or a spot wider than kMaxSingleViewSpotDeg)
// its six cube faces, 3 x 2 tiles labelled +X -X +Y on top, -Y +Z -Z below; a spot light
// the view over its cone. Above the view: chunk, light and its direction; below: the
// legend, each colour with its count of groups. Groups asked for are outlined in magenta
// (`check`: the groups where the two methods disagree).
#pragma once

#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "core/verdict.h"
#include "core/window.h"
#include "util/status.h"

namespace shadowcull::gpu {

struct RenderRequest {
    int light = 0;          // 0-based (light N on the command line is N-1)
    int resolution = 1024;  // pixels per side of each light view
    std::string colouredBy = "analytic verdicts";  // for the title
    // (index into ChunkVerdicts::objects, group) to outline, and what the outline means.
    std::vector<std::pair<size_t, int>> outlined;
    std::string outlineMeaning = "marked";
};

// What the picture shows: the legend's counts (groups of the centre chunk, for the light)
// and where the views lie in the picture.
struct RenderReport {
    int width = 0, height = 0;            // of the whole picture
    uint64_t culled = 0, kept = 0, undecided = 0;
    uint64_t outsideFrame = 0;            // centre groups cropped by the frame (directional)
    uint64_t outlined = 0;                // outlined groups seen in the view
    std::vector<std::string> title, legend;  // the text lines drawn
    int viewX = 0, viewY = 0, tile = 0, cols = 1, rows = 1;  // view tiles: top-left, side
    std::string gl;  // the backend, GL_VENDOR, GL_RENDERER, GL_VERSION it was drawn with
};

// Writes an 8-bit RGB PNG. Errors: BadInput for a light or resolution out of range,
// Internal when no GL context can be made, Io when the file cannot be written.
Expected<RenderReport> renderLightView(const BakeWindow& window, const ChunkVerdicts& verdicts,
                                       const RenderRequest& request, const std::string& pngPath);

}  // namespace shadowcull::gpu
