// Pixel bookkeeping of the confirmation passes: rectangles of pixels, the 8 x 8 pixel cells
// the casters reach (CellMask), and the tests that drop pieces which cannot change what the
// queries read there. Every drop here is exact: what is left out could not have changed a
// lit or passed count at a marked cell (tests/gpu_test.cpp, PruningChangesNoCount).
#pragma once

#include <algorithm>
#include <array>
#include <climits>
#include <cstdint>
#include <optional>
#include <vector>

#include <glm/vec3.hpp>

#include "core/window.h"
#include "gpu/conservative.h"
#include "gpu/light_view.h"

namespace shadowcull::gpu {

// Pixels [x0, x1) x [y0, y1).
struct PixelRect {
    int x0, y0, x1, y1;
    static PixelRect empty() { return {INT32_MAX, INT32_MAX, INT32_MIN, INT32_MIN}; }
    bool isEmpty() const { return x0 >= x1 || y0 >= y1; }
    void add(const PixelRect& o) {
        x0 = std::min(x0, o.x0), y0 = std::min(y0, o.y0), x1 = std::max(x1, o.x1), y1 = std::max(y1, o.y1);
    }
    PixelRect intersect(const PixelRect& o) const {
        return {std::max(x0, o.x0), std::max(y0, o.y0), std::min(x1, o.x1), std::min(y1, o.y1)};
    }
    bool overlaps(const PixelRect& o) const { return !intersect(o).isEmpty(); }
};

// The pixels the casters can reach, on a grid of 8 x 8 pixel cells, with a summed-area
// table so that "does this rectangle meet a marked cell" is O(1), and per cell the depth
// range of the casters there. The other passes are read only at the casters' pixels:
// pieces that cannot touch a marked cell are dropped, and so are receivers that lie
// nowhere behind a caster and occluder sheets that lie nowhere in front of one.
class CellMask {
public:
    CellMask(int width, int height, bool all)
        : nx_((width + kCell - 1) / kCell), ny_((height + kCell - 1) / kCell),
          sum_(size_t(nx_ + 1) * size_t(ny_ + 1), 0), marked_(size_t(nx_) * size_t(ny_), all ? 1 : 0),
          zmin_(marked_.size(), all ? -1e300 : 1e300), zmax_(marked_.size(), all ? 1e300 : -1e300) {}
    void mark(const PixelRect& r, double zmin, double zmax) {
        if (r.isEmpty()) return;
        for (int y = r.y0 / kCell; y <= (r.y1 - 1) / kCell && y < ny_; ++y)
            for (int x = r.x0 / kCell; x <= (r.x1 - 1) / kCell && x < nx_; ++x) {
                const size_t k = size_t(y) * size_t(nx_) + size_t(x);
                marked_[k] = 1;
                zmin_[k] = std::min(zmin_[k], zmin);
                zmax_[k] = std::max(zmax_[k], zmax);
            }
    }
    void finish() {
        for (int y = 0; y < ny_; ++y)
            for (int x = 0; x < nx_; ++x)
                at(x + 1, y + 1) = marked_[size_t(y) * size_t(nx_) + size_t(x)] + at(x, y + 1) + at(x + 1, y) - at(x, y);
    }
    bool touches(const PixelRect& r) const {
        int x0, y0, x1, y1;
        if (!cells(r, x0, y0, x1, y1)) return false;
        return at(x1, y1) - at(x0, y1) - at(x1, y0) + at(x0, y0) > 0;
    }
    // The casters' depth range over the marked cells of r (for large r, everything).
    void depthRange(const PixelRect& r, double& zmin, double& zmax) const {
        zmin = 1e300, zmax = -1e300;
        int x0, y0, x1, y1;
        if (!cells(r, x0, y0, x1, y1)) return;
        if (int64_t(x1 - x0) * int64_t(y1 - y0) > 1024) {
            zmin = -1e300, zmax = 1e300;
            return;
        }
        for (int y = y0; y < y1; ++y)
            for (int x = x0; x < x1; ++x) {
                const size_t k = size_t(y) * size_t(nx_) + size_t(x);
                if (!marked_[k]) continue;
                zmin = std::min(zmin, zmin_[k]);
                zmax = std::max(zmax, zmax_[k]);
            }
    }

private:
    static constexpr int kCell = 8;
    bool cells(const PixelRect& r, int& x0, int& y0, int& x1, int& y1) const {
        if (r.isEmpty()) return false;
        x0 = r.x0 / kCell, y0 = r.y0 / kCell;
        x1 = std::min(nx_, (r.x1 - 1) / kCell + 1), y1 = std::min(ny_, (r.y1 - 1) / kCell + 1);
        return x0 < x1 && y0 < y1;
    }
    uint32_t& at(int x, int y) { return sum_[size_t(y) * size_t(nx_ + 1) + size_t(x)]; }
    uint32_t at(int x, int y) const { return sum_[size_t(y) * size_t(nx_ + 1) + size_t(x)]; }
    int nx_, ny_;
    std::vector<uint32_t> sum_;
    std::vector<uint8_t> marked_;
    std::vector<double> zmin_, zmax_;
};

// The pixels a piece's fragments can reach: those whose square, widened by the piece's
// dilation and margin, meets its bounding box (which holds the shape drawn), clamped to the
// view, with a pixel to spare.
PixelRect reachOf(const RasterPiece& r, const LightView& v);

// Drops the pieces that cannot touch a cell the casters reach, and with `behindOnly`
// (receivers) those whose farthest depth cannot exceed the nearest caster depth there by
// the bias: they can never pass the query's test. `depthEps` is the shader's absolute
// depth margin; the relative terms cover its relative margin and float rounding, twice.
void keepTouching(std::vector<RasterPiece>& pieces, size_t from, const CellMask& mask, const LightView& v,
                  bool behindOnly = false, double bias = 0, double depthEps = 0);

// False when the union of a sheet's triangle pieces (kind 0; those kept for the caster
// cells) holds no whole pixel square [x, x+1] x [y, y+1] (integers x, y), judged by their
// pixel box with 1e-3 px to spare for the float rounding of the boxes. Such a sheet blocks
// no pixel, so leaving it out changes nothing the queries read: a pixel whose square is not
// inside the union meets the union's boundary, which lies on the sheet's crack edges
// (confirm_stage.cpp, point 3), so the shader marks it cracked there; and a pixel of a
// caster cell that lies inside the union has every triangle under it kept, so their box
// holds it. (Jagged scanned meshes split into thousands of such slivers, each of which
// needed its own draw-and-resolve batch when it overlapped another.)
bool holdsWholePixel(const std::vector<RasterPiece>& pieces);

// True when every triangle piece (kind 0) of a sheet lies behind every caster over its own
// reach: its nearest vertex depth beyond the casters' farthest there, by 1e-3 relative (as
// the sheet-wide test in confirm_stage.cpp, far above the shader's depth margins). Then at
// any pixel the sheet's recorded depth, the farthest of its pieces there, is behind every
// caster fragment's nearest depth, so the sheet blocks none of them and leaving it out
// changes no count. (A sheet as large as a dense rock's face spans too many cells for one
// depth range, but its parts behind the examined group lie behind it piece by piece.)
bool behindCasters(const std::vector<RasterPiece>& pieces, const CellMask& mask, const LightView& v);

// A pixel rectangle holding reachOf() of every piece the builder makes from a triangle or
// segment within the convex hull of `pts`, with a dilation up to `dilatePx`; nothing when
// the hull cannot be bounded so. reachOf widens a piece's box by 1.51 px + dilation +
// margin (below 1e-3 + 1e-6 (|coordinates| + size)); one pixel more covers the float
// rounding of the box and of clipped vertices.
std::optional<PixelRect> hullReach(const glm::dvec3* pts, size_t n, const PieceBuilder& pb, float dilatePx);

}  // namespace shadowcull::gpu
