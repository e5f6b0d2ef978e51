#include "gpu/render_picture.h"

#include "io/png_write.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include <glm/geometric.hpp>

namespace shadowcull::gpu {

namespace {

constexpr Rgb kText{235, 235, 235}, kBackground{28, 28, 32}, kTileBorder{90, 90, 100};

const char* const kFaceNames[6] = {"+X", "-X", "+Y", "-Y", "+Z", "-Z"};

// Pixels where a mask meets its outside, widened to `thickness`.
// `img` and `mask` have the same size.
void paintOutline(RgbImage& img, const std::vector<uint8_t>& mask, int thickness) {
    const int w = img.width(), h = img.height();
    auto in = [&](int x, int y) { return x >= 0 && y >= 0 && x < w && y < h && mask[size_t(y) * size_t(w) + size_t(x)]; };
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x)
            if (in(x, y) && !(in(x - 1, y) && in(x + 1, y) && in(x, y - 1) && in(x, y + 1)))
                img.fillRect(x - thickness / 2, y - thickness / 2, thickness, thickness, kOutlineColour);
}

// Bounding rectangle of a mask within one tile, or nothing.
bool maskBox(const std::vector<uint8_t>& mask, int width, int tx, int ty, int tile, int box[4]) {
    box[0] = box[1] = 1 << 30, box[2] = box[3] = -1;
    for (int y = ty; y < ty + tile; ++y)
        for (int x = tx; x < tx + tile; ++x)
            if (mask[size_t(y) * size_t(width) + size_t(x)]) {
                box[0] = std::min(box[0], x), box[1] = std::min(box[1], y);
                box[2] = std::max(box[2], x), box[3] = std::max(box[3], y);
            }
    return box[2] >= 0;
}

// World x, y and z as arrows on a view tile (bottom-left), so that a reader knows which way
// the picture is turned. An axis along the view direction shrinks to a dot and is left out.
void axisGizmo(RgbImage& img, const LightView& v, int tx, int ty, int tile, int scale) {
    const double len = std::min(40.0 * scale, tile / 6.0);
    if (len < 12) return;
    const double ox = tx + len + 12 * scale, oy = ty + tile - len - 12 * scale;
    const glm::dvec3 axes[3] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
    const char* names[3] = {"x", "y", "z"};
    const Rgb colours[3] = {{255, 110, 110}, {120, 255, 120}, {120, 160, 255}};
    for (int k = 0; k < 3; ++k) {
        const double du = glm::dot(axes[k], v.U), dv = glm::dot(axes[k], v.V);
        if (std::hypot(du, dv) < 0.25) continue;
        const double ex = ox + du * len, ey = oy - dv * len;  // image rows grow downwards
        img.arrow(ox, oy, ex, ey, colours[k], scale);
        drawText(img, int(ex + du * 6 * scale) - 2 * scale, int(ey - dv * 6 * scale) - 3 * scale, names[k], colours[k], scale);
    }
}

}  // namespace

void addOutline(RenderedViews& rv, const std::vector<uint8_t>& mask) {
    const int viewW = rv.cols * rv.tile;
    paintOutline(rv.image, mask, std::max(2, rv.tile / 256));
    for (int ty = 0; ty < rv.rows * rv.tile; ty += rv.tile)
        for (int tx = 0; tx < viewW; tx += rv.tile) {
            int b[4];
            if (maskBox(mask, viewW, tx, ty, rv.tile, b)) rv.rings.push_back({b[0], b[1], b[2], b[3]});
        }
}

RgbImage composePicture(const RenderedViews& rv, const std::vector<std::string>& title,
                        const std::vector<LegendEntry>& legend, RenderReport& report) {
    const int viewW = rv.cols * rv.tile, viewH = rv.rows * rv.tile;
    // Text twice the font's size once the views are wide enough to hold it.
    const int s = viewW >= 900 ? 2 : 1;
    const int pad = 8 * s, lineH = kLineHeight * s + 4 * s, swatch = kGlyphHeight * s + 2 * s;
    int textW = 0;
    for (const std::string& t : title) textW = std::max(textW, textWidth(t, s));
    for (const LegendEntry& e : legend) textW = std::max(textW, textWidth(e.text, s) + swatch + 2 * pad);
    const int width = std::max(viewW + 2 * pad, textW + 2 * pad);
    const int headerH = pad + int(title.size()) * lineH + pad / 2;
    const int footerH = pad + int(legend.size()) * lineH + pad;
    RgbImage img(width, headerH + viewH + footerH, kBackground);
    int y = pad;
    for (size_t k = 0; k < title.size(); ++k, y += lineH)
        drawText(img, pad, y, title[k], k == 0 ? Rgb{255, 255, 255} : kText, s);

    const int vx = (width - viewW) / 2, vy = headerH;
    img.blit(rv.image, vx, vy);
    // A ring around each outlined group, so that a group a few pixels wide is found.
    for (const std::array<int, 4>& b : rv.rings) {
        const int r = 10 * s;
        img.strokeRect(vx + b[0] - r, vy + b[1] - r, b[2] - b[0] + 1 + 2 * r, b[3] - b[1] + 1 + 2 * r, kOutlineColour, 2 * s);
    }
    for (size_t v = 0; v < rv.views.size(); ++v) {
        const int tx = int(v) % rv.cols * rv.tile, ty = int(v) / rv.cols * rv.tile;
        for (const auto& [px, py] : rv.points) {
            const int r = 10 * s;
            if (px >= tx && px < tx + rv.tile && py >= ty && py < ty + rv.tile)
                img.strokeRect(vx + px - r, vy + py - r, 2 * r + 1, 2 * r + 1, kOutlineColour, 2 * s);
        }
        if (rv.views.size() > 1) {
            img.strokeRect(vx + tx, vy + ty, rv.tile, rv.tile, kTileBorder, 1);
            const std::string name = rv.views[v].perspective && rv.views[v].face < 6 ? kFaceNames[rv.views[v].face] : "";
            std::string label = name + " face";
            img.fillRect(vx + tx + 1, vy + ty + 1, textWidth(label, s) + 2 * pad, lineH + pad / 2, {0, 0, 0});
            drawText(img, vx + tx + 1 + pad, vy + ty + 1 + pad / 2 + s, label, {255, 255, 255}, s);
        }
        axisGizmo(img, rv.views[v], vx + tx, vy + ty, rv.tile, s);
    }

    y = vy + viewH + pad;
    for (const LegendEntry& e : legend) {
        int x = pad;
        if (e.swatch) {
            img.fillRect(x, y, swatch, swatch, e.colour);
            img.strokeRect(x, y, swatch, swatch, {150, 150, 150}, 1);
        }
        x += swatch + pad;
        drawText(img, x, y + s, e.text, kText, s);
        y += lineH;
    }
    report.width = img.width(), report.height = img.height();
    report.viewX = vx, report.viewY = vy, report.tile = rv.tile, report.cols = rv.cols, report.rows = rv.rows;
    report.title = title;
    report.legend.clear();
    for (const LegendEntry& e : legend) report.legend.push_back(e.text);
    return img;
}

// libpng's own stderr lines become the tool's messages (io/png_write.h).
Status writePng(const std::string& path, const RgbImage& image) {
    return writeRgbPng(path, image.width(), image.height(), image.pixels());
}

}  // namespace shadowcull::gpu
