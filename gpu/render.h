// `shadowcull render SPACE --chunk NAME --light N --out image.png`: the light's view of a
// bake window, coloured as in the original tool:
//   grey   - neighbour chunks (loaded as occluders and receivers, not baked)
//   red    - centre-chunk groups culled for this light (proved 0)
//   green  - centre-chunk groups kept (proved 1: a witness, or the baseline's samples)
//   yellow - centre-chunk groups undecided (written 1 without a proof)
// Shaded by the angle to the light so that shapes read. A directional light gives one
// resolution x resolution view; a point light (or a spot wider than
// kMaxSingleViewSpotDeg) its six cube faces side by side, 3 x 2 tiles in the order +x -x
// +y -y +z -z; a spot light the view over its cone.
#pragma once

#include <string>

#include "core/status.h"
#include "core/verdict.h"
#include "core/window.h"

namespace shadowcull::gpu {

// `light` is 0-based (light N on the command line is N-1). Writes an 8-bit RGB PNG.
// Errors: BadInput for a light or resolution out of range, Internal when no GL context
// can be made, Io when the file cannot be written.
Status renderLightView(const BakeWindow& window, const ChunkVerdicts& verdicts, int light, int resolution,
                       const std::string& pngPath);

}  // namespace shadowcull::gpu
