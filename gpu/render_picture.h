// The picture around a light's rendered view (gpu/render.cpp): title, face labels, axis
// gizmo, outlines of marked groups, the legend; and the PNG writer. No GL here.
#pragma once

#include <array>
#include <string>
#include <vector>

#include "gpu/light_view.h"
#include "gpu/render.h"
#include "util/bitmap_font.h"
#include "util/status.h"

namespace shadowcull::gpu {

// Verdict colours (the original tool's), shared by the render and its legend.
constexpr Rgb kCulledColour{217, 31, 26}, kKeptColour{51, 204, 64}, kUndecidedColour{242, 217, 26},
    kNeighbourColour{120, 120, 120}, kOutlineColour{255, 0, 255};

// The light views as rendered: tiles of `tile` pixels, `cols` x `rows`, top row first.
struct RenderedViews {
    std::vector<LightView> views;
    int tile = 0, cols = 1, rows = 1;
    RgbImage image;
    // Rings around outlined groups: {x0, y0, x1, y1} in views image pixels, one per group
    // and tile it covers (their outlines are painted into `image` by addOutline).
    std::vector<std::array<int, 4>> rings;
    // Outlined groups too thin to cover a pixel: the projection of their box's centre
    // (views image pixels), ringed like the others.
    std::vector<std::array<int, 2>> points;
};

// One legend line: a colour swatch (or none) and its text.
struct LegendEntry {
    std::string text;
    bool swatch = true;
    Rgb colour;
};

// Outlines a group: `mask` (views image size, 1 where the group covers the pixel, seen
// through anything in front of it) is painted into `views.image` as an outline, and a ring
// is kept for each tile it covers. Nothing of the mask is kept: a picture with many
// outlined groups costs one mask at a time.
void addOutline(RenderedViews& views, const std::vector<uint8_t>& mask);

// Lays out the title lines, the views (with face labels, axis gizmo and outlines) and the
// legend; fills the report's title, legend and picture geometry.
RgbImage composePicture(const RenderedViews& views, const std::vector<std::string>& title,
                        const std::vector<LegendEntry>& legend, RenderReport& report);

Status writePng(const std::string& path, const RgbImage& image);

}  // namespace shadowcull::gpu
