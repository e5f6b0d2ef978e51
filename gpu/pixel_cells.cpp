// Pixel bookkeeping of the confirmation passes (see pixel_cells.h).
#include "gpu/pixel_cells.h"

#include <cmath>

namespace shadowcull::gpu {

PixelRect reachOf(const RasterPiece& r, const LightView& v) {
    const double h = 0.5 + double(r.misc[0]) + double(r.misc[1]) + 0.01 + 1.0;
    const double lx = double(r.box[0]) - h, ly = double(r.box[1]) - h;
    const double hx = double(r.box[2]) + h, hy = double(r.box[3]) + h;
    return {int(std::clamp(std::floor(lx), 0.0, double(v.width))), int(std::clamp(std::floor(ly), 0.0, double(v.height))),
            int(std::clamp(std::ceil(hx), 0.0, double(v.width))), int(std::clamp(std::ceil(hy), 0.0, double(v.height)))};
}

void keepTouching(std::vector<RasterPiece>& pieces, size_t from, const CellMask& mask, const LightView& v,
                  bool behindOnly, double bias, double depthEps) {
    pieces.erase(std::remove_if(pieces.begin() + std::ptrdiff_t(from), pieces.end(),
                                [&](const RasterPiece& r) {
                                    const PixelRect reach = reachOf(r, v);
                                    if (!mask.touches(reach)) return true;
                                    if (!behindOnly) return false;
                                    double zmin, zmax;
                                    mask.depthRange(reach, zmin, zmax);
                                    const double far = double(r.plane2[2]);
                                    return far + 2 * depthEps + 1e-5 * std::abs(far) <
                                           zmin - 2 * depthEps - 1e-5 * std::abs(zmin) + bias;
                                }),
                 pieces.end());
}

bool holdsWholePixel(const std::vector<RasterPiece>& pieces) {
    double b[4] = {1e300, 1e300, -1e300, -1e300};
    for (const RasterPiece& r : pieces) {
        if (r.misc[2] != 0.0f) continue;  // a crack segment
        b[0] = std::min(b[0], double(r.box[0])), b[1] = std::min(b[1], double(r.box[1]));
        b[2] = std::max(b[2], double(r.box[2])), b[3] = std::max(b[3], double(r.box[3]));
    }
    const double d = 1e-3 + 1e-6 * std::max({std::abs(b[0]), std::abs(b[1]), std::abs(b[2]), std::abs(b[3])});
    return std::floor(b[2] + d) - std::ceil(b[0] - d) >= 1 && std::floor(b[3] + d) - std::ceil(b[1] - d) >= 1;
}

bool behindCasters(const std::vector<RasterPiece>& pieces, const CellMask& mask, const LightView& v) {
    for (const RasterPiece& r : pieces) {
        if (r.misc[2] != 0.0f) continue;  // a crack segment: it only ever unblocks
        double casterNear, casterFar;
        mask.depthRange(reachOf(r, v), casterNear, casterFar);
        if (!(double(r.plane2[1]) > casterFar + 1e-3 * (1 + std::abs(casterFar)))) return false;
    }
    return true;
}

std::optional<PixelRect> hullReach(const glm::dvec3* pts, size_t n, const PieceBuilder& pb, float dilatePx) {
    const int width = pb.view().width, height = pb.view().height;
    double b[4];
    if (!pb.hullBounds(pts, n, b)) return std::nullopt;
    const double maxAbs = std::max({std::abs(b[0]), std::abs(b[1]), std::abs(b[2]), std::abs(b[3])});
    const double h = 2.52 + double(dilatePx) + 1e-3 + 2e-6 * (maxAbs + std::max(width, height));
    auto clampTo = [](double v, int hi) { return int(std::clamp(v, 0.0, double(hi))); };
    return PixelRect{clampTo(std::floor(b[0] - h), width), clampTo(std::floor(b[1] - h), height),
                     clampTo(std::ceil(b[2] + h), width), clampTo(std::ceil(b[3] + h), height)};
}

}  // namespace shadowcull::gpu
