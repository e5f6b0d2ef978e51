// The second half of `shadowcull preview` (gpu/preview.h), without GL: what the camera pass
// read back, judged pixel by pixel, and the picture. Internal to gpu/.
//
// Every receiving pixel whose shadow differs between the frames is put in one class
// (docs/semantics.md, "Why the frames agree"). Its caster is the culled group of the
// witness below, else the one nearest the light at the first texel that differed; its
// surface is the group the camera sees there.
//   false cull  - a witness shows there: the filter covers the sampling footprint (every
//                 differing texel is then a witness within filterRadius), or the exact light
//                 ray through the lookup point q' meets a culled caster first with q' more
//                 than the bias behind it (preview_witness.h). Split by the surface: the
//                 caster's own (a self-shadow missing) or any other (a shadow missing on
//                 a kept surface: every surface receives, culled casters' too).
//   own surface - the caster's own surface, no witness: its self-shadowing as the engine's
//                 bias draws it (acne), which the spec does not count.
//   band        - another surface, no witness: a texel-centre ray beside q' meets a culled
//                 caster that q's own ray does not (the texel-edge band).
// The gate is the false culls; the report names each culled caster they belong to.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include <glm/vec3.hpp>

#include "core/verdict.h"
#include "gpu/light_view.h"
#include "gpu/preview.h"
#include "gpu/window_draw.h"
#include "util/bitmap_font.h"

namespace shadowcull::gpu {

// The camera's rays, window-local: perspective from `eye` towards `target`, y up (z when
// looking straight down), as the camera pass's clip matrix (cameraClip) draws them.
struct PreviewCamera {
    glm::dvec3 eye{0.0}, target{0.0};
    glm::dvec3 forward{0.0}, side{0.0}, up{0.0};
    double tanHalfX = 1, tanHalfY = 1;
    PreviewCamera(const glm::dvec3& eye, const glm::dvec3& target, double fovYDeg, double aspect);
    // The unit ray through the centre of pixel (x, y) of a width x height frame, row 0 at
    // the top.
    glm::dvec3 rayThrough(int x, int y, int width, int height) const;
};

// What the camera pass read back, RGBA float each, rows bottom to top:
//   pos  - the window-local receiver point (float), and its range index + 1 (0: sky);
//   lit  - shadowed taps with every caster, with the kept ones, the receiving cosine (< 0:
//          not receiving), the surface kind (0 sky, 1 terrain, 2 neighbour, 3 centre);
//   diff - footprint (metres), the first differing texel's caster range + 1, the depth
//          margin there, and the triangle's primitive index in its draw (float bits).
struct PreviewFrames {
    int width = 0, height = 0;
    std::vector<float> pos, lit, diff;
};

// What the frames are judged against.
struct PreviewScene {
    const BakeWindow& window;
    const ChunkVerdicts& verdicts;
    int light = 0;  // 0-based
    const std::vector<GroupRange>& ranges;
    std::vector<uint8_t> culledRange;  // per range: drawn with every caster, not with the kept
    std::vector<int> verdictObject;    // per window object: its index in verdicts, or -1
    const WindowTriangles& triangles;
    PreviewCamera camera;
    int taps = 1;  // PCF taps per pixel
};

// The three frames (all, kept, difference) of the picture.
struct PreviewPanels {
    RgbImage all, kept, diff;
    std::vector<std::array<int, 3>> marks;  // x, y, pixel class (for rings round isolated pixels)
};

// Counts and classifies the pixels into `report` (receiverPixels, coveredPixels, the
// differing counts, falseCulls, listed) and paints the panels.
PreviewPanels judgePixels(const PreviewScene& scene, const PreviewFrames& frames, const PreviewRequest& rq,
                          PreviewReport& report);

// The picture: title lines, the three labelled panels and the legend.
RgbImage composePreviewPicture(const PreviewPanels& panels, const std::vector<std::string>& title,
                               const PreviewReport& report, int width, int height);

}  // namespace shadowcull::gpu
