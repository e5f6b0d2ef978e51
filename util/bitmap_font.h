// A tiny built-in 5x7 bitmap font (with descenders) and an 8-bit RGB canvas to draw it on, so that the PNG
// pictures (`render`, `check`) carry their own titles, legends and labels without a font
// library. Printable ASCII only (32..126); anything else draws as '?'. No GL dependency.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace shadowcull {

struct Rgb {
    uint8_t r = 0, g = 0, b = 0;
};

// Row 0 at the top. Drawing outside the canvas is clipped, never an error.
class RgbImage {
public:
    RgbImage() = default;
    RgbImage(int width, int height, Rgb fill = {});
    int width() const { return width_; }
    int height() const { return height_; }
    const std::vector<uint8_t>& pixels() const { return rgb_; }  // width * height * 3, top row first

    Rgb at(int x, int y) const;
    void set(int x, int y, Rgb c);
    void fillRect(int x, int y, int w, int h, Rgb c);
    void strokeRect(int x, int y, int w, int h, Rgb c, int thickness = 1);
    // A line `thickness` pixels wide (square brush), end points included.
    void line(double x0, double y0, double x1, double y1, Rgb c, int thickness = 1);
    // A line ending in an arrow head at (x1, y1).
    void arrow(double x0, double y0, double x1, double y1, Rgb c, int thickness = 2);
    // Copies `src` with its top-left corner at (x, y).
    void blit(const RgbImage& src, int x, int y);

private:
    int width_ = 0, height_ = 0;
    std::vector<uint8_t> rgb_;
};

// Glyph cell: 5 x 7 pixels and a descender row (g, j, p, q, y), advanced by 6 (one column
// of spacing), lines 10 apart; all times `scale`.
constexpr int kGlyphWidth = 5, kGlyphHeight = 8, kGlyphAdvance = 6, kLineHeight = 10;

// Width in pixels of `text` drawn at `scale` (no trailing spacing column).
int textWidth(const std::string& text, int scale = 1);

// Draws `text` with its top-left corner at (x, y). Returns the x after the last glyph.
int drawText(RgbImage& image, int x, int y, const std::string& text, Rgb colour, int scale = 1);

// The 8 rows of a glyph's bitmap, bit 4 the leftmost column (for tests and the renderer).
void glyphRows(char c, uint8_t rows[kGlyphHeight]);

}  // namespace shadowcull
